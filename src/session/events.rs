//! The `event …` lines the session writes without being asked: the board's boot line, a
//! fault, the runs restored at boot, and each run that finished or was aborted.
//!
//! Owns [`write_boot_event`], [`write_fault_event`] and [`write_runs_restored`] (the board
//! writes the first two before a session exists; re-exported as `session::write_…`) and the
//! collection of finished runs from the robot into the run store, which every entry point of
//! the session does first, so that its reply follows the events it refers to.

use core::fmt::{self, Write};

use super::Session;
use super::library::fault_name;
use super::report;
use super::settings::BootRefusal;
use super::traits::{Calibrator, Robot};
use crate::kinematics::reference::PoseF64;
use crate::motion::controller::{Fault, Status};
use crate::motion::run::PathKind;
use crate::protocol::reply::EOL;
use crate::protocol::token::EventTag;
use crate::storage::{LoadOutcome, RunsLoaded};
use crate::util::decimal::Decimal;

/// The first line the board sends after a reset: `event boot: parameters loaded` (with
/// ` (previous record; newest: <why>)` when the newest record was unusable and the one before it
/// was loaded), or `event boot: default parameters (<why>)` when no stored record was used,
/// followed by `, reset: <cause>` when the board knows why it reset (`watchdog`, `brown-out`,
/// `pin`, `software`, `power-on`, …), by `; <name> <value> refused (<why>), default used` for
/// each stored value the settings' rules refused ([`BootRefusal`]), then by the board's note
/// after `; ` (which clock runs, and [`ControlTimerStopped`] when the control timer does not
/// count; on the emulated board, what QEMU lacks).
///
/// # Errors
/// Only those of `out`.
pub fn write_boot_event(
    out: &mut dyn Write,
    loaded: &LoadOutcome,
    refused: &[BootRefusal],
    reset_cause: Option<&str>,
    board_note: Option<&str>,
) -> fmt::Result {
    EventTag::Boot.write(out)?;
    match &loaded.warning {
        None => out.write_str("parameters loaded")?,
        Some(w) => write!(out, "default parameters ({w})")?,
    }
    if let Some(w) = &loaded.older {
        write!(out, " (previous record; newest: {w})")?;
    }
    if let Some(cause) = reset_cause {
        write!(out, ", reset: {cause}")?;
    }
    for r in refused {
        write!(
            out,
            "; {} {} refused ({}), default used",
            r.name.as_str(),
            crate::util::decimal::Plain(r.value),
            r.why
        )?;
    }
    if let Some(note) = board_note {
        write!(out, "; {note}")?;
    }
    out.write_str(EOL)
}

/// The boot line's note when the board's control-period timer does not count (its name in
/// the field): no control period runs, so the encoders are never read, nothing moves and
/// nothing is written to flash. On silicon a part whose timer clock is off; under QEMU, whose
/// STM32F405 models neither TIM7 nor TIM11, the shipped firmware's normal state.
#[derive(Clone, Copy, Debug)]
pub struct ControlTimerStopped(pub &'static str);

impl fmt::Display for ControlTimerStopped {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "control timer {} not counting (an emulator such as QEMU does not model it): \
             no control loop, so no motion, no odometry and no flash writes",
            self.0
        )
    }
}

/// `event fault: <text>`: a fault found at boot that the board works around (e.g. a missing
/// crystal), or a fault the controller latched, in full.
///
/// # Errors
/// Only those of `out`.
pub fn write_fault_event(out: &mut dyn Write, text: impl fmt::Display) -> fmt::Result {
    EventTag::Fault.write(out)?;
    write!(out, "{text}\r\n")
}

/// The line that tells the operator which runs survived a reset:
/// `event runs restored: <n> runs, <m> measured`, followed by `; <k> skipped: <first problem>`
/// when stored runs could not be restored. Nothing when no runs are stored (a new board, or
/// after `drop all`).
///
/// # Errors
/// Only those of `out`.
pub fn write_runs_restored(out: &mut dyn Write, loaded: &RunsLoaded) -> fmt::Result {
    if !loaded.found || (loaded.restored == 0 && loaded.problem.is_none()) {
        return Ok(());
    }
    write!(
        out,
        "event runs restored: {}, {} measured",
        super::report::Count(loaded.restored, "run"),
        loaded.measured
    )?;
    match (&loaded.problem, loaded.skipped) {
        (Some(p), 0) => write!(out, "; {p}")?,
        (Some(p), k) => write!(out, "; {k} skipped: {p}")?,
        (None, _) => {}
    }
    out.write_str(EOL)
}

/// `event run <n> finished: <path> odometry end x=… y=… theta_deg=…; measure it`.
fn write_run_finished(
    out: &mut dyn Write,
    n: usize,
    path: &PathKind,
    end: &PoseF64,
) -> fmt::Result {
    EventTag::RunFinished(n).write(out)?;
    report::write_path(out, path)?;
    write!(
        out,
        " odometry end x={} y={} theta_deg={}; measure it\r\n",
        Decimal::signed(end.x_m, 6),
        Decimal::signed(end.y_m, 6),
        Decimal::signed(
            crate::util::trig::fmod(end.theta_rad.to_degrees(), 360.0),
            4
        ),
    )
}

/// `event run <n> aborted, not stored: <path>[ (fault: <name>)]`.
fn write_run_aborted(
    out: &mut dyn Write,
    n: usize,
    path: &PathKind,
    fault: Option<&str>,
) -> fmt::Result {
    EventTag::RunAborted(n).write(out)?;
    report::write_path(out, path)?;
    if let Some(fault) = fault {
        write!(out, " (fault: {fault})")?;
    }
    out.write_str(EOL)
}

impl<C: Calibrator> Session<C> {
    /// Collects a finished run from the robot into the store and announces it; announces a run
    /// that ended without finishing (stop, Ctrl-C, Esc, the button, a fault) as aborted.
    pub(super) fn collect_finished(
        &mut self,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        // Status first: a run that finishes between the two calls is then taken below, never
        // mistaken for an aborted one.
        let status = robot.status();
        while let Some(run) = robot.take_finished_run() {
            let started = self.active.take();
            self.last_aborted = None;
            let end = run.odometry_end;
            let path = run.path;
            // Starting a run is refused while the store is full, so this only fails if runs
            // were started behind the session's back; the oldest unmeasured data is then lost.
            if self.runs.is_full() {
                write!(out, "event run discarded: run store full\r\n")?;
                continue;
            }
            let number = started.map_or(self.next_number, |a| a.number as u16);
            let _ = self.runs.push(run);
            let _ = self.run_ids.push(None);
            let _ = self.numbers.push(number);
            self.next_number = number.saturating_add(1);
            self.runs_changed();
            write_run_finished(out, usize::from(number), &path, &end)?;
        }
        if let Some(a) = self.active
            && !matches!(status, Status::Running { .. })
        {
            self.active = None;
            self.last_aborted = Some(a);
            write_run_aborted(
                out,
                a.number,
                &a.path,
                status.fault().as_ref().map(fault_name),
            )?;
        }
        self.announce_fault(status.fault(), out)
    }

    /// Announces a newly latched fault in full, once: `event fault: <what>` (which wheel, its
    /// following error and peak duty, …), which the short name in `status` does not say. An
    /// identification's failure has its own `event identify err …` line.
    fn announce_fault(&mut self, fault: Option<Fault>, out: &mut dyn Write) -> fmt::Result {
        match fault {
            None => self.fault_announced = false,
            Some(_) if self.fault_announced => {}
            Some(f) => {
                self.fault_announced = true;
                if !matches!(f, Fault::Identify(_)) {
                    write_fault_event(out, f)?;
                }
            }
        }
        Ok(())
    }
}
