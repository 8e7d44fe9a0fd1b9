//! The host side of the benchmark: the reference result lines, and the accuracy of the
//! fixed-point odometry on the standard trace against the `f64` exact-arc reference.

use std::process::ExitCode;

use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::odometry::{Integration, Pose};
use odocal::kinematics::reference::{ArcModel, PoseF64};
use qemu_bench::report;
use qemu_bench::trace::Trace;

/// Steps of the midpoint run (as on the target).
const MIDPOINT_STEPS: u32 = 100_000;

/// Accuracy budget of the odometry: 0.1 mm from the exact-arc reference after 1 km.
const BUDGET_M: f64 = 1e-4;

fn integrate(integration: Integration, trace: Trace) -> Result<(Pose, Vec<WheelTicks>), String> {
    let (odo, mut state) = qemu_bench::odometry(integration).map_err(|e| e.to_string())?;
    let mut knots = vec![WheelTicks::default()];
    let mut pose = state.pose();
    for totals in trace {
        pose = odo.update(&mut state, totals);
        knots.push(totals);
    }
    Ok((pose, knots))
}

/// Runs the host reference; prints result and info lines; fails when the budget is not met.
pub fn run() -> ExitCode {
    match run_inner() {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("error {e}");
            ExitCode::FAILURE
        }
    }
}

fn run_inner() -> Result<bool, String> {
    let mut out = String::new();
    let (pose, knots) = integrate(Integration::ExactArc, Trace::standard())?;
    report::pose_line(&mut out, "odometry_exact_arc", &pose).map_err(|e| e.to_string())?;

    // Accuracy against the f64 exact-arc integration of the same knots.
    let geometry = qemu_bench::geometry();
    let model = ArcModel::from_geometry(&geometry);
    let reference = model.integrate(PoseF64::default(), &knots);
    let fixed = pose.to_f64();
    let error_m = fixed.distance_to(&reference);
    let heading_error = {
        let d = fixed.theta_rad - reference.theta_rad;
        // Wrap into [-π, π): the fixed-point heading is wrapped, the reference is not.
        (d + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI
    };
    let mut path_m = 0.0;
    for w in knots.windows(2) {
        let d = w[1] - w[0];
        path_m += 0.5
            * (geometry.meters_per_tick_right() * d.right.unsigned_abs() as f64
                + geometry.meters_per_tick_left() * d.left.unsigned_abs() as f64);
    }
    let (mid, _) = integrate(Integration::Midpoint, Trace::with_steps(MIDPOINT_STEPS))?;
    report::pose_line(&mut out, "odometry_midpoint", &mid).map_err(|e| e.to_string())?;
    solve(&mut out)?;
    console(&mut out)?;
    console_locks(&mut out)?;
    control(&mut out)?;
    identify(&mut out)?;
    print!("{out}");
    println!(
        "info accuracy steps={} path_m={path_m:.1} position_error_m={error_m:.3e} \
         heading_error_rad={heading_error:.3e} budget_m={BUDGET_M:e}",
        knots.len() - 1
    );
    Ok(error_m <= BUDGET_M)
}

/// The exact calibration of the recorded squares: result lines plus the estimate vs the truth.
pub fn solve(out: &mut String) -> Result<(), String> {
    use odocal::calibration::{Method, calibrate};
    use qemu_bench::squares::{self, SquareRuns};

    let runs = SquareRuns::generate();
    report::bits_line(out, "squares_fixture", &[("checksum", runs.checksum())])
        .map_err(|e| e.to_string())?;
    let result = calibrate(&runs.observations(), &squares::nominal(), Method::Exact);
    report::calibration_line(out, "solve_exact", &result).map_err(|e| e.to_string())?;
    let c = result.map_err(|e| format!("exact calibration failed: {e}"))?;
    out.push_str(&format!(
        "info solve e_d={:.6} (true {}) e_b={:.6} (true {}) iterations={}\n",
        c.e_d,
        squares::TRUE_E_D,
        c.e_b,
        squares::TRUE_E_B,
        c.iterations
    ));
    Ok(())
}

/// The control task driving a square with the simulated robot: the result line.
pub fn control(out: &mut String) -> Result<(), String> {
    use qemu_bench::control;

    let mut c = control::controller().map_err(|e| e.to_string())?;
    let (periods, record) = control::drive_square(&mut c, |_, c, r, l, robot| {
        let out = c.step(r, l);
        out.command.apply(robot);
        out
    })?;
    report::run_line(out, "control_square_step", periods, &record).map_err(|e| e.to_string())?;
    let mut c = control::controller().map_err(|e| e.to_string())?;
    let (periods, record) = control::drive_square(&mut c, control::period)?;
    report::run_line(out, "control_square", periods, &record).map_err(|e| e.to_string())
}

/// A motor identification of the simulated robot's motors: the result line.
pub fn identify(out: &mut String) -> Result<(), String> {
    use odocal::motion::controller::Controller;
    use qemu_bench::control;

    let mut c = control::controller().map_err(|e| e.to_string())?;
    let (periods, report) =
        control::identify(&mut c, control::period, Controller::take_check_report)?;
    report::identify_line(out, "identify_lifted", periods, &report).map_err(|e| e.to_string())
}

/// The console session of [`qemu_bench::console::LOCK_SCRIPT`] through a controller lock: the
/// result line.
pub fn console_locks(out: &mut String) -> Result<(), String> {
    use odocal::session::library::LockedController;
    use qemu_bench::console::{self, Bracketed};
    use qemu_bench::squares::SquareRuns;

    let runs = SquareRuns::generate();
    let mut controller = qemu_bench::control::controller().map_err(|e| e.to_string())?;
    let mut robot = LockedController(Bracketed {
        controller: &mut controller,
        open: || {},
        close: || {},
    });
    let mut session = console::session(&runs);
    let mut reply = console::ReplyHash::default();
    for line in console::LOCK_SCRIPT {
        console::command(&mut session, &mut robot, &runs, line, &mut reply);
    }
    report::bits_line(
        out,
        "console_locks",
        &[("reply_hash", reply.hash), ("reply_bytes", reply.bytes)],
    )
    .map_err(|e| e.to_string())
}

/// The console's `calibrate` and `apply exact` on the recorded squares: the result line.
pub fn console(out: &mut String) -> Result<(), String> {
    use qemu_bench::console;
    use qemu_bench::squares::SquareRuns;

    let runs = SquareRuns::generate();
    let mut controller = qemu_bench::control::controller().map_err(|e| e.to_string())?;
    let mut robot = odocal::session::library::LockedController(&mut controller);
    let mut session = console::session(&runs);
    let mut reply = console::ReplyHash::default();
    for line in console::COMMANDS {
        console::command(&mut session, &mut robot, &runs, line, &mut reply);
    }
    report::bits_line(
        out,
        "console_calibrate_apply",
        &[
            ("reply_hash", reply.hash),
            ("reply_bytes", reply.bytes),
            (
                "exact_solves",
                u64::from(session.calibrator().exact_solves()),
            ),
        ],
    )
    .map_err(|e| e.to_string())
}
