//! The motion controller: the one object the control task steps (default 1 kHz, up to 10 kHz).
//!
//! Each [`Controller::step`] takes the raw hardware counter values of both encoders and:
//! 1. extends them to `i64` tick totals (wrap-safe, glitch-checked, see [`crate::kinematics::encoder`]);
//! 2. updates the odometry pose ([`crate::kinematics::odometry`]) (a run's end pose in its own start
//!    frame is mapped from it when the run's record is taken);
//! 3. steps the active mode — a routine ([`crate::motion::routine`]: square, line, circle), velocity
//!    driving with a deadman, or idle — and the two wheel speed controllers ([`crate::motion::speed`]);
//! 4. checks for faults (encoder glitch, stall) and returns the motor command.
//!
//! Safety: a glitch stops the motors in the same period, a stall as soon as it is detected, an
//! [`Controller::abort`] in the next period, the velocity deadman `deadman_ms` (counted in
//! control periods) after the last [`Controller::drive`]. Faults are latched until
//! [`Controller::clear_fault`]; while latched nothing starts.
//!
//! Units: duties in `[-1, 1]` (positive forward), ticks forward positive, SI elsewhere.
//!
//! Parts: `config` (what the controller is built from, validated once, and the settings that
//! change while idle), `mode` (the idle / run / drive state machine and its commands),
//! `fault` (stall detection and the latched faults), `stopped` (the proof that the motors are
//! stopped, which every flash write takes).

mod config;
mod fault;
mod mode;
mod stopped;

pub use config::{
    ConfigError, ControllerConfig, DEFAULT_DEADMAN_MS, DEFAULT_RATE_HZ, FollowingConfig,
    MAX_RATE_HZ, RATE_RULE, RATES_HZ, SetError, StallConfig, periods_of_ms, rate_supported,
};
pub use fault::Fault;
use fault::FollowingState;
use mode::{ActiveCheck, ActiveRun, DriveState};
pub use mode::{ButtonAction, DriveError, StartError};
pub use stopped::{MotorsRunning, MotorsStopped};

use crate::kinematics::encoder::{Encoder, EncoderGlitch, WheelTicks};
use crate::kinematics::geometry::Geometry;
use crate::kinematics::odometry::{Odometry, OdometryState, Pose};
use crate::motion::bringup::{CheckKind, CheckReport};
use crate::motion::motor::{MotorDriver, StopMode};
use crate::motion::path::SegmentKind;
use crate::motion::routine::ticks_f32;
use crate::motion::run::{PathKind, RunRecord};
use crate::motion::speed::{SpeedPi, SpeedPiState, WheelReference};
pub use crate::motion::wheel::Wheel;

/// What the motors should do for the next period.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum MotorCommand {
    /// Drive with these duties in `[-1, 1]`.
    Duty {
        /// Right motor duty.
        right: f32,
        /// Left motor duty.
        left: f32,
    },
    /// Stop both motors.
    Stop(StopMode),
}

impl MotorCommand {
    /// Sends the command to a driver.
    pub fn apply<M: MotorDriver>(&self, driver: &mut M) {
        match *self {
            MotorCommand::Duty { right, left } => driver.set_duty(right, left),
            MotorCommand::Stop(mode) => driver.stop(mode),
        }
    }

    /// Whether this is a stop (or zero duty on both motors).
    pub fn is_stop(&self) -> bool {
        match *self {
            MotorCommand::Duty { right, left } => right == 0.0 && left == 0.0,
            MotorCommand::Stop(_) => true,
        }
    }
}

/// What the controller is doing.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Status {
    /// Motors stopped, ready.
    Idle,
    /// A routine is running.
    Running {
        /// The path.
        path: PathKind,
        /// Index of the current segment.
        segment: u8,
    },
    /// Velocity mode.
    Driving,
    /// A bring-up check is running.
    Checking(CheckKind),
    /// A fault is latched; motors stopped.
    Faulted(Fault),
}

impl Status {
    /// Whether a run, a drive or a check is in progress (neither idle nor faulted).
    pub fn is_busy(&self) -> bool {
        !matches!(self, Status::Idle | Status::Faulted(_))
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<Fault> {
        match self {
            Status::Faulted(f) => Some(*f),
            _ => None,
        }
    }
}

/// Routine tracking information for one step (for diagnostics and tests).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tracking {
    /// Index of the segment.
    pub segment: usize,
    /// The segment.
    pub kind: SegmentKind,
    /// Reference minus measured ticks of the right wheel.
    pub error_right_ticks: f32,
    /// Reference minus measured ticks of the left wheel.
    pub error_left_ticks: f32,
}

impl Tracking {
    /// Wheel synchronisation error: how far the right wheel is ahead of the left one relative
    /// to their common profile, ticks.
    pub fn sync_error_ticks(&self) -> f32 {
        self.error_left_ticks - self.error_right_ticks
    }
}

/// The result of one control period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepOutput {
    /// Motor command for the next period.
    pub command: MotorCommand,
    /// Odometry pose.
    pub pose: Pose,
    /// The latched fault, if any.
    pub fault: Option<Fault>,
    /// Routine tracking, while a routine runs.
    pub tracking: Option<Tracking>,
    /// Tick totals since power-up.
    pub totals: WheelTicks,
}

/// The motion controller (see the module docs).
#[derive(Clone, Debug)]
pub struct Controller {
    config: ControllerConfig,
    odometry: Odometry,
    odo_state: OdometryState,
    encoders: Option<(Encoder, Encoder)>,
    totals: WheelTicks,
    pi: (SpeedPi, SpeedPi),
    pi_state: (SpeedPiState, SpeedPiState),
    last_duty: (f32, f32),
    run: Option<ActiveRun>,
    drive: Option<DriveState>,
    fault: Option<Fault>,
    finished: Option<RunRecord>,
    stall_count: (u32, u32),
    stall_periods: u32,
    following: FollowingState,
    check: Option<ActiveCheck>,
    check_report: Option<CheckReport>,
    deadman_periods: u32,
    still_periods: u32,
    /// Tick totals when the wheels were last seen moving (see [`Controller::motors_stopped`]).
    still_anchor: WheelTicks,
    /// [`STILL_TRAVEL_M`] in counts of each wheel (right, left).
    still_limit_ticks: (u64, u64),
    /// Velocity mode's conversion to wheel ticks (right, left), from the geometry.
    wheel_scales: (WheelScale, WheelScale),
    /// Control periods the board missed while the robot moved, since boot (saturating).
    missed_periods: u32,
    /// Periods missed just before the next step (a flash erase while idle, a late period while
    /// moving): that step's counts span them all, its glitch limit is widened and the speed
    /// loops' counts are scaled to match.
    catch_up: u32,
    /// Missed periods while moving, [`MISS_WEIGHT`] each, less one per period stepped while
    /// moving: above [`MISS_WEIGHT`] × the periods of [`OVERRUN_FAULT_MS`] latches
    /// [`Fault::Overrun`].
    miss_debt: u32,
    /// The pose may be wrong: after a stall either wheel moved so far that the left one's
    /// 16-bit counter may have wrapped. Cleared when a run starts from a new pose.
    pose_lost: bool,
}

/// A gap this long (in control periods' time) while moving latches [`Fault::Overrun`], ms.
pub const OVERRUN_FAULT_MS: u32 = 5;

/// Missed periods are weighed against on-time ones 1 : `MISS_WEIGHT`: a sustained miss rate
/// above 1 period in 20 (5 %) latches [`Fault::Overrun`] as one gap of [`OVERRUN_FAULT_MS`]
/// does, a rate below it never does. Beyond 5 % the control task no longer fits its period
/// (a run of misses, not one interrupt held up once): the speed loop runs on a sample time it
/// was not tuned for and the profile falls behind real time by a period at each miss.
pub const MISS_WEIGHT: u32 = 20;

/// A wheel's speed in ticks/s is `v·ticks_per_m + ω·ticks_per_rad` for the robot's centre
/// speed `v` and turn rate `ω` (derived in `f64` when the geometry changes, used in `f32`).
#[derive(Clone, Copy, Debug, PartialEq)]
struct WheelScale {
    /// `1 / (m per tick)`.
    ticks_per_m: f32,
    /// `±(b/2) / (m per tick)`: positive for the right wheel (CCW turns drive it forward).
    ticks_per_rad: f32,
}

/// The velocity-mode scales of both wheels of `g` (right, left).
fn wheel_scales(g: &Geometry) -> (WheelScale, WheelScale) {
    let half_b = 0.5 * g.wheelbase_m;
    let scale = |m_per_tick: f64, sign: f64| WheelScale {
        ticks_per_m: (1.0 / m_per_tick) as f32,
        ticks_per_rad: (sign * half_b / m_per_tick) as f32,
    };
    (
        scale(g.meters_per_tick_right(), 1.0),
        scale(g.meters_per_tick_left(), -1.0),
    )
}

/// Periods without wheel motion after which the motors count as stopped (0.1 s).
const STILL_SECONDS_INV: u32 = 10;

/// Largest wheel travel that still counts as "not moving", m: 1 mm (424 counts of the paper's
/// robot). Over the 0.1 s window that is below 10 mm/s, while a count of encoder jitter (2.4 µm)
/// is far inside it.
const STILL_TRAVEL_M: f64 = 0.001;

/// [`STILL_TRAVEL_M`] in counts of each wheel of `g` (computed when the geometry changes, so
/// the control period compares integers).
fn still_limits(g: &Geometry) -> (u64, u64) {
    (
        (STILL_TRAVEL_M / g.meters_per_tick_right()) as u64,
        (STILL_TRAVEL_M / g.meters_per_tick_left()) as u64,
    )
}

impl Controller {
    /// A controller for `config`; idle, encoders synchronised at the first [`Controller::step`].
    /// The rules of the setters apply: the limits must be countable on the geometry's encoders
    /// ([`MotionLimits::validate_for`], as [`Controller::set_limits`]), and everything kept in
    /// counts or periods (the glitch limit included) is derived from the geometry, limits and
    /// rate by the setters' own functions, whatever `config` held.
    ///
    /// [`MotionLimits::validate_for`]: crate::motion::profile::MotionLimits::validate_for
    ///
    /// # Errors
    /// [`ConfigError`] for the first invalid setting.
    pub fn new(config: ControllerConfig) -> Result<Self, ConfigError> {
        if !rate_supported(config.rate_hz) {
            return Err(ConfigError::Rate);
        }
        config.limits.validate_for(&config.geometry)?;
        config.speed.validate()?;
        let s = &config.stall;
        if !(s.min_duty > 0.0 && s.min_duty <= 1.0 && (1..=10_000).contains(&s.time_ms)) {
            return Err(ConfigError::Stall);
        }
        if !(1..=10_000).contains(&config.deadman_ms) {
            return Err(ConfigError::Deadman);
        }
        let f = &config.following;
        if !(f.max_error_m > 0.0 && f.max_error_m <= 10.0 && (1..=10_000).contains(&f.time_ms)) {
            return Err(ConfigError::Following);
        }
        let odometry = Odometry::new(&config.geometry, config.integration)?;
        let per_ms = |ms: u32| periods_of_ms(ms, config.rate_hz);
        let mut c = Controller {
            config,
            odometry,
            odo_state: OdometryState::default(),
            encoders: None,
            totals: WheelTicks::default(),
            pi: Self::speed_pis(&config),
            pi_state: Default::default(),
            last_duty: (0.0, 0.0),
            run: None,
            drive: None,
            fault: None,
            finished: None,
            stall_count: (0, 0),
            stall_periods: per_ms(config.stall.time_ms),
            following: FollowingState::for_config(&config),
            check: None,
            check_report: None,
            deadman_periods: per_ms(config.deadman_ms),
            still_periods: 0,
            still_anchor: WheelTicks::default(),
            still_limit_ticks: still_limits(&config.geometry),
            wheel_scales: wheel_scales(&config.geometry),
            missed_periods: 0,
            catch_up: 0,
            miss_debt: 0,
            pose_lost: false,
        };
        // The rest is derived in the fields above by the functions `rederive` uses.
        c.derive_glitch_limits();
        Ok(c)
    }

    fn speed_pis(c: &ControllerConfig) -> (SpeedPi, SpeedPi) {
        let rate = c.rate_hz as f32;
        (
            SpeedPi::new(
                c.speed
                    .gains(&c.speed.right, c.geometry.meters_per_tick_right()),
                rate,
            ),
            SpeedPi::new(
                c.speed
                    .gains(&c.speed.left, c.geometry.meters_per_tick_left()),
                rate,
            ),
        )
    }

    /// One control period: `raw_right`, `raw_left` are the hardware counter values.
    pub fn step(&mut self, raw_right: u32, raw_left: u32) -> StepOutput {
        let stop = MotorCommand::Stop(self.config.stop_mode);
        let Some((enc_r, enc_l)) = self.encoders.as_mut() else {
            self.encoders = Some((
                Encoder::new(self.config.encoder(Wheel::Right), raw_right),
                Encoder::new(self.config.encoder(Wheel::Left), raw_left),
            ));
            self.odometry
                .reset(&mut self.odo_state, WheelTicks::default(), Pose::default());
            return self.output(stop, None);
        };
        let glitch = |w: Wheel, e: EncoderGlitch| Fault::EncoderGlitch {
            wheel: w,
            delta: e.delta,
        };
        // The counts of every missed period arrive at once: motion (a robot rolled back to its
        // mark during an erase, or a late period while moving), not a glitch, as far as the
        // counters can tell.
        let periods = self.catch_up.saturating_add(1);
        let (res_r, res_l) = if self.catch_up > 0 {
            self.catch_up = 0;
            let (r, l) = (
                enc_r.update_over(raw_right, periods),
                enc_l.update_over(raw_left, periods),
            );
            // Half of what the left counter tells apart, on either wheel (the right one's count
            // is exact, the left one's may already be a wrapped reading).
            let left_range = u64::from(enc_l.config().width.max_unambiguous_step() / 2);
            let beyond = |d: &Result<i64, EncoderGlitch>| {
                d.as_ref().is_ok_and(|d| d.unsigned_abs() > left_range)
            };
            if beyond(&r) || beyond(&l) {
                self.pose_lost = true;
            }
            (r, l)
        } else {
            (enc_r.update(raw_right), enc_l.update(raw_left))
        };
        self.totals = WheelTicks::new(enc_r.total(), enc_l.total());
        let (dr, dl) = match (res_r, res_l) {
            (Ok(r), Ok(l)) => (r, l),
            (Err(e), _) => {
                self.latch(glitch(Wheel::Right, e));
                (0, 0)
            }
            (_, Err(e)) => {
                self.latch(glitch(Wheel::Left, e));
                (0, 0)
            }
        };
        self.odometry.update(&mut self.odo_state, self.totals);
        // Still = neither wheel has drifted more than STILL_TRAVEL_M from where it last moved:
        // an encoder edge jittering by a count or two on a wheel at rest is not motion.
        let drift = self.totals - self.still_anchor;
        let still = drift.right.unsigned_abs() <= self.still_limit_ticks.0
            && drift.left.unsigned_abs() <= self.still_limit_ticks.1;
        if still {
            self.still_periods = self.still_periods.saturating_add(1);
        } else {
            self.still_periods = 0;
            self.still_anchor = self.totals;
        }
        if self.fault.is_none() {
            self.check_stall(dr, dl);
        }
        if self.fault.is_some() {
            return self.output(stop, None);
        }
        if self.is_idle() {
            self.miss_debt = 0;
        } else {
            self.miss_debt = self.miss_debt.saturating_sub(1);
        }
        // The speed loops and checks see one period's share of counts that took `periods`
        // (a count passed the glitch check, so it fits an i32: the core's 32-bit divide).
        let p = i32::try_from(periods).unwrap_or(i32::MAX);
        let share = |d: i64| i64::from(i32::try_from(d).unwrap_or(0) / p);
        let (full_r, full_l) = (dr, dl);
        let (dr, dl) = (share(dr), share(dl));
        if periods > 1 {
            // What sums the motion (identification's travel bound) takes the rest whole.
            self.check_catch_up(full_r - dr, full_l - dl);
        }
        let (command, tracking) = if self.driving_run() {
            self.step_run(dr, dl)
        } else if self.drive.is_some() {
            (self.step_drive(dr, dl), None)
        } else if self.check.is_some() {
            (self.step_check(dr, dl), None)
        } else {
            (stop, None)
        };
        if self.fault.is_some() {
            // The following-error check latched in this period.
            return self.output(stop, None);
        }
        self.last_duty = match command {
            MotorCommand::Duty { right, left } => (right, left),
            MotorCommand::Stop(_) => (0.0, 0.0),
        };
        self.output(self.wired(command), tracking)
    }

    /// `command` (wheel frame) with the wiring's motor signs applied, as the driver needs it.
    fn wired(&self, command: MotorCommand) -> MotorCommand {
        match command {
            MotorCommand::Duty { right, left } => {
                let w = &self.config.wiring;
                MotorCommand::Duty {
                    right: right * w.motor_sign(Wheel::Right),
                    left: left * w.motor_sign(Wheel::Left),
                }
            }
            stop @ MotorCommand::Stop(_) => stop,
        }
    }

    fn output(&self, command: MotorCommand, tracking: Option<Tracking>) -> StepOutput {
        StepOutput {
            command,
            pose: self.odo_state.pose(),
            fault: self.fault,
            tracking,
            totals: self.totals,
        }
    }

    fn duties(&mut self, r: &WheelReference, l: &WheelReference, dr: i64, dl: i64) -> MotorCommand {
        // A period's count is within the glitch limit (1,273 counts at 1 kHz for the paper's
        // robot): exact in f32, which is exact to 2²⁴.
        let (dr, dl) = (ticks_f32(dr), ticks_f32(dl));
        let right = self.pi.0.step(&mut self.pi_state.0, r, dr);
        let left = self.pi.1.step(&mut self.pi_state.1, l, dl);
        self.check_following((r.delta_ticks - dr, l.delta_ticks - dl), (right, left));
        MotorCommand::Duty { right, left }
    }

    /// What the controller is doing.
    pub fn status(&self) -> Status {
        if let Some(f) = self.fault {
            Status::Faulted(f)
        } else if let Some(run) = self.run.as_ref().filter(|r| !r.done()) {
            Status::Running {
                path: *run.routine.path(),
                segment: run.routine.segment_index() as u8,
            }
        } else if self.drive.is_some() {
            Status::Driving
        } else if let Some(c) = &self.check {
            Status::Checking(c.kind())
        } else {
            Status::Idle
        }
    }

    /// The odometry pose.
    pub fn pose(&self) -> Pose {
        self.odo_state.pose()
    }

    /// Sets the odometry pose to the origin (heading +x) at the current tick totals. A run in
    /// progress keeps its own start frame.
    pub fn reset_odometry(&mut self) {
        let at = self.odo_state.pose();
        if let Some(run) = self.run.as_mut().filter(|r| !r.done()) {
            run.frame = run.frame.after_reset(&at);
        }
        self.odometry
            .reset(&mut self.odo_state, self.totals, Pose::default());
    }

    /// The motors are stopped when no motion is commanded and neither wheel has moved more than
    /// 1 mm for 0.1 s (below 10 mm/s; encoder jitter of a few counts does not count): then the
    /// proof that flash erases, which stall the CPU, may go ahead.
    ///
    /// # Errors
    /// [`MotorsRunning`] while anything moves or may move, and before the first control period.
    pub fn motors_stopped(&self) -> Result<MotorsStopped, MotorsRunning> {
        if self.is_idle() && self.still_periods >= self.config.rate_hz / STILL_SECONDS_INV {
            Ok(MotorsStopped::confirmed())
        } else {
            Err(MotorsRunning)
        }
    }

    /// The latched fault.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }

    /// The configuration in force (geometry and limits as last set).
    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }

    /// Position error (reference − measured) of each wheel's speed loop since the current motion
    /// started, ticks (right, left); their difference is the wheel synchronisation error.
    pub fn wheel_errors_ticks(&self) -> (f32, f32) {
        (
            self.pi_state.0.position_error_ticks(),
            self.pi_state.1.position_error_ticks(),
        )
    }

    /// Tick totals since the first step.
    pub fn totals(&self) -> WheelTicks {
        self.totals
    }

    /// The board missed `missed` control periods before this one (the app core's
    /// `MissedPeriods` counts them): the next step takes its counts as spanning them all.
    /// While the robot moves they are counted, and a gap of [`OVERRUN_FAULT_MS`] or more, or a
    /// miss rate above 1 in [`MISS_WEIGHT`] periods kept up, latches [`Fault::Overrun`] (motors
    /// stop at the next step); while idle (a flash erase with the motors stopped) nothing
    /// depends on the period.
    pub fn note_missed_periods(&mut self, missed: u32) {
        if missed == 0 {
            return;
        }
        self.catch_up = self.catch_up.saturating_add(missed);
        if self.is_idle() {
            return;
        }
        self.missed_periods = self.missed_periods.saturating_add(missed);
        self.miss_debt = self
            .miss_debt
            .saturating_add(missed.saturating_mul(MISS_WEIGHT));
        let limit = config::periods_of_ms(OVERRUN_FAULT_MS, self.config.rate_hz);
        if self.miss_debt >= limit.saturating_mul(MISS_WEIGHT) {
            self.latch(Fault::Overrun { missed });
        }
    }

    /// Control periods missed while moving since boot.
    pub fn missed_periods(&self) -> u32 {
        self.missed_periods
    }

    /// Whether the pose may be wrong: after periods missed while idle (a flash erase) the right
    /// wheel had moved more than 16,383 counts (3.9 cm on 150 mm wheels at 200,000 counts/rev),
    /// half of what the left wheel's 16-bit counter tells apart, so the left one may have
    /// wrapped. Below that the counts that arrived during the stall are the motion. Cleared when
    /// a run or drive starts (it measures from its own start).
    pub fn pose_lost(&self) -> bool {
        self.pose_lost
    }
}

#[cfg(test)]
mod size_probe {
    use core::mem::size_of;

    /// The controller's state stays within the size it was trimmed to so that the firmware's
    /// static RAM stays well within its 48 KiB budget (docs/performance.md, Firmware footprint,
    /// has the margin; the routine's parts are bounded in [`crate::motion::routine`]; the
    /// identification's probe added 160 B, the missed-period bookkeeping 16 B). The bound is the
    /// host's size (64-bit `usize`; the board's is no larger): a controller that grows fails
    /// here, and raising its bound is a change to check against the footprint.
    #[test]
    fn sizes() {
        let sizes = [("Controller", size_of::<super::Controller>(), 4936)];
        for (name, size, max) in sizes {
            assert!(size <= max, "{name} is {size} B, above its {max} B");
        }
    }
}
