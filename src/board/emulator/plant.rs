//! The simulated robot inside the emulator build: the library's robot model
//! ([`crate::plant`], the one host-sim runs, here without slip and in its portable arithmetic)
//! with the emulator's true factors, publishing its true pose for the test client.
//!
//! - **True geometry**: the paper's nominal robot with the true factors [`TRUE_E_D`],
//!   [`TRUE_E_B`] (host-sim's defaults), which the firmware does not know.
//! - **Motors, encoders**: the model's defaults ([`RobotConfig::new`]: 1 m/s at full duty,
//!   τ = 50 ms, the left motor 2 % weaker, 10 sub-steps per control period; the board's wrapping
//!   counters, right 32-bit counting up, left 16-bit counting down, both starting just below a
//!   wrap).
//! - **True pose**: published after every period in [`EMULATOR_TRUTH`] for the test client (the
//!   "tape measure": it reads the block through the emulator's monitor).
//!
//! The firmware-in-the-loop test checks that a whole calibration session gives the same factors
//! as host-sim's `serial` command on the same model.

use core::sync::atomic::{AtomicU32, Ordering};

use crate::kinematics::geometry::Geometry;
use crate::motion::controller::MotorCommand;
use crate::plant::{Portable, RobotConfig, SimRobot};

/// True `E_d = D_R / D_L` of the simulated robot.
pub const TRUE_E_D: f64 = 0.995;
/// True `E_b = b / b_nominal` of the simulated robot.
pub const TRUE_E_B: f64 = 1.010;

/// The plant's state for outside observers: true pose (x, y in metres, heading in radians,
/// start frame), wheel speeds (rad/s) and control periods simulated, as `f64`/`u64` bits, each
/// as two words (low, high). The client reads it with the monitor's `xp /12wx <address>` while
/// the robot is at rest (so the halves belong together).
#[unsafe(no_mangle)]
pub static EMULATOR_TRUTH: [AtomicU32; 12] = [const { AtomicU32::new(0) }; 12];

/// The simulated motors, wheels and encoders.
pub struct Plant {
    robot: SimRobot<Portable>,
}

impl Plant {
    /// A robot at rest at the origin, heading +x, stepped at `rate_hz`.
    pub fn new(rate_hz: u32) -> Self {
        let geometry = Geometry::PAPER_NOMINAL.with_factors(TRUE_E_D, TRUE_E_B, 1.0);
        let plant = Plant {
            robot: SimRobot::new(RobotConfig::new(geometry, rate_hz)),
        };
        plant.publish();
        plant
    }

    /// Steps periods of `rate_hz` from now on (the control rate was changed).
    pub fn set_rate_hz(&mut self, rate_hz: u32) {
        self.robot.set_rate_hz(rate_hz);
    }

    /// The hardware counter values (right 32-bit up, left 16-bit down) as the controller takes
    /// them.
    pub fn raw(&self) -> (u32, u32) {
        self.robot.raw()
    }

    /// Simulates one control period with `command` held.
    pub fn advance(&mut self, command: MotorCommand) {
        self.robot.apply(command);
        self.robot.advance();
        self.publish();
    }

    fn publish(&self) {
        let pose = self.robot.true_pose();
        let (omega_right, omega_left) = self.robot.wheel_speeds_radps();
        let values = [
            pose.x_m.to_bits(),
            pose.y_m.to_bits(),
            pose.theta_rad.to_bits(),
            omega_right.to_bits(),
            omega_left.to_bits(),
            self.robot.periods(),
        ];
        for (cells, v) in EMULATOR_TRUTH.chunks_exact(2).zip(values) {
            cells[0].store(v as u32, Ordering::Relaxed);
            cells[1].store((v >> 32) as u32, Ordering::Relaxed);
        }
    }
}
