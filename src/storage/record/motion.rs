//! The record's check of the operator's motion settings (speed and acceleration limits, the
//! calibration routine's square, the declared measuring noise) against the ranges their owners
//! define, the same ones `set` accepts.

use super::{ParamRecord, RecordError};
use crate::motion::convention::{HEADING_SD_RANGE_DEG, MEASURE_SD_RANGE_M};
use crate::motion::routine::RunPlan;
use crate::util::num::within;

impl ParamRecord {
    /// Checks that every motion limit and the square plan are finite and within the ranges
    /// `set` accepts (the record holds nothing `set` could not have written).
    ///
    /// # Errors
    /// The first offending setting, as a [`RecordError`].
    pub(super) fn validate_motion(&self) -> Result<(), RecordError> {
        self.motion.validate().map_err(RecordError::Limits)?;
        let (side_lo, side_hi) = RunPlan::SIDE_RANGE_M;
        if !within(self.square_side_m, side_lo as f32, side_hi as f32) {
            return Err(RecordError::SquareSide);
        }
        let (runs_lo, runs_hi) = RunPlan::RUNS_PER_DIRECTION_RANGE;
        if !(runs_lo..=runs_hi).contains(&self.runs_per_direction) {
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
