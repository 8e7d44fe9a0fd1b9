//! The `square` subcommand: UMBmark squares (and lines, circles) driven closed-loop by the
//! library's [`Controller`] through the simulated robot, with the numbers the motion issue asks
//! for: true and odometry end poses, the peak wheel synchronisation error during legs, and how
//! well the run record's knots re-integrate to the true end pose.

use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::{ArcModel, PoseF64};
use odocal::motion::controller::Controller;
use odocal::motion::run::{Direction, PathKind, RunRecord};
use odocal::motion::speed::SpeedTuning;

use crate::sim::robot::{Sim, SimConfig, default_controller};

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

/// `E_max,syst = max(|cg_cw|, |cg_ccw|)` of end errors, and their pooled scatter
/// `sqrt(Σ|e − cg|² / (n − 2))` (0 with fewer than three runs).
pub fn e_max_and_scatter(ends: &[(Direction, f64, f64)]) -> (f64, f64) {
    let mut e_max: f64 = 0.0;
    let mut ss = 0.0;
    let mut n = 0usize;
    for dir in [Direction::Cw, Direction::Ccw] {
        let pts: Vec<(f64, f64)> = ends
            .iter()
            .filter(|e| e.0 == dir)
            .map(|e| (e.1, e.2))
            .collect();
        if pts.is_empty() {
            continue;
        }
        let k = pts.len() as f64;
        let cx = pts.iter().map(|p| p.0).sum::<f64>() / k;
        let cy = pts.iter().map(|p| p.1).sum::<f64>() / k;
        e_max = e_max.max(cx.hypot(cy));
        ss += pts
            .iter()
            .map(|p| (p.0 - cx).powi(2) + (p.1 - cy).powi(2))
            .sum::<f64>();
        n += pts.len();
    }
    let scatter = if n >= 3 {
        (ss / (n - 2) as f64).sqrt()
    } else {
        0.0
    };
    (e_max, scatter)
}
