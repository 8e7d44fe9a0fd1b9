//! What a command did, as values: the session executes `run`/`next`/`line`/`circle`, `stop`,
//! `measure`, `drop` and returns an [`Outcome`], and `set`, `reset-params`, `save`, `apply` a
//! [`ParamOutcome`]; their `ok` lines are written here ([`write_outcome`],
//! [`write_param_outcome`]), next to the refusals' `err` lines ([`super::refusal`]).

use core::fmt::{self, Write};

use super::command::UnitSetting;
use super::param::ParamName;
use super::refusal::write_path;
use super::reply::EOL;
use super::token;
use crate::motion::convention::Convention;
use crate::motion::run::{Measurement, PathKind};
use crate::util::decimal::Decimal;

/// A run command that succeeded, with what its reply names.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum Outcome {
    /// A run started.
    Started {
        /// Its number (kept for the session once it finishes).
        run: usize,
        /// Its path.
        path: PathKind,
    },
    /// `stop`: the motors stop; the run in progress, if any, was aborted and not stored.
    Stopped {
        /// The aborted run's number.
        aborted: Option<usize>,
    },
    /// A measurement was stored for run `run`.
    Measured {
        /// The run.
        run: usize,
        /// Its path.
        path: PathKind,
        /// The measurement it replaced, if any.
        replaced: Option<Measurement>,
        /// The measurement as read (x, y in metres, θ in radians as typed, if typed).
        read: Measurement,
        /// Measured − odometry end, x and y, metres.
        error_m: (f64, f64),
        /// The heading kept from the replaced measurement (no new one was given), radians.
        heading_kept: Option<f64>,
    },
    /// Run `run` was dropped; `left` runs remain.
    Dropped {
        /// Its number before the drop.
        run: usize,
        /// Its path.
        path: PathKind,
        /// Runs left.
        left: usize,
    },
    /// Every run was dropped.
    DroppedAll {
        /// How many.
        runs: usize,
    },
    /// `set measure_unit` / `set heading_unit`: the unit of bare values for this session.
    UnitSet(UnitSetting),
}

/// A command without a run or a parameter that succeeded (`clear`, `echo`, `stream`, `odom
/// reset`, `drive`): a small value of its own, so the session's many call sites build only
/// this, not an [`Outcome`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Ack {
    /// `clear` (or a short press) cleared a latched fault; `clear` names it.
    FaultCleared {
        /// The fault's name, when the reply names it.
        name: Option<&'static str>,
    },
    /// `clear` with no fault latched cleared the reset cause of the last boot.
    ResetCauseCleared,
    /// `clear` with nothing to clear.
    NoFaultLatched,
    /// `echo on|off`.
    Echo {
        /// Echo on.
        on: bool,
    },
    /// `stream on` at `hz`, or `stream off` (`None`).
    Stream {
        /// The rate, Hz, while on.
        hz: Option<u32>,
    },
    /// `odom reset`.
    OdometryReset,
    /// `drive` accepted as given.
    Driving,
    /// `convention [name]`: the convention in force (`changed`: just set).
    Convention {
        /// The convention in force.
        name: Convention,
        /// It was set by this command.
        changed: bool,
    },
    /// `drive` accepted at the motion limits: the speed and turn rate it was cut to.
    DriveLimited {
        /// Forward speed, m/s.
        v_mps: f32,
        /// Turn rate, rad/s.
        w_radps: f32,
    },
}

/// `<n> run` / `<n> runs`.
fn write_count(out: &mut dyn Write, n: usize, noun: &str) -> fmt::Result {
    write!(out, "{n} {noun}{}", if n == 1 { "" } else { "s" })
}

/// Writes ` x=… y=…[ theta_deg=…]` of a measurement (metres with 6 decimals, degrees with 4).
///
/// # Errors
/// Only if `out` refuses the text.
pub fn write_measurement(out: &mut dyn Write, m: &Measurement) -> fmt::Result {
    write!(
        out,
        "x={} y={}",
        Decimal::signed(m.x_m, 6),
        Decimal::signed(m.y_m, 6)
    )?;
    if let Some(t) = m.theta_rad {
        write!(out, " theta_deg={}", Decimal::signed(t.to_degrees(), 4))?;
    }
    Ok(())
}

/// Writes the `ok …` line of `outcome`.
///
/// # Errors
/// Only if `out` refuses the text.
#[inline(never)]
pub fn write_outcome(out: &mut dyn Write, outcome: &Outcome) -> fmt::Result {
    match *outcome {
        Outcome::Started { run, path } => {
            super::token::write_run_started(out, run)?;
            write_path(out, &path)?;
        }
        Outcome::Stopped { aborted: None } => out.write_str("ok stopped")?,
        Outcome::Stopped { aborted: Some(n) } => {
            write!(out, "ok stopped: run {n} aborted, not stored")?
        }
        Outcome::Measured {
            run,
            path,
            replaced,
            read,
            error_m: (dx, dy),
            heading_kept,
        } => {
            write!(out, "ok run {run} ")?;
            write_path(out, &path)?;
            out.write_str(" measured")?;
            if let Some(old) = replaced {
                out.write_str(" (replaced ")?;
                write_measurement(out, &old)?;
                out.write_str(")")?;
            }
            write!(
                out,
                ": read x={} mm y={} mm",
                Decimal::signed(read.x_m * 1e3, 3),
                Decimal::signed(read.y_m * 1e3, 3)
            )?;
            if let (Some(t), None) = (read.theta_rad, heading_kept) {
                write!(out, " theta={} deg", Decimal::signed(t.to_degrees(), 2))?;
            }
            write!(
                out,
                "; error vs odometry dx={} dy={} m",
                Decimal::signed(dx, 6),
                Decimal::signed(dy, 6),
            )?;
            if let Some(t) = heading_kept {
                write!(
                    out,
                    " (heading kept: theta_deg={})",
                    Decimal::signed(t.to_degrees(), 4)
                )?;
            }
        }
        Outcome::Dropped { run, path, left } => {
            write!(out, "ok dropped run {run}: ")?;
            write_path(out, &path)?;
            out.write_str("; ")?;
            write_count(out, left, "run")?;
            out.write_str(" left")?;
        }
        Outcome::DroppedAll { runs } => {
            out.write_str("ok dropped all ")?;
            write_count(out, runs, "run")?;
        }
        Outcome::UnitSet(setting) => {
            let (name, symbol) = match setting {
                UnitSetting::Length(u) => ("measure", u.symbol()),
                UnitSetting::Angle(u) => ("heading", u.symbol()),
            };
            write!(
                out,
                "ok {name}_unit = {symbol}: bare {name} values are {symbol} (this session only, \
                 not saved)"
            )?;
        }
    }
    out.write_str(EOL)
}

/// Writes the `ok …` line of `ack`.
///
/// # Errors
/// Only if `out` refuses the text.
#[inline(never)]
pub fn write_ack(out: &mut dyn Write, ack: Ack) -> fmt::Result {
    match ack {
        Ack::FaultCleared { name: None } => out.write_str("ok fault cleared")?,
        Ack::FaultCleared { name: Some(n) } => write!(out, "ok fault cleared ({n})")?,
        Ack::ResetCauseCleared => out.write_str("ok reset cause cleared")?,
        Ack::NoFaultLatched => out.write_str("ok no fault latched")?,
        Ack::Echo { on } => out.write_str(if on { "ok echo on" } else { "ok echo off" })?,
        Ack::Stream { hz: Some(hz) } => write!(out, "ok stream on {hz} Hz")?,
        Ack::Stream { hz: None } => out.write_str("ok stream off")?,
        Ack::OdometryReset => out.write_str("ok odometry reset")?,
        Ack::Driving => out.write_str("ok")?,
        Ack::Convention { name, changed } => {
            write!(out, "ok convention {}", name.as_str())?;
            if changed {
                out.write_str(": runs re-read (typed as listed)")?;
            }
        }
        Ack::DriveLimited { v_mps, w_radps } => write!(
            out,
            "ok {}v={} m/s w={} rad/s (max_speed, max_turn_rate)",
            token::DRIVE_LIMITED,
            Decimal::signed(f64::from(v_mps), 3),
            Decimal::signed(f64::from(w_radps), 3)
        )?,
    }
    out.write_str(EOL)
}

/// What `set` changed besides the parameter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SetChange<'a> {
    /// The value was the current one: nothing changed.
    Unchanged,
    /// The parameter changed.
    Changed,
    /// The nominal geometry changed and dropped the applied calibration of this method.
    CalibrationDropped(&'a str),
    /// The nominal geometry was set back and restored the calibration of this method.
    CalibrationRestored(&'a str),
}

/// A parameter command that succeeded.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum ParamOutcome<'a> {
    /// `set`: `name` is `value` now.
    Set {
        /// The parameter.
        name: ParamName,
        /// Its value now.
        value: f64,
        /// What else changed.
        change: SetChange<'a>,
    },
    /// `reset-params`: every parameter at its default, in RAM.
    Reset,
    /// `save`: the parameters are in flash.
    Saved,
    /// `apply`: the method's result is the active geometry, in RAM.
    Applied {
        /// The method.
        method: &'a str,
        /// Its factors `E_d`, `E_b`, `E_s`.
        factors: (f64, f64, f64),
    },
}

/// `<value> <unit>` of a parameter as `params` and `set` show it (a count unit in the singular
/// for one: `1 run`).
///
/// # Errors
/// Only if `out` refuses the text.
pub fn write_param_value(out: &mut dyn Write, name: ParamName, value: f64) -> fmt::Result {
    let unit = match name.unit() {
        "runs" if value == 1.0 => "run",
        unit => unit,
    };
    write!(out, "{} {unit}", Decimal::fixed(value, name.places()))
}

/// Writes the `ok …` line of a parameter command.
///
/// # Errors
/// Only if `out` refuses the text.
pub fn write_param_outcome(out: &mut dyn Write, outcome: &ParamOutcome<'_>) -> fmt::Result {
    match *outcome {
        ParamOutcome::Set {
            name,
            value,
            change,
        } => {
            write!(out, "ok {} = ", name.as_str())?;
            write_param_value(out, name, value)?;
            match change {
                SetChange::Unchanged => return write!(out, "{}\r\n", token::UNCHANGED),
                SetChange::Changed => {}
                SetChange::CalibrationRestored(m) => write!(out, " (calibration {m} restored)")?,
                SetChange::CalibrationDropped(m) => write!(
                    out,
                    " (calibration {m} dropped: it is relative to the old geometry; set the old \
                     value back to restore it)"
                )?,
            }
            out.write_str(token::NOT_SAVED)?;
        }
        ParamOutcome::Reset => {
            out.write_str("ok parameters reset to defaults")?;
            out.write_str(token::NOT_SAVED)?;
        }
        ParamOutcome::Saved => out.write_str("ok saved")?,
        ParamOutcome::Applied {
            method,
            factors: (e_d, e_b, e_s),
        } => {
            write!(
                out,
                "ok applied {method}: E_d={} E_b={} E_s={}",
                Decimal::fixed(e_d, 9),
                Decimal::fixed(e_b, 9),
                Decimal::fixed(e_s, 9)
            )?;
            out.write_str(token::NOT_SAVED)?;
        }
    }
    out.write_str(EOL)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::token::is_not_saved;

    /// The not-saved token as the board writes it: after `reset-params` (as after `set` and
    /// `apply`), never after `save`.
    #[test]
    fn not_saved_token_as_the_board_writes_it() {
        let mut reset = String::new();
        write_param_outcome(&mut reset, &ParamOutcome::Reset).unwrap();
        assert!(is_not_saved(&reset), "{reset}");
        let mut saved = String::new();
        write_param_outcome(&mut saved, &ParamOutcome::Saved).unwrap();
        assert!(!is_not_saved(&saved), "{saved}");
    }

    /// A `drive` cut to the limits is read back as such by the protocol's own reader; an
    /// accepted one is not.
    #[test]
    fn a_limited_drive_reads_as_limited() {
        let mut limited = String::new();
        write_ack(
            &mut limited,
            Ack::DriveLimited {
                v_mps: 0.3,
                w_radps: -1.0,
            },
        )
        .unwrap();
        assert_eq!(
            limited,
            "ok limited to v=+0.300 m/s w=-1.000 rad/s (max_speed, max_turn_rate)\r\n"
        );
        assert!(token::is_drive_limited(limited.trim_end()));
        let mut driving = String::new();
        write_ack(&mut driving, Ack::Driving).unwrap();
        assert!(!token::is_drive_limited(driving.trim_end()));
    }
}
