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
    /// The wheel turned faster than the speed cap (`max_speed`) plus its margin, or than
    /// [`MAX_SPEED_MPS`] in one period.
    ///
    /// [`MAX_SPEED_MPS`]: super::MAX_SPEED_MPS
    TooFast,
    /// On the floor, the robot went farther than [`TRAVEL_LIMIT_M`] from its start.
    ///
    /// [`TRAVEL_LIMIT_M`]: super::TRAVEL_LIMIT_M
    TooFar,
    /// A step's speed differed from the probe's prediction by more than half: the load changed.
    Changed,
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
            IdentifyProblem::TooFast => {
                "wheel faster than max_speed + 10 %: the response is not what the probe measured"
            }
            IdentifyProblem::TooFar => {
                "the robot went more than 1 m from its start: stopped (give it room, or lift it)"
            }
            IdentifyProblem::Changed => {
                "a step's speed is not what the probe measured: the load changed (a wheel touched or left the ground, or is blocked)"
            }
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
