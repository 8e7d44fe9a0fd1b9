//! A small deterministic robot for the control-task workload: two first-order motors
//! (duty → wheel speed, 50 ms lag, the left motor 2 % weaker) and the board's two encoder
//! counters (right 32-bit counting up, left 16-bit counting down), in `f64` through basic
//! operations only, so host and target move it identically.
//!
//! It stands in for the hardware around `Controller::step`: the bench reads the counters, calls
//! the step (the measured window), applies the returned command and advances the plant one
//! control period. The geometry is the controller's own, so the routine finishes as planned.

use odocal::kinematics::geometry::Geometry;
use odocal::motion::bringup::{CheckKind, CheckReport};
use odocal::motion::controller::{Controller, ControllerConfig, MotorCommand, StepOutput};
use odocal::motion::identify::IdentifyMode;
use odocal::motion::motor::StopMode;
use odocal::motion::run::RunRecord;
use odocal::motion::run::{Direction, PathKind};

/// Control rate, Hz.
pub const RATE_HZ: u32 = 1000;
/// The square the routine drives: 1 m sides, clockwise.
pub const PATH: PathKind = PathKind::Square {
    direction: Direction::Cw,
    side_m: 1.0,
};
/// Safety limit on the number of periods (the square takes about 25,000, the identification
/// 8,000).
pub const MAX_PERIODS: u32 = 120_000;
/// Where the identification workload runs: wheels off the ground, each wheel in turn (four
/// passes, the longer of the two modes).
pub const IDENTIFY_MODE: IdentifyMode = IdentifyMode::Lifted;

/// `1 − e^(−h/τ)` for h = 1 ms and τ = 50 ms (drive), 25 ms (brake), 200 ms (coast); written
/// out so that no transcendental function is evaluated.
const ALPHA_DRIVE: f64 = 0.0198013266932447;
const ALPHA_BRAKE: f64 = 0.03921056084767679;
const ALPHA_COAST: f64 = 0.004987520807317687;

/// Wheel speed at full duty, encoder counts per period (1 m/s on a 150 mm wheel at 1 kHz:
/// 200,000 / (π · 0.15) / 1000).
const FULL_DUTY_COUNTS: f64 = 424.41318157838754;

/// The simulated motors and counters.
#[derive(Clone, Debug)]
pub struct Plant {
    /// Wheel speeds, counts per period (right, left).
    speed: [f64; 2],
    /// Wheel positions, counts (continuous).
    position: [f64; 2],
    command: MotorCommand,
}

impl Default for Plant {
    fn default() -> Self {
        Plant {
            speed: [0.0; 2],
            position: [0.0; 2],
            command: MotorCommand::Stop(StopMode::Brake),
        }
    }
}

impl Plant {
    /// The counter values: right 32-bit counting forward, left 16-bit counting backwards
    /// (the board's mirrored left motor), both starting just below a wrap.
    pub fn raw(&self) -> (u32, u32) {
        let right = libm::floor(self.position[0]) as i64;
        let left = libm::floor(self.position[1]) as i64;
        let raw_right = (u32::MAX - 20_000).wrapping_add(right as u32);
        let raw_left = u32::from(300u16.wrapping_sub(left as u16));
        (raw_right, raw_left)
    }

    /// Takes the command of a control step.
    pub fn apply(&mut self, out: &StepOutput) {
        self.command = out.command;
    }

    /// Moves the wheels for one period.
    pub fn advance(&mut self) {
        let (target, alpha) = match self.command {
            MotorCommand::Duty { right, left } => (
                [
                    FULL_DUTY_COUNTS * f64::from(right),
                    0.98 * FULL_DUTY_COUNTS * f64::from(left),
                ],
                ALPHA_DRIVE,
            ),
            MotorCommand::Stop(StopMode::Brake) => ([0.0; 2], ALPHA_BRAKE),
            MotorCommand::Stop(StopMode::Coast) => ([0.0; 2], ALPHA_COAST),
        };
        for ((speed, position), target) in self
            .speed
            .iter_mut()
            .zip(self.position.iter_mut())
            .zip(target)
        {
            let before = *speed;
            *speed += (target - before) * alpha;
            *position += 0.5 * (before + *speed);
        }
    }
}

/// The controller of the workload: the board's defaults for the nominal geometry at 1 kHz.
///
/// # Errors
/// The configuration error (none for these constants; a host test checks it).
pub fn controller() -> Result<Controller, odocal::motion::controller::ConfigError> {
    Controller::new(ControllerConfig::new(Geometry::PAPER_NOMINAL, RATE_HZ))
}

/// Drives [`PATH`] with `controller` and a fresh plant; `step` performs each control step (the
/// bench wraps it in its markers). Returns the periods driven and the run record.
///
/// # Errors
/// A refused start, a fault, or no finished run within [`MAX_PERIODS`].
pub fn drive_square<F>(
    controller: &mut Controller,
    mut step: F,
) -> Result<(u32, RunRecord), &'static str>
where
    F: FnMut(&mut Controller, u32, u32) -> StepOutput,
{
    let mut plant = Plant::default();
    let (r, l) = plant.raw();
    controller.step(r, l);
    controller.start(PATH).map_err(|_| "start refused")?;
    let mut periods = 0;
    loop {
        if let Some(record) = controller.take_finished_run() {
            return Ok((periods, record));
        }
        if periods >= MAX_PERIODS {
            return Err("the square did not finish");
        }
        let (r, l) = plant.raw();
        let out = step(controller, r, l);
        if out.fault.is_some() {
            return Err("controller fault");
        }
        plant.apply(&out);
        plant.advance();
        periods += 1;
    }
}

/// Runs a motor identification ([`IDENTIFY_MODE`]) with `controller` and a fresh plant, as the
/// firmware does: `step` performs each control step (the control task), `take` each poll of the
/// check report (the console task, once per period here); the bench wraps both in its markers.
/// Returns the periods stepped and the report.
///
/// # Errors
/// A refused start, or no report within [`MAX_PERIODS`].
pub fn identify<F, T>(
    controller: &mut Controller,
    mut step: F,
    mut take: T,
) -> Result<(u32, CheckReport), &'static str>
where
    F: FnMut(&mut Controller, u32, u32) -> StepOutput,
    T: FnMut(&mut Controller) -> Option<CheckReport>,
{
    let mut plant = Plant::default();
    let (r, l) = plant.raw();
    controller.step(r, l);
    controller
        .start_check(CheckKind::Identify(IDENTIFY_MODE))
        .map_err(|_| "identification refused")?;
    let mut periods = 0;
    loop {
        if periods >= MAX_PERIODS {
            return Err("the identification did not finish");
        }
        let (r, l) = plant.raw();
        let out = step(controller, r, l);
        plant.apply(&out);
        plant.advance();
        periods += 1;
        if let Some(report) = take(controller) {
            return Ok((periods, report));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lag_constants_match_the_time_constants() {
        for (alpha, tau_ms) in [
            (ALPHA_DRIVE, 50.0),
            (ALPHA_BRAKE, 25.0),
            (ALPHA_COAST, 200.0),
        ] {
            let exact = 1.0 - libm::exp(-1.0 / tau_ms);
            // The literals are the correctly rounded values; 1 − exp(x) itself rounds at 1e-17.
            assert!((alpha - exact).abs() < 1e-16, "{alpha} vs {exact}");
        }
        let exact = 200_000.0 / (core::f64::consts::PI * 0.15) / 1000.0;
        assert!((FULL_DUTY_COUNTS - exact).abs() < 1e-12);
    }

    #[test]
    fn the_square_finishes_well_within_the_period_limit() {
        let mut c = controller().unwrap();
        let (periods, record) = drive_square(&mut c, |c, r, l| c.step(r, l)).unwrap();
        // 4 m at up to 0.3 m/s plus four quarter turns: at least 15 s.
        assert!(periods > 15_000 && periods < MAX_PERIODS, "{periods}");
        // A square ends where it started (the plant has the controller's geometry; the
        // remaining error is the routine's settling tolerance of 20 ticks per wheel, 0.05 mm).
        let end = record.odometry_end;
        assert!(end.x_m.abs() < 1e-3 && end.y_m.abs() < 1e-3, "{end:?}");
    }

    #[test]
    fn the_identification_finds_the_plant() {
        let mut c = controller().unwrap();
        let (periods, report) = identify(
            &mut c,
            |c, r, l| c.step(r, l),
            Controller::take_check_report,
        )
        .unwrap();
        // Four passes of 3 × 400 + 500 + 300 ms at 1 kHz, and the period that closes it.
        assert_eq!(periods, 8_001);
        let CheckReport::Identify(r) = report else {
            panic!("{report:?}");
        };
        // The plant: 1 m/s (right) and 0.98 m/s (left) at full duty, 50 ms lag, no dead-band,
        // sampled without noise but through the counters' floor: every parameter within 1 %.
        for (fit, gain) in [(r.right, 1.0), (r.left, 0.98)] {
            let p = fit.params;
            for est in [p.gain_forward_mps, p.gain_backward_mps] {
                assert!((f64::from(est) - gain).abs() < 0.01 * gain, "{p:?}");
            }
            assert!((p.time_constant_s - 0.05).abs() < 0.01 * 0.05, "{p:?}");
            assert!(p.deadband < 0.01, "{p:?}");
        }
    }
}
