//! Square runs for the calibration tests: commanded from the nominal geometry, driven by a
//! true robot of the independent arc model (`support/arcs.rs`), measured with seeded normal
//! noise; and the records the board stores for them. The including test declares the `arcs`
//! and `rng` modules.

#![allow(dead_code)] // each test binary uses its own subset

use super::arcs::{self, Robot};
use super::rng::Rng;
use odocal::calibration::RunObservation;
use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;
use odocal::motion::run::{Direction, Measurement, PathKind, RunRecord};

pub const NOMINAL: Geometry = Geometry::PAPER_NOMINAL;
pub const SIDE_M: f64 = 2.0;

/// A normal deviate (Box–Muller).
pub fn normal(rng: &mut Rng) -> f64 {
    let u1: f64 = ((rng.next() >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let u2 = (rng.next() >> 11) as f64 / (1u64 << 53) as f64;
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

pub struct Run {
    pub direction: Direction,
    pub side_m: f64,
    pub knots: Vec<WheelTicks>,
    pub odo: PoseF64,
    pub measured: Measurement,
}

impl Run {
    /// A square commanded from the nominal geometry, driven by `truth`; the true path starts
    /// turned by `slip_rad` (the wheels spun in the first jerk), and the tape measure adds
    /// `sigma_m` / `sigma_rad` of normal noise.
    pub fn square(
        truth: &Robot,
        direction: Direction,
        slip_rad: f64,
        sigma_m: f64,
        sigma_rad: f64,
        rng: &mut Rng,
    ) -> Self {
        Run::square_of(
            SIDE_M,
            truth,
            direction,
            slip_rad,
            (sigma_m, sigma_rad),
            rng,
        )
    }

    /// [`Run::square`] of side `side_m`, measured with `(sigma_m, sigma_rad)` of noise.
    pub fn square_of(
        side_m: f64,
        truth: &Robot,
        direction: Direction,
        slip_rad: f64,
        (sigma_m, sigma_rad): (f64, f64),
        rng: &mut Rng,
    ) -> Self {
        let nominal = Robot::of(&NOMINAL);
        let knots = arcs::square_knots(&nominal, direction, side_m);
        let odo = nominal.drive(PoseF64::default(), &knots);
        let t = truth.drive(PoseF64::new(0.0, 0.0, slip_rad), &knots);
        Run {
            direction,
            side_m,
            knots,
            odo,
            measured: Measurement {
                x_m: t.x_m + sigma_m * normal(rng),
                y_m: t.y_m + sigma_m * normal(rng),
                theta_rad: Some(t.theta_rad + sigma_rad * normal(rng)),
            },
        }
    }

    pub fn obs(&self) -> RunObservation<'_> {
        RunObservation {
            path: PathKind::Square {
                direction: self.direction,
                side_m: self.side_m,
            },
            geometry: NOMINAL,
            knots: &self.knots,
            odometry_end: self.odo,
            measured: self.measured,
            truth_path: &[],
        }
    }
}

/// The runs as the board stores them, run `i` (0-based) as `runs` would number it `i + 1`.
pub fn records(runs: &[Run]) -> Vec<RunRecord> {
    runs.iter()
        .map(|r| RunRecord {
            path: r.obs().path,
            geometry: NOMINAL,
            knots: heapless::Vec::from_slice(&r.knots).unwrap(),
            odometry_end: r.odo,
            measured: Some(r.measured),
        })
        .collect()
}

/// 3 + 3 squares of 2 m, CW and CCW alternating, on the robot of the unit slip that went
/// unnoticed (E_d = 0.995, E_b = 1.010), measured to 1 mm and 0.2° (noise seed `seed`).
pub fn six_squares(seed: u64) -> Vec<Run> {
    let truth = Robot::paper(0.995, 1.010, 1.0);
    let mut rng = Rng(seed);
    (0..6)
        .map(|i| {
            let d = if i % 2 == 0 {
                Direction::Cw
            } else {
                Direction::Ccw
            };
            Run::square(&truth, d, 0.0, 1e-3, 0.2f64.to_radians(), &mut rng)
        })
        .collect()
}
