//! The motion controller: the one object the control task steps (default 1 kHz, up to 10 kHz).
//!
//! Each [`Controller::step`] takes the raw hardware counter values of both encoders and:
//! 1. extends them to `i64` tick totals (wrap-safe, glitch-checked, see [`crate::encoder`]);
//! 2. updates the odometry pose ([`crate::odometry`]) and, during a run, a second odometry in the
//!    run's start frame;
//! 3. steps the active mode — a routine ([`crate::routine`]: square, line, circle), velocity
//!    driving with a deadman, or idle — and the two wheel speed controllers ([`crate::speed`]);
//! 4. checks for faults (encoder glitch, stall) and returns the motor command.
//!
//! Safety: a glitch stops the motors in the same period, a stall as soon as it is detected, an
//! [`Controller::abort`] in the next period, the velocity deadman `deadman_ms` (counted in
//! control periods) after the last [`Controller::drive`]. Faults are latched until
//! [`Controller::clear_fault`]; while latched nothing starts.
//!
//! Units: duties in `[-1, 1]` (positive forward), ticks forward positive, SI elsewhere.

use core::fmt;

use crate::button::Press;
use crate::encoder::{
    CounterWidth, Encoder, EncoderConfig, EncoderGlitch, Polarity, WheelTicks, max_step_for,
};
use crate::geometry::{Geometry, GeometryError};
use crate::motor::{MotorDriver, StopMode};
use crate::num::clamp;
use crate::odometry::{Integration, Odometry, OdometryState, Pose};
use crate::profile::{LimitsError, MotionLimits};
use crate::routine::{PathError, Routine, RunPlan, SegmentKind, SettleConfig, validate_path};
use crate::run::{PathKind, RunRecord};
use crate::speed::{SpeedPi, SpeedPiState, SpeedTuning, TuningError, WheelReference};

/// Stall detection: a wheel commanded with at least `min_duty` that counts no tick for
/// `time_ms` is stalled.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct StallConfig {
    /// Smallest |duty| that counts as commanded motion.
    pub min_duty: f32,
    /// How long a commanded wheel may count no tick, ms.
    pub time_ms: u32,
}

/// Everything the controller needs; validated once by [`Controller::new`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerConfig {
    /// Kinematic geometry used by odometry and for the routine's targets.
    pub geometry: Geometry,
    /// Speed and acceleration limits.
    pub limits: MotionLimits,
    /// Control rate, Hz (1,000 ..= 10,000).
    pub rate_hz: u32,
    /// Right encoder counter.
    pub right_encoder: EncoderConfig,
    /// Left encoder counter.
    pub left_encoder: EncoderConfig,
    /// Speed-loop tuning.
    pub speed: SpeedTuning,
    /// When a segment counts as reached.
    pub settle: SettleConfig,
    /// Stall detection.
    pub stall: StallConfig,
    /// Velocity-mode deadman, ms.
    pub deadman_ms: u32,
    /// How the motors are stopped.
    pub stop_mode: StopMode,
    /// Odometry integration rule.
    pub integration: Integration,
}

/// Encoder glitch limit for `geometry` at `rate_hz`: 2 m/s of the smaller wheel, +50 %.
fn glitch_limit(width: CounterWidth, geometry: &Geometry, rate_hz: u32) -> u32 {
    let period_s = 1.0 / f64::from(rate_hz.max(1));
    let d_min = libm::fmin(geometry.diameter_right_m, geometry.diameter_left_m);
    max_step_for(width, geometry.counts_per_rev, d_min, 2.0, period_s)
}

impl ControllerConfig {
    /// Defaults for the board: right encoder on a 32-bit timer, left on a 16-bit timer counting
    /// backwards, glitch limit for 2 m/s; default limits and tuning; 500 ms deadman; brake.
    pub fn new(geometry: Geometry, rate_hz: u32) -> Self {
        let step = |w| glitch_limit(w, &geometry, rate_hz);
        ControllerConfig {
            geometry,
            limits: MotionLimits::DEFAULT,
            rate_hz,
            right_encoder: EncoderConfig {
                width: CounterWidth::Bits32,
                polarity: Polarity::Normal,
                max_step: step(CounterWidth::Bits32),
            },
            left_encoder: EncoderConfig {
                width: CounterWidth::Bits16,
                polarity: Polarity::Inverted,
                max_step: step(CounterWidth::Bits16),
            },
            speed: SpeedTuning::DEFAULT,
            settle: SettleConfig {
                tolerance_ticks: 20,
                periods: rate_hz / 20,
                timeout_periods: 2 * rate_hz,
            },
            stall: StallConfig {
                min_duty: 0.1,
                time_ms: 300,
            },
            deadman_ms: 500,
            stop_mode: StopMode::Brake,
            integration: Integration::ExactArc,
        }
    }
}

/// Why a [`ControllerConfig`] was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum ConfigError {
    /// The geometry is invalid.
    Geometry(GeometryError),
    /// The motion limits are invalid.
    Limits(LimitsError),
    /// The speed tuning is invalid.
    Tuning(TuningError),
    /// The rate is outside 1,000 ..= 10,000 Hz.
    Rate,
    /// The stall duty is not within (0, 1] or the stall time is outside 1 ..= 10,000 ms.
    Stall,
    /// The deadman is outside 1 ..= 10,000 ms.
    Deadman,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::Geometry(e) => write!(f, "{e}"),
            ConfigError::Limits(e) => write!(f, "{e}"),
            ConfigError::Tuning(e) => write!(f, "{e}"),
            ConfigError::Rate => f.write_str("control rate must be within 1000..10000 Hz"),
            ConfigError::Stall => f.write_str("stall duty must be in (0, 1], time 1..10000 ms"),
            ConfigError::Deadman => f.write_str("deadman must be within 1..10000 ms"),
        }
    }
}

impl From<GeometryError> for ConfigError {
    fn from(e: GeometryError) -> Self {
        ConfigError::Geometry(e)
    }
}

impl From<LimitsError> for ConfigError {
    fn from(e: LimitsError) -> Self {
        ConfigError::Limits(e)
    }
}

impl From<TuningError> for ConfigError {
    fn from(e: TuningError) -> Self {
        ConfigError::Tuning(e)
    }
}

/// A wheel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Wheel {
    /// The right wheel.
    Right,
    /// The left wheel.
    Left,
}

/// A latched fault; the motors are stopped until [`Controller::clear_fault`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum Fault {
    /// An encoder counter jumped further than the wheel can move in one period.
    EncoderGlitch {
        /// Which encoder.
        wheel: Wheel,
        /// The rejected delta, counts.
        delta: i64,
    },
    /// A wheel was commanded to move but counted no tick for the stall time.
    Stall {
        /// Which wheel.
        wheel: Wheel,
    },
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Fault::EncoderGlitch { wheel, delta } => {
                write!(f, "{wheel:?} encoder glitch ({delta} counts in one period)")
            }
            Fault::Stall { wheel } => write!(f, "{wheel:?} wheel stalled"),
        }
    }
}

/// Why a run was not started.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum StartError {
    /// A run or velocity drive is active.
    Busy,
    /// A fault is latched; clear it first.
    Faulted,
    /// The encoders have not been read yet (no `step` so far).
    NotReady,
    /// The path's size is implausible.
    Path(PathError),
}

impl fmt::Display for StartError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StartError::Busy => f.write_str("busy"),
            StartError::Faulted => f.write_str("fault latched, clear it first"),
            StartError::NotReady => f.write_str("encoders not read yet"),
            StartError::Path(e) => write!(f, "{e}"),
        }
    }
}

/// Why a velocity command was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum DriveError {
    /// A routine is running.
    Busy,
    /// A fault is latched; clear it first.
    Faulted,
    /// The encoders have not been read yet.
    NotReady,
    /// A speed is not finite.
    NotFinite,
}

impl fmt::Display for DriveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            DriveError::Busy => "busy",
            DriveError::Faulted => "fault latched, clear it first",
            DriveError::NotReady => "encoders not read yet",
            DriveError::NotFinite => "speeds must be finite",
        })
    }
}

/// Why a setting was not applied.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum SetError {
    /// Only allowed while idle.
    Busy,
    /// The geometry is invalid.
    Geometry(GeometryError),
    /// The limits are invalid.
    Limits(LimitsError),
}

impl fmt::Display for SetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SetError::Busy => f.write_str("only allowed while idle"),
            SetError::Geometry(e) => write!(f, "{e}"),
            SetError::Limits(e) => write!(f, "{e}"),
        }
    }
}

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
    /// A fault is latched; motors stopped.
    Faulted(Fault),
}

/// Routine tracking information for one step (for diagnostics and tests).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tracking {
    /// Index of the segment.
    pub segment: usize,
    /// The segment.
    pub kind: SegmentKind,
    /// Reference minus measured ticks of the right wheel.
    pub error_right_ticks: f64,
    /// Reference minus measured ticks of the left wheel.
    pub error_left_ticks: f64,
}

impl Tracking {
    /// Wheel synchronisation error: how far the right wheel is ahead of the left one relative
    /// to their common profile, ticks.
    pub fn sync_error_ticks(&self) -> f64 {
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

/// What a button press did (see [`Controller::on_press`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ButtonAction {
    /// A short press started this run.
    Started(PathKind),
    /// A short press could not start a run.
    StartRefused(StartError),
    /// A short press cleared a latched fault (the next short press starts).
    ClearedFault,
    /// A long press aborted any motion.
    Aborted,
}

/// A routine in progress.
#[derive(Clone, Debug, PartialEq)]
struct ActiveRun {
    routine: Routine,
    start_totals: WheelTicks,
    /// Odometry in the run's start frame (origin, heading +x).
    odometry: OdometryState,
}

/// Velocity mode state.
#[derive(Clone, Copy, Debug, PartialEq)]
struct DriveState {
    /// Commanded centre speed (m/s) and turn rate (rad/s), clamped to the limits.
    target: (f64, f64),
    /// Ramped reference speed and turn rate at the previous and at the current step.
    previous: (f64, f64),
    /// See `previous`.
    now: (f64, f64),
    /// Periods left before the deadman stops the motors.
    remaining: u32,
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
    deadman_periods: u32,
    still_periods: u32,
}

/// Periods without wheel motion after which the motors count as stopped (0.1 s).
const STILL_SECONDS_INV: u32 = 10;

impl Controller {
    /// A controller for `config`; idle, encoders synchronised at the first [`Controller::step`].
    ///
    /// # Errors
    /// [`ConfigError`] for the first invalid setting.
    pub fn new(config: ControllerConfig) -> Result<Self, ConfigError> {
        if !(1000..=10_000).contains(&config.rate_hz) {
            return Err(ConfigError::Rate);
        }
        config.limits.validate()?;
        config.speed.validate()?;
        let s = &config.stall;
        if !(s.min_duty > 0.0 && s.min_duty <= 1.0 && (1..=10_000).contains(&s.time_ms)) {
            return Err(ConfigError::Stall);
        }
        if !(1..=10_000).contains(&config.deadman_ms) {
            return Err(ConfigError::Deadman);
        }
        let odometry = Odometry::new(&config.geometry, config.integration)?;
        let per_ms = |ms: u32| (u64::from(ms) * u64::from(config.rate_hz) / 1000) as u32;
        Ok(Controller {
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
            stall_periods: per_ms(config.stall.time_ms).max(1),
            deadman_periods: per_ms(config.deadman_ms).max(1),
            still_periods: 0,
        })
    }

    fn speed_pis(c: &ControllerConfig) -> (SpeedPi, SpeedPi) {
        let rate = c.rate_hz as f32;
        (
            SpeedPi::new(c.speed.gains(c.geometry.meters_per_tick_right()), rate),
            SpeedPi::new(c.speed.gains(c.geometry.meters_per_tick_left()), rate),
        )
    }

    /// One control period: `raw_right`, `raw_left` are the hardware counter values.
    pub fn step(&mut self, raw_right: u32, raw_left: u32) -> StepOutput {
        let stop = MotorCommand::Stop(self.config.stop_mode);
        let Some((enc_r, enc_l)) = self.encoders.as_mut() else {
            self.encoders = Some((
                Encoder::new(self.config.right_encoder, raw_right),
                Encoder::new(self.config.left_encoder, raw_left),
            ));
            self.odometry
                .reset(&mut self.odo_state, WheelTicks::default(), Pose::default());
            return self.output(stop, None);
        };
        let glitch = |w: Wheel, e: EncoderGlitch| Fault::EncoderGlitch {
            wheel: w,
            delta: e.delta,
        };
        let (res_r, res_l) = (enc_r.update(raw_right), enc_l.update(raw_left));
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
        self.still_periods = if dr == 0 && dl == 0 {
            self.still_periods.saturating_add(1)
        } else {
            0
        };
        if self.fault.is_none() {
            self.check_stall(dr, dl);
        }
        if self.fault.is_some() {
            return self.output(stop, None);
        }
        let (command, tracking) = if self.run.is_some() {
            self.step_run(dr, dl)
        } else if self.drive.is_some() {
            (self.step_drive(dr, dl), None)
        } else {
            (stop, None)
        };
        self.last_duty = match command {
            MotorCommand::Duty { right, left } => (right, left),
            MotorCommand::Stop(_) => (0.0, 0.0),
        };
        self.output(command, tracking)
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

    /// Latches a fault and ends any motion.
    fn latch(&mut self, fault: Fault) {
        if self.fault.is_none() {
            error!("fault: stopping motors");
        }
        self.fault = Some(fault);
        self.run = None;
        self.drive = None;
        self.last_duty = (0.0, 0.0);
    }

    /// A wheel driven with at least `min_duty` in the last period that counted no tick.
    fn check_stall(&mut self, dr: i64, dl: i64) {
        let min = self.config.stall.min_duty;
        let count = |c: &mut u32, duty: f32, d: i64| {
            if libm::fabsf(duty) >= min && d == 0 {
                *c = c.saturating_add(1);
            } else {
                *c = 0;
            }
            *c
        };
        let r = count(&mut self.stall_count.0, self.last_duty.0, dr);
        let l = count(&mut self.stall_count.1, self.last_duty.1, dl);
        if r >= self.stall_periods {
            self.latch(Fault::Stall {
                wheel: Wheel::Right,
            });
        } else if l >= self.stall_periods {
            self.latch(Fault::Stall { wheel: Wheel::Left });
        }
    }

    fn duties(&mut self, r: &WheelReference, l: &WheelReference, dr: i64, dl: i64) -> MotorCommand {
        MotorCommand::Duty {
            right: self.pi.0.step(&mut self.pi_state.0, r, dr as f32),
            left: self.pi.1.step(&mut self.pi_state.1, l, dl as f32),
        }
    }

    fn step_run(&mut self, dr: i64, dl: i64) -> (MotorCommand, Option<Tracking>) {
        let Some(run) = self.run.as_mut() else {
            return (MotorCommand::Stop(self.config.stop_mode), None);
        };
        let since_start = self.totals - run.start_totals;
        self.odometry.update(&mut run.odometry, since_start);
        let s = run
            .routine
            .step(since_start, &self.config.geometry, &self.config.limits);
        let tracking = Tracking {
            segment: s.segment,
            kind: s.kind,
            error_right_ticks: s.error.0,
            error_left_ticks: s.error.1,
        };
        if s.finished {
            self.finish_run();
            return (MotorCommand::Stop(self.config.stop_mode), Some(tracking));
        }
        (self.duties(&s.right, &s.left, dr, dl), Some(tracking))
    }

    fn finish_run(&mut self) {
        let Some(run) = self.run.take() else {
            return;
        };
        let odometry_end = run.odometry.pose().to_f64();
        let path = *run.routine.path();
        info!("run finished");
        self.finished = Some(RunRecord {
            path,
            geometry: self.config.geometry,
            knots: run.routine.into_knots(),
            odometry_end,
            measured: None,
        });
    }

    fn step_drive(&mut self, dr: i64, dl: i64) -> MotorCommand {
        let rate = f64::from(self.config.rate_hz);
        let l = &self.config.limits;
        let g = &self.config.geometry;
        let Some(d) = self.drive.as_mut() else {
            return MotorCommand::Stop(self.config.stop_mode);
        };
        if d.remaining == 0 {
            info!("drive deadman: stopping");
            self.drive = None;
            return MotorCommand::Stop(self.config.stop_mode);
        }
        d.remaining -= 1;
        let ramp =
            |cur: f64, target: f64, max_accel: f32| ramp_toward(cur, target, max_accel, rate);
        // The reference ramps linearly between steps: the period that just ended went from
        // `previous` to `now` (its increment is compared with the encoders'); the one that
        // starts goes from `now` to `next` (its midpoint speed is the feed-forward).
        let (prev, now) = (d.previous, d.now);
        let next = (
            ramp(now.0, d.target.0, l.max_accel_mps2),
            ramp(now.1, d.target.1, l.max_turn_accel_radps2),
        );
        d.previous = now;
        d.now = next;
        let half_b = 0.5 * g.wheelbase_m;
        let wheel =
            |(v, w): (f64, f64), sign: f64, m_per_tick: f64| (v + sign * w * half_b) / m_per_tick;
        let reference = |sign: f64, k: f64| {
            let (a, b, c) = (
                wheel(prev, sign, k),
                wheel(now, sign, k),
                wheel(next, sign, k),
            );
            WheelReference {
                delta_ticks: (0.5 * (a + b) / rate) as f32,
                velocity_tps: (0.5 * (b + c)) as f32,
                accel_tps2: ((c - b) * rate) as f32,
            }
        };
        let r = reference(1.0, g.meters_per_tick_right());
        let lf = reference(-1.0, g.meters_per_tick_left());
        self.duties(&r, &lf, dr, dl)
    }

    /// Starts a run of `path` from the current pose (its start frame is the current pose).
    ///
    /// # Errors
    /// [`StartError`] when busy, faulted, not ready, or the path is implausible.
    pub fn start(&mut self, path: PathKind) -> Result<(), StartError> {
        if self.fault.is_some() {
            return Err(StartError::Faulted);
        }
        if self.run.is_some() || self.drive.is_some() {
            return Err(StartError::Busy);
        }
        if self.encoders.is_none() {
            return Err(StartError::NotReady);
        }
        validate_path(&path).map_err(StartError::Path)?;
        let routine = Routine::new(
            path,
            &self.config.geometry,
            &self.config.limits,
            self.config.rate_hz,
            self.config.settle,
        )
        .map_err(StartError::Path)?;
        let mut odometry = OdometryState::default();
        self.odometry
            .reset(&mut odometry, WheelTicks::default(), Pose::default());
        self.run = Some(ActiveRun {
            routine,
            start_totals: self.totals,
            odometry,
        });
        self.reset_loops();
        info!("run started");
        Ok(())
    }

    fn reset_loops(&mut self) {
        self.pi_state = Default::default();
        self.stall_count = (0, 0);
        self.last_duty = (0.0, 0.0);
    }

    /// Ends any run or velocity drive; the next step commands a stop. The run is discarded.
    pub fn abort(&mut self) {
        if self.run.is_some() || self.drive.is_some() {
            warn!("motion aborted");
        }
        self.run = None;
        self.drive = None;
    }

    /// Velocity mode: centre speed `v_mps` and turn rate `w_radps` (CCW positive), each clamped
    /// to the limits and ramped with the acceleration limits. The motors stop `deadman_ms` after
    /// the last call.
    ///
    /// # Errors
    /// [`DriveError`] while a routine runs, a fault is latched, before the first step, or for
    /// non-finite speeds.
    pub fn drive(&mut self, v_mps: f32, w_radps: f32) -> Result<(), DriveError> {
        if self.fault.is_some() {
            return Err(DriveError::Faulted);
        }
        if self.run.is_some() {
            return Err(DriveError::Busy);
        }
        if self.encoders.is_none() {
            return Err(DriveError::NotReady);
        }
        if !v_mps.is_finite() || !w_radps.is_finite() {
            return Err(DriveError::NotFinite);
        }
        let l = &self.config.limits;
        let target = (
            f64::from(clamp(v_mps, -l.max_speed_mps, l.max_speed_mps)),
            f64::from(clamp(
                w_radps,
                -l.max_turn_rate_radps,
                l.max_turn_rate_radps,
            )),
        );
        let remaining = self.deadman_periods;
        match self.drive.as_mut() {
            Some(d) => {
                d.target = target;
                d.remaining = remaining;
            }
            None => {
                self.reset_loops();
                self.drive = Some(DriveState {
                    target,
                    previous: (0.0, 0.0),
                    now: (0.0, 0.0),
                    remaining,
                });
            }
        }
        Ok(())
    }

    /// The user button: a short press starts the next planned run (and advances the plan so
    /// runs alternate CW/CCW) or, while a fault is latched, clears it; a long press aborts.
    pub fn on_press(&mut self, press: Press, plan: &mut RunPlan) -> ButtonAction {
        match press {
            Press::Long => {
                self.abort();
                ButtonAction::Aborted
            }
            Press::Short if self.fault.is_some() => {
                self.clear_fault();
                ButtonAction::ClearedFault
            }
            Press::Short => {
                let path = plan.next_path();
                match self.start(path) {
                    Ok(()) => {
                        plan.advance();
                        ButtonAction::Started(path)
                    }
                    Err(e) => ButtonAction::StartRefused(e),
                }
            }
        }
    }

    /// The record of the last completed run, once.
    pub fn take_finished_run(&mut self) -> Option<RunRecord> {
        self.finished.take()
    }

    fn is_idle(&self) -> bool {
        self.run.is_none() && self.drive.is_none()
    }

    /// Applies a new geometry (a calibration); only while idle. The pose continues from where
    /// it is; later ticks are converted with the new geometry.
    ///
    /// # Errors
    /// [`SetError::Busy`] while moving, [`SetError::Geometry`] for an invalid geometry.
    pub fn set_geometry(&mut self, geometry: Geometry) -> Result<(), SetError> {
        if !self.is_idle() {
            return Err(SetError::Busy);
        }
        let odometry =
            Odometry::new(&geometry, self.config.integration).map_err(SetError::Geometry)?;
        let pose = self.odo_state.pose();
        self.odometry = odometry;
        self.odometry.reset(&mut self.odo_state, self.totals, pose);
        self.config.geometry = geometry;
        // The glitch limit is a speed in counts per period: it follows the geometry.
        let rate = self.config.rate_hz;
        self.config.right_encoder.max_step =
            glitch_limit(self.config.right_encoder.width, &geometry, rate);
        self.config.left_encoder.max_step =
            glitch_limit(self.config.left_encoder.width, &geometry, rate);
        if let Some((r, l)) = self.encoders.as_mut() {
            r.set_max_step(self.config.right_encoder.max_step);
            l.set_max_step(self.config.left_encoder.max_step);
        }
        self.pi = Self::speed_pis(&self.config);
        Ok(())
    }

    /// Applies new motion limits; only while idle.
    ///
    /// # Errors
    /// [`SetError::Busy`] while moving, [`SetError::Limits`] for invalid limits.
    pub fn set_limits(&mut self, limits: MotionLimits) -> Result<(), SetError> {
        if !self.is_idle() {
            return Err(SetError::Busy);
        }
        limits.validate().map_err(SetError::Limits)?;
        self.config.limits = limits;
        Ok(())
    }

    /// Clears a latched fault (the motors stay stopped until the next start or drive).
    pub fn clear_fault(&mut self) {
        self.fault = None;
        self.stall_count = (0, 0);
    }

    /// What the controller is doing.
    pub fn status(&self) -> Status {
        if let Some(f) = self.fault {
            Status::Faulted(f)
        } else if let Some(run) = &self.run {
            Status::Running {
                path: *run.routine.path(),
                segment: run.routine.segment_index() as u8,
            }
        } else if self.drive.is_some() {
            Status::Driving
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
        self.odometry
            .reset(&mut self.odo_state, self.totals, Pose::default());
    }

    /// True when no motion is commanded and neither wheel has moved for 0.1 s: safe for flash
    /// erases that stall the CPU.
    pub fn motors_stopped(&self) -> bool {
        self.is_idle() && self.still_periods >= self.config.rate_hz / STILL_SECONDS_INV
    }

    /// The latched fault.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }

    /// The configuration in force (geometry and limits as last set).
    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }

    /// Tick totals since the first step.
    pub fn totals(&self) -> WheelTicks {
        self.totals
    }
}

/// One period of a velocity ramp: `cur` moved toward `target` by at most `max_accel / rate_hz`.
/// Out of line: inlined at both call sites it would exist twice in flash.
#[inline(never)]
fn ramp_toward(cur: f64, target: f64, max_accel: f32, rate_hz: f64) -> f64 {
    let step = f64::from(max_accel) / rate_hz;
    cur + clamp(target - cur, -step, step)
}
