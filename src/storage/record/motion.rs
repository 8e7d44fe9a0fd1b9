//! The plausible ranges of the operator's motion settings as the record checks them: speed and
//! acceleration limits and the calibration routine's square.

use super::{ParamRecord, RecordError};
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
}
