//! The plausible ranges of the operator's motion settings as the record checks them: speed and
//! acceleration limits, the calibration routine's square and the declared measuring noise.

use super::{ParamRecord, RecordError};
use crate::motion::convention::{HEADING_SD_RANGE_DEG, MEASURE_SD_RANGE_M};
use crate::util::num::within;

impl ParamRecord {
    /// Checks that every motion limit and the square plan are finite and within their plausible
    /// ranges.
    ///
    /// # Errors
    /// The first offending setting, as a [`RecordError`].
    pub(super) fn validate_motion(&self) -> Result<(), RecordError> {
        let m = &self.motion;
        if !within(m.max_speed_mps, 0.001, 5.0) {
            return Err(RecordError::MaxSpeed);
        }
        if !within(m.max_accel_mps2, 0.001, 20.0) {
            return Err(RecordError::MaxAccel);
        }
        if !within(m.max_turn_rate_radps, 0.001, 20.0) {
            return Err(RecordError::MaxTurnRate);
        }
        if !within(m.max_turn_accel_radps2, 0.001, 100.0) {
            return Err(RecordError::MaxTurnAccel);
        }
        if !within(self.square_side_m, 0.1, 20.0) {
            return Err(RecordError::SquareSide);
        }
        if !(1..=50).contains(&self.runs_per_direction) {
            return Err(RecordError::RunsPerDirection);
        }
        Ok(())
    }

    /// Checks that the declared measuring noise is within the ranges `set` accepts.
    ///
    /// # Errors
    /// [`RecordError::MeasuringNoise`].
    pub(super) fn validate_noise(&self) -> Result<(), RecordError> {
        // Bounds as stored (`f32`, the heading in radians): `set` stores a value within the range
        // rounded by the same monotone conversions, so it never falls outside them.
        let (p_lo, p_hi) = MEASURE_SD_RANGE_M;
        let (h_lo, h_hi) = HEADING_SD_RANGE_DEG;
        let p_ok = within(self.measure_sd_m, p_lo as f32, p_hi as f32);
        let h_ok = within(
            self.heading_sd_rad,
            h_lo.to_radians() as f32,
            h_hi.to_radians() as f32,
        );
        if !(p_ok && h_ok) {
            return Err(RecordError::MeasuringNoise);
        }
        Ok(())
    }
}
