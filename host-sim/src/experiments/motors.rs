//! The motors experiment (`host-sim motors`): motor identification on simulated robots whose motors differ from
//! the defaults the speed loops are tuned for (gain ×0.5 and ×2, time constant ×0.5 and ×3,
//! with a dead-band), and what the identified tuning changes on the floor.
//!
//! Per robot: `identify lifted` on a fresh simulated board (the library's routine through the
//! serial protocol), the identified parameters against the simulated ones; then 5 + 5 squares
//! with the default tuning and the same squares (same slip noise) with the identified one: the
//! peak wheel synchronisation error on the legs and the end-pose scatter (UMBmark's clusters),
//! side by side.

use odocal::kinematics::geometry::Geometry;
use odocal::motion::identify::IdentifyMode;
use odocal::motion::run::{Direction, PathKind};
use odocal::motion::speed::{MotorParams, SpeedTuning};

use crate::experiments::square::drive_path_tuned;
use crate::experiments::square::e_max_and_scatter;
use crate::sim::board::Board;
use crate::sim::flash::SimParamFlash;
use crate::sim::robot::{MotorModel, SimConfig};

/// A simulated robot's motors: per wheel (right, left) full-duty speed above the dead-band
/// (m/s), time constant (s), dead-band (duty).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorCase {
    /// Short description.
    pub name: &'static str,
    /// Gains, m/s per unit duty.
    pub gain_mps: (f64, f64),
    /// Time constants, s.
    pub tau_s: (f64, f64),
    /// Dead-bands, duty.
    pub deadband: (f64, f64),
}

/// The four robots of the issue: gain ×0.5 and ×2 against the default 1 m/s, time constant
/// ×0.5 and ×3 against the default 50 ms, each with a dead-band, and the two wheels of a robot
/// unequal (as real motors are).
pub const CASES: [MotorCase; 4] = [
    MotorCase {
        name: "gain x0.5, tau x0.5",
        gain_mps: (0.5, 0.45),
        tau_s: (0.025, 0.03),
        deadband: (0.05, 0.06),
    },
    MotorCase {
        name: "gain x0.5, tau x3",
        gain_mps: (0.5, 0.55),
        tau_s: (0.15, 0.13),
        deadband: (0.05, 0.04),
    },
    MotorCase {
        name: "gain x2, tau x0.5",
        gain_mps: (2.0, 1.8),
        tau_s: (0.025, 0.028),
        deadband: (0.06, 0.05),
    },
    MotorCase {
        name: "gain x2, tau x3",
        gain_mps: (2.0, 2.2),
        tau_s: (0.15, 0.16),
        deadband: (0.08, 0.06),
    },
];

impl MotorCase {
    /// The simulated robot: the paper's nominal geometry (true = believed, so the identified
    /// gains compare with the simulated ones directly), these motors, `slip`, `seed`.
    pub fn sim_config(&self, slip: f64, seed: u64) -> SimConfig {
        let g = Geometry::PAPER_NOMINAL;
        let mut c = SimConfig::new(g, 1000);
        c.motor = MotorModel::per_wheel(
            self.gain_mps,
            g.mean_diameter_m(),
            self.tau_s,
            self.deadband,
        );
        c.slip_sigma = slip;
        c.seed = seed;
        c
    }

    /// The simulated motor of one wheel as the speed loop's parameters (both directions equal).
    pub fn truth(&self, right: bool) -> MotorParams {
        let pick = |p: (f64, f64)| (if right { p.0 } else { p.1 }) as f32;
        MotorParams {
            gain_forward_mps: pick(self.gain_mps),
            gain_backward_mps: pick(self.gain_mps),
            time_constant_s: pick(self.tau_s),
            deadband: pick(self.deadband),
        }
    }
}

/// Largest relative error of `est` against `truth` over gain (both directions), time constant
/// and dead-band; NaN if any of them is NaN (never dropped, so a `< bound` check fails).
pub fn worst_relative_error(est: &MotorParams, truth: &MotorParams) -> f64 {
    let rel = |e: f32, t: f32| (f64::from(e) - f64::from(t)).abs() / f64::from(t);
    [
        rel(est.gain_forward_mps, truth.gain_forward_mps),
        rel(est.gain_backward_mps, truth.gain_backward_mps),
        rel(est.time_constant_s, truth.time_constant_s),
        rel(est.deadband, truth.deadband),
    ]
    .into_iter()
    .fold(0.0, |worst, e| {
        if worst.is_nan() || e.is_nan() {
            f64::NAN
        } else {
            worst.max(e)
        }
    })
}

/// Runs `identify lifted` on a fresh simulated board with these motors; the tuning it applied.
///
/// # Errors
/// The board's text when the identification fails.
pub fn identify(case: &MotorCase) -> Result<SpeedTuning, String> {
    let mut flash = SimParamFlash::erased();
    let mut out = String::new();
    let mut board = Board::boot(case.sim_config(0.0, 1), &mut flash, &mut out)?;
    board.identify(IdentifyMode::Lifted)?;
    Ok(board.session.settings().tuning)
}

/// 5 + 5 squares of `side_m` with `tuning`, slip `slip` (seeds shared between tunings).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SquareFigures {
    /// Largest |wheel synchronisation error| on the legs of all squares, ticks.
    pub peak_sync_ticks: f64,
    /// Scatter of the end errors around their CW/CCW centres of gravity, metres.
    pub scatter_m: f64,
    /// `E_max,syst` of the squares, metres.
    pub e_max_m: f64,
}

/// Drives the squares (see [`SquareFigures`]).
///
/// # Errors
/// A failed run.
pub fn squares(
    case: &MotorCase,
    tuning: SpeedTuning,
    side_m: f64,
    slip: f64,
) -> Result<SquareFigures, String> {
    let mut ends = Vec::new();
    let mut peak: f64 = 0.0;
    for (d, direction) in [Direction::Cw, Direction::Ccw].into_iter().enumerate() {
        for i in 0..5u64 {
            let c = case.sim_config(slip, 100 + 10 * d as u64 + i);
            let r = drive_path_tuned(
                c,
                Geometry::PAPER_NOMINAL,
                tuning,
                PathKind::Square { direction, side_m },
            )?;
            peak = peak.max(r.peak_leg_sync_ticks);
            let o = r.record.odometry_end;
            ends.push((direction, r.true_end.x_m - o.x_m, r.true_end.y_m - o.y_m));
        }
    }
    let (e_max_m, scatter_m) = e_max_and_scatter(&ends);
    Ok(SquareFigures {
        peak_sync_ticks: peak,
        scatter_m,
        e_max_m,
    })
}
