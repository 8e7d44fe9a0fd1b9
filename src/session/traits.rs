//! What the session needs from the rest of the system, as small traits.
//!
//! [`Robot`] is implemented once, by [`super::library::LockedController`], which locks the
//! controller for the duration of *one* call (never across a calibration solve): on the board
//! an RTIC lock, in host-sim and the tests the controller itself. [`SettingsAndRuns`] persists [`Settings`] and the runs; [`Calibrator`] runs the
//! calibration methods. All units SI (metres, seconds, radians) unless a name says otherwise.

use core::fmt;

use super::Settings;
use crate::calibration::CalibrationError;
use crate::calibration::fit_check::{FitCheck, MeasuringNoise};
use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::PoseF64;
use crate::motion::bringup::{CheckKind, CheckReport};
use crate::motion::controller::{MotorsRunning, MotorsStopped, Status};
use crate::motion::convention::Convention;
use crate::motion::profile::{LimitsError, MotionLimits};
use crate::motion::run::{PathKind, RunRecord};
use crate::motion::speed::SpeedTuning;
use crate::motion::wiring::Wiring;
use crate::storage::{RunsLoaded, StoreError, StoredRun};

/// Stored runs with the numbers they keep for the session (`numbers` empty: numbered by
/// position, 1, 2, …, as a host numbers the runs it kept).
#[derive(Clone, Copy, Debug)]
pub struct Numbered<'a> {
    /// The runs, in store order.
    pub runs: &'a [RunRecord],
    /// Their numbers, in the same order.
    pub numbers: &'a [u16],
}

impl Numbered<'_> {
    /// The number of the run at 1-based store `position`.
    pub fn number(&self, position: usize) -> usize {
        position
            .checked_sub(1)
            .and_then(|i| self.numbers.get(i))
            .map_or(position, |&n| usize::from(n))
    }
}

/// What the robot knows about the control loop's health (only what is worth telling).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Health {
    /// Control periods missed while moving, since boot.
    pub missed_periods: u32,
    /// The pose may be wrong: counts during a stall may have wrapped a counter.
    pub pose_lost: bool,
}

/// Why the robot refused a request.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum RobotError {
    /// A run or drive is in progress.
    Busy,
    /// A fault is latched (its short name, [`super::library::fault_name`]).
    Fault(&'static str),
    /// The request itself is invalid for the controller (e.g. a limit it cannot honour).
    Rejected(Rejection),
}

/// Why the controller refused a request it could not carry out (not busy, not faulted).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Rejection {
    /// The encoders have not been read yet (the first control period has not run).
    NotReady,
    /// The routine does not accept the path's size.
    Path,
    /// The controller does not accept the check.
    Check,
    /// A `drive` speed is not finite.
    NotFinite,
    /// The geometry is invalid for the controller.
    Geometry,
    /// The motion limits are invalid for the controller (why: the limits' own rule).
    Limits(LimitsError),
    /// The speed-loop tuning is invalid for the controller.
    Tuning,
    /// The control rate is not one the controller runs at.
    Rate,
}

impl fmt::Display for Rejection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Rejection::NotReady => "the control loop has not run yet (encoders not read: no control-timer interrupt, as under QEMU)",
            Rejection::Path => "path size not accepted by the routine",
            Rejection::Check => "check not accepted by the controller",
            Rejection::NotFinite => "speeds must be finite",
            Rejection::Geometry => "geometry not accepted by the controller",
            Rejection::Limits(e) => return write!(f, "limits not accepted: {e}"),
            Rejection::Tuning => "tuning not accepted by the controller",
            Rejection::Rate => "control rate not accepted by the controller",
        })
    }
}

impl fmt::Display for RobotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RobotError::Busy => {
                f.write_str("robot is busy: wait for what is in progress to finish")
            }
            RobotError::Fault(name) => write!(f, "fault latched: {name}"),
            RobotError::Rejected(why) => write!(f, "refused: {why}"),
        }
    }
}

/// The controller operations the session uses. Every method is one short critical section.
pub trait Robot {
    /// Starts a path routine.
    ///
    /// # Errors
    /// [`RobotError::Busy`] while moving, [`RobotError::Fault`] with a latched fault.
    fn start(&mut self, path: PathKind) -> Result<(), RobotError>;
    /// Aborts any motion; the motors stop in the next control period.
    fn abort(&mut self);
    /// Velocity command (m/s, rad/s CCW positive), with the controller's 500 ms deadman.
    ///
    /// # Errors
    /// [`RobotError::Busy`] while a routine runs, [`RobotError::Fault`] with a latched fault.
    fn drive(&mut self, v_mps: f32, w_radps: f32) -> Result<(), RobotError>;
    /// The record of a routine that finished since the last call.
    fn take_finished_run(&mut self) -> Option<RunRecord>;
    /// Uses `geometry` for odometry and targets from now on (the pose continues).
    ///
    /// # Errors
    /// [`RobotError::Busy`] unless idle.
    fn set_geometry(&mut self, geometry: Geometry) -> Result<(), RobotError>;
    /// Uses `limits` for the next routines and drive commands.
    ///
    /// # Errors
    /// [`RobotError::Busy`] unless idle; [`RobotError::Rejected`] if the controller cannot use them.
    fn set_limits(&mut self, limits: &MotionLimits) -> Result<(), RobotError>;
    /// Current state, the latched fault in full (which wheel, how far off); replies name a
    /// fault by [`super::library::fault_name`] (`stall`, `following-error`, …).
    fn status(&mut self) -> Status;
    /// The control loop's health (a robot without the bookkeeping: all well).
    fn health(&mut self) -> Health {
        Health::default()
    }
    /// Odometry pose.
    fn pose(&mut self) -> PoseF64;
    /// Cumulative wheel tick totals (for the stream's wheel speeds).
    fn totals(&mut self) -> WheelTicks;
    /// Clears a latched fault (the motors stay stopped).
    fn clear_fault(&mut self);
    /// Sets the odometry pose to the origin.
    ///
    /// # Errors
    /// [`RobotError::Busy`] unless idle.
    fn reset_odometry(&mut self) -> Result<(), RobotError>;
    /// The proof that both motors are stopped, which flash writes take.
    ///
    /// # Errors
    /// [`MotorsRunning`] (`err 18`) while they are not confirmed stopped.
    fn motors_stopped(&mut self) -> Result<MotorsStopped, MotorsRunning>;
    /// Uses `wiring` for the motor and encoder signs from now on.
    ///
    /// # Errors
    /// [`RobotError::Busy`] unless idle.
    fn set_wiring(&mut self, wiring: Wiring) -> Result<(), RobotError>;
    /// Starts a bring-up check.
    ///
    /// # Errors
    /// [`RobotError::Busy`] unless idle, [`RobotError::Fault`] with a latched fault.
    fn start_check(&mut self, kind: CheckKind) -> Result<(), RobotError>;
    /// The report of a bring-up check or motor identification that finished since the last
    /// call.
    fn take_check_report(&mut self) -> Option<CheckReport>;
    /// Uses `tuning` for the speed loops from the next control period on.
    ///
    /// # Errors
    /// [`RobotError::Busy`] unless idle; [`RobotError::Rejected`] for an invalid tuning.
    fn set_tuning(&mut self, tuning: &SpeedTuning) -> Result<(), RobotError>;
    /// Runs the control loop at `rate_hz` from the next period on: the controller converts
    /// everything it times, and the board retimes its control-period source to match.
    ///
    /// # Errors
    /// [`RobotError::Busy`] unless idle; [`RobotError::Rejected`] for a rate it cannot run at.
    fn set_rate(&mut self, rate_hz: u32) -> Result<(), RobotError>;
}

/// Where the session keeps its settings and its runs across a power cut.
pub trait SettingsAndRuns {
    /// Whether anything can be written at all (the part's flash holds the storage map, its
    /// layout is valid): asked before the motors, so that a store that can never write says so.
    ///
    /// # Errors
    /// [`StoreError`]: why nothing can be written.
    fn usable(&self) -> Result<(), StoreError>;
    /// Writes `settings`, with the motors `stopped`.
    ///
    /// # Errors
    /// [`StoreError`]; the previously stored settings stay intact.
    fn save(&mut self, settings: &Settings, stopped: MotorsStopped) -> Result<(), StoreError>;
    /// Stores the run store: each run whose id is `None` is written and gets its id, then the
    /// list of runs with their measurements; runs no longer listed are forgotten; the motors are
    /// `stopped`. A power cut
    /// leaves the previously stored runs or these, never a mix, and never touches the
    /// parameters.
    ///
    /// # Errors
    /// [`StoreError`]; the previously stored runs stay intact.
    fn save_runs(
        &mut self,
        runs: &[RunRecord],
        ids: &mut [Option<StoredRun>],
        stopped: MotorsStopped,
    ) -> Result<(), StoreError>;
    /// Restores the stored runs (at boot) into `runs` and where each is stored into `ids`.
    /// Never fails: what cannot be restored is skipped and reported in the result.
    fn load_runs(
        &mut self,
        runs: &mut heapless::Vec<RunRecord, { crate::motion::run::MAX_RUNS }>,
        ids: &mut heapless::Vec<Option<StoredRun>, { crate::motion::run::MAX_RUNS }>,
    ) -> RunsLoaded;
}

/// How one stored run fits a result (the exact method's robust fit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunResidual {
    /// 1-based position in the store (the session writes the run's number).
    pub run: usize,
    /// End residual `measured − predicted` in x, metres.
    pub dx_m: f64,
    /// End residual in y, metres.
    pub dy_m: f64,
    /// End heading residual, radians, when the heading was measured.
    pub dtheta_rad: Option<f64>,
    /// The run's weight in the robust fit, (0, 1].
    pub weight: f64,
    /// The run disagrees with the others (robust scale).
    pub outlier: bool,
}

/// Which run's removal makes the others agree (leave-one-out of the robust fit).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Culprit {
    /// Without this run (1-based store position) the robust fit of the others flags none, and
    /// no other run's removal does that.
    Run(usize),
    /// No single run's removal restores agreement, or more than one does.
    CannotTell,
}

/// One method's calibration result, factors relative to the nominal geometry.
#[derive(Clone, Debug, PartialEq)]
pub struct Solution {
    /// `E_d = D_R / D_L`.
    pub e_d: f64,
    /// `E_b = b / b_nominal`.
    pub e_b: f64,
    /// `E_s = D_a / D_a,nominal` (1 when the method does not estimate it).
    pub e_s: f64,
    /// Corrected absolute geometry.
    pub geometry: Geometry,
    /// Predicted worst end-position error of a square with this geometry, metres, if known.
    pub e_max_m: Option<f64>,
    /// One-sigma uncertainty of `E_d`, if known.
    pub sd_e_d: Option<f64>,
    /// One-sigma uncertainty of `E_b`, if known.
    pub sd_e_b: Option<f64>,
    /// Every measured run's residual against this result, when the method reports them.
    pub residuals: heapless::Vec<RunResidual, { crate::motion::run::MAX_RUNS }>,
}

impl Solution {
    /// The runs the robust fit flagged, by 1-based store position.
    pub fn flagged(&self) -> impl Iterator<Item = usize> + '_ {
        self.residuals.iter().filter(|r| r.outlier).map(|r| r.run)
    }
}

/// Why a calibration method produced no result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum SolveError {
    /// The method name is not known.
    UnknownMethod,
    /// The runs do not contain what this method needs.
    NotEnoughRuns,
    /// The computation failed (degenerate data, no convergence): the calibration's own error.
    Failed(CalibrationError),
}

impl fmt::Display for SolveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SolveError::UnknownMethod => f.write_str("unknown method"),
            SolveError::NotEnoughRuns => f.write_str("not enough suitable measured runs"),
            // The calibration's wording, and what the operator can do about it at the console.
            SolveError::Failed(e) => {
                write!(f, "{e}")?;
                f.write_str(match e {
                    CalibrationError::NoHeading => " (measure x y theta)",
                    CalibrationError::MixedSide => " (drop some runs)",
                    CalibrationError::MixedGeometry => " (drop the older ones)",
                    _ => "",
                })
            }
        }
    }
}

/// How the session reads its measured runs: the convention in force and the measuring noise
/// declared (`convention`, `set measure_sd`, `set heading_sd`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reading {
    /// How every measured run is re-read.
    pub convention: Convention,
    /// The noise a measured end carries besides the robot's own scatter.
    pub noise: MeasuringNoise,
}

impl Reading {
    /// The standard convention and the default noise.
    pub const DEFAULT: Reading = Reading {
        convention: Convention::Standard,
        noise: MeasuringNoise::DEFAULT,
    };
}

impl Default for Reading {
    fn default() -> Self {
        Reading::DEFAULT
    }
}

/// The calibration methods.
pub trait Calibrator {
    /// Method names, in the order `calibrate` shows them.
    fn methods(&self) -> &[&'static str];
    /// The stored runs or their measurements changed: results kept from earlier solves are
    /// stale. (`calibrate`'s table and advice and `apply` ask for the same solution; a
    /// calibrator may keep it until this is called.)
    fn runs_changed(&mut self);
    /// Solves one method from the stored runs (unmeasured runs are ignored).
    ///
    /// # Errors
    /// [`SolveError`].
    fn solve(
        &mut self,
        runs: &[RunRecord],
        nominal: &Geometry,
        method: &str,
    ) -> Result<Solution, SolveError>;
    /// Reads every measured run under `reading`'s convention and assumes its noise for a
    /// measured end from now on (results kept from earlier solves under another reading are
    /// stale).
    fn set_reading(&mut self, reading: Reading);
    /// Whether the runs the exact fit kept (those it did not flag) agree with one geometry
    /// within the noise set by [`Calibrator::set_reading`] and the robot's own scatter: the χ²
    /// of a least-squares exact fit weighted by that noise. `None` when the fit fails or leaves
    /// no degree of freedom.
    fn fit_check(&mut self, runs: &[RunRecord], nominal: &Geometry) -> Option<FitCheck>;
    /// The method's leave-one-out prediction error on the measured runs: each left out in turn,
    /// the method fitted on the others, and the left-out run's end position predicted from its
    /// ticks with that geometry; the RMS of the misses, metres. `None` when a fold cannot be
    /// solved (too few runs in a direction without the one left out).
    fn prediction_error(
        &mut self,
        runs: &[RunRecord],
        nominal: &Geometry,
        method: &str,
    ) -> Option<f64>;
    /// Leaves each measured run out of the robust fit in turn and names the one whose removal
    /// makes the others agree, or says it cannot tell.
    fn culprit(&mut self, runs: &[RunRecord], nominal: &Geometry) -> Culprit;
    /// Writes track-size advice for these runs as data lines (each ending in `\r\n`), for
    /// every method or only for `only`. Runs the robust fit flagged are left out of it, and
    /// each line then says so by their numbers in `numbered`.
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    fn advice(
        &mut self,
        numbered: Numbered<'_>,
        nominal: &Geometry,
        only: Option<&str>,
        out: &mut dyn fmt::Write,
    ) -> fmt::Result;
}
