//! The controller tests' plant: each wheel is the first-order motor the default speed tuning
//! assumes (1 m/s at full duty, τ = 50 ms), integrated exactly per period, behind counters
//! like the board's.

use odocal::kinematics::geometry::Geometry;
use odocal::motion::controller::{Controller, MotorCommand, StepOutput};

/// Two lagged motors; positions and speeds in ticks and ticks/s.
pub struct Plant {
    pub pos: [f64; 2],
    pub vel: [f64; 2],
    pub dt: f64,
    /// Largest |duty| the motors act on (a supply limit below 1 saturates them).
    pub max_duty: f32,
    /// Speed at full duty, m/s.
    pub full_duty_mps: f64,
}

impl Plant {
    pub fn new(rate_hz: u32) -> Self {
        Plant {
            pos: [0.0; 2],
            vel: [0.0; 2],
            dt: 1.0 / f64::from(rate_hz),
            max_duty: 1.0,
            full_duty_mps: 1.0,
        }
    }

    /// Raw counters like the board's: right 32-bit, left 16-bit counting down.
    pub fn raw(&self) -> (u32, u32) {
        let r = self.pos[0].floor() as i64;
        let l = self.pos[1].floor() as i64;
        (r as u32, u32::from((l as u16).wrapping_neg()))
    }

    pub fn step(&mut self, c: &mut Controller) -> StepOutput {
        let (r, l) = self.raw();
        let out = c.step(r, l);
        let duty = match out.command {
            MotorCommand::Duty { right, left } => [right, left],
            MotorCommand::Stop(_) => [0.0, 0.0],
        };
        let k = self.full_duty_mps / Geometry::PAPER_NOMINAL.meters_per_tick_right(); // ticks/s at duty 1
        let tau = 0.05;
        let e = (-self.dt / tau).exp();
        for (i, d) in duty.iter().enumerate() {
            let target = k * f64::from(d.clamp(-self.max_duty, self.max_duty));
            self.pos[i] += target * self.dt + (self.vel[i] - target) * tau * (1.0 - e);
            self.vel[i] = target + (self.vel[i] - target) * e;
        }
        out
    }
}
