//! An independent model of a differential-drive robot driving recorded wheel ticks: the truth
//! of the calibration and odometry accuracy tests. It is written apart from the library and
//! shares none of its arithmetic (`kinematics::reference`, `kinematics::geometry`'s travel per
//! tick and factors, `calibration::synth`, `util::trig`, `libm`), so a slip in the code under test
//! shows as a difference from this model instead of being inverted by the fit that shares it.
//!
//! Between two knots both wheels turn at constant rates, so the wheel midpoint follows a circular
//! arc. With wheel travels `s_R`, `s_L` and wheelbase `b` the heading turns by
//! `φ = (s_R − s_L)/b` and the midpoint travels `s = (s_R + s_L)/2` along the arc, of radius
//! `R = s/φ`. In the frame of the arc's start the end lies at `(R sin φ, R (1 − cos φ))`,
//! i.e. `s · (sin φ / φ, (1 − cos φ) / φ)`, which is then rotated by the start heading into the
//! world. The two ratios come from std's `sin`/`cos`, or below `|φ| = 1e-2` from their Taylor
//! series (first omitted terms `φ⁸/9!` and `φ⁹/10!`, below 1e-21), which avoids the cancellation
//! of `1 − cos φ`. The heading at a knot comes from the tick totals since the start, as on the
//! board (an arc's heading is linear in the wheel travel).

use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;
use odocal::motion::run::{Direction, Measurement};

/// The paper's nominal robot: wheel diameter, metres.
pub const PAPER_DIAMETER_M: f64 = 0.150;
/// The paper's nominal robot: wheelbase, metres.
pub const PAPER_WHEELBASE_M: f64 = 0.385;
/// The paper's nominal robot: encoder counts per wheel revolution.
pub const PAPER_COUNTS_PER_REV: f64 = 200_000.0;

/// Travel per tick of each wheel and the wheelbase of a robot, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Robot {
    /// Right wheel travel per tick.
    pub right_m_per_tick: f64,
    /// Left wheel travel per tick.
    pub left_m_per_tick: f64,
    /// Wheelbase.
    pub wheelbase_m: f64,
}

#[allow(dead_code)] // each test binary uses its own subset
impl Robot {
    /// Wheels of diameters `d_r`, `d_l` (metres) read by `counts_per_rev` encoders, wheelbase
    /// `b`: a wheel travels its circumference `π D` per revolution.
    pub fn new(d_r: f64, d_l: f64, b: f64, counts_per_rev: f64) -> Self {
        Robot {
            right_m_per_tick: std::f64::consts::PI * d_r / counts_per_rev,
            left_m_per_tick: std::f64::consts::PI * d_l / counts_per_rev,
            wheelbase_m: b,
        }
    }

    /// The paper's robot with the factors of DESIGN.md §4: `E_d = D_R/D_L`, `E_b = b/b_nominal`,
    /// `E_s = D_a/D_a,nominal`, the mean diameter `D_a = (D_R + D_L)/2` kept by `E_d`; solved
    /// for the diameters, `D_R = 2 D_a E_d/(1 + E_d)` and `D_L = 2 D_a/(1 + E_d)`.
    pub fn paper(e_d: f64, e_b: f64, e_s: f64) -> Self {
        let d_a = e_s * PAPER_DIAMETER_M;
        Robot::new(
            2.0 * d_a * e_d / (1.0 + e_d),
            2.0 * d_a / (1.0 + e_d),
            e_b * PAPER_WHEELBASE_M,
            PAPER_COUNTS_PER_REV,
        )
    }

    /// The robot whose dimensions a library [`Geometry`] holds (its fields only).
    pub fn of(g: &Geometry) -> Self {
        Robot::new(
            g.diameter_right_m,
            g.diameter_left_m,
            g.wheelbase_m,
            f64::from(g.counts_per_rev),
        )
    }

    /// Heading change over `ticks` (right, left) of wheel rotation, radians.
    pub fn turn(&self, right_ticks: i64, left_ticks: i64) -> f64 {
        (self.right_m_per_tick * right_ticks as f64 - self.left_m_per_tick * left_ticks as f64)
            / self.wheelbase_m
    }

    /// The pose at every knot of `knots` (cumulative ticks, the first one at `start`).
    pub fn path(&self, start: PoseF64, knots: &[WheelTicks]) -> Vec<PoseF64> {
        let Some(first) = knots.first() else {
            return Vec::new();
        };
        let mut poses = Vec::with_capacity(knots.len());
        poses.push(start);
        let mut pose = start;
        for w in knots.windows(2) {
            pose = self.arc(pose, first, &w[0], &w[1], start.theta_rad);
            poses.push(pose);
        }
        poses
    }

    /// The pose at the last knot of `knots` (cumulative ticks, the first one at `start`).
    pub fn drive(&self, start: PoseF64, knots: &[WheelTicks]) -> PoseF64 {
        let Some(first) = knots.first() else {
            return start;
        };
        let mut pose = start;
        for w in knots.windows(2) {
            pose = self.arc(pose, first, &w[0], &w[1], start.theta_rad);
        }
        pose
    }

    /// One arc from `pose` at knot `a` to knot `b`; headings from the totals since `first`.
    fn arc(
        &self,
        pose: PoseF64,
        first: &WheelTicks,
        a: &WheelTicks,
        b: &WheelTicks,
        theta_start: f64,
    ) -> PoseF64 {
        let s_r = self.right_m_per_tick * (b.right - a.right) as f64;
        let s_l = self.left_m_per_tick * (b.left - a.left) as f64;
        let s = 0.5 * (s_r + s_l);
        let theta_end = theta_start + self.turn(b.right - first.right, b.left - first.left);
        let phi = theta_end - pose.theta_rad;
        let (along, across) = arc_ratios(phi);
        let (sin0, cos0) = pose.theta_rad.sin_cos();
        let (fwd, left) = (s * along, s * across);
        PoseF64::new(
            pose.x_m + fwd * cos0 - left * sin0,
            pose.y_m + fwd * sin0 + left * cos0,
            theta_end,
        )
    }
}

/// `(sin φ / φ, (1 − cos φ) / φ)`: the end of a unit-length arc turning by `φ`, in its start frame.
fn arc_ratios(phi: f64) -> (f64, f64) {
    if phi.abs() < 1e-2 {
        let p2 = phi * phi;
        (
            1.0 - p2 / 6.0 * (1.0 - p2 / 20.0 * (1.0 - p2 / 42.0)),
            phi / 2.0 * (1.0 - p2 / 12.0 * (1.0 - p2 / 30.0 * (1.0 - p2 / 56.0))),
        )
    } else {
        let (s, c) = phi.sin_cos();
        (s / phi, (1.0 - c) / phi)
    }
}

/// The knots of a square run of side `side_m` (4 legs, each followed by an in-place quarter
/// turn), commanded by odometry that believes `belief`: a leg is `L` of travel per wheel, a turn
/// `±(π/2)(b/2)` (right wheel forward for CCW), each rounded to whole ticks of that wheel.
#[allow(dead_code)] // each test binary uses its own subset
pub fn square_knots(belief: &Robot, direction: Direction, side_m: f64) -> Vec<WheelTicks> {
    let sign = match direction {
        Direction::Ccw => 1.0,
        Direction::Cw => -1.0,
    };
    let arc = sign * std::f64::consts::FRAC_PI_2 * belief.wheelbase_m / 2.0;
    let leg = (
        (side_m / belief.right_m_per_tick).round() as i64,
        (side_m / belief.left_m_per_tick).round() as i64,
    );
    let turn = (
        (arc / belief.right_m_per_tick).round() as i64,
        (-arc / belief.left_m_per_tick).round() as i64,
    );
    let mut knots = vec![WheelTicks::new(0, 0)];
    let (mut r, mut l) = (0, 0);
    for _ in 0..4 {
        for (dr, dl) in [leg, turn] {
            (r, l) = (r + dr, l + dl);
            knots.push(WheelTicks::new(r, l));
        }
    }
    knots
}

/// The end pose of `knots` as a measurement of the true robot (x, y and θ, no noise).
#[allow(dead_code)] // each test binary uses its own subset
pub fn measure(truth: &Robot, start: PoseF64, knots: &[WheelTicks]) -> Measurement {
    let end = truth.drive(start, knots);
    Measurement {
        x_m: end.x_m,
        y_m: end.y_m,
        theta_rad: Some(end.theta_rad),
    }
}

/// The largest `|v|` of `values`, NaN if any is NaN (where `f64::max` would drop it), so that a
/// bound `worst_abs(…) < tol` fails on a NaN.
#[allow(dead_code)] // each test binary uses its own subset
pub fn worst_abs(values: impl IntoIterator<Item = f64>) -> f64 {
    values.into_iter().fold(0.0, |worst, v| {
        if worst.is_nan() || v.is_nan() {
            f64::NAN
        } else {
            worst.max(v.abs())
        }
    })
}
