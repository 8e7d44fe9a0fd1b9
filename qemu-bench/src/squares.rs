//! A fixed set of recorded UMBmark runs: 5 CW + 5 CCW squares of 4 m, with tick knots as the
//! firmware records them (start + 12 knots per segment = 97 of `run::MAX_KNOTS`), odometry end
//! poses and measured true end poses.
//!
//! The robot believes in the paper's nominal geometry and really has `E_d = 0.9975`,
//! `E_b = 1.0143`. Knots inside a segment carry a deterministic wheel-speed wobble of up to ±20
//! ticks (the path is not made of ideal lines); the measurements carry deterministic noise of
//! ±1 mm in x and y and ±0.1° in θ. The numbers are derived in integer arithmetic from a
//! xorshift32 generator and turned into `f64` by exact conversions, and the end poses are
//! integrated with `reference::ArcModel` through `libm`, so host and target build the same
//! inputs (the fixture checksum line shows it).

use odocal::calibration::RunObservation;
use odocal::calibration::synth::square_segments;
use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::{ArcModel, PoseF64};
use odocal::motion::run::{Direction, Measurement, PathKind};

/// Number of runs (CW, CCW alternating).
pub const RUNS: usize = 10;
/// Knots per segment (as the firmware records).
pub const KNOTS_PER_SEGMENT: usize = 12;
/// Knots per run: the start plus 8 segments.
pub const KNOTS: usize = 1 + 8 * KNOTS_PER_SEGMENT;
/// Side of the squares, metres.
pub const SIDE_M: f64 = 4.0;
/// The true diameter ratio.
pub const TRUE_E_D: f64 = 0.9975;
/// The true wheelbase factor.
pub const TRUE_E_B: f64 = 1.0143;

const SEED: u32 = 0x5EED_0B5E;

/// The nominal geometry, which is also what the robot believed while driving.
pub fn nominal() -> Geometry {
    Geometry::PAPER_NOMINAL
}

/// The geometry the runs were really driven with.
pub fn truth() -> Geometry {
    Geometry::PAPER_NOMINAL.with_factors(TRUE_E_D, TRUE_E_B, 1.0)
}

/// The recorded runs.
#[derive(Clone, Debug)]
pub struct SquareRuns {
    knots: [[WheelTicks; KNOTS]; RUNS],
    odometry_end: [PoseF64; RUNS],
    measured: [Measurement; RUNS],
}

struct Rng(u32);

impl Rng {
    fn next_u32(&mut self) -> u32 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.0 = x;
        x
    }

    /// Uniform integer in `-a..=a`.
    fn symmetric(&mut self, a: i64) -> i64 {
        i64::from(self.next_u32()) % (2 * a + 1) - a
    }

    /// Uniform in `[-a, a)` (the conversion of a 32-bit integer is exact).
    fn symmetric_f64(&mut self, a: f64) -> f64 {
        (f64::from(self.next_u32()) / 4_294_967_296.0 - 0.5) * 2.0 * a
    }
}

impl SquareRuns {
    /// Builds the fixture.
    pub fn generate() -> Self {
        let belief = nominal();
        let truth_model = ArcModel::from_geometry(&truth());
        let belief_model = ArcModel::from_geometry(&belief);
        let mut rng = Rng(SEED);
        let mut runs = SquareRuns {
            knots: [[WheelTicks::default(); KNOTS]; RUNS],
            odometry_end: [PoseF64::default(); RUNS],
            measured: [Measurement {
                x_m: 0.0,
                y_m: 0.0,
                theta_rad: None,
            }; RUNS],
        };
        for run in 0..RUNS {
            let segments = square_segments(&belief, direction(run), SIDE_M);
            let knots = &mut runs.knots[run];
            let mut start = WheelTicks::default();
            let mut k = 1;
            for s in segments {
                for j in 1..=KNOTS_PER_SEGMENT as i64 {
                    let n = KNOTS_PER_SEGMENT as i64;
                    let wobble = if j < n { rng.symmetric(20) } else { 0 };
                    knots[k] = WheelTicks::new(
                        start.right + s.right * j / n + wobble,
                        start.left + s.left * j / n - wobble,
                    );
                    k += 1;
                }
                start = knots[k - 1];
            }
            runs.odometry_end[run] = belief_model.integrate(PoseF64::default(), knots);
            let t = truth_model.integrate(PoseF64::default(), knots);
            runs.measured[run] = Measurement {
                x_m: t.x_m + rng.symmetric_f64(1e-3),
                y_m: t.y_m + rng.symmetric_f64(1e-3),
                theta_rad: Some(t.theta_rad + rng.symmetric_f64(0.1f64.to_radians())),
            };
        }
        runs
    }

    /// The runs as the calibration engine takes them.
    pub fn observations(&self) -> [RunObservation<'_>; RUNS] {
        core::array::from_fn(|run| RunObservation {
            path: PathKind::Square {
                direction: direction(run),
                side_m: SIDE_M,
            },
            geometry: nominal(),
            knots: &self.knots[run],
            odometry_end: self.odometry_end[run],
            measured: self.measured[run],
            truth_path: &[],
        })
    }

    /// The runs as the firmware's session stores them (measured, driven with the nominal
    /// geometry).
    pub fn records(&self) -> impl Iterator<Item = odocal::motion::run::RunRecord> + '_ {
        (0..RUNS).map(|run| odocal::motion::run::RunRecord {
            path: PathKind::Square {
                direction: direction(run),
                side_m: SIDE_M,
            },
            geometry: nominal(),
            knots: self.knots[run].iter().copied().collect(),
            odometry_end: self.odometry_end[run],
            measured: Some(self.measured[run]),
        })
    }

    /// XOR of the bits of every end pose and measurement: equal on host and target iff the
    /// fixture is.
    pub fn checksum(&self) -> u64 {
        let mut h = 0u64;
        for run in 0..RUNS {
            let o = &self.odometry_end[run];
            let m = &self.measured[run];
            for v in [
                o.x_m,
                o.y_m,
                o.theta_rad,
                m.x_m,
                m.y_m,
                m.theta_rad.unwrap_or(0.0),
            ] {
                h = h.rotate_left(7) ^ v.to_bits();
            }
        }
        h
    }
}

fn direction(run: usize) -> Direction {
    if run.is_multiple_of(2) {
        Direction::Cw
    } else {
        Direction::Ccw
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn knots_end_where_the_segments_end_and_fit_a_record() {
        const { assert!(KNOTS <= odocal::motion::run::MAX_KNOTS) };
        let runs = SquareRuns::generate();
        let seg = square_segments(&nominal(), Direction::Cw, SIDE_M);
        let mut end = WheelTicks::default();
        for s in seg {
            end = WheelTicks::new(end.right + s.right, end.left + s.left);
        }
        assert_eq!(runs.knots[0][KNOTS - 1], end);
        // The measured end differs from the odometry's by the systematic error of a few cm.
        let e = runs.observations()[0].error();
        assert!(e.0.abs() < 0.5 && e.1.abs() < 0.5, "{e:?}");
    }
}
