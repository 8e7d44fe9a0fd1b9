//! The control-task workloads: the library's robot model ([`odocal::plant`], the one host-sim
//! and the emulator board run, in its portable arithmetic so that host and target move it
//! identically) driven by the app core's control period ([`odocal::app::control::period`], the
//! function the firmware's TIM7 task and host-sim's board call).
//!
//! Each period the bench reads the robot's counters, runs one control period (the measured
//! window: stop request, controller step, motor command into the robot) and advances the robot
//! one period. The robot's true geometry is the controller's own (the paper's nominal robot), so
//! the routine finishes as planned.

use odocal::app::Handoff;
use odocal::app::control;
use odocal::kinematics::geometry::Geometry;
use odocal::motion::bringup::{CheckKind, CheckReport};
use odocal::motion::controller::{Controller, ControllerConfig, StepOutput};
use odocal::motion::identify::IdentifyMode;
use odocal::motion::run::RunRecord;
use odocal::motion::run::{Direction, PathKind};
use odocal::plant::{Portable, RobotConfig, SimRobot};

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

/// The simulated robot of the workloads.
pub type BenchRobot = SimRobot<Portable>;

/// The robot: the paper's nominal geometry, the model's default motors (1 m/s at full duty,
/// 50 ms lag, the left one 2 % weaker) and counters (right 32-bit up, left 16-bit down, both
/// starting just below a wrap), stepped at [`RATE_HZ`].
pub fn robot() -> BenchRobot {
    SimRobot::new(RobotConfig::new(Geometry::PAPER_NOMINAL, RATE_HZ))
}

/// The controller of the workload: the board's defaults for the nominal geometry at 1 kHz.
///
/// # Errors
/// The configuration error (none for these constants; a host test checks it).
pub fn controller() -> Result<Controller, odocal::motion::controller::ConfigError> {
    Controller::new(ControllerConfig::new(Geometry::PAPER_NOMINAL, RATE_HZ))
}

/// One control period as the firmware's control task runs it (no button press).
pub fn period(
    handoff: &Handoff,
    controller: &mut Controller,
    raw_right: u32,
    raw_left: u32,
    robot: &mut BenchRobot,
) -> StepOutput {
    control::period(handoff, controller, 0, raw_right, raw_left, None, robot)
}

/// Drives [`PATH`] with `controller` and a fresh robot; `step` performs each control period
/// (for example [`period`]; the bench wraps it in its markers). Returns the periods driven and
/// the run record.
///
/// # Errors
/// A refused start, a fault, or no finished run within [`MAX_PERIODS`].
pub fn drive_square<F>(
    controller: &mut Controller,
    mut step: F,
) -> Result<(u32, RunRecord), &'static str>
where
    F: FnMut(&Handoff, &mut Controller, u32, u32, &mut BenchRobot) -> StepOutput,
{
    let handoff = Handoff::new();
    let mut robot = robot();
    let (r, l) = robot.raw();
    period(&handoff, controller, r, l, &mut robot);
    controller.start(PATH).map_err(|_| "start refused")?;
    let mut periods = 0;
    loop {
        if let Some(record) = controller.take_finished_run() {
            return Ok((periods, record));
        }
        if periods >= MAX_PERIODS {
            return Err("the square did not finish");
        }
        let (r, l) = robot.raw();
        let out = step(&handoff, controller, r, l, &mut robot);
        if out.fault.is_some() {
            return Err("controller fault");
        }
        robot.advance();
        periods += 1;
    }
}

/// Runs a motor identification ([`IDENTIFY_MODE`]) with `controller` and a fresh robot, as the
/// firmware does: `step` performs each control period (the control task), `take` each poll of
/// the check report (the console task, once per period here); the bench wraps both in its
/// markers. Returns the periods stepped and the report.
///
/// # Errors
/// A refused start, or no report within [`MAX_PERIODS`].
pub fn identify<F, T>(
    controller: &mut Controller,
    mut step: F,
    mut take: T,
) -> Result<(u32, CheckReport), &'static str>
where
    F: FnMut(&Handoff, &mut Controller, u32, u32, &mut BenchRobot) -> StepOutput,
    T: FnMut(&mut Controller) -> Option<CheckReport>,
{
    let handoff = Handoff::new();
    let mut robot = robot();
    let (r, l) = robot.raw();
    period(&handoff, controller, r, l, &mut robot);
    controller
        .start_check(CheckKind::Identify(IDENTIFY_MODE))
        .map_err(|_| "identification refused")?;
    let mut periods = 0;
    loop {
        if periods >= MAX_PERIODS {
            return Err("the identification did not finish");
        }
        let (r, l) = robot.raw();
        step(&handoff, controller, r, l, &mut robot);
        robot.advance();
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
    fn the_square_finishes_well_within_the_period_limit() {
        let mut c = controller().unwrap();
        let (periods, record) = drive_square(&mut c, period).unwrap();
        // 4 m at up to 0.3 m/s plus four quarter turns: at least 15 s.
        assert!(periods > 15_000 && periods < MAX_PERIODS, "{periods}");
        // A square ends where it started (the robot has the controller's geometry; the
        // remaining error is the routine's settling tolerance of 20 ticks per wheel, 0.05 mm).
        let end = record.odometry_end;
        assert!(end.x_m.abs() < 1e-3 && end.y_m.abs() < 1e-3, "{end:?}");
    }

    #[test]
    fn the_identification_finds_the_robot() {
        let mut c = controller().unwrap();
        let (periods, report) = identify(&mut c, period, Controller::take_check_report).unwrap();
        // Four passes of 3 × 400 + 500 + 300 ms at 1 kHz, a probe per wheel (stairs of 300 ms
        // at 4, 6 and 8 % duty: 8 % is the first past 25 % of the 0.3 m/s cap on this robot, 1 m/s
        // per unit duty; then a 300 ms brake), and the period that closes it.
        assert_eq!(periods, 4 * 2_000 + 2 * (3 * 300 + 300) + 1);
        let CheckReport::Identify(r) = report else {
            panic!("{report:?}");
        };
        // The robot: 1 m/s (right) and 0.98 m/s (left) at full duty, 50 ms lag, no dead-band,
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
