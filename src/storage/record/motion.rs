//! The operator's motion settings as the record stores them: speed and acceleration limits and
//! the calibration routine's square, with their plausible ranges.

use super::RecordError;
use crate::util::num::within;

/// Motion settings an operator can `set` and `save`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionSettings {
    /// Maximum straight-line speed, m/s.
    pub max_speed_mps: f32,
    /// Maximum straight-line acceleration, m/s².
    pub max_accel_mps2: f32,
    /// Maximum in-place turn rate, rad/s.
    pub max_turn_rate_radps: f32,
    /// Maximum in-place turn acceleration, rad/s².
    pub max_turn_accel_radps2: f32,
    /// Side length of the calibration square, metres.
    pub square_side_m: f32,
    /// Square runs per direction (CW and CCW each) for a calibration.
    pub runs_per_direction: u8,
}

impl MotionSettings {
    /// Factory settings: 0.3 m/s, 0.3 m/s², 1 rad/s, 2 rad/s², 2 m square, 5 runs per direction.
    pub const DEFAULT: MotionSettings = MotionSettings {
        max_speed_mps: 0.3,
        max_accel_mps2: 0.3,
        max_turn_rate_radps: 1.0,
        max_turn_accel_radps2: 2.0,
        square_side_m: 2.0,
        runs_per_direction: 5,
    };

    /// Checks that every setting is finite and within its plausible range.
    ///
    /// # Errors
    /// The first offending setting, as a [`RecordError`].
    pub fn validate(&self) -> Result<(), RecordError> {
        if !within(self.max_speed_mps, 0.001, 5.0) {
            return Err(RecordError::MaxSpeed);
        }
        if !within(self.max_accel_mps2, 0.001, 20.0) {
            return Err(RecordError::MaxAccel);
        }
        if !within(self.max_turn_rate_radps, 0.001, 20.0) {
            return Err(RecordError::MaxTurnRate);
        }
        if !within(self.max_turn_accel_radps2, 0.001, 100.0) {
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

impl MotionSettings {
    /// The stored form of the controller's `limits` and the calibration plan.
    pub fn from_limits(
        limits: &crate::motion::profile::MotionLimits,
        square_side_m: f32,
        runs_per_direction: u8,
    ) -> Self {
        MotionSettings {
            max_speed_mps: limits.max_speed_mps,
            max_accel_mps2: limits.max_accel_mps2,
            max_turn_rate_radps: limits.max_turn_rate_radps,
            max_turn_accel_radps2: limits.max_turn_accel_radps2,
            square_side_m,
            runs_per_direction,
        }
    }

    /// The speed and acceleration limits the controller uses.
    pub fn limits(&self) -> crate::motion::profile::MotionLimits {
        crate::motion::profile::MotionLimits {
            max_speed_mps: self.max_speed_mps,
            max_accel_mps2: self.max_accel_mps2,
            max_turn_rate_radps: self.max_turn_rate_radps,
            max_turn_accel_radps2: self.max_turn_accel_radps2,
        }
    }
}

impl Default for MotionSettings {
    fn default() -> Self {
        MotionSettings::DEFAULT
    }
}
