//! The calibration session: executes protocol commands and button presses against the robot.
//!
//! Owns the run store, settings and command execution; may use every layer below it
//! (protocol, storage, calibration, motion, kinematics, util), never `crate::board`.
//!
//! The session owns the run store (up to [`MAX_RUNS`] [`RunRecord`]s, measured or not), the
//! [`Settings`] and the pose-stream schedule. It never owns the hardware: every call takes the
//! [`Robot`] (one short controller operation per method) and, where needed, the
//! [`SettingsAndRuns`], so the firmware can lock its control task's controller per call and never
//! holds that lock during a calibration solve.
//!
//! Workflow: the plan is `runs_per_direction` squares per direction with side `square_side`;
//! `next` (or the button's short press) starts the next planned run, alternating CW/CCW; the
//! plan is counted from the run store, so a dropped run is planned again. After
//! each run the operator enters `measure x y [θ]` (true end pose in the run's start frame,
//! metres/degrees; it attaches to the last finished run). `calibrate` needs at least one measured
//! square in each direction; runs stay stored across `calibrate`, so a bad one can be dropped and
//! the calibration recomputed. `apply` makes a result active (`apply online` factors computed
//! elsewhere), `save` stores it.
//!
//! RAM: one [`RunRecord`] is `MAX_KNOTS` × 16 B plus ~100 B (1,712 B with 100 knots), so the
//! store costs `MAX_RUNS` × that, ≈ 20.8 KB for the whole session (the `run_store_ram` test
//! prints the exact figures).
//!
//! Parts: this file holds the state, the run store's flash bookkeeping and the dispatch of a
//! line to its command; each command group is an `impl Session` block of its own file
//! (`run_commands`, `calibrate_commands`, `param_commands`, `drive`, `bringup`, `identify`),
//! as are the unprompted `event …` lines and the collection of finished runs (`events`), the
//! periodic poll and pose stream (`stream`) and the button and stop keys (`button`); `report`
//! writes the longer replies.

mod boot;
mod bringup;
mod button;
mod calibrate_commands;
pub mod crash;
mod drive;
mod events;
mod fit_check;
mod identify;
pub mod library;
pub mod measure;
mod param_commands;
mod report;
mod run_commands;
pub mod settings;
mod stream;
pub mod traits;

use core::fmt::{self, Write};

use heapless::Vec;

use crate::motion::bringup::{CheckKind, PushReport};
use crate::motion::run::{Direction, PathKind, RunRecord};
use crate::protocol::command::UnitSetting;
use crate::protocol::outcome::{Ack, Outcome, write_ack, write_outcome};
use crate::protocol::record;
use crate::protocol::refusal::{InProgress, Refusal, write_refusal};
use crate::protocol::reply::{ErrorCode, write_err, write_ok_with};
use crate::protocol::rx::Received;
use crate::protocol::unit::{AngleUnit, LengthUnit};
use crate::protocol::{Command, LineEvent, ParseError};
use crate::storage::StoredRun;
pub use crate::storage::record::AppliedCalibration;
use crate::util::text::keyword_eq;
pub use boot::{Booted, boot};
pub use calibrate_commands::write_calibration;
pub use events::{ControlTimerStopped, write_boot_event, write_fault_event, write_runs_restored};
pub use settings::{BootRefusal, BootRefusals, SettingsError, check_nominal};

/// The session's settings: the stored parameter record itself, so a parameter lives in one
/// struct (its row of [`crate::protocol::PARAMS`] names the field).
pub type Settings = crate::storage::record::ParamRecord;
/// What [`Robot::status`] and [`Robot::motors_stopped`] answer: the controller's own types.
pub use crate::motion::controller::{MotorsRunning, MotorsStopped, Status};
pub use crate::storage::StoreError;
pub use stream::DEFAULT_STREAM_HZ;
pub use traits::{
    Calibrator, Culprit, Health, Numbered, Reading, Rejection, Robot, RobotError, RunResidual,
    SettingsAndRuns, Solution, SolveError,
};

pub use crate::motion::run::MAX_RUNS;

/// A run the session started and has not collected yet.
#[derive(Clone, Copy, Debug, PartialEq)]
struct ActiveRun {
    /// The number announced when it started.
    number: usize,
    path: PathKind,
}

/// A calibration dropped by a change of the nominal geometry, restored if the geometry is set
/// back.
#[derive(Clone, Debug, PartialEq)]
struct Dropped {
    nominal: crate::kinematics::geometry::Geometry,
    active: crate::kinematics::geometry::Geometry,
    calibration: AppliedCalibration,
}

/// Session state: run store, settings, stream schedule.
#[derive(Debug)]
pub struct Session<C> {
    calibrator: C,
    settings: Settings,
    runs: Vec<RunRecord, MAX_RUNS>,
    stream: Option<stream::Stream>,
    /// The number of each run of `runs`, as announced when it started (kept for the session: a
    /// dropped run leaves a gap).
    numbers: Vec<u16, MAX_RUNS>,
    /// The number the next run gets.
    next_number: u16,
    /// The unit of bare lengths in `measure` (`set measure_unit`; this session only).
    measure_unit: Option<LengthUnit>,
    /// The unit of a bare heading in `measure` (`set heading_unit`; this session only).
    heading_unit: Option<AngleUnit>,
    /// The settings changed since they were loaded or saved (`set`, `apply`, `identify`,
    /// `reset-params`).
    unsaved: bool,
    /// The last hand-push check of this boot (tells a reversed encoder from a reversed motor).
    last_push: Option<PushReport>,
    /// Echo received characters (a person at a terminal); `echo off` for programs.
    echo: bool,
    /// A line is being typed and echoed as it is typed: the pose stream holds meanwhile
    /// ([`Session::set_typing`]).
    typing: bool,
    /// The run in progress, as far as the session knows.
    active: Option<ActiveRun>,
    /// The last run ended by an abort (not stored); plain `measure` is refused until the next
    /// run finishes, so its measurement cannot land on an earlier run.
    last_aborted: Option<ActiveRun>,
    /// The latched fault has been announced (`event fault: …`); cleared with the fault.
    fault_announced: bool,
    /// The calibration the last geometry change dropped.
    dropped: Option<Dropped>,
    /// Where each run of `runs` is stored in flash (`None`: not stored yet).
    run_ids: Vec<Option<StoredRun>, MAX_RUNS>,
    /// The runs changed since they were last stored.
    runs_dirty: bool,
    /// Storing them failed; the next change tries again (not every poll).
    runs_store_failed: bool,
    /// A short press was refused since [`Session::take_press_refused`] last looked.
    press_refused: bool,
    /// The panic or HardFault that caused the last reset, shown by `status` until `clear`.
    last_crash: Option<crash::CrashRecord>,
}

/// The `err` reply for an operation the robot refused: `err 11` for a fault, `err 10`
/// otherwise; busy says what is in progress and to wait for it.
fn robot_err(out: &mut dyn Write, e: RobotError, robot: &mut dyn Robot) -> fmt::Result {
    match e {
        RobotError::Fault(name) => write_refusal(out, &Refusal::Fault { name }),
        RobotError::Busy => busy_err(out, robot.status()),
        RobotError::Rejected(why) => write_refusal(out, &Refusal::ControllerRefused { why: &why }),
    }
}

/// `err 10: <what> is in progress: wait for …`, for a command refused while the robot is busy.
fn busy_err(out: &mut dyn Write, status: Status) -> fmt::Result {
    let what = match status {
        Status::Running { path, .. } => InProgress::Run(path),
        Status::Driving => InProgress::Drive,
        Status::Checking(CheckKind::Identify(_)) => InProgress::Identify,
        Status::Checking(_) => InProgress::Bringup,
        Status::Idle | Status::Faulted(_) => InProgress::Ending,
    };
    write_refusal(out, &Refusal::Busy(what))
}

/// The `err` reply for a failed store operation: its code and text are the error's own.
fn storage_err(out: &mut dyn Write, e: StoreError) -> fmt::Result {
    write_refusal(out, &Refusal::Store(e))
}

/// Counts of square runs per direction: `(stored, measured)` for CW and CCW.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Progress {
    /// CW squares stored.
    pub cw: usize,
    /// CCW squares stored.
    pub ccw: usize,
    /// CW squares measured.
    pub cw_measured: usize,
    /// CCW squares measured.
    pub ccw_measured: usize,
}

impl<C: Calibrator> Session<C> {
    /// A session with `settings` (as loaded at boot) and no runs.
    pub fn new(settings: Settings, calibrator: C) -> Self {
        Session {
            calibrator,
            settings,
            runs: Vec::new(),
            numbers: Vec::new(),
            next_number: 1,
            measure_unit: None,
            heading_unit: None,
            unsaved: false,
            stream: None,
            last_push: None,
            echo: true,
            typing: false,
            active: None,
            last_aborted: None,
            fault_announced: false,
            dropped: None,
            run_ids: Vec::new(),
            runs_dirty: false,
            runs_store_failed: false,
            press_refused: false,
            last_crash: None,
        }
    }

    /// Restores the runs stored in flash (at boot, before the first command) and writes what
    /// was restored as `event runs restored: <n> runs, <m> measured[; <k> skipped: <why>]`
    /// (nothing when no runs were ever stored).
    ///
    /// # Errors
    /// Only those of `out`.
    pub fn restore_runs(
        &mut self,
        storage: &mut dyn SettingsAndRuns,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let loaded = storage.load_runs(&mut self.runs, &mut self.run_ids);
        self.renumber();
        self.calibrator.runs_changed();
        self.runs_dirty = false;
        self.runs_store_failed = false;
        write_runs_restored(out, &loaded)
    }

    /// Numbers the stored runs 1, 2, … (at boot, and after `drop all`).
    fn renumber(&mut self) {
        self.numbers.clear();
        for n in 1..=self.runs.len() {
            let _ = self.numbers.push(n as u16);
        }
        self.next_number = self.runs.len() as u16 + 1;
    }

    /// The store position (0-based) of run number `number`, if it is stored.
    fn position(&self, number: usize) -> Option<usize> {
        self.numbers.iter().position(|&n| usize::from(n) == number)
    }

    /// The stored runs with their session numbers.
    fn numbered(&self) -> Numbered<'_> {
        Numbered {
            runs: &self.runs,
            numbers: &self.numbers,
        }
    }

    /// The number of the run at store position `index` (0-based).
    fn number_at(&self, index: usize) -> usize {
        self.numbered().number(index + 1)
    }

    /// Refuses motion while the last finished run is unmeasured: the robot must not leave the
    /// end pose the run is to be measured at.
    fn unmeasured_end(&self) -> Option<Refusal<'static>> {
        let last = self.runs.last().filter(|r| r.measured.is_none())?;
        Some(Refusal::Unmeasured {
            run: self.number_at(self.runs.len() - 1),
            path: last.path,
        })
    }

    /// Marks the run store changed: it is written to flash at the next opportunity, and
    /// calibration results kept from the old runs are stale.
    fn runs_changed(&mut self) {
        self.calibrator.runs_changed();
        self.store_runs_again();
    }

    /// Writes the runs to flash again at the next opportunity (unchanged, e.g. after a save
    /// that may have wiped damaged flash).
    fn store_runs_again(&mut self) {
        self.runs_dirty = true;
        self.runs_store_failed = false;
    }

    /// Writes the run store to flash if it changed and the motors are stopped (a page change
    /// erases a sector, which stalls the CPU); a failure is reported once as
    /// `event runs not stored: <why>` and retried at the next change.
    fn store_runs(
        &mut self,
        robot: &mut dyn Robot,
        storage: &mut dyn SettingsAndRuns,
        out: &mut dyn Write,
    ) -> fmt::Result {
        if !self.runs_dirty || self.runs_store_failed {
            return Ok(());
        }
        let Ok(stopped) = robot.motors_stopped() else {
            return Ok(());
        };
        match storage.save_runs(&self.runs, &mut self.run_ids, stopped) {
            Ok(()) => {
                self.runs_dirty = false;
                Ok(())
            }
            Err(e) => {
                self.runs_store_failed = true;
                write!(out, "event runs not stored: {e}\r\n")
            }
        }
    }

    /// The panic or HardFault the last reset came from (the board's record of it):
    /// `status` shows it until `clear`.
    pub fn note_crash(&mut self, crash: crash::CrashRecord) {
        self.last_crash = Some(crash);
    }

    /// Whether every run change has been written to flash.
    pub fn runs_stored(&self) -> bool {
        !self.runs_dirty
    }

    /// Whether received characters are to be echoed (`echo on|off`; on at boot, for a person at
    /// a terminal program with its default settings).
    pub fn echo(&self) -> bool {
        self.echo
    }

    /// The current settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The calibrator.
    pub fn calibrator(&self) -> &C {
        &self.calibrator
    }

    /// The stored runs, oldest first.
    pub fn runs(&self) -> &[RunRecord] {
        &self.runs
    }

    /// Square-run counts per direction.
    pub fn progress(&self) -> Progress {
        progress_of(&self.runs)
    }

    /// The direction of the next planned square, or `None` when the plan is complete.
    /// Alternates CW/CCW, starting with CW.
    pub fn next_planned(&self) -> Option<Direction> {
        let p = self.progress();
        let n = usize::from(self.settings.runs_per_direction);
        match (p.cw < n, p.ccw < n) {
            (true, true) if p.cw <= p.ccw => Some(Direction::Cw),
            (_, true) => Some(Direction::Ccw),
            (true, false) => Some(Direction::Cw),
            (false, false) => None,
        }
    }

    /// A received input as the console takes it from its queue: a line that was not echoed as
    /// it arrived is echoed first (when echo is on), so the echo stands right before its reply;
    /// then as [`Session::handle_event`].
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    pub fn handle_input(
        &mut self,
        input: &Received,
        robot: &mut dyn Robot,
        storage: &mut dyn SettingsAndRuns,
        out: &mut dyn Write,
    ) -> fmt::Result {
        if self.echo {
            input.write_echo(out)?;
        }
        self.handle_event(input.item.as_event(), robot, storage, out)
    }

    /// One event from the line assembler: a line is executed, a rejected line answered with its
    /// error (or executed as `stop` if its last word was `stop`), a stop key stops.
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    pub fn handle_event(
        &mut self,
        event: LineEvent<'_>,
        robot: &mut dyn Robot,
        storage: &mut dyn SettingsAndRuns,
        out: &mut dyn Write,
    ) -> fmt::Result {
        match event {
            LineEvent::Line(text) => self.handle_line(text, robot, storage, out),
            LineEvent::Rejected { stop: true, .. } => {
                self.execute(Command::Stop, robot, storage, out)
            }
            LineEvent::Rejected { error, stop: false } => {
                write_err(out, ErrorCode::from(&error), &error)
            }
            LineEvent::Stop(key) => self.interrupt(key, robot, out),
        }
    }

    /// Parses and executes one line, writing the reply (nothing for a blank line).
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    pub fn handle_line(
        &mut self,
        line: &str,
        robot: &mut dyn Robot,
        storage: &mut dyn SettingsAndRuns,
        out: &mut dyn Write,
    ) -> fmt::Result {
        match Command::parse(line) {
            Ok(cmd) => self.execute(cmd, robot, storage, out),
            Err(ParseError::Empty) => Ok(()),
            // Stopping is always safe: a line whose last word is `stop` stops, whatever stray
            // text came before it.
            Err(_)
                if line
                    .split_ascii_whitespace()
                    .next_back()
                    .is_some_and(|w| keyword_eq(w, "stop")) =>
            {
                self.execute(Command::Stop, robot, storage, out)
            }
            Err(e) => write_err(out, ErrorCode::from(&e), &e),
        }
    }

    /// Executes a parsed command; a change of the runs is stored in flash right after the
    /// reply.
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    pub fn execute(
        &mut self,
        cmd: Command<'_>,
        robot: &mut dyn Robot,
        storage: &mut dyn SettingsAndRuns,
        out: &mut dyn Write,
    ) -> fmt::Result {
        self.execute_command(cmd, robot, storage, out)?;
        self.store_runs(robot, storage, out)
    }
    fn execute_command(
        &mut self,
        cmd: Command<'_>,
        robot: &mut dyn Robot,
        storage: &mut dyn SettingsAndRuns,
        out: &mut dyn Write,
    ) -> fmt::Result {
        self.collect_finished(robot, out)?;
        let side = self.settings.square_side_f64();
        match cmd {
            Command::Help => report::write_help(out),
            Command::Status => {
                let status = robot.status();
                let health = robot.health();
                let pose = robot.pose();
                write_ok_with(out, &mut |out| {
                    report::write_status_text(out, &status, &health, &pose, self)
                })
            }
            Command::Params => report::write_params(out, &self.settings),
            Command::Set { name, value } => self.set(name, value, robot, out),
            Command::Run { direction, side_m } => {
                let path = PathKind::Square {
                    direction,
                    side_m: side_m.unwrap_or(side),
                };
                self.start(path, robot, out)
            }
            Command::Next => self.start_next(robot, out).map(|_| ()),
            Command::Line { length_m } => {
                let path = PathKind::Line {
                    length_m: length_m.unwrap_or(side),
                };
                self.start(path, robot, out)
            }
            Command::Circle {
                direction,
                radius_m,
            } => {
                let path = PathKind::Circle {
                    direction,
                    radius_m: radius_m.unwrap_or(0.5 * side),
                };
                self.start(path, robot, out)
            }
            Command::Bringup { kind } => self.bringup(kind, robot, out),
            Command::Identify { mode } => self.bringup(CheckKind::Identify(mode), robot, out),
            Command::Stop => self.stop(robot, out),
            Command::Clear => {
                // The last reset's crash is acknowledged with the fault.
                let crash = self.last_crash.take();
                match robot.status().fault() {
                    Some(fault) => {
                        robot.clear_fault();
                        let name = Some(library::fault_name(&fault));
                        write_ack(out, Ack::FaultCleared { name })
                    }
                    None if crash.is_some() => write_ack(out, Ack::ResetCauseCleared),
                    None => write_ack(out, Ack::NoFaultLatched),
                }
            }
            Command::Measure {
                run,
                x,
                y,
                theta,
                confirmed,
            } => self.measure(run, (x, y, theta), confirmed, robot, out),
            Command::SetUnit(unit) => {
                match unit {
                    UnitSetting::Length(u) => self.measure_unit = Some(u),
                    UnitSetting::Angle(u) => self.heading_unit = Some(u),
                }
                write_outcome(out, &Outcome::UnitSet(unit))
            }
            Command::Runs => report::write_runs(out, &self.runs, &self.numbers),
            Command::Record { index, first_knot } => self.record(index, first_knot, out),
            Command::Version => record::write_version(out),
            Command::Drop { index } => self.drop_run(index, robot, out),
            Command::DropAll { confirmed } => self.drop_all(confirmed, robot, out),
            Command::Convention { name } => self.convention(name, out),
            Command::Calibrate { method } => self.calibrate(method, robot, out),
            Command::Apply { method, confirmed } => self.apply(method, confirmed, robot, out),
            Command::ApplyFactors { e_d, e_b, e_s } => {
                self.apply_factors((e_d, e_b, e_s), robot, out)
            }
            Command::Save => self.save(robot, storage, out),
            Command::ResetParams { confirmed } => self.reset_params(confirmed, robot, out),
            Command::Pose => self.pose(robot, out),
            Command::OdomReset => self.odom_reset(robot, out),
            Command::Stream { on } => self.set_stream(on, out),
            Command::Echo { on } => {
                self.echo = on;
                write_ack(out, Ack::Echo { on })
            }
            Command::Drive { v_mps, w_radps } => self.drive(v_mps, w_radps, robot, out),
        }
    }
}

/// The one validation rule of `apply` and `save`: the settings must make a parameter record
/// that validates.
///
/// # Errors
/// [`StoreError::InvalidRecord`] with the record's reason.
pub fn storable(settings: &Settings) -> Result<(), StoreError> {
    settings.validate().map_err(StoreError::InvalidRecord)
}

/// Square runs per direction, stored and measured, of `runs`.
pub fn progress_of(runs: &[RunRecord]) -> Progress {
    let mut p = Progress::default();
    for r in runs {
        if let PathKind::Square { direction, .. } = r.path {
            let measured = usize::from(r.measured.is_some());
            match direction {
                Direction::Cw => {
                    p.cw += 1;
                    p.cw_measured += measured;
                }
                Direction::Ccw => {
                    p.ccw += 1;
                    p.ccw_measured += measured;
                }
            }
        }
    }
    p
}
