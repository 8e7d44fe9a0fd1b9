//! The commands on runs: starting one (`run`, `next`, `line`, `circle`), stopping it (`stop`),
//! measuring its true end pose (`measure`), reading its record (`record`) and dropping runs
//! from the store (`drop <n>`, `drop all`).
//!
//! Owns which run the session announced as started and the rules of `measure` (which run a
//! plain `measure` fills, when it is refused); the plausibility check is [`super::measure`]'s.
//! Each command returns a typed [`Outcome`] or [`RunError`]; the reply text is the protocol's
//! ([`crate::protocol::outcome`], [`crate::protocol::refusal`]).

use core::fmt::{self, Write};

use heapless::Vec;

use super::traits::{Calibrator, Robot, RobotError};
use super::{ActiveRun, Session, measure, robot_err};
use crate::motion::run::{Measurement, PathKind};
use crate::protocol::command::check_measure_range;
use crate::protocol::outcome::{Outcome, write_outcome};
use crate::protocol::record;
use crate::protocol::refusal::{Refusal, write_refusal};
use crate::protocol::reply::{ErrorCode, write_err};
use crate::protocol::unit::{Angle, Length};

/// Removes and returns element `i` of `v`, keeping the order of the others (as `Vec::remove`),
/// or `None` when there is no element `i`. The element walks to the end by swaps of disjoint
/// neighbours, so no overlapping copy (`memmove`, 1.5 KiB of flash) is needed.
fn remove_at<T, const N: usize>(v: &mut Vec<T, N>, i: usize) -> Option<T> {
    for k in i + 1..v.len() {
        let (front, back) = v.split_at_mut(k);
        if let (Some(a), Some(b)) = (front.last_mut(), back.first_mut()) {
            core::mem::swap(a, b);
        }
    }
    if i < v.len() { v.pop() } else { None }
}

/// Why a run command was refused.
#[derive(Clone, Copy, Debug)]
pub(super) enum RunError {
    /// The session's own rule (the runs, the plan, a confirmation).
    Refused(Refusal<'static>),
    /// The robot refused (busy, a fault, the controller).
    Robot(RobotError),
    /// The measurement of run `run` is implausible.
    Implausible {
        run: usize,
        path: PathKind,
        why: measure::Implausible,
    },
}

impl From<Refusal<'static>> for RunError {
    fn from(r: Refusal<'static>) -> Self {
        RunError::Refused(r)
    }
}

/// Writes the reply of a run command: its `ok` line, or its `err` line.
fn write_reply(
    out: &mut dyn Write,
    result: Result<Outcome, RunError>,
    robot: &mut dyn Robot,
) -> fmt::Result {
    match result {
        Ok(outcome) => write_outcome(out, &outcome),
        Err(RunError::Refused(r)) => write_refusal(out, &r),
        Err(RunError::Robot(e)) => robot_err(out, e, robot),
        Err(RunError::Implausible { run, path, why }) => write_refusal(
            out,
            &Refusal::Implausible {
                run,
                path,
                why: &why,
            },
        ),
    }
}

impl<C: Calibrator> Session<C> {
    /// Starts a run along `path` and writes the reply.
    pub(super) fn start(
        &mut self,
        path: PathKind,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let result = self.try_start(path, robot);
        write_reply(out, result, robot)
    }

    /// Starts a run along `path`; refused while the last finished run is unmeasured (a run is
    /// measured or dropped before the next one starts, so its end pose is not lost and a plain
    /// `measure` cannot fill the wrong run) and while the run store is full.
    fn try_start(&mut self, path: PathKind, robot: &mut dyn Robot) -> Result<Outcome, RunError> {
        if let Some(refusal) = self.unmeasured_end() {
            return Err(refusal.into());
        }
        if self.runs.is_full() {
            return Err(Refusal::StoreFull.into());
        }
        robot.start(path).map_err(RunError::Robot)?;
        let run = usize::from(self.next_number);
        self.active = Some(ActiveRun { number: run, path });
        Ok(Outcome::Started { run, path })
    }

    /// `next`: starts the next planned square (or says the plan is complete) and writes the
    /// reply; returns whether it started.
    pub(super) fn start_next(
        &mut self,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> Result<bool, fmt::Error> {
        let result = match self.next_planned() {
            Some(direction) => {
                let path = PathKind::Square {
                    direction,
                    side_m: self.settings.square_side_f64(),
                };
                self.try_start(path, robot)
            }
            None => Err(Refusal::PlanComplete.into()),
        };
        let started = result.is_ok();
        write_reply(out, result, robot)?;
        Ok(started)
    }

    /// `stop`: stops any motion and says whether that aborted the run in progress (the
    /// aborted run's event is written first).
    pub(super) fn stop(&mut self, robot: &mut dyn Robot, out: &mut dyn Write) -> fmt::Result {
        let before = self.active;
        robot.abort();
        self.collect_finished(robot, out)?;
        let aborted = before
            .filter(|a| self.last_aborted == Some(*a))
            .map(|a| a.number);
        write_outcome(out, &Outcome::Stopped { aborted })
    }

    /// `record <n> [first knot]`: one page of run `index`'s record.
    pub(super) fn record(
        &self,
        index: usize,
        first_knot: usize,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let stored = self.runs.len();
        let Some(run) = self.position(index).and_then(|i| self.runs.get(i)) else {
            return write_refusal(out, &Refusal::NoSuchRun { run: index, stored });
        };
        if first_knot > 0 && first_knot >= run.knots.len() {
            let knots = run.knots.len();
            return write_refusal(out, &Refusal::NoSuchKnot { run: index, knots });
        }
        record::write_record_page(out, index, run, first_knot)
    }

    /// `drop <n>`: removes run number `index` from the store; the other runs keep their
    /// numbers (a gap is left).
    pub(super) fn drop_run(
        &mut self,
        index: usize,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let result = self.try_drop_run(index);
        write_reply(out, result, robot)
    }

    fn try_drop_run(&mut self, index: usize) -> Result<Outcome, RunError> {
        let stored = self.runs.len();
        let position = self.position(index);
        let removed = position.and_then(|i| remove_at(&mut self.runs, i));
        let (Some(run), Some(i)) = (removed, position) else {
            return Err(Refusal::NoSuchRun { run: index, stored }.into());
        };
        let _ = remove_at(&mut self.run_ids, i);
        let _ = remove_at(&mut self.numbers, i);
        self.runs_changed();
        Ok(Outcome::Dropped {
            run: index,
            path: run.path,
            left: self.runs.len(),
        })
    }

    /// `drop all [yes]`: empties the run store, only when confirmed with `yes`; refused while
    /// anything moves.
    pub(super) fn drop_all(
        &mut self,
        confirmed: bool,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let result = self.try_drop_all(confirmed, robot);
        write_reply(out, result, robot)
    }

    fn try_drop_all(
        &mut self,
        confirmed: bool,
        robot: &mut dyn Robot,
    ) -> Result<Outcome, RunError> {
        if self.active.is_some() || robot.status().is_busy() {
            return Err(RunError::Robot(RobotError::Busy));
        }
        let runs = self.runs.len();
        if !confirmed {
            return Err(Refusal::DropAllUnconfirmed { runs }.into());
        }
        self.runs.clear();
        self.run_ids.clear();
        self.renumber();
        self.runs_changed();
        Ok(Outcome::DroppedAll { runs })
    }

    /// `measure [#n] x y [θ] [yes]` and its reply: each bare value in the session's declared
    /// unit (none declared: refused, naming the units), ranges checked once converted.
    pub(super) fn measure(
        &mut self,
        index: Option<usize>,
        (x, y, theta): (Length, Length, Option<Angle>),
        confirmed: bool,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let no_unit = |what, value| Refusal::NoUnit { what, value };
        let (x_m, y_m) = (x.metres(self.measure_unit), y.metres(self.measure_unit));
        let (Some(x_m), Some(y_m)) = (x_m, y_m) else {
            let (what, value) = if x_m.is_none() {
                ("x", x.value)
            } else {
                ("y", y.value)
            };
            return write_refusal(out, &no_unit(what, value));
        };
        let theta_deg = match theta {
            None => None,
            Some(t) => match t.degrees(self.heading_unit) {
                Some(d) => Some(d),
                None => return write_refusal(out, &no_unit("theta", t.value)),
            },
        };
        if let Err(e) = check_measure_range(x_m, y_m, theta_deg) {
            return write_err(out, ErrorCode::from(&e), &e);
        }
        let result = self.try_measure(index, (x_m, y_m, theta_deg), confirmed, robot);
        write_reply(out, result, robot)
    }

    /// `measure [#n] x y [θ]`: without `#n` it fills the last finished run if that is
    /// unmeasured (never an earlier one, never after an aborted run); `#n` fills or replaces run
    /// `n` and says what it replaced, keeping run n's measured heading when no new one is given.
    /// Refused while anything moves, and beyond the plausibility bound unless `confirmed`.
    fn try_measure(
        &mut self,
        index: Option<usize>,
        (x_m, y_m, theta_deg): (f64, f64, Option<f64>),
        confirmed: bool,
        robot: &mut dyn Robot,
    ) -> Result<Outcome, RunError> {
        if robot.status().is_busy() {
            return Err(Refusal::MeasureWhileDriving.into());
        }
        let stored = self.runs.len();
        let (n, i) = match index {
            Some(n) => match self.position(n) {
                Some(i) => (n, i),
                None => return Err(Refusal::NoSuchRun { run: n, stored }.into()),
            },
            None => {
                if let Some(a) = self.last_aborted {
                    return Err(Refusal::Aborted { run: a.number }.into());
                }
                let last = stored.wrapping_sub(1);
                match self.runs.last() {
                    None => return Err(Refusal::NothingToMeasure.into()),
                    Some(r) if r.measured.is_some() => {
                        let run = self.number_at(last);
                        return Err(Refusal::AlreadyMeasured { run }.into());
                    }
                    Some(_) => (self.number_at(last), last),
                }
            }
        };
        let Some(run) = self.runs.get_mut(i) else {
            return Err(Refusal::NoSuchRun { run: n, stored }.into());
        };
        if let Err(why) = measure::check(run, x_m, y_m, theta_deg)
            && !confirmed
        {
            return Err(RunError::Implausible {
                run: n,
                path: run.path,
                why,
            });
        }
        // `measure #n x y` without θ keeps the heading measured before.
        let heading_kept = match theta_deg {
            None => run.measured.and_then(|m| m.theta_rad),
            Some(_) => None,
        };
        let read = Measurement {
            x_m,
            y_m,
            theta_rad: theta_deg.map(f64::to_radians).or(heading_kept),
        };
        let replaced = run.measured.replace(read);
        let odo = run.odometry_end;
        let path = run.path;
        self.runs_changed();
        Ok(Outcome::Measured {
            run: n,
            path,
            replaced,
            read,
            error_m: (x_m - odo.x_m, y_m - odo.y_m),
            heading_kept,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::remove_at;
    use heapless::Vec;

    #[test]
    fn remove_at_keeps_the_order_of_the_others() {
        let mut v: Vec<u32, 5> = Vec::from_slice(&[10, 11, 12, 13, 14]).unwrap();
        assert_eq!(remove_at(&mut v, 1), Some(11));
        assert_eq!(v.as_slice(), &[10, 12, 13, 14]);
        assert_eq!(remove_at(&mut v, 3), Some(14));
        assert_eq!(v.as_slice(), &[10, 12, 13]);
        assert_eq!(remove_at(&mut v, 0), Some(10));
        assert_eq!(v.as_slice(), &[12, 13]);
        assert_eq!(remove_at(&mut v, 2), None);
        assert_eq!(v.as_slice(), &[12, 13]);
    }
}
