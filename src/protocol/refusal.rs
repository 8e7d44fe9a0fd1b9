//! Why the session refused a command, as values: each [`Refusal`] maps to one error code
//! ([`Refusal::code`]) and its `err` line is written here ([`write_refusal`]), so the session
//! decides and the protocol words it.
//!
//! The refusals of the parser and the line assembler are [`super::ParseError`] and
//! [`super::LineError`]; these are the ones that depend on the session's state (the runs, the
//! robot's activity, a confirmation).

use core::fmt::{self, Write};

use super::reply::{EOL, ErrorCode};
use crate::motion::controller::MotorsRunning;
use crate::motion::run::PathKind;
use crate::storage::StoreError;
use crate::util::decimal::{Decimal, Plain, Scientific};

/// What is in progress when a command is refused as busy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum InProgress {
    /// A run along this path.
    Run(PathKind),
    /// Velocity commands (`drive`).
    Drive,
    /// A bring-up check.
    Bringup,
    /// A motor identification.
    Identify,
    /// A run that the controller has ended and the session has not collected yet.
    Ending,
}

/// A command the session refused, with what the reply names.
#[derive(Clone, Copy)]
#[non_exhaustive]
pub enum Refusal<'a> {
    /// `err 10`: something is in progress; wait for it.
    Busy(InProgress),
    /// `err 10`: `measure` while a run drives.
    MeasureWhileDriving,
    /// `err 12`: `measure` with no finished run.
    NothingToMeasure,
    /// `err 12`: plain `measure` when the last run is measured already.
    AlreadyMeasured {
        /// The last run's number.
        run: usize,
    },
    /// `err 12`: plain `measure` after an aborted run.
    Aborted {
        /// The aborted run's number.
        run: usize,
    },
    /// `err 14`: no run with this number.
    NoSuchRun {
        /// The number asked for.
        run: usize,
        /// Runs stored.
        stored: usize,
    },
    /// `err 6`: `record <n> <first>` beyond the run's knots.
    NoSuchKnot {
        /// The run.
        run: usize,
        /// Its knots.
        knots: usize,
    },
    /// `err 15`: the run store is full.
    StoreFull,
    /// `err 20`: every planned run is done.
    PlanComplete,
    /// `err 24`: the last finished run is not measured.
    Unmeasured {
        /// Its number.
        run: usize,
        /// Its path.
        path: PathKind,
    },
    /// `err 26`: a bare `measure` value and no unit declared for the session.
    NoUnit {
        /// The argument (`x`, `y`, `theta`).
        what: &'static str,
        /// The value as typed.
        value: f64,
    },
    /// `err 25`: `reset-params` without `yes` while it would discard a change.
    ResetUnconfirmed {
        /// The applied calibration's method, if one is applied.
        calibration: Option<&'a str>,
        /// The settings differ from what is saved.
        unsaved: bool,
    },
    /// `err 25`: `drop all` without `yes`.
    DropAllUnconfirmed {
        /// Runs it would forget.
        runs: usize,
    },
    /// `err 25`: `apply` without `yes` while runs are flagged.
    Flagged {
        /// The flagged runs' numbers.
        runs: &'a [usize],
        /// The method as the calibrator names it.
        method: &'a str,
    },
    /// `err 25`: the runs fit no geometry within the measuring noise; `apply` needs `yes`.
    PoorFit {
        /// The fit's χ² probability.
        probability: f64,
        /// The method as the calibrator names it.
        method: &'a str,
    },
    /// `err 13`: no measured square in a direction.
    NotEnoughRuns {
        /// Measured CW squares.
        cw: usize,
        /// Measured CCW squares.
        ccw: usize,
    },
    /// `err 7`: an unknown method.
    UnknownMethod {
        /// The calibrator's methods.
        methods: &'a [&'static str],
    },
    /// `err 16`: the calibration method failed, for the reason `why`.
    MethodFailed {
        /// Why (the calibrator's error).
        why: &'a dyn fmt::Display,
    },
    /// `err 16`: every method of the `calibrate` table failed.
    NoMethodSucceeded,
    /// `err 11`: a fault is latched.
    Fault {
        /// Its short name (`stall`, `following-error`, …).
        name: &'a str,
    },
    /// `err 10`: the controller refused the request, for the reason `why`.
    ControllerRefused {
        /// Why.
        why: &'a dyn fmt::Display,
    },
    /// `err 17`: parameters refused (an inconsistent geometry, a record `save` would refuse).
    InvalidParams {
        /// Why.
        why: &'a dyn fmt::Display,
    },
    /// `err 18`: a flash write refused because the motors are not confirmed stopped (worded by
    /// [`MotorsRunning`]).
    MotorsRunning(MotorsRunning),
    /// A store operation failed, worded by [`StoreError`]'s one `Display`: `err 17` for
    /// settings the parameter record refuses, `err 19` for the flash.
    Store(StoreError),
    /// `err 22`: an implausible measurement of run `run`, for the reason `why`.
    Implausible {
        /// The run.
        run: usize,
        /// Its path.
        path: PathKind,
        /// Why (the session's plausibility check).
        why: &'a dyn fmt::Display,
    },
}

impl fmt::Debug for Refusal<'_> {
    /// The `err` line's text without its terminator.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        struct Line<'f, 'g>(&'f mut fmt::Formatter<'g>);
        impl Write for Line<'_, '_> {
            fn write_str(&mut self, s: &str) -> fmt::Result {
                self.0.write_str(s.trim_end_matches(EOL))
            }
        }
        write_refusal(&mut Line(f), self)
    }
}

impl Refusal<'_> {
    /// The error code on the wire.
    pub fn code(&self) -> ErrorCode {
        match self {
            Refusal::Busy(_) | Refusal::MeasureWhileDriving | Refusal::ControllerRefused { .. } => {
                ErrorCode::Busy
            }
            Refusal::MethodFailed { .. } | Refusal::NoMethodSucceeded => {
                ErrorCode::CalibrationFailed
            }
            Refusal::Fault { .. } => ErrorCode::Fault,
            Refusal::InvalidParams { .. } => ErrorCode::InvalidParams,
            Refusal::MotorsRunning(_) => ErrorCode::MotorsRunning,
            Refusal::Store(StoreError::InvalidRecord(_)) => ErrorCode::InvalidParams,
            Refusal::Store(_) => ErrorCode::Storage,
            Refusal::NothingToMeasure
            | Refusal::AlreadyMeasured { .. }
            | Refusal::Aborted { .. } => ErrorCode::NoRun,
            Refusal::NoSuchRun { .. } => ErrorCode::NoSuchRun,
            Refusal::NoSuchKnot { .. } => ErrorCode::OutOfRange,
            Refusal::StoreFull => ErrorCode::StoreFull,
            Refusal::PlanComplete => ErrorCode::PlanComplete,
            Refusal::Unmeasured { .. } => ErrorCode::Unmeasured,
            Refusal::DropAllUnconfirmed { .. }
            | Refusal::Flagged { .. }
            | Refusal::PoorFit { .. }
            | Refusal::ResetUnconfirmed { .. } => ErrorCode::NotConfirmed,
            Refusal::NoUnit { .. } => ErrorCode::NoUnit,
            Refusal::NotEnoughRuns { .. } => ErrorCode::NotEnoughRuns,
            Refusal::UnknownMethod { .. } => ErrorCode::BadKeyword,
            Refusal::Implausible { .. } => ErrorCode::Implausible,
        }
    }
}

/// `square cw L=2.000 m`, `line d=1.000 m`, `circle ccw r=0.500 m`: a path as replies name it.
///
/// # Errors
/// Only if `out` refuses the text.
pub fn write_path(out: &mut dyn Write, path: &PathKind) -> fmt::Result {
    match path {
        PathKind::Square { direction, side_m } => {
            write!(
                out,
                "square {} L={} m",
                direction.as_str(),
                Decimal::fixed(*side_m, 3)
            )
        }
        PathKind::Line { length_m } => write!(out, "line d={} m", Decimal::fixed(*length_m, 3)),
        PathKind::Circle {
            direction,
            radius_m,
        } => write!(
            out,
            "circle {} r={} m",
            direction.as_str(),
            Decimal::fixed(*radius_m, 3)
        ),
    }
}

/// `run 2 is` / `runs 2 5 are`.
fn write_run_list(out: &mut dyn Write, runs: &[usize]) -> fmt::Result {
    write_run_numbers(out, runs)?;
    out.write_str(if runs.len() == 1 { " is" } else { " are" })
}

/// `run <n>` / `runs <n> <m> …`.
pub(crate) fn write_run_numbers(out: &mut dyn Write, runs: &[usize]) -> fmt::Result {
    out.write_str(if runs.len() == 1 { "run" } else { "runs" })?;
    for n in runs {
        write!(out, " {n}")?;
    }
    Ok(())
}

/// `<n> run` / `<n> runs`.
fn write_runs(out: &mut dyn Write, n: usize) -> fmt::Result {
    write!(out, "{n} run{}", if n == 1 { "" } else { "s" })
}

/// Writes `err <code>: <what and what to do>\r\n` for `refusal`.
///
/// # Errors
/// Only if `out` refuses the text.
pub fn write_refusal(out: &mut dyn Write, refusal: &Refusal<'_>) -> fmt::Result {
    write!(out, "err {}: ", refusal.code().code())?;
    match *refusal {
        Refusal::Busy(what) => match what {
            InProgress::Run(path) => {
                out.write_str("a run is in progress (")?;
                write_path(out, &path)?;
                out.write_str("): wait for it to finish")?;
            }
            InProgress::Drive => out.write_str(
                "drive is in progress: wait for the motors to stop (500 ms after the last drive)",
            )?,
            InProgress::Identify => {
                out.write_str("identify is in progress: wait for its result")?
            }
            InProgress::Bringup => out.write_str("bringup is in progress: wait for its result")?,
            InProgress::Ending => out.write_str("a run is ending: wait for its event line")?,
        },
        Refusal::MeasureWhileDriving => {
            out.write_str("a run is driving: measure after its `event run … finished` line")?
        }
        Refusal::NothingToMeasure => {
            out.write_str("no finished run to measure (run cw|ccw or next first)")?
        }
        Refusal::AlreadyMeasured { run } => write!(
            out,
            "run {run} is already measured (measure #{run} x y [theta] replaces it)"
        )?,
        Refusal::Aborted { run } => write!(
            out,
            "run {run} was aborted and not stored: nothing to measure (drive it again; measure \
             #<n> x y fills an earlier run)"
        )?,
        Refusal::NoSuchRun { run, stored } => write!(out, "no run {run} ({stored} stored)")?,
        Refusal::NoSuchKnot { run, knots } => write!(out, "run {run} has {knots} knots")?,
        Refusal::StoreFull => out.write_str("run store full (drop <n> first)")?,
        Refusal::PlanComplete => {
            out.write_str("all planned runs done (calibrate, or run cw|ccw for more)")?
        }
        Refusal::Unmeasured { run, path } => {
            write!(out, "run {run} (")?;
            write_path(out, &path)?;
            write!(
                out,
                ") is not measured yet: measure it or drop it first (measure x y [theta], or \
                 drop {run})"
            )?;
        }
        Refusal::NoUnit { what, value } => {
            let (units, setting) = if what == "theta" {
                ("deg or rad", "heading_unit deg|rad")
            } else {
                ("mm, cm or m", "measure_unit mm|cm|m")
            };
            write!(
                out,
                "<{what}> {} has no unit: write {units} after it ({}{}), or declare one for \
                 this session: set {setting}",
                Plain(value),
                Plain(value),
                if what == "theta" { "deg" } else { "mm" },
            )?;
        }
        Refusal::ResetUnconfirmed {
            calibration,
            unsaved,
        } => {
            out.write_str("reset-params discards ")?;
            if let Some(m) = calibration {
                write!(out, "the applied calibration ({m})")?;
                if unsaved {
                    out.write_str(" and ")?;
                }
            }
            if unsaved {
                out.write_str("changes not saved")?;
            }
            out.write_str(": type reset-params yes to do it (save first to keep them)")?;
        }
        Refusal::DropAllUnconfirmed { runs } => {
            out.write_str("drop all forgets ")?;
            write_runs(out, runs)?;
            out.write_str(" and their measurements, in flash too: type drop all yes to do it")?;
        }
        Refusal::Flagged { runs, method } => {
            write_run_list(out, runs)?;
            write!(
                out,
                " flagged (disagrees with the others, see calibrate): measure #<n> x y again or \
                 drop <n>, or type apply {method} yes to apply anyway"
            )?;
        }
        Refusal::PoorFit {
            probability,
            method,
        } => write!(
            out,
            "the runs fit no geometry (p={}, see calibrate): apply {method} yes applies anyway",
            Scientific::new(probability, 2)
        )?,
        Refusal::NotEnoughRuns { cw, ccw } => write!(
            out,
            "need measured square runs in both directions (measured: cw {cw}, ccw {ccw})"
        )?,
        Refusal::UnknownMethod { methods } => {
            out.write_str("unknown method; one of ")?;
            for (i, m) in methods.iter().enumerate() {
                if i > 0 {
                    out.write_str("|")?;
                }
                out.write_str(m)?;
            }
        }
        Refusal::MethodFailed { why } | Refusal::InvalidParams { why } => write!(out, "{why}")?,
        Refusal::Store(e) => write!(out, "{e}")?,
        Refusal::MotorsRunning(e) => write!(out, "{e}")?,
        Refusal::NoMethodSucceeded => {
            out.write_str("no method succeeded (check the measurements: runs)")?
        }
        Refusal::Fault { name } => write!(out, "fault latched: {name}")?,
        Refusal::ControllerRefused { why } => write!(out, "refused: {why}")?,
        Refusal::Implausible { run, path, why } => {
            write!(out, "run {run} ")?;
            write_path(out, &path)?;
            write!(out, ": {why}")?;
        }
    }
    out.write_str(EOL)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::run::Direction;

    fn text(r: &Refusal<'_>) -> std::string::String {
        let mut s = std::string::String::new();
        write_refusal(&mut s, r).unwrap();
        s
    }

    #[test]
    fn each_refusal_has_its_code_and_one_line() {
        let path = PathKind::Square {
            direction: Direction::Cw,
            side_m: 1.0,
        };
        assert_eq!(
            text(&Refusal::Unmeasured { run: 3, path }),
            "err 24: run 3 (square cw L=1.000 m) is not measured yet: measure it or drop it \
             first (measure x y [theta], or drop 3)\r\n"
        );
        assert_eq!(
            text(&Refusal::Flagged {
                runs: &[2, 5],
                method: "exact"
            }),
            "err 25: runs 2 5 are flagged (disagrees with the others, see calibrate): measure \
             #<n> x y again or drop <n>, or type apply exact yes to apply anyway\r\n"
        );
        assert_eq!(
            text(&Refusal::DropAllUnconfirmed { runs: 2 }),
            "err 25: drop all forgets 2 runs and their measurements, in flash too: type drop all \
             yes to do it\r\n"
        );
        assert_eq!(
            text(&Refusal::Busy(InProgress::Run(path))),
            "err 10: a run is in progress (square cw L=1.000 m): wait for it to finish\r\n"
        );
        assert_eq!(
            text(&Refusal::UnknownMethod {
                methods: &["a", "b"]
            }),
            "err 7: unknown method; one of a|b\r\n"
        );
        // A store's typed error keeps its kind up to the reply that names it.
        assert_eq!(
            text(&Refusal::Store(StoreError::Full)),
            "err 19: flash error: run flash full\r\n"
        );
        assert_eq!(
            text(&Refusal::MotorsRunning(MotorsRunning)),
            "err 18: motors not confirmed stopped (running, or the control loop has not run yet), flash not written\r\n"
        );
    }
}
