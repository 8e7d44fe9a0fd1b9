//! The simulated robot (cargo feature `plant`): the one model of the motors, wheels, encoders
//! and true pose that every simulation of the robot uses — host-sim's robot (which adds
//! seeded slip noise and its command-line options around it), the emulator board's plant inside
//! the firmware image (`board/emulator`, feature `emulator`) and qemu-bench's control workload.
//! Never part of the shipped firmware.
//!
//! - **True geometry** `D_R`, `D_L`, `b` (generally not the nominal ones the firmware believes).
//! - **Motors** ([`MotorModel`]): first-order lag from duty to wheel angular speed,
//!   `τ ω̇ + ω = K·duty` above a dead-band, integrated exactly over each sub-step (the duty is
//!   held for a control period, as the PWM does). A stop brakes (τ/2) or coasts (4τ).
//! - **Encoders**: the wheel angle is quantised to `counts_per_rev` counts per revolution
//!   (floor) and presented as wrapping hardware counters like the board's: right on a 32-bit
//!   timer, left on a 16-bit timer counting *down* when the wheel rolls forward; optionally
//!   miswired ([`RobotConfig::wiring`]).
//! - **True pose** in `f64`, integrated as one exact arc per control period (the wheels' ground
//!   travel over it; the speeds change only smoothly within a period).
//! - **Disturbances** a test or a simulated operator applies: a blocked wheel, a counter jump,
//!   a hand pushing the robot, per-period slip factors of the wheels' ground travel
//!   ([`SimRobot::advance_slipping`]; host-sim draws them from its noise model), and a true
//!   geometry that changes mid-run ([`SimRobot::set_true_geometry`]: a worn tyre, a load).
//!
//! It is portable `no_std` code like the rest of the library, generic over its arithmetic
//! ([`Numerics`]): [`Portable`] gives the same bits on the host and the Cortex-M4.

mod motor;
mod numerics;
mod robot;

pub use motor::{BRAKE_TAU_RATIO, COAST_TAU_RATIO, MotorModel};
pub use numerics::{Lanes, Numerics, Portable, ScalarPair};
pub use robot::{RobotConfig, SimRobot, floor_i64};

#[cfg(test)]
mod tests;
