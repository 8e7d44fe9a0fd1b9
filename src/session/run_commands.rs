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

use super::traits::{Activity, Calibrator, Robot, RobotError};
use super::{ActiveRun, Session, measure, robot_err};
use crate::motion::run::{Measurement, PathKind};
use crate::protocol::outcome::{Outcome, write_outcome};
use crate::protocol::record;
use crate::protocol::refusal::{Refusal, write_refusal};

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
        if let Some(last) = self.runs.last().filter(|r| r.measured.is_none()) {
            return Err(Refusal::Unmeasured {
                run: self.runs.len(),
                path: last.path,
            }
            .into());
        }
        if self.runs.is_full() {
            return Err(Refusal::StoreFull.into());
        }
        robot.start(path).map_err(RunError::Robot)?;
        let run = self.runs.len() + 1;
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
        let Some(run) = index.checked_sub(1).and_then(|i| self.runs.get(i)) else {
            return write_refusal(out, &Refusal::NoSuchRun { run: index, stored });
        };
        if first_knot > 0 && first_knot >= run.knots.len() {
            let knots = run.knots.len();
            return write_refusal(out, &Refusal::NoSuchKnot { run: index, knots });
        }
        record::write_record_page(out, index, run, first_knot)
    }

    /// `drop <n>`: removes run `index` from the store; later runs move up one number.
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
        let removed = index
            .checked_sub(1)
            .and_then(|i| remove_at(&mut self.runs, i));
        let Some(run) = removed else {
            return Err(Refusal::NoSuchRun { run: index, stored }.into());
        };
        let _ = remove_at(&mut self.run_ids, index - 1);
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
        if self.active.is_some() || robot.status().activity != Activity::Idle {
            return Err(RunError::Robot(RobotError::Busy));
        }
        let runs = self.runs.len();
        if !confirmed {
            return Err(Refusal::DropAllUnconfirmed { runs }.into());
        }
        self.runs.clear();
        self.run_ids.clear();
        self.runs_changed();
        Ok(Outcome::DroppedAll { runs })
    }

    /// `measure [#n] x y [θ]` and its reply.
    pub(super) fn measure(
        &mut self,
        index: Option<usize>,
        typed: measure::MeasuredPose,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let result = self.try_measure(index, typed, robot);
        write_reply(out, result, robot)
    }

    /// `measure [#n] x y [θ]`: without `#n` it fills the last finished run if that is
    /// unmeasured (never an earlier one, never after an aborted run); `#n` fills or replaces run
    /// `n` and says what it replaced, keeping run n's measured heading when no new one is given.
    /// Refused while anything moves, and when implausible (a bare value is never converted: the
    /// reply asks for the unit written out).
    fn try_measure(
        &mut self,
        index: Option<usize>,
        typed: measure::MeasuredPose,
        robot: &mut dyn Robot,
    ) -> Result<Outcome, RunError> {
        if robot.status().activity != Activity::Idle {
            return Err(Refusal::MeasureWhileDriving.into());
        }
        let stored = self.runs.len();
        let n = match index {
            Some(n) if n > stored => return Err(Refusal::NoSuchRun { run: n, stored }.into()),
            Some(n) => n,
            None => {
                if let Some(a) = self.last_aborted {
                    return Err(Refusal::Aborted { run: a.number }.into());
                }
                match self.runs.last() {
                    None => return Err(Refusal::NothingToMeasure.into()),
                    Some(r) if r.measured.is_some() => {
                        return Err(Refusal::AlreadyMeasured { run: stored }.into());
                    }
                    Some(_) => stored,
                }
            }
        };
        let Some(run) = self.runs.get_mut(n - 1) else {
            return Err(Refusal::NoSuchRun { run: n, stored }.into());
        };
        if let Err(why) = measure::check_typed(run, typed.x, typed.y, typed.theta) {
            return Err(RunError::Implausible {
                run: n,
                path: run.path,
                why,
            });
        }
        // `measure #n x y` without θ keeps the heading measured before.
        let heading_kept = match typed.theta {
            None => run.measured.and_then(|m| m.theta_rad),
            Some(_) => None,
        };
        let (x_m, y_m) = (typed.x.m, typed.y.m);
        let replaced = run.measured.replace(Measurement {
            x_m,
            y_m,
            theta_rad: typed.theta.map(|t| t.deg.to_radians()).or(heading_kept),
        });
        let odo = run.odometry_end;
        let path = run.path;
        self.runs_changed();
        Ok(Outcome::Measured {
            run: n,
            path,
            replaced,
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
