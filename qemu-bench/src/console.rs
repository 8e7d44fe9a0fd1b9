//! The console's `calibrate` and `apply exact` commands on the recorded squares: the session as
//! the firmware's console task runs it, with the library's calibrator, over the fixture runs.
//!
//! The session gets the runs the way the board gets them after a reset ([`Session::restore_runs`]
//! from its storage); here the storage is [`FixtureRuns`], which hands over the fixture and has
//! no flash to write (the bench counts the commands, not the flash). The reply text is reduced to
//! a hash and a length ([`ReplyHash`]), which must be equal on host and target.

use core::fmt;

use heapless::Vec;
use odocal::motion::controller::Controller;
use odocal::motion::run::{MAX_RUNS, RunRecord};
use odocal::session::library::{ControllerLock, LibraryCalibrator};
use odocal::session::{MotorsStopped, Robot, Session, Settings, SettingsAndRuns, StoreError};
use odocal::storage::{FlashFault, RunsLoaded, StoredRun};

use crate::squares::SquareRuns;

/// The console commands the bench counts, in order.
pub const COMMANDS: [&str; 2] = ["calibrate", "apply exact"];

/// A console session touching every kind of controller access the console task makes: reads
/// (`status`, `params`, `runs`), every parameter group handed to the controller (limits,
/// geometry, wiring, tuning, rate, and back), `calibrate` and `apply` (the solve outside any
/// lock, the geometry under it), `reset-params`. The bench counts every controller lock the
/// console takes on its way (the firmware's `LockedController`): the longest is the most the console
/// task can delay a control period.
pub const LOCK_SCRIPT: [&str; 17] = [
    "status",
    "params",
    "runs",
    "set max_speed 0.25",
    "set d_right 0.1502",
    "set d_right 0.15",
    "set motor_left_sign -1",
    "set motor_left_sign 1",
    "set speed_bandwidth 30",
    "set control_hz 10000",
    "set control_hz 1000",
    "calibrate",
    "apply exact",
    "status",
    "reset-params yes",
    "params",
    "status",
];

/// Whether a console line changes what the controller runs with (`set`, `apply`, `apply online`,
/// `reset-params`): refused unless the robot is idle, so its locks can only delay a period in
/// which nothing moves. The others (`status`, `params`, `runs`, `calibrate`) run at any time.
pub fn changes_settings(line: &str) -> bool {
    matches!(
        odocal::protocol::Command::parse(line),
        Ok(odocal::protocol::Command::Set { .. }
            | odocal::protocol::Command::Apply { .. }
            | odocal::protocol::Command::ApplyFactors { .. }
            | odocal::protocol::Command::ResetParams { .. })
    )
}

/// The controller behind a lock whose every hold is bracketed by `open` and `close` (the
/// bench's window markers on the target, nothing on the host): the console task's view of the
/// controller, as the firmware's RTIC lock gives it.
pub struct Bracketed<'a> {
    /// The controller.
    pub controller: &'a mut Controller,
    /// Called when the lock is taken.
    pub open: fn(),
    /// Called when it is released.
    pub close: fn(),
}

impl ControllerLock for Bracketed<'_> {
    fn with_controller<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> R {
        (self.open)();
        let r = f(self.controller);
        (self.close)();
        r
    }
}

/// Storage that holds the fixture runs and nothing else.
pub struct FixtureRuns<'a>(pub &'a SquareRuns);

const NO_FLASH: StoreError = StoreError::Flash(FlashFault::Other);

impl SettingsAndRuns for FixtureRuns<'_> {
    fn usable(&self) -> Result<(), StoreError> {
        Err(NO_FLASH)
    }

    fn save(&mut self, _: &Settings, _: MotorsStopped) -> Result<(), StoreError> {
        Err(NO_FLASH)
    }

    fn save_runs(
        &mut self,
        _: &[RunRecord],
        _: &mut [Option<StoredRun>],
        _: MotorsStopped,
    ) -> Result<(), StoreError> {
        Err(NO_FLASH)
    }

    fn load_runs(
        &mut self,
        runs: &mut Vec<RunRecord, MAX_RUNS>,
        ids: &mut Vec<Option<StoredRun>, MAX_RUNS>,
    ) -> RunsLoaded {
        runs.clear();
        ids.clear();
        let mut loaded = RunsLoaded {
            found: true,
            ..RunsLoaded::default()
        };
        for record in self.0.records() {
            if runs.push(record).is_err() || ids.push(None).is_err() {
                loaded.skipped += 1;
                continue;
            }
            loaded.restored += 1;
            loaded.measured += 1;
        }
        loaded
    }
}

/// FNV-1a hash and length of the reply text.
pub struct ReplyHash {
    /// The hash.
    pub hash: u64,
    /// Bytes written.
    pub bytes: u64,
}

impl Default for ReplyHash {
    fn default() -> Self {
        ReplyHash {
            hash: 0xcbf2_9ce4_8422_2325,
            bytes: 0,
        }
    }
}

impl fmt::Write for ReplyHash {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for b in s.bytes() {
            self.hash = (self.hash ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
        self.bytes += s.len() as u64;
        Ok(())
    }
}

/// A session with the default settings (the paper's nominal geometry, as the fixture's runs
/// were driven) and the fixture runs restored.
pub fn session(runs: &SquareRuns) -> Session<LibraryCalibrator> {
    let mut session = Session::new(Settings::default(), LibraryCalibrator::default());
    let mut sink = ReplyHash::default();
    let _ = session.restore_runs(&mut FixtureRuns(runs), &mut sink);
    session
}

/// Executes one console line on `session`; the reply goes into `reply`.
pub fn command(
    session: &mut Session<LibraryCalibrator>,
    robot: &mut dyn Robot,
    runs: &SquareRuns,
    line: &str,
    reply: &mut ReplyHash,
) {
    let _ = session.handle_line(line, robot, &mut FixtureRuns(runs), reply);
}
