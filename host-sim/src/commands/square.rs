//! The `square` subcommand: UMBmark squares (and lines, circles) driven closed-loop by the
//! library's [`Controller`] through the simulated robot, with the numbers the motion issue asks
//! for: true and odometry end poses, the peak wheel synchronisation error during legs, and how
//! well the run record's knots re-integrate to the true end pose.

use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::{ArcModel, PoseF64};
use odocal::motion::controller::Controller;
use odocal::motion::run::{Direction, PathKind, RunRecord};
use odocal::motion::speed::SpeedTuning;

use crate::sim::robot::{Sim, SimConfig, default_controller, sim_config};

/// The outcome of one closed-loop run.
#[derive(Clone, Debug)]
pub struct PathResult {
    /// What was driven.
    pub path: PathKind,
    /// True pose when the run finished (start frame).
    pub true_end: PoseF64,
    /// True pose after the robot came to rest.
    pub true_rest: PoseF64,
    /// The run record (odometry end pose, knots).
    pub record: RunRecord,
    /// Largest |wheel synchronisation error| during legs, ticks.
    pub peak_leg_sync_ticks: f64,
    /// Largest |tracking error| of either wheel, ticks.
    pub peak_tracking_ticks: f64,
    /// The knots integrated with the true geometry.
    pub knots_true: PoseF64,
    /// Control periods the run took.
    pub periods: u64,
}

impl PathResult {
    /// |knots integrated with the true geometry − true end pose|, metres.
    pub fn knot_error_m(&self) -> f64 {
        self.knots_true.distance_to(&self.true_end)
    }
}

/// Drives `path` once with a robot configured by `sim_config`, whose controller believes
/// `belief`.
///
/// # Errors
/// An invalid configuration, a refused start, a fault, or a run that did not finish in 20 min
/// of simulated time.
pub fn drive_path(
    sim_config: SimConfig,
    belief: Geometry,
    path: PathKind,
) -> Result<PathResult, String> {
    drive_path_tuned(sim_config, belief, SpeedTuning::DEFAULT, path)
}

/// [`drive_path`] with the speed loops tuned by `tuning` (e.g. an identified one).
///
/// # Errors
/// As [`drive_path`], and an invalid tuning.
pub fn drive_path_tuned(
    sim_config: SimConfig,
    belief: Geometry,
    tuning: SpeedTuning,
    path: PathKind,
) -> Result<PathResult, String> {
    let mut controller = default_controller(belief, sim_config.rate_hz)?;
    controller
        .set_tuning(tuning)
        .map_err(|e| format!("tuning: {e}"))?;
    let mut sim = Sim::new(sim_config);
    sim.step(&mut controller);
    drive_path_with(&mut sim, &mut controller, path)
}

/// Drives `path` with an existing robot and controller (the run's frame is the current pose).
///
/// # Errors
/// A refused start, a fault, or a run that did not finish in 20 min of simulated time.
pub fn drive_path_with(
    sim: &mut Sim,
    controller: &mut Controller,
    path: PathKind,
) -> Result<PathResult, String> {
    let start = sim.true_pose();
    controller.start(path).map_err(|e| format!("start: {e}"))?;
    let max = 1200 * u64::from(sim.config().rate_hz);
    let mut finished: Option<(RunRecord, PoseF64)> = None;
    let stats = sim.run_with(controller, max, |sim, c, _| {
        if let Some(r) = c.take_finished_run() {
            finished = Some((r, sim.pose_at_last_read()));
        }
    });
    if let Some(fault) = controller.fault() {
        return Err(format!("fault: {fault}"));
    }
    let Some((record, end_world)) = finished else {
        return Err(format!("run did not finish ({} periods)", stats.periods));
    };
    sim.rest(controller, u64::from(sim.config().rate_hz) / 2);
    let truth = ArcModel::from_geometry(&sim.config().true_geometry);
    let knots_true = truth.integrate(PoseF64::default(), &record.knots);
    Ok(PathResult {
        path,
        true_end: start.relative(&end_world),
        true_rest: start.relative(&sim.true_pose()),
        record,
        peak_leg_sync_ticks: stats.peak_leg_sync_ticks,
        peak_tracking_ticks: stats.peak_tracking_ticks,
        knots_true,
        periods: stats.periods,
    })
}

/// Command-line arguments of the `square` subcommand.
#[derive(clap::Args, Debug, Clone)]
pub struct SquareArgs {
    /// True E_b of the simulated robot (b_true / b_nominal).
    #[arg(long, default_value_t = 1.010)]
    pub eb: f64,
    /// True E_d of the simulated robot (D_R / D_L).
    #[arg(long, default_value_t = 0.995)]
    pub ed: f64,
    /// Side lengths to drive, metres.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4")]
    pub sides: Vec<f64>,
    /// Relative slip noise per millisecond of travel (standard deviation; per control period at 1 kHz).
    #[arg(long, default_value_t = 0.0)]
    pub slip: f64,
    /// Seed of the slip noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Control rate, Hz: 1000, 2000, 4000, 5000, 8000 or 10000 (the board's `control_hz`).
    #[arg(long = "rate-hz", visible_alias = "rate", default_value_t = odocal::motion::controller::DEFAULT_RATE_HZ, value_parser = crate::commands::parse_rate_hz)]
    pub rate: u32,
}

/// Runs the `square` subcommand: CW and CCW squares of every side, nominal belief.
///
/// # Errors
/// Any failed run.
pub fn run(args: &SquareArgs) -> Result<(), String> {
    let nominal = Geometry::PAPER_NOMINAL;
    let cfg = sim_config(args.ed, args.eb, args.slip, args.seed, args.rate);
    println!(
        "true E_b = {}, E_d = {}; controller believes the nominal geometry; slip σ = {}",
        args.eb, args.ed, args.slip
    );
    println!(
        "{:>5} {:>4} | {:>9} {:>9} | {:>9} {:>9} | {:>9} {:>9} | {:>8} | {:>10}",
        "L m",
        "dir",
        "true x mm",
        "true y mm",
        "odo x mm",
        "odo y mm",
        "err x mm",
        "err y mm",
        "sync tk",
        "knots µm"
    );
    for &side in &args.sides {
        for direction in [Direction::Cw, Direction::Ccw] {
            let r = drive_path(
                cfg,
                nominal,
                PathKind::Square {
                    direction,
                    side_m: side,
                },
            )?;
            let o = r.record.odometry_end;
            println!(
                "{:>5} {:>4} | {:>9.3} {:>9.3} | {:>9.3} {:>9.3} | {:>9.3} {:>9.3} | {:>8.1} | {:>10.3}",
                side,
                direction.as_str(),
                r.true_end.x_m * 1e3,
                r.true_end.y_m * 1e3,
                o.x_m * 1e3,
                o.y_m * 1e3,
                (r.true_end.x_m - o.x_m) * 1e3,
                (r.true_end.y_m - o.y_m) * 1e3,
                r.peak_leg_sync_ticks,
                r.knot_error_m() * 1e6,
            );
        }
    }
    println!("(err = true − odometry at the run's end; sync = peak |wheel sync error| on legs;");
    println!(" knots = |knots integrated with the true geometry − true end position|)");
    Ok(())
}
