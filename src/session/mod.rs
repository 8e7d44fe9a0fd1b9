//! The calibration session: executes protocol commands and button presses against the robot.
//!
//! Owns the run store, settings and command execution; may use every layer below it
//! (protocol, storage, calibration, motion, kinematics, util), never `crate::board`.
//!
//! The session owns the run store (up to [`MAX_RUNS`] [`RunRecord`]s, measured or not), the
//! [`Settings`] and the pose-stream schedule. It never owns the hardware: every call takes the
//! [`Robot`] (one short controller operation per method) and, where needed, the
//! [`ParamStorage`], so the firmware can lock its control task's controller per call and never
//! holds that lock during a calibration solve.
//!
//! Workflow: the plan is `runs_per_direction` squares per direction with side `square_side`;
//! `next` (or the button's short press) starts the next planned run, alternating CW/CCW; the
//! plan is counted from the run store, so a dropped run is planned again. After
//! each run the operator enters `measure x y [θ]` (true end pose in the run's start frame,
//! metres/degrees; it attaches to the last finished run). `calibrate` needs at least one measured
//! square in each direction; runs stay stored across `calibrate`, so a bad one can be dropped and
//! the calibration recomputed. `apply` makes a result active, `save` stores it.
//!
//! RAM: one [`RunRecord`] is `MAX_KNOTS` × 16 B plus ~100 B (1,712 B with 100 knots), so the
//! store costs `MAX_RUNS` × that, ≈ 20.8 KB for the whole session (the `run_store_ram` test
//! prints the exact figures).

mod bringup;
mod identify;
pub mod library;
pub mod measure;
mod report;
pub mod settings;
pub mod traits;

use core::fmt::{self, Write};

use heapless::Vec;

use crate::kinematics::encoder::WheelTicks;
use crate::motion::bringup::{CheckKind, PushReport};
use crate::motion::controller::Fault;
use crate::motion::run::{Direction, Measurement, PathKind, RunRecord};
use crate::protocol::record;
use crate::protocol::reply::{EOL, ErrorCode, write_err};
use crate::protocol::rx::Received;
use crate::protocol::{Command, LineEvent, ParseError, StopKey};
use crate::storage::{LoadWarning, RunsLoaded, StoredRun};
use crate::util::decimal::Decimal;
use crate::util::num::clamp;
use crate::util::text::keyword_eq;
pub use settings::{AppliedCalibration, Changed, Settings, SettingsError, check_nominal};
pub use traits::{
    Activity, Calibrator, ParamStorage, Robot, RobotError, RobotStatus, RunResidual, Solution,
    SolveError, StorageError,
};

pub use crate::motion::run::MAX_RUNS;

/// Default pose-stream rate, Hz.
pub const DEFAULT_STREAM_HZ: u32 = 10;

/// Pose-stream schedule.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Stream {
    period_us: u64,
    /// Time of the next line; `None` = emit at the next poll.
    next_due_us: Option<u64>,
    /// Time and wheel tick totals of the previous line, for the wheel speeds.
    last: Option<(u64, WheelTicks)>,
}

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
    stream: Option<Stream>,
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
}

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

fn robot_err(out: &mut dyn Write, e: RobotError) -> fmt::Result {
    let code = match e {
        RobotError::Fault(_) => ErrorCode::Fault,
        RobotError::Busy | RobotError::Rejected(_) => ErrorCode::Busy,
    };
    write_err(out, code, &e)
}

fn storage_err(out: &mut dyn Write, e: StorageError) -> fmt::Result {
    let code = match e {
        StorageError::MotorsRunning => ErrorCode::MotorsRunning,
        StorageError::Invalid(_) | StorageError::Record(_) => ErrorCode::InvalidParams,
        StorageError::Flash(_) => ErrorCode::Storage,
    };
    write_err(out, code, &e)
}

/// The first line the board sends after a reset: `event boot: parameters loaded`, or
/// `event boot: default parameters (<why>)` when the stored record was not used, followed by
/// `, reset: <cause>` when the board knows why it reset (`watchdog`, `brown-out`, `pin`,
/// `software`, `power-on`, …).
///
/// # Errors
/// Only those of `out`.
pub fn write_boot_event(
    out: &mut dyn Write,
    warning: Option<&LoadWarning>,
    reset_cause: Option<&str>,
) -> fmt::Result {
    match warning {
        None => write!(out, "event boot: parameters loaded")?,
        Some(w) => write!(out, "event boot: default parameters ({w})")?,
    }
    if let Some(cause) = reset_cause {
        write!(out, ", reset: {cause}")?;
    }
    out.write_str(EOL)
}

/// `event fault: <text>`: a fault found at boot that the board works around (e.g. a missing
/// crystal), or a fault the controller latched, in full.
///
/// # Errors
/// Only those of `out`.
pub fn write_fault_event(out: &mut dyn Write, text: impl fmt::Display) -> fmt::Result {
    write!(out, "event fault: {text}\r\n")
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
        "event runs restored: {} runs, {} measured",
        loaded.restored, loaded.measured
    )?;
    match (&loaded.problem, loaded.skipped) {
        (Some(p), 0) => write!(out, "; {p}")?,
        (Some(p), k) => write!(out, "; {k} skipped: {p}")?,
        (None, _) => {}
    }
    out.write_str(EOL)
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
        storage: &mut dyn ParamStorage,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let loaded = storage.load_runs(&mut self.runs, &mut self.run_ids);
        self.calibrator.runs_changed();
        self.runs_dirty = false;
        self.runs_store_failed = false;
        write_runs_restored(out, &loaded)
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
        storage: &mut dyn ParamStorage,
        out: &mut dyn Write,
    ) -> fmt::Result {
        if !self.runs_dirty || self.runs_store_failed || !robot.motors_stopped() {
            return Ok(());
        }
        match storage.save_runs(&self.runs, &mut self.run_ids, true) {
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

    /// Collects a finished run from the robot into the store and announces it; announces a run
    /// that ended without finishing (stop, Ctrl-C, Esc, the button, a fault) as aborted.
    fn collect_finished(&mut self, robot: &mut dyn Robot, out: &mut dyn Write) -> fmt::Result {
        // Status first: a run that finishes between the two calls is then taken below, never
        // mistaken for an aborted one.
        let status = robot.status();
        while let Some(run) = robot.take_finished_run() {
            self.active = None;
            self.last_aborted = None;
            let end = run.odometry_end;
            let path = run.path;
            // Starting a run is refused while the store is full, so this only fails if runs
            // were started behind the session's back; the oldest unmeasured data is then lost.
            if self.runs.is_full() {
                write!(out, "event run discarded: run store full\r\n")?;
                continue;
            }
            let _ = self.runs.push(run);
            let _ = self.run_ids.push(None);
            self.runs_changed();
            let n = self.runs.len();
            write!(out, "event run {n} finished: ")?;
            report::write_path(out, &path)?;
            write!(
                out,
                " odometry end x={} y={} theta_deg={}; measure it\r\n",
                Decimal::signed(end.x_m, 6),
                Decimal::signed(end.y_m, 6),
                Decimal::signed(
                    crate::util::trig::fmod(end.theta_rad.to_degrees(), 360.0),
                    4
                ),
            )?;
        }
        if let Some(a) = self.active
            && !matches!(status.activity, Activity::Running(_))
        {
            self.active = None;
            self.last_aborted = Some(a);
            write!(out, "event run {} aborted, not stored: ", a.number)?;
            report::write_path(out, &a.path)?;
            if let Some(fault) = status.fault {
                write!(out, " (fault: {fault})")?;
            }
            out.write_str(EOL)?;
        }
        self.announce_fault(status.fault_detail, out)
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

    /// Periodic work: collects finished runs (announcing them with `event` lines), stores
    /// changed runs in flash once the motors are stopped, and writes a `stream` line when one
    /// is due at `now_us` (a monotonic time, microseconds) and no line is being typed
    /// ([`Session::set_typing`]).
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    pub fn poll(
        &mut self,
        now_us: u64,
        robot: &mut dyn Robot,
        storage: &mut dyn ParamStorage,
        out: &mut dyn Write,
    ) -> fmt::Result {
        self.collect_finished(robot, out)?;
        self.collect_check(robot, out)?;
        self.store_runs(robot, storage, out)?;
        if !self.typing && self.stream_due(now_us) {
            let pose = robot.pose();
            let totals = robot.totals();
            let (vr, vl) = self.wheel_speeds(now_us, totals);
            report::write_stream_line(out, now_us, &pose, vr, vl)?;
        }
        Ok(())
    }

    /// Mean wheel speeds `(right, left)` in m/s since the previous stream line (0 for the first
    /// line), from the tick totals and the active geometry; remembers this sample.
    fn wheel_speeds(&mut self, now_us: u64, totals: WheelTicks) -> (f64, f64) {
        let g = self.settings.active;
        let Some(stream) = self.stream.as_mut() else {
            return (0.0, 0.0);
        };
        let speeds = match stream.last {
            Some((t, prev)) if now_us > t => {
                let dt = (now_us - t) as f64 * 1e-6;
                (
                    (totals.right - prev.right) as f64 * g.meters_per_tick_right() / dt,
                    (totals.left - prev.left) as f64 * g.meters_per_tick_left() / dt,
                )
            }
            _ => (0.0, 0.0),
        };
        stream.last = Some((now_us, totals));
        speeds
    }

    /// Tells the session whether a line is being typed at the console and echoed as it is typed
    /// ([`crate::protocol::line::LineAssembler::typing`]). Meanwhile the pose stream holds: its
    /// lines would land between the typed characters, cutting both. It resumes with the next
    /// poll after the line ends (Enter or Ctrl-C), restarting its schedule from there.
    pub fn set_typing(&mut self, typing: bool) {
        self.typing = typing;
    }

    /// Whether a stream line is due at `now_us`; if so, schedules the next one. The schedule
    /// advances by whole periods (no drift); after a stall longer than one period, or if the
    /// clock went backwards (a wrapped timer), it restarts from `now_us` instead of bursting or
    /// falling silent.
    pub fn stream_due(&mut self, now_us: u64) -> bool {
        let Some(stream) = self.stream.as_mut() else {
            return false;
        };
        let period = stream.period_us;
        match stream.next_due_us {
            Some(due) if now_us < due && due - now_us <= period => false,
            Some(due) if now_us >= due && now_us - due < period => {
                stream.next_due_us = Some(due + period);
                true
            }
            _ => {
                stream.next_due_us = Some(now_us + period);
                true
            }
        }
    }

    /// The button's short press: clears a latched fault, otherwise starts the next planned run
    /// (refused with the usual error while the robot moves). The outcome is written as an
    /// `event button: …` line.
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    pub fn button_short(&mut self, robot: &mut dyn Robot, out: &mut dyn Write) -> fmt::Result {
        self.collect_finished(robot, out)?;
        write!(out, "event button: ")?;
        if robot.status().fault.is_some() {
            robot.clear_fault();
            return write!(out, "ok fault cleared\r\n");
        }
        self.start_next(robot, out)
    }

    /// The button's long press: stops any motion.
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    pub fn button_long(&mut self, robot: &mut dyn Robot, out: &mut dyn Write) -> fmt::Result {
        robot.abort();
        self.collect_finished(robot, out)?;
        write!(out, "event button: ok stopped\r\n")
    }

    /// Ctrl-C or Esc: stops any motion (the board's receive interrupt has already told the
    /// control task; this is idempotent). Writes `event stopped (Ctrl-C)` always, `event stopped
    /// (Esc)` only if something was still moving (arrow keys send Esc too), then the aborted
    /// run's event if it was not announced yet.
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    pub fn interrupt(
        &mut self,
        key: StopKey,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let moving = robot.status().activity != Activity::Idle || self.active.is_some();
        robot.abort();
        if moving || key == StopKey::CtrlC {
            let name = match key {
                StopKey::CtrlC => "Ctrl-C",
                StopKey::Escape => "Esc",
            };
            write!(out, "event stopped ({name})\r\n")?;
        }
        self.collect_finished(robot, out)
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
        storage: &mut dyn ParamStorage,
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
        storage: &mut dyn ParamStorage,
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
        storage: &mut dyn ParamStorage,
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

    fn start(&mut self, path: PathKind, robot: &mut dyn Robot, out: &mut dyn Write) -> fmt::Result {
        if self.runs.is_full() {
            let msg = "run store full (drop <n> first)";
            return write_err(out, ErrorCode::StoreFull, &msg);
        }
        match robot.start(path) {
            Ok(()) => {
                let number = self.runs.len() + 1;
                self.active = Some(ActiveRun { number, path });
                write!(out, "ok run {number} started: ")?;
                report::write_path(out, &path)?;
                out.write_str(EOL)
            }
            Err(e) => robot_err(out, e),
        }
    }

    fn start_next(&mut self, robot: &mut dyn Robot, out: &mut dyn Write) -> fmt::Result {
        match self.next_planned() {
            Some(direction) => {
                let path = PathKind::Square {
                    direction,
                    side_m: self.settings.square_side_f64(),
                };
                self.start(path, robot, out)
            }
            None => write_err(
                out,
                ErrorCode::PlanComplete,
                &"all planned runs done (calibrate, or run cw|ccw for more)",
            ),
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
        storage: &mut dyn ParamStorage,
        out: &mut dyn Write,
    ) -> fmt::Result {
        self.execute_command(cmd, robot, storage, out)?;
        self.store_runs(robot, storage, out)
    }

    fn execute_command(
        &mut self,
        cmd: Command<'_>,
        robot: &mut dyn Robot,
        storage: &mut dyn ParamStorage,
        out: &mut dyn Write,
    ) -> fmt::Result {
        self.collect_finished(robot, out)?;
        let side = self.settings.square_side_f64();
        match cmd {
            Command::Help => report::write_help(out),
            Command::Status => {
                let status = robot.status();
                let pose = robot.pose();
                report::write_status(out, &status, &pose, self)
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
            Command::Next => self.start_next(robot, out),
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
            Command::Stop => {
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
            Command::Clear => match robot.status().fault {
                Some(name) => {
                    robot.clear_fault();
                    write!(out, "ok fault cleared ({name})\r\n")
                }
                None => write!(out, "ok no fault latched\r\n"),
            },
            Command::Measure {
                run,
                x_m,
                y_m,
                theta_deg,
            } => self.measure(run, x_m, y_m, theta_deg, robot, out),
            Command::Runs => report::write_runs(out, &self.runs),
            Command::Record { index, first_knot } => {
                let Some(run) = index.checked_sub(1).and_then(|i| self.runs.get(i)) else {
                    let n = self.runs.len();
                    return write!(
                        out,
                        "err {}: no run {index} ({n} stored)\r\n",
                        ErrorCode::NoSuchRun.code()
                    );
                };
                if first_knot > 0 && first_knot >= run.knots.len() {
                    return write!(
                        out,
                        "err {}: run {index} has {} knots\r\n",
                        ErrorCode::OutOfRange.code(),
                        run.knots.len()
                    );
                }
                record::write_record_page(out, index, run, first_knot)
            }
            Command::Version => record::write_version(out),
            Command::Drop { index } => {
                let removed = index
                    .checked_sub(1)
                    .and_then(|i| remove_at(&mut self.runs, i));
                let Some(run) = removed else {
                    let n = self.runs.len();
                    return write!(
                        out,
                        "err {}: no run {index} ({n} stored)\r\n",
                        ErrorCode::NoSuchRun.code()
                    );
                };
                let _ = remove_at(&mut self.run_ids, index - 1);
                self.runs_changed();
                write!(out, "ok dropped run {index}: ")?;
                report::write_path(out, &run.path)?;
                write!(out, "; {} runs left\r\n", self.runs.len())
            }
            Command::DropAll => {
                if self.active.is_some() || robot.status().activity != Activity::Idle {
                    return robot_err(out, RobotError::Busy);
                }
                let n = self.runs.len();
                self.runs.clear();
                self.run_ids.clear();
                self.runs_changed();
                write!(out, "ok dropped all {n} runs\r\n")
            }
            Command::Calibrate { method } => self.calibrate(method, robot, out),
            Command::Apply { method } => self.apply(method, robot, out),
            Command::Save => {
                if let Err(e) = storable(&self.settings) {
                    return storage_err(out, e);
                }
                match storage.save(&self.settings, robot.motors_stopped()) {
                    Ok(()) => {
                        // A save that had to wipe damaged flash took the runs with it.
                        if !self.runs.is_empty() {
                            self.store_runs_again();
                        }
                        write!(out, "ok saved\r\n")
                    }
                    Err(e) => storage_err(out, e),
                }
            }
            Command::ResetParams => self.reset_params(robot, storage, out),
            Command::Pose => {
                let p = robot.pose();
                write!(out, "ok ")?;
                report::write_pose(out, &p)?;
                out.write_str(EOL)
            }
            Command::OdomReset => match robot.reset_odometry() {
                Ok(()) => write!(out, "ok odometry reset\r\n"),
                Err(e) => robot_err(out, e),
            },
            Command::Stream { on: Some(hz) } => {
                let hz = hz.unwrap_or(DEFAULT_STREAM_HZ).max(1);
                self.stream = Some(Stream {
                    period_us: 1_000_000 / u64::from(hz),
                    next_due_us: None,
                    last: None,
                });
                write!(out, "ok stream on {hz} Hz\r\n")
            }
            Command::Stream { on: None } => {
                self.stream = None;
                write!(out, "ok stream off\r\n")
            }
            Command::Echo { on } => {
                self.echo = on;
                write!(out, "ok echo {}\r\n", if on { "on" } else { "off" })
            }
            Command::Drive { v_mps, w_radps } => match robot.drive(v_mps, w_radps) {
                Ok(()) => {
                    // The controller clamps to the same limits; say so rather than silently.
                    let l = &self.settings.motion;
                    let v = clamp(v_mps, -l.max_speed_mps, l.max_speed_mps);
                    let w = clamp(w_radps, -l.max_turn_rate_radps, l.max_turn_rate_radps);
                    if v == v_mps && w == w_radps {
                        write!(out, "ok\r\n")
                    } else {
                        write!(
                            out,
                            "ok limited to v={} m/s w={} rad/s (max_speed, max_turn_rate)\r\n",
                            Decimal::signed(f64::from(v), 3),
                            Decimal::signed(f64::from(w), 3)
                        )
                    }
                }
                Err(e) => robot_err(out, e),
            },
        }
    }

    fn set(
        &mut self,
        name: crate::protocol::ParamName,
        value: f64,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        if robot.status().activity != Activity::Idle {
            return robot_err(out, RobotError::Busy);
        }
        let (mut new, changed) = match self.settings.with_value(name, value) {
            Ok(x) => x,
            Err(e) => return write_err(out, ErrorCode::InvalidParams, &e),
        };
        if changed == Changed::Nothing {
            write!(out, "ok {} = ", name.as_str())?;
            report::write_param_value(out, &self.settings, name)?;
            return write!(out, " (unchanged)\r\n");
        }
        // A calibration is relative to the nominal geometry it was computed for: it is dropped
        // when that changes, and restored when the geometry is set back.
        let mut restored = None;
        if changed == Changed::Geometry
            && let Some(d) = &self.dropped
            && d.nominal == new.nominal
        {
            new.active = d.active;
            new.calibration = Some(d.calibration.clone());
            restored = Some(d.calibration.method.clone());
        }
        let pushed = match changed {
            Changed::Geometry => robot.set_geometry(new.active),
            Changed::Motion => robot.set_limits(&new.motion),
            Changed::Plan | Changed::Nothing => Ok(()),
            Changed::Wiring => robot.set_wiring(new.wiring),
            Changed::Tuning => robot.set_tuning(&new.tuning),
            Changed::Rate => robot.set_rate(new.control_hz),
        };
        if let Err(e) = pushed {
            return robot_err(out, e);
        }
        let dropped = match (&self.settings.calibration, changed) {
            (Some(c), Changed::Geometry) => {
                self.dropped = Some(Dropped {
                    nominal: self.settings.nominal,
                    active: self.settings.active,
                    calibration: c.clone(),
                });
                Some(c.method.clone())
            }
            _ => None,
        };
        if restored.is_some() && dropped.is_none() {
            self.dropped = None;
        }
        self.settings = new;
        write!(out, "ok {} = ", name.as_str())?;
        report::write_param_value(out, &self.settings, name)?;
        if let Some(m) = restored {
            write!(out, " (calibration {m} restored)")?;
        } else if let Some(m) = dropped {
            write!(
                out,
                " (calibration {m} dropped: it is relative to the old geometry; set the old \
                 value back to restore it; the stored one stays until save)"
            )?;
        }
        out.write_str(EOL)
    }

    /// `measure [#n] x y [θ]`: without `#n` it fills the last finished run if that is
    /// unmeasured (never an earlier one, never after an aborted run); `#n` fills or replaces run
    /// `n` and says what it replaced. Refused while anything moves, and when implausible.
    fn measure(
        &mut self,
        index: Option<usize>,
        x_m: f64,
        y_m: f64,
        theta_deg: Option<f64>,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        if robot.status().activity != Activity::Idle {
            return write_err(
                out,
                ErrorCode::Busy,
                &"a run is driving: measure after its `event run … finished` line",
            );
        }
        let stored = self.runs.len();
        let n = match index {
            Some(n) if n > stored => {
                return write!(
                    out,
                    "err {}: no run {n} ({stored} stored)\r\n",
                    ErrorCode::NoSuchRun.code()
                );
            }
            Some(n) => n,
            None => {
                if let Some(a) = self.last_aborted {
                    return write!(
                        out,
                        "err {}: run {} was aborted and not stored: nothing to measure (drive \
                         it again; measure #<n> x y fills an earlier run)\r\n",
                        ErrorCode::NoRun.code(),
                        a.number
                    );
                }
                match self.runs.last() {
                    None => {
                        return write_err(
                            out,
                            ErrorCode::NoRun,
                            &"no finished run to measure (run cw|ccw or next first)",
                        );
                    }
                    Some(r) if r.measured.is_some() => {
                        return write!(
                            out,
                            "err {}: run {stored} is already measured (measure #{stored} x y \
                             [theta] replaces it)\r\n",
                            ErrorCode::NoRun.code()
                        );
                    }
                    Some(_) => stored,
                }
            }
        };
        let Some(run) = self.runs.get_mut(n - 1) else {
            return write_err(out, ErrorCode::NoSuchRun, &"no such run");
        };
        if let Err(why) = measure::check(run, x_m, y_m, theta_deg) {
            write!(out, "err {}: run {n} ", ErrorCode::Implausible.code())?;
            report::write_path(out, &run.path)?;
            return write!(out, ": {why}\r\n");
        }
        let replaced = run.measured.replace(Measurement {
            x_m,
            y_m,
            theta_rad: theta_deg.map(f64::to_radians),
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
            ": error vs odometry dx={} dy={} m\r\n",
            Decimal::signed(x_m - odo.x_m, 6),
            Decimal::signed(y_m - odo.y_m, 6),
        )
    }

    /// Why `calibrate`/`apply` cannot run yet, if so.
    fn refuse_calibration(&self, out: &mut dyn Write) -> Option<fmt::Result> {
        refuse_calibration(&self.progress(), out)
    }

    fn calibrate(
        &mut self,
        method: Option<&str>,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        // The exact solve takes seconds on the target; the console must stay responsive (`stop`)
        // while anything moves.
        if robot.status().activity != Activity::Idle {
            return robot_err(out, RobotError::Busy);
        }
        if let Some(m) = method
            && !self.calibrator.methods().iter().any(|k| keyword_eq(k, m))
        {
            return self.unknown_method(out);
        }
        let nominal = self.settings.nominal;
        write_calibration(&mut self.calibrator, &self.runs, &nominal, method, out)
    }

    fn unknown_method(&self, out: &mut dyn Write) -> fmt::Result {
        write!(
            out,
            "err {}: unknown method; one of ",
            ErrorCode::BadKeyword.code()
        )?;
        for (i, m) in self.calibrator.methods().iter().enumerate() {
            if i > 0 {
                out.write_str("|")?;
            }
            out.write_str(m)?;
        }
        out.write_str(EOL)
    }

    fn apply(&mut self, method: &str, robot: &mut dyn Robot, out: &mut dyn Write) -> fmt::Result {
        if robot.status().activity != Activity::Idle {
            return robot_err(out, RobotError::Busy);
        }
        let Some(name) = self
            .calibrator
            .methods()
            .iter()
            .copied()
            .find(|k| keyword_eq(k, method))
        else {
            return self.unknown_method(out);
        };
        if let Some(refused) = self.refuse_calibration(out) {
            return refused;
        }
        let nominal = self.settings.nominal;
        let sol = match self.calibrator.solve(&self.runs, &nominal, name) {
            Ok(s) => s,
            Err(e) => return write_err(out, ErrorCode::CalibrationFailed, &e),
        };
        let p = self.progress();
        // The longest whole-character prefix that fits (method names are short ASCII), copied
        // as one `str`: pushing `char`s would link the UTF-8 encoder for this one use.
        let mut end = name.len().min(settings::METHOD_NAME_LEN);
        while !name.is_char_boundary(end) {
            end -= 1;
        }
        let mut method_name = heapless::String::new();
        let _ = method_name.push_str(name.get(..end).unwrap_or(""));
        let mut candidate = self.settings.clone();
        candidate.active = sol.geometry;
        candidate.calibration = Some(AppliedCalibration {
            method: method_name,
            e_d: sol.e_d,
            e_b: sol.e_b,
            e_s: sol.e_s,
            runs_used: (p.cw_measured + p.ccw_measured).min(usize::from(u16::MAX)) as u16,
            e_max_m: sol.e_max_m.unwrap_or(0.0),
        });
        // The rule `save` applies: what cannot be stored is not applied either.
        if let Err(e) = storable(&candidate) {
            return storage_err(out, e);
        }
        if let Err(e) = robot.set_geometry(sol.geometry) {
            return robot_err(out, e);
        }
        self.settings = candidate;
        self.dropped = None;
        write!(
            out,
            "ok applied {name}: E_d={} E_b={} E_s={} (not saved; save to keep)\r\n",
            Decimal::fixed(sol.e_d, 9),
            Decimal::fixed(sol.e_b, 9),
            Decimal::fixed(sol.e_s, 9)
        )
    }

    fn reset_params(
        &mut self,
        robot: &mut dyn Robot,
        storage: &mut dyn ParamStorage,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let defaults = Settings::default();
        if robot.status().activity != Activity::Idle {
            return robot_err(out, RobotError::Busy);
        }
        if let Err(e) = storage.reset(robot.motors_stopped()) {
            return storage_err(out, e);
        }
        // A reset that had to wipe damaged flash took the runs with it.
        if !self.runs.is_empty() {
            self.store_runs_again();
        }
        // Idle was checked above, so the controller accepts every part.
        if let Err(e) = push_settings(robot, &defaults) {
            return robot_err(out, e);
        }
        self.settings = defaults;
        self.dropped = None;
        write!(out, "ok parameters reset to defaults and stored\r\n")
    }
}

/// Hands every part of `settings` the controller runs with to `robot`: the active geometry, the
/// motion limits, the wiring, the speed-loop tuning and the control rate (the same parts as
/// [`Settings::controller_config`], which boots the controller).
///
/// # Errors
/// The first part the robot refuses (all are accepted while it is idle).
fn push_settings(robot: &mut dyn Robot, settings: &Settings) -> Result<(), RobotError> {
    robot.set_geometry(settings.active)?;
    robot.set_limits(&settings.motion)?;
    robot.set_wiring(settings.wiring)?;
    robot.set_tuning(&settings.tuning)?;
    robot.set_rate(settings.control_hz)
}

/// The one validation rule of `apply` and `save`: the settings must make a parameter record
/// that validates.
///
/// # Errors
/// [`StorageError::Record`] with the record's reason.
pub fn storable(settings: &Settings) -> Result<(), StorageError> {
    settings
        .to_record()
        .and_then(|r| r.validate().map(|()| r))
        .map(|_| ())
        .map_err(StorageError::Record)
}

/// The `calibrate` reply for `runs` (the header, one row per method or only `method`, the first
/// result's per-run residuals, the advice and the final line): what the board prints, and what a
/// host prints when it recalibrates the runs it kept (the console's offline `recalibrate`).
/// The caller has checked `method` against the calibrator's names.
///
/// # Errors
/// Only if `out` refuses the text.
pub fn write_calibration<C: Calibrator>(
    calibrator: &mut C,
    runs: &[RunRecord],
    nominal: &crate::kinematics::geometry::Geometry,
    method: Option<&str>,
    out: &mut dyn Write,
) -> fmt::Result {
    let p = progress_of(runs);
    if let Some(refused) = refuse_calibration(&p, out) {
        return refused;
    }
    report::write_solution_header(out)?;
    let mut solved = 0usize;
    // The first result with per-run residuals (the exact fit) is listed after the table.
    let mut residuals: Option<(&'static str, Vec<RunResidual, MAX_RUNS>)> = None;
    let methods: Vec<&'static str, 16> = calibrator.methods().iter().take(16).copied().collect();
    for name in methods {
        if method.is_some_and(|m| !keyword_eq(m, name)) {
            continue;
        }
        let result = calibrator.solve(runs, nominal, name);
        if let Ok(s) = &result {
            solved += 1;
            if residuals.is_none() && !s.residuals.is_empty() {
                residuals = Some((name, s.residuals.clone()));
            }
        }
        report::write_solution_row(out, name, &result)?;
    }
    if let Some((name, r)) = &residuals {
        report::write_residuals(out, name, r)?;
    }
    if solved == 0 {
        // Advice from a failed fit would be meaningless.
        return write_err(
            out,
            ErrorCode::CalibrationFailed,
            &"no method succeeded (check the measurements: runs)",
        );
    }
    calibrator.advice(runs, nominal, method, out)?;
    write!(
        out,
        "ok {solved} solved from {} measured runs (cw {}, ccw {}); apply <method> to use one\r\n",
        p.cw_measured + p.ccw_measured,
        p.cw_measured,
        p.ccw_measured,
    )
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

/// The `err 13` reply when `calibrate`/`apply` cannot run yet (no measured square in a
/// direction), if so.
fn refuse_calibration(p: &Progress, out: &mut dyn Write) -> Option<fmt::Result> {
    if p.cw_measured == 0 || p.ccw_measured == 0 {
        return Some(write!(
            out,
            "err {}: need measured square runs in both directions \
             (measured: cw {}, ccw {})\r\n",
            ErrorCode::NotEnoughRuns.code(),
            p.cw_measured,
            p.ccw_measured,
        ));
    }
    None
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
