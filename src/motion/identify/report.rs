//! What an identification ends with: each wheel's identified plant, or the wheel and the problem
//! that stopped it.

use super::IdentifyMode;
use crate::motion::speed::MotorParams;
use crate::motion::wheel::Wheel;

/// What was wrong with a wheel's response.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum IdentifyProblem {
    /// The wheel did not move at a duty step.
    NoMotion,
    /// The wheel's counts ran against the duty: motor or encoder reversed.
    Reversed,
    /// The other wheel's encoder moved more than this one's (lifted): swapped wiring.
    CrossWired,
    /// The top duty step gained too little speed: supply or current limit.
    Saturated,
    /// The wheel turned faster than [`MAX_SPEED_MPS`].
    ///
    /// [`MAX_SPEED_MPS`]: super::MAX_SPEED_MPS
    TooFast,
    /// The first-order model does not describe the response (noisy, slipping, out of range).
    Implausible,
    /// The stall check latched (no count at a commanded duty for its time).
    Stalled,
    /// An encoder counter jumped.
    EncoderGlitch,
}

impl IdentifyProblem {
    /// What the operator reads.
    pub fn describe(self) -> &'static str {
        match self {
            IdentifyProblem::NoMotion | IdentifyProblem::Stalled => {
                "no motion: check motor power, the encoder, that the wheel is free, and a dead-band below 20 % duty"
            }
            IdentifyProblem::Reversed => {
                "counts run against the duty: motor or encoder reversed (run bringup)"
            }
            IdentifyProblem::CrossWired => {
                "the other wheel's encoder moved: motors or encoders swapped between the sides (run bringup)"
            }
            IdentifyProblem::Saturated => {
                "speed saturates at the top duty step: check the motor supply and current limit"
            }
            IdentifyProblem::TooFast => "wheel faster than 2 m/s: motor too strong for the steps",
            IdentifyProblem::Implausible => {
                "response not a first-order motor (slipping, loose coupling, noisy encoder)"
            }
            IdentifyProblem::EncoderGlitch => "encoder counter jumped",
        }
    }
}

/// Why an identification ended without a result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct IdentifyFailure {
    /// The wheel.
    pub wheel: Wheel,
    /// What was wrong.
    pub problem: IdentifyProblem,
}

/// One wheel's identified plant.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct MotorFit {
    /// The plant for the speed loop.
    pub params: MotorParams,
    /// Deceleration when coasting from `coast_from_mps` (mean of both directions), m/s².
    pub coast_decel_mps2: f32,
    /// Speed the coast deceleration refers to (the top step's, mean of both directions), m/s.
    pub coast_from_mps: f32,
    /// RMS residual of the one-period speed prediction, m/s.
    pub residual_mps: f32,
}

/// A finished identification.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct IdentifyReport {
    /// Where the robot was.
    pub mode: IdentifyMode,
    /// Right motor.
    pub right: MotorFit,
    /// Left motor.
    pub left: MotorFit,
}
