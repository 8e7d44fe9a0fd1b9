//! The rules for changing the session's settings, which are the stored record itself
//! ([`ParamRecord`]: everything `params` shows and `save` persists).
//!
//! Each parameter's field is named by its row of [`crate::protocol::PARAMS`] (how it is read
//! and written); this module adds what holds across parameters: integer rounding, the sign and
//! rate rules, the nominal geometry's consistency and the calibration a geometry change
//! invalidates. Units: metres, seconds, radians.

use core::fmt;

use crate::kinematics::geometry::{Geometry, GeometryError};
use crate::motion::controller::{ControllerConfig, rate_supported};
use crate::motion::profile::LimitsError;
use crate::motion::speed::TuningError;
use crate::protocol::{ParamGroup, ParamName, ValueKind};
use crate::storage::record::ParamRecord;
use crate::util::num::round_u32;

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
    /// The motion limits are invalid, or faster than the encoders count.
    Limits(LimitsError),
}

/// A stored value that [`ParamRecord::check`] refused at boot and its default replaced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BootRefusal {
    /// The parameter.
    pub name: ParamName,
    /// The value stored.
    pub value: f64,
    /// The rule it broke.
    pub why: SettingsError,
}

/// The values refused at boot (at most one per rule and limit).
pub type BootRefusals = heapless::Vec<BootRefusal, 3>;

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
            SettingsError::Limits(e) => write!(f, "{e}"),
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

impl ParamRecord {
    /// The planned side as the `f64` nearest to its decimal value (to the micrometre), so a
    /// planned run and `run cw <same value>` record exactly the same side.
    pub fn square_side_f64(&self) -> f64 {
        libm::round(f64::from(self.square_side_m) * 1e6) / 1e6
    }

    /// The controller configuration these settings ask for: the board's defaults at the stored
    /// control rate with the active geometry, the motion limits, the wiring corrections and the
    /// speed-loop tuning. The firmware and the simulated board both boot their controller from
    /// it.
    /// [`Controller::new`](crate::motion::controller::Controller::new) applies to it the rules
    /// of `set` (glitch limit re-derived, encoders' countability checked); run
    /// [`ParamRecord::for_boot`] first so that it accepts the result.
    pub fn controller_config(&self) -> ControllerConfig {
        let mut c = ControllerConfig::new(self.active, self.control_hz);
        c.limits = self.motion;
        c.wiring = self.wiring;
        c.speed = self.tuning;
        c
    }

    /// The rules that hold across the settings as a whole, as `set` (and so `apply` and
    /// `reset-params`, which hand their settings to the controller the same way) enforces them:
    /// the nominal geometry consistent ([`check_nominal`]) and the motion limits within what the
    /// active geometry's encoders count ([`crate::motion::profile::MotionLimits::validate_for`],
    /// the controller's own check). The parameter named is the one whose default is taken when
    /// a stored record breaks the rule.
    ///
    /// # Errors
    /// The first broken rule, with the parameter to blame.
    pub fn check(&self) -> Result<(), (ParamName, SettingsError)> {
        check_nominal(&self.nominal).map_err(|e| {
            let name = match e {
                SettingsError::WheelbaseRatio { .. } => ParamName::Wheelbase,
                _ => ParamName::DiameterRight,
            };
            (name, e)
        })?;
        self.motion.validate_for(&self.active).map_err(|e| {
            let m = &self.motion;
            let name = match e {
                LimitsError::Accel => ParamName::MaxAccel,
                LimitsError::TurnAccel => ParamName::MaxTurnAccel,
                LimitsError::TurnRate => ParamName::MaxTurnRate,
                LimitsError::BeyondEncoders
                    if f64::from(m.max_speed_mps) < m.wheel_speed_mps(&self.active) =>
                {
                    ParamName::MaxTurnRate
                }
                _ => ParamName::MaxSpeed,
            };
            (name, SettingsError::Limits(e))
        })
    }

    /// The settings a board boots with from a stored record: the record itself when it keeps
    /// [`ParamRecord::check`]'s rules, else with each value that breaks one replaced by its
    /// default (a geometry value takes the whole default geometry, the calibration with it,
    /// since a calibration is relative to its nominal geometry). Returns the values replaced,
    /// for the boot line; nothing else is changed.
    pub fn for_boot(&self) -> (ParamRecord, BootRefusals) {
        let mut s = self.clone();
        let mut refused = BootRefusals::new();
        while let Err((mut name, why)) = s.check() {
            if s.value(name) == ParamRecord::DEFAULT.value(name) {
                // Even the default limit is beyond these encoders: the geometry is to blame.
                name = ParamName::CountsPerRev;
            }
            let value = s.value(name);
            if refused.push(BootRefusal { name, value, why }).is_err() {
                // More than one value of each rule: nothing of the record is trusted.
                return (ParamRecord::DEFAULT, refused);
            }
            if name.spec().group == ParamGroup::Geometry {
                s.nominal = ParamRecord::DEFAULT.nominal;
                s.active = s.nominal;
                s.calibration = None;
            } else {
                (name.spec().set)(&mut s, ParamRecord::DEFAULT.value(name));
            }
        }
        (s, refused)
    }

    /// Current value of a parameter (its row's reading of the record).
    pub fn value(&self, name: ParamName) -> f64 {
        (name.spec().get)(self)
    }

    /// A copy with one parameter changed. `value` must already be within `name.range()` (the
    /// parser guarantees it); integer parameters are rounded. A value equal to the current one
    /// (as stored: `f32` limits compare as `f32`) changes nothing (`None`); otherwise the part of
    /// the settings that changed is returned (`name`'s [`ParamGroup`]).
    /// Changing the nominal geometry drops the calibration, because its factors were relative to
    /// the old nominal.
    ///
    /// # Errors
    /// A [`SettingsError`] if a sign is not ±1, the rate is not one the controller runs at, the
    /// tuning would be invalid, or the nominal geometry would be invalid or inconsistent
    /// ([`check_nominal`]).
    pub fn with_value(
        &self,
        name: ParamName,
        value: f64,
    ) -> Result<(ParamRecord, Option<ParamGroup>), SettingsError> {
        let spec = name.spec();
        let value = match spec.value {
            ValueKind::Real { .. } => value,
            ValueKind::Whole => f64::from(round_u32(value)),
            ValueKind::Sign if value == 1.0 || value == -1.0 => value,
            ValueKind::Sign => return Err(SettingsError::Sign),
        };
        if spec.group == ParamGroup::Rate && !rate_supported(round_u32(value)) {
            return Err(SettingsError::Rate);
        }
        let mut s = self.clone();
        (spec.set)(&mut s, value);
        // Only `name` differs so far: compare it alone, as [`ParamRecord::value`] reads it
        // (exact for every field type), instead of the whole record.
        if s.value(name) == self.value(name) {
            return Ok((s, None));
        }
        if spec.group == ParamGroup::Tuning {
            s.tuning.validate().map_err(SettingsError::Tuning)?;
        }
        if spec.group == ParamGroup::Geometry {
            check_nominal(&s.nominal)?;
            s.active = s.nominal;
            s.calibration = None;
        }
        Ok((s, Some(spec.group)))
    }
}
