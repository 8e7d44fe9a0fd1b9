//! The one record the board persists: geometry, calibration result, motion settings, wiring, the
//! speed-loop tuning and the control rate.
//!
//! [`ParamRecord`] is what `save` writes and what boot loads, and it is the session's settings
//! (what `params` shows and `set` changes): one struct per parameter set. Its stored form is a hand-written,
//! fixed-length little-endian layout ([`ParamRecord::ENCODED_LEN`] bytes, byte 0 = format
//! version, see `docs/storage.md` for the table). Lengths are metres, speeds m/s, accelerations
//! m/s², turn rates rad/s, turn accelerations rad/s²; calibration factors are dimensionless
//! (`E_d = D_R / D_L`, `E_b = b_actual / b_nominal`, `E_s` = mean-diameter scale).
//!
//! Decoding ([`ParamRecord::decode`]) only checks the layout (version, length, method name);
//! [`ParamRecord::validate`] checks every value (finite, plausible range). A stored record is used
//! only when both pass.
//!
//! Parts: `calibration` (the applied calibration and the stored form of its method name),
//! `motion` (the plausible ranges of the motion settings), `error` (why a record is rejected or cannot be decoded),
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

pub use self::calibration::{AppliedCalibration, METHOD_NAME_MAX, MethodName};
pub(super) use self::codec::{Reader, Writer};
pub use self::error::{FormatError, RecordError};

use crate::kinematics::geometry::Geometry;
use crate::motion::controller::{DEFAULT_RATE_HZ, rate_supported};
use crate::motion::convention::{Convention, MeasuringNoise};
use crate::motion::profile::MotionLimits;
use crate::motion::speed::SpeedTuning;
use crate::motion::wiring::Wiring;

/// The calibration factors a stored record may hold (`E_d`, `E_b`, `E_s`, and each calibrated
/// dimension against its nominal one). Narrower on purpose than the range a fit may visit while
/// it iterates (`calibration::FACTOR_RANGE`, 0.5..2): a calibration 20 % off the nominal
/// geometry is a measuring or typing mistake, not a robot, and is neither applied nor loaded.
pub const STORED_FACTOR_RANGE: core::ops::RangeInclusive<f64> = 0.8..=1.25;

/// Everything the board persists, as one stored record: also the session's settings (what
/// `params` shows and `set` changes), so a parameter lives in one struct. Each operator
/// parameter's field is named by its row of `protocol::PARAMS`.
#[derive(Debug, PartialEq)]
pub struct ParamRecord {
    /// Nominal geometry (as built / as specified: D_R, D_L, b, counts per revolution).
    pub nominal: Geometry,
    /// Geometry in use: the calibrated one, or `nominal` when there is no calibration.
    pub active: Geometry,
    /// The calibration that produced `active` (`None`: uncalibrated, stored as method `none`).
    pub calibration: Option<AppliedCalibration>,
    /// Motion limits (magnitudes: speeds m/s, accelerations m/s², turn rates rad/s, turn
    /// accelerations rad/s²).
    pub motion: MotionLimits,
    /// Planned square side `L`, metres.
    pub square_side_m: f32,
    /// Planned square runs per direction.
    pub runs_per_direction: u8,
    /// Motors and encoders reversed against the standard wiring.
    pub wiring: Wiring,
    /// Speed-loop tuning: both motors' models and the bandwidth (the output limit is not
    /// stored: always full duty).
    pub tuning: SpeedTuning,
    /// Control (and odometry) rate, Hz (one of [`crate::motion::controller::RATES_HZ`]).
    pub control_hz: u32,
    /// The measuring noise `calibrate`'s fit check assumes: 1σ of a measured x or y, metres.
    pub measure_sd_m: f32,
    /// 1σ of a measured heading, radians.
    pub heading_sd_rad: f32,
    /// How every measured run is read (`convention`): the runs keep what was typed.
    pub convention: Convention,
}

impl Clone for ParamRecord {
    // Out of line: `set`, `apply` and the parameter resets each inlined their own copy.
    #[inline(never)]
    fn clone(&self) -> Self {
        ParamRecord {
            calibration: self.calibration.clone(),
            ..*self
        }
    }
}

impl ParamRecord {
    /// The paper's nominal robot (D = 150 mm, b = 385 mm, 200,000 counts/rev), uncalibrated,
    /// factory motion settings (0.3 m/s, 0.3 m/s², 1 rad/s, 2 rad/s², 2 m squares, 5 runs per
    /// direction), standard wiring, default tuning and rate.
    pub const DEFAULT: ParamRecord = ParamRecord {
        nominal: Geometry::PAPER_NOMINAL,
        active: Geometry::PAPER_NOMINAL,
        calibration: None,
        motion: MotionLimits::DEFAULT,
        square_side_m: 2.0,
        runs_per_direction: 5,
        wiring: Wiring::STANDARD,
        tuning: SpeedTuning::DEFAULT,
        control_hz: DEFAULT_RATE_HZ,
        measure_sd_m: MeasuringNoise::DEFAULT.position_m as f32,
        heading_sd_rad: MeasuringNoise::DEFAULT.heading_rad as f32,
        convention: Convention::Standard,
    };

    /// The measuring noise the fit check assumes.
    pub fn measuring_noise(&self) -> MeasuringNoise {
        MeasuringNoise {
            position_m: f64::from(self.measure_sd_m),
            heading_rad: f64::from(self.heading_sd_rad),
        }
    }

    /// The geometry odometry and the routine use: the calibrated one.
    pub fn active_geometry(&self) -> Geometry {
        self.active
    }

    /// The calibration's numbers as stored: the factors, the geometry, the runs and `E_max`
    /// (1, the nominal geometry, 0 and 0 when uncalibrated).
    pub(super) fn stored_calibration(&self) -> StoredCalibration {
        match &self.calibration {
            None => StoredCalibration {
                e_d: 1.0,
                e_b: 1.0,
                e_s: 1.0,
                geometry: self.nominal,
                runs: 0,
                e_max_m: 0.0,
            },
            Some(c) => StoredCalibration {
                e_d: c.e_d,
                e_b: c.e_b,
                e_s: c.e_s,
                geometry: self.active,
                runs: c.runs_used,
                e_max_m: c.e_max_m,
            },
        }
    }

    /// The calibration's method as stored (`none` when uncalibrated).
    ///
    /// # Errors
    /// [`RecordError::MethodName`] if the name is not storable.
    pub(super) fn stored_method(&self) -> Result<MethodName, RecordError> {
        match &self.calibration {
            None => Ok(MethodName::NONE),
            Some(c) => MethodName::new(&c.method),
        }
    }

    /// Checks every field: finite, plausible ranges, calibrated geometry consistent with the
    /// nominal one, a storable method name.
    ///
    /// # Errors
    /// The first offending field, as a [`RecordError`].
    pub fn validate(&self) -> Result<(), RecordError> {
        self.nominal
            .validate()
            .map_err(RecordError::NominalGeometry)?;
        let c = self.stored_calibration();
        c.geometry
            .validate()
            .map_err(RecordError::CalibratedGeometry)?;
        let factor_ok = |e: f64| e.is_finite() && STORED_FACTOR_RANGE.contains(&e);
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
        self.stored_method()?;
        if c.runs > 1000 {
            return Err(RecordError::Runs);
        }
        if !(c.e_max_m.is_finite() && (0.0..=10.0).contains(&c.e_max_m)) {
            return Err(RecordError::PredictedError);
        }
        self.validate_motion()?;
        self.tuning.validate().map_err(RecordError::Tuning)?;
        if !rate_supported(self.control_hz) {
            return Err(RecordError::ControlRate);
        }
        self.validate_noise()
    }
}

/// The calibration's numbers as the stored layout holds them (the method apart).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct StoredCalibration {
    pub(super) e_d: f64,
    pub(super) e_b: f64,
    pub(super) e_s: f64,
    pub(super) geometry: Geometry,
    pub(super) runs: u16,
    pub(super) e_max_m: f64,
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
