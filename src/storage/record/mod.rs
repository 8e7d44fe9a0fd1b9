//! The one record the board persists: geometry, calibration result, motion settings, wiring, the
//! speed-loop tuning and the control rate.
//!
//! [`ParamRecord`] is what `save` writes and what boot loads. Its stored form is a hand-written,
//! fixed-length little-endian layout ([`ParamRecord::ENCODED_LEN`] bytes, byte 0 = format
//! version, see `docs/storage.md` for the table). Lengths are metres, speeds m/s, accelerations
//! m/s², turn rates rad/s, turn accelerations rad/s²; calibration factors are dimensionless
//! (`E_d = D_R / D_L`, `E_b = b_actual / b_nominal`, `E_s` = mean-diameter scale).
//!
//! Decoding ([`ParamRecord::decode`]) only checks the layout (version, length, method name);
//! [`ParamRecord::validate`] checks every value (finite, plausible range). A stored record is used
//! only when both pass.
//!
//! Parts: `calibration` (the stored calibration result and its method name), `motion` (the
//! operator's motion settings), `error` (why a record is rejected or cannot be decoded),
//! `codec` (the little-endian writer and reader, shared with the run records) and `format`
//! (the stored layout of every version: encoding, and decoding with the migration of older
//! versions).

mod calibration;
mod codec;
mod error;
mod format;
mod motion;
#[cfg(test)]
mod tests;

use sequential_storage::map::{SerializationError, Value};

pub use self::calibration::{Calibration, METHOD_NAME_MAX, MethodName};
pub(super) use self::codec::{Reader, Writer};
pub use self::error::{FormatError, RecordError};
pub use self::motion::MotionSettings;

use crate::kinematics::geometry::Geometry;
use crate::motion::controller::{DEFAULT_RATE_HZ, rate_supported};
use crate::motion::speed::SpeedTuning;
use crate::motion::wiring::Wiring;

/// Everything the board persists, as one stored record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamRecord {
    /// Nominal geometry (design values: D_R = D_L = D, b, counts per revolution).
    pub nominal: Geometry,
    /// Calibration result; [`Calibration::none`] of the nominal geometry when uncalibrated.
    pub calibration: Calibration,
    /// Operator motion settings.
    pub motion: MotionSettings,
    /// Motors and encoders reversed against the standard wiring.
    pub wiring: Wiring,
    /// Speed-loop tuning: both motors' models and the bandwidth (the output limit is not
    /// stored: always full duty).
    pub tuning: SpeedTuning,
    /// Control rate, Hz (one of [`crate::motion::controller::RATES_HZ`]).
    pub control_hz: u32,
}

impl ParamRecord {
    /// The paper's nominal robot (D = 150 mm, b = 385 mm, 200,000 counts/rev), uncalibrated,
    /// factory motion settings.
    pub const DEFAULT: ParamRecord = ParamRecord {
        nominal: Geometry::PAPER_NOMINAL,
        calibration: Calibration::none(Geometry::PAPER_NOMINAL),
        motion: MotionSettings::DEFAULT,
        wiring: Wiring::STANDARD,
        tuning: SpeedTuning::DEFAULT,
        control_hz: DEFAULT_RATE_HZ,
    };

    /// The geometry odometry and the routine use: the calibrated one.
    pub fn active_geometry(&self) -> Geometry {
        self.calibration.geometry
    }

    /// Checks every field: finite, plausible ranges, calibrated geometry consistent with the
    /// nominal one.
    ///
    /// # Errors
    /// The first offending field, as a [`RecordError`].
    pub fn validate(&self) -> Result<(), RecordError> {
        self.nominal
            .validate()
            .map_err(RecordError::NominalGeometry)?;
        let c = &self.calibration;
        c.geometry
            .validate()
            .map_err(RecordError::CalibratedGeometry)?;
        let factor_ok = |e: f64| e.is_finite() && (0.8..=1.25).contains(&e);
        if !(factor_ok(c.e_d) && factor_ok(c.e_b) && factor_ok(c.e_s)) {
            return Err(RecordError::Factor);
        }
        let n = &self.nominal;
        if c.geometry.counts_per_rev != n.counts_per_rev
            || !factor_ok(c.geometry.diameter_right_m / n.diameter_right_m)
            || !factor_ok(c.geometry.diameter_left_m / n.diameter_left_m)
            || !factor_ok(c.geometry.wheelbase_m / n.wheelbase_m)
        {
            return Err(RecordError::CalibrationMismatch);
        }
        MethodName::from_bytes(c.method.as_str().as_bytes())?;
        if c.runs > 1000 {
            return Err(RecordError::Runs);
        }
        if !(c.predicted_e_max_m.is_finite() && (0.0..=10.0).contains(&c.predicted_e_max_m)) {
            return Err(RecordError::PredictedError);
        }
        self.motion.validate()?;
        self.tuning.validate().map_err(RecordError::Tuning)?;
        if !rate_supported(self.control_hz) {
            return Err(RecordError::ControlRate);
        }
        Ok(())
    }
}

impl Default for ParamRecord {
    fn default() -> Self {
        ParamRecord::DEFAULT
    }
}

impl<'a> Value<'a> for ParamRecord {
    fn serialize_into(&self, buffer: &mut [u8]) -> Result<usize, SerializationError> {
        Ok(self.encode(buffer)?)
    }

    fn deserialize_from(buffer: &'a [u8]) -> Result<(Self, usize), SerializationError> {
        Ok((ParamRecord::decode(buffer)?, buffer.len()))
    }
}
