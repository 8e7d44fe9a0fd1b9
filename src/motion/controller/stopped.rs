//! The one rule for writing the flash: only with the motors confirmed stopped.
//!
//! A flash erase stalls every instruction fetch (the control task included) for up to seconds,
//! so nothing may move meanwhile. [`Controller::motors_stopped`] is where that is decided: it
//! gives a [`MotorsStopped`] proof, which the storage's writing functions take, or the
//! [`MotorsRunning`] refusal (`err 18`), worded here once.

use core::fmt;

#[cfg(doc)]
use super::Controller;

/// Proof that both motors were confirmed stopped (see [`Controller::motors_stopped`]): what the
/// storage's writing functions take, so that no write can be asked for without it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MotorsStopped(());

impl MotorsStopped {
    /// The controller's word (only [`Controller::motors_stopped`] gives it on the board).
    pub(super) const fn confirmed() -> Self {
        MotorsStopped(())
    }

    /// For code with no controller to ask and no motors to stop: the storage's tests and
    /// tools (host-sim's flash image commands) and the session's test doubles of the robot.
    pub const fn without_controller() -> Self {
        MotorsStopped(())
    }
}

/// A flash write refused because the motors are not confirmed stopped (`err 18`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MotorsRunning;

impl fmt::Display for MotorsRunning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(
            "motors not confirmed stopped (running, or the control loop has not run yet), flash not written",
        )
    }
}

impl core::error::Error for MotorsRunning {}
