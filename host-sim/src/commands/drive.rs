//! The `drive` subcommand: a scripted velocity profile (straight line, in-place turn or arc)
//! sent to the library's [`Controller::drive`] the way a main computer would (a command every
//! 100 ms), through the simulated robot; prints the odometry pose against the true pose.
//!
//! When the script ends, the commands stop and the controller's deadman stops the motors. The
//! peak wheel synchronisation error (how far one wheel got ahead of the other against their
//! common reference) is printed as `peak sync error: <N> ticks`.
//!
//! The robot is the simulated board ([`Board`]): `--motor-gain`, `--motor-tau`,
//! `--motor-deadband` give it other motors than the defaults the speed loops are tuned for, and
//! `--identify` first sends it `identify` (the library's motor identification, through the
//! serial protocol), which applies the identified tuning, and then drives the same script.

use clap::ValueEnum;
use odocal::kinematics::reference::PoseF64;
use odocal::motion::controller::{Controller, Fault};
use odocal::motion::identify::IdentifyMode;

use crate::sim::board::Board;
use crate::sim::flash::SimParamFlash;
use crate::sim::robot::{MotorArgs, Sim, WiringOption, sim_config};

/// A scripted motion.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Script {
    /// Straight line at `--speed`.
    Line,
    /// In-place turn at `--turn-rate`.
    Turn,
    /// Arc at `--speed` and `--turn-rate`.
    Arc,
}

/// Command-line arguments of the `drive` subcommand.
#[derive(clap::Args, Debug, Clone)]
pub struct DriveArgs {
    /// What to drive.
    #[arg(value_enum)]
    pub script: Script,
    /// Centre speed, m/s.
    #[arg(long, default_value_t = 0.3)]
    pub speed: f32,
    /// Turn rate, rad/s (CCW positive).
    #[arg(long, default_value_t = 0.5)]
    pub turn_rate: f32,
    /// How long commands are sent, seconds.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// True E_b of the simulated robot.
    #[arg(long, default_value_t = 1.0)]
    pub eb: f64,
    /// True E_d of the simulated robot.
    #[arg(long, default_value_t = 1.0)]
    pub ed: f64,
    /// Relative slip noise per millisecond of travel (standard deviation; per control period at 1 kHz).
    #[arg(long, default_value_t = 0.0)]
    pub slip: f64,
    /// Seed of the slip noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Control rate, Hz: 1000, 2000, 4000, 5000, 8000 or 10000 (the board's `control_hz`).
    #[arg(long = "rate-hz", visible_alias = "rate", default_value_t = odocal::motion::controller::DEFAULT_RATE_HZ, value_parser = crate::commands::parse_rate_hz)]
    pub rate: u32,
    /// How the simulated robot is wired (a reversed motor or encoder must end in a
    /// following-error fault, not a runaway).
    #[arg(long, value_enum, default_value_t = WiringOption::Standard)]
    pub wiring: WiringOption,
    /// The simulated motors.
    #[command(flatten)]
    pub motors: MotorArgs,
    /// Identify the motors first (`identify` on the simulated board, wheels lifted) and drive
    /// with the tuning it applies.
    #[arg(long)]
    pub identify: bool,
}

/// Outcome of a scripted drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveResult {
    /// Odometry pose at rest, in the frame of the odometry pose at the start.
    pub odometry: PoseF64,
    /// True pose at rest, in the frame of the true pose at the start.
    pub truth: PoseF64,
    /// Periods from the last `drive` call to the first stop command.
    pub stop_after_periods: u64,
    /// Largest |wheel synchronisation error| while driving, ticks.
    pub peak_sync_ticks: f64,
}

/// A drive that ended in a latched fault.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveFault {
    /// The fault.
    pub fault: Fault,
    /// Robot time from the first command to the period that latched it, s.
    pub after_s: f64,
    /// True distance the robot moved from where it started, m.
    pub moved_m: f64,
}

/// Sends `(v, w)` every 100 ms for `seconds`, then lets the deadman stop the robot and waits
/// for it to come to rest.
///
/// # Errors
/// A refused command or a fault.
pub fn drive_script(
    sim: &mut Sim,
    controller: &mut Controller,
    v_mps: f32,
    w_radps: f32,
    seconds: f64,
) -> Result<Result<DriveResult, DriveFault>, String> {
    let rate = u64::from(sim.config().rate_hz);
    let periods = (seconds * rate as f64).round() as u64;
    let every = (rate / 10).max(1);
    let mut last_call = 0;
    let start = sim.true_pose();
    let odometry_start = controller.pose().to_f64();
    let mut peak_sync = 0.0f64;
    let mut track = |c: &Controller| {
        let (r, l) = c.wheel_errors_ticks();
        peak_sync = peak_sync.max(f64::from(l - r).abs());
    };
    for k in 0..periods {
        if k % every == 0 {
            controller
                .drive(v_mps, w_radps)
                .map_err(|e| format!("drive: {e}"))?;
            last_call = k;
        }
        let out = sim.step(controller);
        track(controller);
        if let Some(fault) = out.fault {
            sim.rest(controller, rate);
            return Ok(Err(DriveFault {
                fault,
                after_s: (k + 1) as f64 / rate as f64,
                moved_m: sim.true_pose().distance_to(&start),
            }));
        }
    }
    let mut k = periods;
    loop {
        let out = sim.step(controller);
        track(controller);
        if let Some(f) = out.fault {
            return Err(format!("fault: {f}"));
        }
        if out.command.is_stop() {
            break;
        }
        k += 1;
        if k > periods + 10 * rate {
            return Err("the deadman did not stop the motors".into());
        }
    }
    let stop_after_periods = k - last_call;
    sim.rest(controller, rate);
    Ok(Ok(DriveResult {
        odometry: odometry_start.relative(&controller.pose().to_f64()),
        truth: start.relative(&sim.true_pose()),
        stop_after_periods,
        peak_sync_ticks: peak_sync,
    }))
}

/// What a `drive` run produced.
#[derive(Clone, Debug, PartialEq)]
pub struct DriveOutcome {
    /// The `identify` reply and events (with `--identify`).
    pub identification: Option<String>,
    /// The drive, or the fault that ended it.
    pub result: Result<DriveResult, DriveFault>,
}

/// The `drive` subcommand's work without the printing: a fresh simulated board, the
/// identification when asked, the script.
///
/// # Errors
/// Invalid options, a failed identification, a refused command.
pub fn execute(args: &DriveArgs) -> Result<DriveOutcome, String> {
    let mut config = sim_config(args.ed, args.eb, args.slip, args.seed, args.rate);
    config.wiring = args.wiring.wiring();
    args.motors.apply(&mut config)?;
    // A fresh board (erased parameter flash: the default parameters and tuning).
    let mut flash = SimParamFlash::erased();
    let mut boot = String::new();
    let mut board = Board::boot(config, &mut flash, &mut boot)?;
    let identification = if args.identify {
        let events = board
            .identify(IdentifyMode::Lifted)
            .map_err(|e| format!("identify: {e}"))?;
        Some(events.replace("\r\n", "\n"))
    } else {
        None
    };
    let (sim, controller) = (&mut board.sim, &mut board.controller);
    let (v, w) = velocities(args);
    let result = drive_script(sim, controller, v, w, args.seconds)?;
    Ok(DriveOutcome {
        identification,
        result,
    })
}

fn velocities(args: &DriveArgs) -> (f32, f32) {
    match args.script {
        Script::Line => (args.speed, 0.0),
        Script::Turn => (0.0, args.turn_rate),
        Script::Arc => (args.speed, args.turn_rate),
    }
}

/// Runs the `drive` subcommand.
///
/// # Errors
/// Any failure of the scripted drive.
pub fn run(args: &DriveArgs) -> Result<(), String> {
    let outcome = execute(args)?;
    if let Some(events) = &outcome.identification {
        print!("{events}");
    }
    let (v, w) = velocities(args);
    // The names the command line takes (`line`, `left-encoder-reversed`).
    let name = |v: Option<clap::builder::PossibleValue>| {
        v.map_or_else(String::new, |v| v.get_name().to_string())
    };
    println!(
        "{}: v = {v} m/s, w = {w} rad/s for {} s; true E_b = {}, E_d = {}; wiring {}",
        name(clap::ValueEnum::to_possible_value(&args.script)),
        args.seconds,
        args.eb,
        args.ed,
        name(clap::ValueEnum::to_possible_value(&args.wiring))
    );
    let r = match outcome.result {
        Ok(r) => r,
        Err(f) => {
            println!(
                "fault latched after {:.3} s of robot time: {}",
                f.after_s, f.fault
            );
            if let Fault::FollowingError { peak_duty_pct, .. } = f.fault {
                println!("peak duty: {peak_duty_pct} %");
            }
            println!(
                "motors stopped; the robot moved {:.3} m in all (run `cargo sim bringup --wiring {}` to find the fix)",
                f.moved_m,
                args.wiring
                    .to_possible_value()
                    .map_or("standard".into(), |v| v.get_name().to_string())
            );
            return Ok(());
        }
    };
    let show = |name: &str, p: &PoseF64| {
        println!(
            "{name:<9} x = {:>10.6} m  y = {:>10.6} m  θ = {:>10.6} rad",
            p.x_m, p.y_m, p.theta_rad
        );
    };
    show("odometry", &r.odometry);
    // Odometry reports the heading wrapped to [-π, π); wrap the true one the same way.
    let mut t = r.truth;
    t.theta_rad = (t.theta_rad + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI)
        - std::f64::consts::PI;
    show("true", &t);
    println!(
        "error     |Δp| = {:.3} mm, Δθ = {:.3e} rad (true − odometry)",
        r.truth.distance_to(&r.odometry) * 1e3,
        t.theta_rad - r.odometry.theta_rad
    );
    println!(
        "deadman stopped the motors {} periods after the last command",
        r.stop_after_periods
    );
    println!("peak sync error: {:.0} ticks", r.peak_sync_ticks);
    Ok(())
}
