//! The simulated robot inside the emulator build: motors, wheels and encoders, with host-sim's
//! model (`host-sim/src/sim/robot.rs`, without slip), in `f64`.
//!
//! - **True geometry**: the paper's nominal robot with the true factors [`TRUE_E_D`],
//!   [`TRUE_E_B`] (host-sim's defaults), which the firmware does not know.
//! - **Motors**: first-order lag `τ ω̇ + ω = K·duty`, solved exactly over each of 10 sub-steps of
//!   a control period (the duty is held for the period); a stop brakes (τ/2) or coasts (4τ).
//!   1 m/s at full duty, τ = 50 ms, the left motor 2 % weaker.
//! - **Encoders**: the wheel angle quantised to `counts_per_rev` (floor), presented as the board's
//!   wrapping counters: right 32-bit counting up, left 16-bit counting down when the wheel rolls
//!   forward, both starting just below a wrap.
//! - **True pose**: exact arcs per sub-step, published in [`EMULATOR_TRUTH`] for the test client (the
//!   "tape measure": it reads the block through the emulator's monitor).
//!
//! The operations and their order are host-sim's, so the same commands give the same counts; the
//! firmware-in-the-loop test checks that a whole calibration session gives the same factors as
//! host-sim's `serial` command.

use core::f64::consts::PI;
use core::sync::atomic::{AtomicU32, Ordering};

use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::sinc;
use crate::motion::controller::MotorCommand;
use crate::motion::motor::{StopMode, clamp_duty};

/// True `E_d = D_R / D_L` of the simulated robot.
pub const TRUE_E_D: f64 = 0.995;
/// True `E_b = b / b_nominal` of the simulated robot.
pub const TRUE_E_B: f64 = 1.010;
/// Integration sub-steps per control period.
const SUBSTEPS: u32 = 10;
/// Motor speed at full duty, m/s.
const FULL_DUTY_MPS: f64 = 1.0;
/// Motor lag, s.
const TAU_S: f64 = 0.05;
/// Left motor strength relative to the right one.
const LEFT_RATIO: f64 = 0.98;
/// Counter values at power-up (right 32-bit, left 16-bit).
const INITIAL_RAW: (u32, u16) = (u32::MAX - 20_000, 300);

/// The plant's state for outside observers: true pose (x, y in metres, heading in radians,
/// start frame), wheel speeds (rad/s) and control periods simulated, as `f64`/`u64` bits, each
/// as two words (low, high). The client reads it with the monitor's `xp /12wx <address>` while
/// the robot is at rest (so the halves belong together).
#[unsafe(no_mangle)]
pub static EMULATOR_TRUTH: [AtomicU32; 12] = [const { AtomicU32::new(0) }; 12];

#[derive(Clone, Copy, Default)]
struct Wheel {
    /// Angular speed, rad/s.
    omega: f64,
    /// Rotation since power-up, counts (continuous).
    counts: f64,
}

/// The simulated motors, wheels and encoders.
pub struct Plant {
    geometry: Geometry,
    gain_right_radps: f64,
    gain_left_radps: f64,
    rate_hz: u32,
    right: Wheel,
    left: Wheel,
    x_m: f64,
    y_m: f64,
    theta_rad: f64,
    periods: u64,
}

impl Plant {
    /// A robot at rest at the origin, heading +x, stepped at `rate_hz`.
    pub fn new(rate_hz: u32) -> Self {
        let geometry = Geometry::PAPER_NOMINAL.with_factors(TRUE_E_D, TRUE_E_B, 1.0);
        let w = 2.0 * FULL_DUTY_MPS / geometry.mean_diameter_m();
        let plant = Plant {
            geometry,
            gain_right_radps: w,
            gain_left_radps: w * LEFT_RATIO,
            rate_hz,
            right: Wheel::default(),
            left: Wheel::default(),
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.0,
            periods: 0,
        };
        plant.publish();
        plant
    }

    /// Steps periods of `rate_hz` from now on (the control rate was changed).
    pub fn set_rate_hz(&mut self, rate_hz: u32) {
        self.rate_hz = rate_hz;
    }

    /// The hardware counter values (right 32-bit up, left 16-bit down) as the controller takes
    /// them.
    pub fn raw(&self) -> (u32, u32) {
        let r = libm::floor(self.right.counts) as i64;
        let l = libm::floor(self.left.counts) as i64;
        (
            INITIAL_RAW.0.wrapping_add(r as u32),
            u32::from(INITIAL_RAW.1.wrapping_sub(l as u16)),
        )
    }

    /// Simulates one control period with `command` held.
    pub fn advance(&mut self, command: MotorCommand) {
        let g = self.geometry;
        let h = 1.0 / (f64::from(self.rate_hz) * f64::from(SUBSTEPS));
        let (target_r, target_l, tau) = match command {
            MotorCommand::Duty { right, left } => (
                self.gain_right_radps * f64::from(clamp_duty(right)),
                self.gain_left_radps * f64::from(clamp_duty(left)),
                TAU_S,
            ),
            MotorCommand::Stop(StopMode::Brake) => (0.0, 0.0, 0.5 * TAU_S),
            MotorCommand::Stop(StopMode::Coast) => (0.0, 0.0, 4.0 * TAU_S),
        };
        let cpr = f64::from(g.counts_per_rev);
        // The decay over a sub-step is the same in all of them: once per period, as host-sim.
        let e = libm::exp(-h / tau);
        let turn = |w: &mut Wheel, target: f64| -> f64 {
            let dphi = target * h + (w.omega - target) * tau * (1.0 - e);
            w.omega = target + (w.omega - target) * e;
            w.counts += dphi / (2.0 * PI) * cpr;
            dphi
        };
        let theta0 = self.theta_rad;
        let (s0, c0) = libm::sincos(theta0);
        let mut offset = 0.0f64;
        for _ in 0..SUBSTEPS {
            let ds_r = turn(&mut self.right, target_r) * 0.5 * g.diameter_right_m;
            let ds_l = turn(&mut self.left, target_l) * 0.5 * g.diameter_left_m;
            let ds = 0.5 * (ds_r + ds_l);
            let dtheta = (ds_r - ds_l) * (1.0 / g.wheelbase_m);
            let u = 0.5 * dtheta;
            // sinc's and the small rotations' Taylor series with the coefficients as reciprocals,
            // as host-sim (truncation below 3e-21).
            let chord = if libm::fabs(u) < 1e-4 {
                let u2 = u * u;
                ds * (1.0 - u2 * (1.0 / 6.0) + u2 * u2 * (1.0 / 120.0))
            } else {
                ds * sinc(u)
            };
            let d = offset + u;
            let (sd, cd) = if libm::fabs(d) < 0.01 {
                let d2 = d * d;
                (
                    d * (1.0
                        - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0) * (1.0 - d2 * (1.0 / 42.0)))),
                    1.0 - d2 * 0.5 * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0))),
                )
            } else {
                libm::sincos(d)
            };
            self.x_m += chord * (c0 * cd - s0 * sd);
            self.y_m += chord * (s0 * cd + c0 * sd);
            offset += dtheta;
        }
        self.theta_rad = theta0 + offset;
        self.periods += 1;
        self.publish();
    }

    fn publish(&self) {
        let values = [
            self.x_m.to_bits(),
            self.y_m.to_bits(),
            self.theta_rad.to_bits(),
            self.right.omega.to_bits(),
            self.left.omega.to_bits(),
            self.periods,
        ];
        for (cells, v) in EMULATOR_TRUTH.chunks_exact(2).zip(values) {
            cells[0].store(v as u32, Ordering::Relaxed);
            cells[1].store((v >> 32) as u32, Ordering::Relaxed);
        }
    }
}
