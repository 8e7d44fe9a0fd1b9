//! The commands on runs: starting one (`run`, `next`, `line`, `circle`), stopping it (`stop`),
//! measuring its true end pose (`measure`), reading its record (`record`) and dropping runs
//! from the store (`drop <n>`, `drop all`).
//!
//! Owns which run the session announced as started and the rules of `measure` (which run a
//! plain `measure` fills, when it is refused); the plausibility check and the measurement's
//! text are [`super::measure`]'s.

use core::fmt::{self, Write};

use heapless::Vec;

use super::traits::{Activity, Calibrator, Robot, RobotError};
use super::{ActiveRun, Session, measure, report, robot_err};
use crate::motion::run::{Measurement, PathKind};
use crate::protocol::record;
use crate::protocol::refusal::{Refusal, write_refusal};
use crate::protocol::reply::EOL;
use crate::util::decimal::Decimal;

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

/// `err 14: no run <index> (<n> stored)`.
fn no_such_run(out: &mut dyn Write, index: usize, stored: usize) -> fmt::Result {
    write_refusal(out, &Refusal::NoSuchRun { run: index, stored })
}

impl<C: Calibrator> Session<C> {
    /// Starts a run along `path`, refused while the run store is full.
    pub(super) fn start(
        &mut self,
        path: PathKind,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        if let Some(refused) = self.refuse_unmeasured(out) {
            return refused;
        }
        if self.runs.is_full() {
            return write_refusal(out, &Refusal::StoreFull);
        }
        match robot.start(path) {
            Ok(()) => {
                let number = self.runs.len() + 1;
                self.active = Some(ActiveRun { number, path });
                write!(out, "ok run {number} started: ")?;
                report::write_path(out, &path)?;
                out.write_str(EOL)
            }
            Err(e) => robot_err(out, e, robot),
        }
    }

    /// `err 24` when the last finished run is not measured: a run is measured or dropped
    /// before the next one starts, so its end pose is not lost and a plain `measure` cannot
    /// fill the wrong run.
    fn refuse_unmeasured(&self, out: &mut dyn Write) -> Option<fmt::Result> {
        let run = self.runs.last().filter(|r| r.measured.is_none())?;
        let refusal = Refusal::Unmeasured {
            run: self.runs.len(),
            path: run.path,
        };
        Some(write_refusal(out, &refusal))
    }

    /// `next`: starts the next planned square, or says the plan is complete.
    pub(super) fn start_next(&mut self, robot: &mut dyn Robot, out: &mut dyn Write) -> fmt::Result {
        match self.next_planned() {
            Some(direction) => {
                let path = PathKind::Square {
                    direction,
                    side_m: self.settings.square_side_f64(),
                };
                self.start(path, robot, out)
            }
            None => write_refusal(out, &Refusal::PlanComplete),
        }
    }

    /// `stop`: stops any motion and says whether that aborted the run in progress.
    pub(super) fn stop(&mut self, robot: &mut dyn Robot, out: &mut dyn Write) -> fmt::Result {
        let before = self.active;
        robot.abort();
        self.collect_finished(robot, out)?;
        match before {
            Some(a) if self.last_aborted == Some(a) => {
                write!(out, "ok stopped: run {} aborted, not stored\r\n", a.number)
            }
            _ => write!(out, "ok stopped\r\n"),
        }
    }

    /// `record <n> [first knot]`: one page of run `index`'s record.
    pub(super) fn record(
        &self,
        index: usize,
        first_knot: usize,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let Some(run) = index.checked_sub(1).and_then(|i| self.runs.get(i)) else {
            return no_such_run(out, index, self.runs.len());
        };
        if first_knot > 0 && first_knot >= run.knots.len() {
            let knots = run.knots.len();
            return write_refusal(out, &Refusal::NoSuchKnot { run: index, knots });
        }
        record::write_record_page(out, index, run, first_knot)
    }

    /// `drop <n>`: removes run `index` from the store; later runs move up one number.
    pub(super) fn drop_run(&mut self, index: usize, out: &mut dyn Write) -> fmt::Result {
        let removed = index
            .checked_sub(1)
            .and_then(|i| remove_at(&mut self.runs, i));
        let Some(run) = removed else {
            return no_such_run(out, index, self.runs.len());
        };
        let _ = remove_at(&mut self.run_ids, index - 1);
        self.runs_changed();
        write!(out, "ok dropped run {index}: ")?;
        report::write_path(out, &run.path)?;
        write!(out, "; {} left\r\n", report::Count(self.runs.len(), "run"))
    }

    /// `drop all [yes]`: empties the run store, only when confirmed with `yes`; refused while
    /// anything moves.
    pub(super) fn drop_all(
        &mut self,
        confirmed: bool,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        if self.active.is_some() || robot.status().activity != Activity::Idle {
            return robot_err(out, RobotError::Busy, robot);
        }
        let n = self.runs.len();
        if !confirmed {
            return write_refusal(out, &Refusal::DropAllUnconfirmed { runs: n });
        }
        self.runs.clear();
        self.run_ids.clear();
        self.runs_changed();
        write!(out, "ok dropped all {}\r\n", report::Count(n, "run"))
    }

    /// `measure [#n] x y [θ]`: without `#n` it fills the last finished run if that is
    /// unmeasured (never an earlier one, never after an aborted run); `#n` fills or replaces run
    /// `n` and says what it replaced, keeping run n's measured heading when no new one is given.
    /// Refused while anything moves, and when implausible (a bare value is never converted: the
    /// reply asks for the unit written out).
    pub(super) fn measure(
        &mut self,
        index: Option<usize>,
        typed: measure::Typed,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let (x_m, y_m) = (typed.x.m, typed.y.m);
        if robot.status().activity != Activity::Idle {
            return write_refusal(out, &Refusal::MeasureWhileDriving);
        }
        let stored = self.runs.len();
        let n = match index {
            Some(n) if n > stored => return no_such_run(out, n, stored),
            Some(n) => n,
            None => {
                if let Some(a) = self.last_aborted {
                    return write_refusal(out, &Refusal::Aborted { run: a.number });
                }
                match self.runs.last() {
                    None => return write_refusal(out, &Refusal::NothingToMeasure),
                    Some(r) if r.measured.is_some() => {
                        return write_refusal(out, &Refusal::AlreadyMeasured { run: stored });
                    }
                    Some(_) => stored,
                }
            }
        };
        let Some(run) = self.runs.get_mut(n - 1) else {
            return no_such_run(out, n, stored);
        };
        if let Err(why) = measure::check_typed(run, typed.x, typed.y, typed.theta) {
            let refusal = Refusal::Implausible {
                run: n,
                path: run.path,
                why: &why,
            };
            return write_refusal(out, &refusal);
        }
        // `measure #n x y` without θ keeps the heading measured before.
        let kept = match typed.theta {
            None => run.measured.and_then(|m| m.theta_rad),
            Some(_) => None,
        };
        let theta_rad = typed.theta.map(|t| t.deg.to_radians()).or(kept);
        let replaced = run.measured.replace(Measurement {
            x_m,
            y_m,
            theta_rad,
        });
        let odo = run.odometry_end;
        let path = run.path;
        self.runs_changed();
        write!(out, "ok run {n} ")?;
        report::write_path(out, &path)?;
        out.write_str(" measured")?;
        if let Some(old) = replaced {
            out.write_str(" (replaced ")?;
            measure::write_measurement(out, &old)?;
            out.write_str(")")?;
        }
        write!(
            out,
            ": error vs odometry dx={} dy={} m",
            Decimal::signed(x_m - odo.x_m, 6),
            Decimal::signed(y_m - odo.y_m, 6),
        )?;
        if let Some(t) = kept {
            write!(
                out,
                " (heading kept: theta_deg={})",
                Decimal::signed(t.to_degrees(), 4)
            )?;
        }
        out.write_str(EOL)
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
