//! The operator-editable parameters the session keeps and stores.
//!
//! [`Settings`] is everything `params` shows and `save` persists: the nominal geometry, the
//! applied calibration (factors relative to nominal and the resulting absolute geometry), the
//! motion limits, the calibration plan, the wiring, the speed-loop tuning and the control rate.
//! Units: metres, seconds, radians. Motion limits and the
//! planned side are `f32` like the controller's limits and the stored record; geometry is `f64`.

use core::fmt;

use crate::kinematics::geometry::{Geometry, GeometryError};
use crate::motion::controller::{ControllerConfig, DEFAULT_RATE_HZ, rate_supported};
use crate::motion::profile::MotionLimits;
use crate::motion::speed::{SpeedTuning, TuningError};
use crate::motion::wiring::Wiring;
use crate::protocol::{ParamGroup, ParamName};
use crate::util::num::round_u32;

/// Longest stored method name, bytes.
pub const METHOD_NAME_LEN: usize = 12;

/// A calibration result in use.
#[derive(Clone, Debug, PartialEq)]
pub struct AppliedCalibration {
    /// Method name (e.g. `exact`).
    pub method: heapless::String<METHOD_NAME_LEN>,
    /// `E_d = D_R / D_L`.
    pub e_d: f64,
    /// `E_b = b / b_nominal`.
    pub e_b: f64,
    /// `E_s = D_a / D_a,nominal`.
    pub e_s: f64,
    /// Number of measured runs it was computed from.
    pub runs_used: u16,
    /// Predicted worst square end error with it, metres (NaN-free; 0 when unknown).
    pub e_max_m: f64,
}

/// Everything the session persists.
#[derive(Debug, PartialEq)]
pub struct Settings {
    /// Nominal geometry (as built / as specified).
    pub nominal: Geometry,
    /// Geometry in use: the calibrated one, or `nominal` when there is no calibration.
    pub active: Geometry,
    /// The calibration that produced `active`.
    pub calibration: Option<AppliedCalibration>,
    /// Motion limits.
    pub motion: MotionLimits,
    /// Planned square side `L`, metres.
    pub square_side_m: f32,
    /// Planned square runs per direction.
    pub runs_per_direction: u8,
    /// Motors and encoders reversed against the standard wiring.
    pub wiring: Wiring,
    /// Speed-loop tuning: both motors' models and the bandwidth (the PI gains and feed-forward
    /// are derived from it).
    pub tuning: SpeedTuning,
    /// Control (and odometry) rate, Hz: one of [`crate::motion::controller::RATES_HZ`].
    pub control_hz: u32,
}

impl Clone for Settings {
    // Out of line: `set`, `apply` and the parameter resets each inlined their own copy.
    #[inline(never)]
    fn clone(&self) -> Self {
        Settings {
            calibration: self.calibration.clone(),
            ..*self
        }
    }
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            nominal: Geometry::PAPER_NOMINAL,
            active: Geometry::PAPER_NOMINAL,
            calibration: None,
            motion: MotionLimits::DEFAULT,
            square_side_m: 2.0,
            runs_per_direction: 5,
            wiring: Wiring::STANDARD,
            tuning: SpeedTuning::DEFAULT,
            control_hz: DEFAULT_RATE_HZ,
        }
    }
}

/// Why a parameter change was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum SettingsError {
    /// The resulting nominal geometry is invalid.
    Geometry(GeometryError),
    /// A wiring sign other than 1 or −1.
    Sign,
    /// The speed-loop tuning would be invalid as a whole.
    Tuning(TuningError),
    /// `d_right / d_left` would be outside [`DIAMETER_RATIO_RANGE`].
    DiameterRatio {
        /// The ratio it would be.
        ratio: f64,
    },
    /// `wheelbase / mean wheel diameter` would be outside [`WHEELBASE_RATIO_RANGE`].
    WheelbaseRatio {
        /// The ratio it would be.
        ratio: f64,
    },
    /// A control rate the controller does not run at (not one of
    /// [`crate::motion::controller::RATES_HZ`]).
    Rate,
}

/// Accepted nominal `d_right / d_left`: wheels of one robot differ by far less; a value outside
/// is a typing error (a missing decimal point, millimetres for metres).
pub const DIAMETER_RATIO_RANGE: (f64, f64) = (0.5, 2.0);
/// Accepted nominal `wheelbase / mean wheel diameter` (real two-wheel robots: about 0.7..20).
pub const WHEELBASE_RATIO_RANGE: (f64, f64) = (0.5, 50.0);

impl fmt::Display for SettingsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SettingsError::Geometry(e) => write!(f, "{e}"),
            SettingsError::Sign => f.write_str("a wiring sign is 1 (standard) or -1 (reversed)"),
            SettingsError::Tuning(e) => write!(f, "{e}"),
            SettingsError::DiameterRatio { ratio } => write!(
                f,
                "d_right/d_left would be {}, outside {}..{} (change the other diameter first, \
                 or both in steps)",
                crate::util::decimal::Decimal::fixed(*ratio, 3),
                crate::util::decimal::Plain(DIAMETER_RATIO_RANGE.0),
                crate::util::decimal::Plain(DIAMETER_RATIO_RANGE.1),
            ),
            SettingsError::Rate => f.write_str(crate::motion::controller::RATE_RULE),
            SettingsError::WheelbaseRatio { ratio } => write!(
                f,
                "wheelbase/wheel diameter would be {}, outside {}..{}",
                crate::util::decimal::Decimal::fixed(*ratio, 3),
                crate::util::decimal::Plain(WHEELBASE_RATIO_RANGE.0),
                crate::util::decimal::Plain(WHEELBASE_RATIO_RANGE.1),
            ),
        }
    }
}

/// Checks a nominal geometry as a whole: each value in range, and the diameters and wheelbase
/// consistent with each other.
///
/// # Errors
/// The first [`SettingsError`] found.
pub fn check_nominal(g: &Geometry) -> Result<(), SettingsError> {
    g.validate().map_err(SettingsError::Geometry)?;
    let ratio = g.diameter_ratio();
    if !(DIAMETER_RATIO_RANGE.0..=DIAMETER_RATIO_RANGE.1).contains(&ratio) {
        return Err(SettingsError::DiameterRatio { ratio });
    }
    let ratio = g.wheelbase_m / g.mean_diameter_m();
    if !(WHEELBASE_RATIO_RANGE.0..=WHEELBASE_RATIO_RANGE.1).contains(&ratio) {
        return Err(SettingsError::WheelbaseRatio { ratio });
    }
    Ok(())
}

impl Settings {
    /// The planned side as the `f64` nearest to its decimal value (to the micrometre), so a
    /// planned run and `run cw <same value>` record exactly the same side.
    pub fn square_side_f64(&self) -> f64 {
        libm::round(f64::from(self.square_side_m) * 1e6) / 1e6
    }

    /// The controller configuration these settings ask for: the board's defaults at the stored
    /// control rate with the active geometry, the motion limits, the wiring corrections and the
    /// speed-loop tuning. The firmware and the simulated board both boot their controller from
    /// it.
    pub fn controller_config(&self) -> ControllerConfig {
        let mut c = ControllerConfig::new(self.active, self.control_hz);
        c.limits = self.motion;
        c.wiring = self.wiring;
        c.speed = self.tuning;
        c
    }

    /// Current value of a parameter.
    pub fn value(&self, name: ParamName) -> f64 {
        match name {
            ParamName::DiameterRight => self.nominal.diameter_right_m,
            ParamName::DiameterLeft => self.nominal.diameter_left_m,
            ParamName::Wheelbase => self.nominal.wheelbase_m,
            ParamName::CountsPerRev => f64::from(self.nominal.counts_per_rev),
            ParamName::MaxSpeed => f64::from(self.motion.max_speed_mps),
            ParamName::MaxAccel => f64::from(self.motion.max_accel_mps2),
            ParamName::MaxTurnRate => f64::from(self.motion.max_turn_rate_radps),
            ParamName::MaxTurnAccel => f64::from(self.motion.max_turn_accel_radps2),
            ParamName::SquareSide => f64::from(self.square_side_m),
            ParamName::RunsPerDirection => f64::from(self.runs_per_direction),
            ParamName::MotorRightSign => sign(self.wiring.motor_right_reversed),
            ParamName::MotorLeftSign => sign(self.wiring.motor_left_reversed),
            ParamName::EncoderRightSign => sign(self.wiring.encoder_right_reversed),
            ParamName::EncoderLeftSign => sign(self.wiring.encoder_left_reversed),
            ParamName::ControlHz => f64::from(self.control_hz),
            _ => tuning_field(&self.tuning, name).map_or(0.0, f64::from),
        }
    }

    /// A copy with one parameter changed. `value` must already be within `name.range()` (the
    /// parser guarantees it); integer parameters are rounded. A value equal to the current one
    /// (as stored: `f32` limits compare as `f32`) changes nothing (`None`); otherwise the part of
    /// the settings that changed is returned (`name`'s [`ParamGroup`]).
    /// Changing the nominal geometry drops the calibration, because its factors were relative to
    /// the old nominal.
    ///
    /// # Errors
    /// A [`SettingsError`] if the nominal geometry would be invalid or inconsistent
    /// ([`check_nominal`]).
    pub fn with_value(
        &self,
        name: ParamName,
        value: f64,
    ) -> Result<(Settings, Option<ParamGroup>), SettingsError> {
        let mut s = self.clone();
        match name {
            ParamName::DiameterRight => {
                s.nominal.diameter_right_m = value;
            }
            ParamName::DiameterLeft => {
                s.nominal.diameter_left_m = value;
            }
            ParamName::Wheelbase => {
                s.nominal.wheelbase_m = value;
            }
            ParamName::CountsPerRev => {
                s.nominal.counts_per_rev = round_u32(value);
            }
            ParamName::MaxSpeed => {
                s.motion.max_speed_mps = value as f32;
            }
            ParamName::MaxAccel => {
                s.motion.max_accel_mps2 = value as f32;
            }
            ParamName::MaxTurnRate => {
                s.motion.max_turn_rate_radps = value as f32;
            }
            ParamName::MaxTurnAccel => {
                s.motion.max_turn_accel_radps2 = value as f32;
            }
            ParamName::SquareSide => {
                s.square_side_m = value as f32;
            }
            ParamName::RunsPerDirection => {
                s.runs_per_direction = u8::try_from(round_u32(value)).unwrap_or(u8::MAX);
            }
            ParamName::MotorRightSign
            | ParamName::MotorLeftSign
            | ParamName::EncoderRightSign
            | ParamName::EncoderLeftSign => {
                let reversed = match value {
                    1.0 => false,
                    -1.0 => true,
                    _ => return Err(SettingsError::Sign),
                };
                let w = &mut s.wiring;
                *match name {
                    ParamName::MotorRightSign => &mut w.motor_right_reversed,
                    ParamName::MotorLeftSign => &mut w.motor_left_reversed,
                    ParamName::EncoderRightSign => &mut w.encoder_right_reversed,
                    _ => &mut w.encoder_left_reversed,
                } = reversed;
            }
            ParamName::ControlHz => {
                let hz = round_u32(value);
                if !rate_supported(hz) {
                    return Err(SettingsError::Rate);
                }
                s.control_hz = hz;
            }
            _ => {
                let Some(field) = tuning_field_mut(&mut s.tuning, name) else {
                    return Ok((s, None));
                };
                *field = value as f32;
            }
        }
        let changed = name.spec().group;
        // Only `name` differs so far: compare it alone, as [`Settings::value`] reads it (exact
        // for every field type), instead of the whole settings (0.4 KiB of field comparisons).
        if s.value(name) == self.value(name) {
            return Ok((s, None));
        }
        if changed == ParamGroup::Tuning {
            s.tuning.validate().map_err(SettingsError::Tuning)?;
        }
        if changed == ParamGroup::Geometry {
            check_nominal(&s.nominal)?;
            s.active = s.nominal;
            s.calibration = None;
        }
        Ok((s, Some(changed)))
    }
}

/// The tuning field a parameter names (`None` for the other parameters).
fn tuning_field(t: &SpeedTuning, name: ParamName) -> Option<f32> {
    let mut t = *t;
    tuning_field_mut(&mut t, name).map(|v| *v)
}

/// See [`tuning_field`].
fn tuning_field_mut(t: &mut SpeedTuning, name: ParamName) -> Option<&mut f32> {
    Some(match name {
        ParamName::MotorRightGainFwd => &mut t.right.gain_forward_mps,
        ParamName::MotorRightGainBack => &mut t.right.gain_backward_mps,
        ParamName::MotorRightTau => &mut t.right.time_constant_s,
        ParamName::MotorRightDeadband => &mut t.right.deadband,
        ParamName::MotorLeftGainFwd => &mut t.left.gain_forward_mps,
        ParamName::MotorLeftGainBack => &mut t.left.gain_backward_mps,
        ParamName::MotorLeftTau => &mut t.left.time_constant_s,
        ParamName::MotorLeftDeadband => &mut t.left.deadband,
        ParamName::SpeedBandwidth => &mut t.bandwidth_radps,
        _ => return None,
    })
}

/// A wiring flag as the protocol's sign: 1 standard, −1 reversed.
fn sign(reversed: bool) -> f64 {
    if reversed { -1.0 } else { 1.0 }
}
