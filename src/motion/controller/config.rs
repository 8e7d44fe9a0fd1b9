//! Controller configuration: what a [`Controller`] is built from, validated once by
//! [`Controller::new`], and the settings that may change while it is idle.

use core::fmt;

use super::fault::FollowingState;
use super::{Controller, Wheel, still_limits, wheel_scales};

use crate::kinematics::encoder::{CounterWidth, EncoderConfig, Polarity, max_step_for};
use crate::kinematics::geometry::{Geometry, GeometryError};
use crate::kinematics::odometry::{Integration, Odometry};
use crate::motion::motor::StopMode;
use crate::motion::profile::{LimitsError, MotionLimits};
use crate::motion::routine::SettleConfig;
use crate::motion::speed::{SpeedTuning, TuningError};
use crate::motion::wiring::Wiring;
use crate::util::num::{fmax, fmin};

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

/// Following-error detection: a wheel whose position falls behind (or runs ahead of) its
/// reference by more than `max_error_m` for `time_ms` is not under control — typically a motor
/// or encoder wired with the opposite sign, which makes the speed loop push the wheel away from
/// its reference at full duty while the encoder keeps counting (so the stall check never fires).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct FollowingConfig {
    /// Largest tolerated |reference − measured| wheel travel, m.
    pub max_error_m: f32,
    /// How long the error may stay above `max_error_m`, ms.
    pub time_ms: u32,
}

impl FollowingConfig {
    /// 0.1 m for 100 ms. A healthy loop tracks within micrometres (the square's peak wheel
    /// error is a few ticks), a blocked wheel at 0.3 m/s reaches 0.1 m after 0.33 s (after the
    /// stall check's 0.3 s, so a stall is reported as a stall), and a reversed wheel at full
    /// duty passes 0.1 m within about 0.1 s of starting.
    pub const DEFAULT: FollowingConfig = FollowingConfig {
        max_error_m: 0.1,
        time_ms: 100,
    };
}

/// The velocity deadman by default, ms: the motors stop when no `drive` came for this long.
pub const DEFAULT_DEADMAN_MS: u32 = 500;

/// Everything the controller needs; validated once by [`Controller::new`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerConfig {
    /// Kinematic geometry used by odometry and for the routine's targets.
    pub geometry: Geometry,
    /// Speed and acceleration limits.
    pub limits: MotionLimits,
    /// Control rate, Hz (1,000 ..= 10,000).
    pub rate_hz: u32,
    /// Right encoder counter, standard wiring (see `wiring` for a reversed one).
    pub right_encoder: EncoderConfig,
    /// Left encoder counter, standard wiring (see `wiring` for a reversed one).
    pub left_encoder: EncoderConfig,
    /// Speed-loop tuning.
    pub speed: SpeedTuning,
    /// When a segment counts as reached.
    pub settle: SettleConfig,
    /// Stall detection.
    pub stall: StallConfig,
    /// Following-error detection.
    pub following: FollowingConfig,
    /// Motors and encoders reversed against the standard wiring (stored, set by the operator).
    pub wiring: Wiring,
    /// Velocity-mode deadman, ms.
    pub deadman_ms: u32,
    /// How the motors are stopped.
    pub stop_mode: StopMode,
    /// Odometry integration rule.
    pub integration: Integration,
}

/// The control rate the board boots with when nothing else is stored, Hz.
pub const DEFAULT_RATE_HZ: u32 = 1_000;

/// The control rates the controller accepts, Hz: 1 kHz to 10 kHz in whole kilohertz that give a
/// whole number of microseconds per period. Every time the controller keeps in milliseconds is
/// then a whole number of periods, the boards' control timers (84, 90 and 100 MHz) divide exactly
/// to each rate, and a simulated period is a whole number of microseconds.
pub const RATES_HZ: [u32; 6] = [1_000, 2_000, 4_000, 5_000, 8_000, 10_000];

/// The fastest control rate, Hz (the last of [`RATES_HZ`]).
pub const MAX_RATE_HZ: u32 = RATES_HZ[RATES_HZ.len() - 1];

/// Whether `rate_hz` is one of [`RATES_HZ`].
pub fn rate_supported(rate_hz: u32) -> bool {
    RATES_HZ.contains(&rate_hz)
}

/// `ms` milliseconds in control periods at `rate_hz` (at least one period). Out of line: its
/// 64-bit division call and clamp were inlined at each of its seven configuration callers.
#[inline(never)]
pub fn periods_of_ms(ms: u32, rate_hz: u32) -> u32 {
    ((u64::from(ms) * u64::from(rate_hz) / 1000) as u32).max(1)
}

/// `periods` at `from_hz` as the periods of the same duration at `to_hz`.
fn rescale(periods: u32, from_hz: u32, to_hz: u32) -> u32 {
    let p = u64::from(periods) * u64::from(to_hz) / u64::from(from_hz.max(1));
    u32::try_from(p).unwrap_or(u32::MAX)
}

/// Slowest wheel speed the glitch limit is set for, m/s: a hand push (bring-up, moving the robot
/// back to its mark) and the speed loop's overshoot stay below it whatever the limits.
pub const GLITCH_FLOOR_MPS: f64 = 2.0;

/// Encoder glitch limit for `geometry` and `limits` at `rate_hz`: the fastest wheel speed the
/// limits allow ([`MotionLimits::wheel_speed_mps`], at least [`GLITCH_FLOOR_MPS`]) on the
/// smaller wheel, +50 %.
pub(super) fn glitch_limit(
    width: CounterWidth,
    geometry: &Geometry,
    limits: &MotionLimits,
    rate_hz: u32,
) -> u32 {
    let period_s = 1.0 / f64::from(rate_hz.max(1));
    let d_min = fmin(geometry.diameter_right_m, geometry.diameter_left_m);
    let speed = fmax(GLITCH_FLOOR_MPS, limits.wheel_speed_mps(geometry));
    max_step_for(width, geometry.counts_per_rev, d_min, speed, period_s)
}

/// How long both wheels must stay within the settling tolerance to end a segment, ms.
const SETTLE_MS: u32 = 50;
/// How long after its profile's end a segment ends anyway, ms.
const SETTLE_TIMEOUT_MS: u32 = 2_000;

impl ControllerConfig {
    /// The encoder configuration of `wheel` with the wiring correction applied.
    pub fn encoder(&self, wheel: Wheel) -> EncoderConfig {
        let mut c = match wheel {
            Wheel::Right => self.right_encoder,
            Wheel::Left => self.left_encoder,
        };
        c.polarity = c.polarity.flipped_if(self.wiring.encoder_reversed(wheel));
        c
    }

    /// Defaults for the board: right encoder on a 32-bit timer, left on a 16-bit timer counting
    /// backwards, glitch limit for the default limits (2 m/s: `GLITCH_FLOOR_MPS`); default
    /// limits and tuning; 500 ms deadman; brake.
    /// Everything timed is set in seconds and converted with `rate_hz` (settling 50 ms, settle
    /// timeout 2 s, stall 300 ms, following error 100 ms, deadman 500 ms).
    pub fn new(geometry: Geometry, rate_hz: u32) -> Self {
        let step = |w| glitch_limit(w, &geometry, &MotionLimits::DEFAULT, rate_hz);
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
                periods: periods_of_ms(SETTLE_MS, rate_hz),
                timeout_periods: periods_of_ms(SETTLE_TIMEOUT_MS, rate_hz),
            },
            stall: StallConfig {
                min_duty: 0.1,
                time_ms: 300,
            },
            following: FollowingConfig::DEFAULT,
            wiring: Wiring::STANDARD,
            deadman_ms: DEFAULT_DEADMAN_MS,
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
    /// The rate is not one of [`RATES_HZ`].
    Rate,
    /// The stall duty is not within (0, 1] or the stall time is outside 1 ..= 10,000 ms.
    Stall,
    /// The following-error bound is not within (0, 10] m or its time outside 1 ..= 10,000 ms.
    Following,
    /// The deadman is outside 1 ..= 10,000 ms.
    Deadman,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::Geometry(e) => write!(f, "{e}"),
            ConfigError::Limits(e) => write!(f, "{e}"),
            ConfigError::Tuning(e) => write!(f, "{e}"),
            ConfigError::Rate => f.write_str(RATE_RULE),
            ConfigError::Stall => f.write_str("stall duty must be in (0, 1], time 1..10000 ms"),
            ConfigError::Deadman => f.write_str("deadman must be within 1..10000 ms"),
            ConfigError::Following => {
                f.write_str("following error must be in (0, 10] m, time 1..10000 ms")
            }
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

/// The rule of [`RATES_HZ`] as the error text the protocol shows.
pub const RATE_RULE: &str = "control rate must be 1000, 2000, 4000, 5000, 8000 or 10000 Hz \
     (1..10 kHz, whole kHz with a whole number of microseconds per period)";

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
    /// The speed-loop tuning is invalid.
    Tuning(TuningError),
    /// The control rate is not one of [`RATES_HZ`].
    Rate,
}

impl fmt::Display for SetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SetError::Busy => f.write_str("only allowed while idle"),
            SetError::Geometry(e) => write!(f, "{e}"),
            SetError::Limits(e) => write!(f, "{e}"),
            SetError::Tuning(e) => write!(f, "{e}"),
            SetError::Rate => f.write_str(RATE_RULE),
        }
    }
}

impl Controller {
    /// Applies a new geometry (a calibration); only while idle. The pose continues from where
    /// it is; later ticks are converted with the new geometry.
    ///
    /// # Errors
    /// [`SetError::Busy`] while moving, [`SetError::Geometry`] for an invalid geometry,
    /// [`SetError::Limits`] when the motion limits would turn its wheels faster than its
    /// encoders count.
    pub fn set_geometry(&mut self, geometry: Geometry) -> Result<(), SetError> {
        if !self.is_idle() {
            return Err(SetError::Busy);
        }
        let odometry =
            Odometry::new(&geometry, self.config.integration).map_err(SetError::Geometry)?;
        // The limits must stay countable on the new wheels (a finer encoder counts faster).
        self.config
            .limits
            .validate_for(&geometry)
            .map_err(SetError::Limits)?;
        self.stash_finished_run();
        let pose = self.odo_state.pose();
        self.odometry = odometry;
        self.odometry.reset(&mut self.odo_state, self.totals, pose);
        self.config.geometry = geometry;
        self.rederive();
        Ok(())
    }

    /// Re-derives everything the controller keeps in counts or periods from the configuration's
    /// geometry and rate (only while idle: nothing is accumulated): the glitch limit (a speed in
    /// counts per period), the speed loops, the stall, deadman and following-error bounds, the
    /// at-rest travel and velocity mode's scales.
    pub(super) fn rederive(&mut self) {
        self.derive_glitch_limits();
        self.pi = Self::speed_pis(&self.config);
        self.stall_periods = periods_of_ms(self.config.stall.time_ms, self.config.rate_hz);
        self.deadman_periods = periods_of_ms(self.config.deadman_ms, self.config.rate_hz);
        self.following = FollowingState::for_config(&self.config);
        self.still_limit_ticks = still_limits(&self.config.geometry);
        self.wheel_scales = wheel_scales(&self.config.geometry);
    }

    /// The encoders' glitch limit (a speed in counts per period) from the configuration's
    /// geometry, limits and rate.
    pub(super) fn derive_glitch_limits(&mut self) {
        let c = &mut self.config;
        c.right_encoder.max_step =
            glitch_limit(c.right_encoder.width, &c.geometry, &c.limits, c.rate_hz);
        c.left_encoder.max_step =
            glitch_limit(c.left_encoder.width, &c.geometry, &c.limits, c.rate_hz);
        if let Some((r, l)) = self.encoders.as_mut() {
            r.set_max_step(self.config.right_encoder.max_step);
            l.set_max_step(self.config.left_encoder.max_step);
        }
    }

    /// Applies new motion limits; only while idle. The encoder glitch limit follows them.
    ///
    /// # Errors
    /// [`SetError::Busy`] while moving, [`SetError::Limits`] for invalid limits or limits the
    /// encoders cannot follow ([`MotionLimits::validate_for`]).
    pub fn set_limits(&mut self, limits: MotionLimits) -> Result<(), SetError> {
        if !self.is_idle() {
            return Err(SetError::Busy);
        }
        limits
            .validate_for(&self.config.geometry)
            .map_err(SetError::Limits)?;
        self.config.limits = limits;
        self.rederive();
        Ok(())
    }

    /// Applies a new speed-loop tuning (motor models and bandwidth); only while idle. The gains
    /// are derived here, once, and used from the next control period on.
    ///
    /// # Errors
    /// [`SetError::Busy`] while moving, [`SetError::Tuning`] for an invalid tuning.
    pub fn set_tuning(&mut self, tuning: SpeedTuning) -> Result<(), SetError> {
        if !self.is_idle() {
            return Err(SetError::Busy);
        }
        tuning.validate().map_err(SetError::Tuning)?;
        self.config.speed = tuning;
        self.pi = Self::speed_pis(&self.config);
        Ok(())
    }

    /// Applies a wiring correction; only while idle. Tick totals and the pose are kept; later
    /// counts and duties use the new signs.
    ///
    /// # Errors
    /// [`SetError::Busy`] while moving.
    pub fn set_wiring(&mut self, wiring: Wiring) -> Result<(), SetError> {
        if !self.is_idle() {
            return Err(SetError::Busy);
        }
        self.config.wiring = wiring;
        let (r, l) = (
            self.config.encoder(Wheel::Right),
            self.config.encoder(Wheel::Left),
        );
        if let Some((er, el)) = self.encoders.as_mut() {
            er.set_polarity(r.polarity);
            el.set_polarity(l.polarity);
        }
        Ok(())
    }

    /// Changes the control rate; only while idle. Everything the controller counts in control
    /// periods is converted from the same time in seconds: the glitch limit (counts per
    /// period), the speed loops' discretisation, stall, following-error and deadman times, the
    /// settling times and the at-rest window (the time already spent at rest is kept). Tick
    /// totals, the pose and a latched fault are kept. The caller steps the controller at the new
    /// rate from the next period on.
    ///
    /// # Errors
    /// [`SetError::Busy`] while moving, [`SetError::Rate`] for a rate not in [`RATES_HZ`].
    pub fn set_rate(&mut self, rate_hz: u32) -> Result<(), SetError> {
        if !self.is_idle() {
            return Err(SetError::Busy);
        }
        if !rate_supported(rate_hz) {
            return Err(SetError::Rate);
        }
        let old = self.config.rate_hz;
        if old == rate_hz {
            return Ok(());
        }
        let c = &mut self.config;
        c.rate_hz = rate_hz;
        c.settle.periods = rescale(c.settle.periods, old, rate_hz).max(1);
        c.settle.timeout_periods = rescale(c.settle.timeout_periods, old, rate_hz).max(1);
        self.rederive();
        self.still_periods = rescale(self.still_periods, old, rate_hz);
        Ok(())
    }
}
