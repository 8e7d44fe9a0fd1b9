//! `f64` exact-arc integration of wheel ticks.
//!
//! This is the reference the fixed-point [`crate::kinematics::odometry`] is measured against, and the model
//! the exact calibration fits: between two samples the wheels are assumed to turn at a constant
//! ratio, so the robot follows a circular arc (or a straight line, or turns in place). With
//! `Δd = (Δd_R + Δd_L)/2` and `Δθ = (Δd_R − Δd_L)/b` (paper eq. 2–4):
//!
//! ```text
//! x += Δd · sinc(Δθ/2) · cos(θ + Δθ/2)
//! y += Δd · sinc(Δθ/2) · sin(θ + Δθ/2)
//! ```
//!
//! which is exact for an arc; the paper's eq. (1) is the same with `sinc = 1` (midpoint rule).
//! Heading is always computed from the tick totals, never accumulated.
//! All trigonometry goes through `util::trig` and `libm`, so host and target compute the same bits.

use core::ops::{Add, Div, Mul, Sub};

use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::geometry::Geometry;
use crate::util::trig;

/// A planar pose in `f64`: metres and radians, frame as in the crate docs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct PoseF64 {
    /// x, metres.
    pub x_m: f64,
    /// y, metres.
    pub y_m: f64,
    /// Heading, radians (not wrapped).
    pub theta_rad: f64,
}

impl PoseF64 {
    /// A pose.
    pub const fn new(x_m: f64, y_m: f64, theta_rad: f64) -> Self {
        PoseF64 {
            x_m,
            y_m,
            theta_rad,
        }
    }

    /// Euclidean distance of the positions, metres.
    pub fn distance_to(&self, other: &PoseF64) -> f64 {
        libm::hypot(self.x_m - other.x_m, self.y_m - other.y_m)
    }

    /// Expresses `world` (a pose in the frame where `self` is given) in the frame of `self`.
    pub fn relative(&self, world: &PoseF64) -> PoseF64 {
        let (s, c) = trig::sincos(self.theta_rad);
        let dx = world.x_m - self.x_m;
        let dy = world.y_m - self.y_m;
        PoseF64::new(
            c * dx + s * dy,
            -s * dx + c * dy,
            world.theta_rad - self.theta_rad,
        )
    }
}

/// `sin(u)/u`, accurate for all `u` (series near 0).
#[inline]
pub fn sinc(u: f64) -> f64 {
    if libm::fabs(u) < 1e-4 {
        let u2 = u * u;
        1.0 - u2 / 6.0 + u2 * u2 / 120.0
    } else {
        trig::sin(u) / u
    }
}

/// The three numbers the arc model needs: travel per tick of each wheel and the wheelbase.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArcModel {
    /// Right wheel travel per tick, metres.
    pub right_m_per_tick: f64,
    /// Left wheel travel per tick, metres.
    pub left_m_per_tick: f64,
    /// Wheelbase, metres.
    pub wheelbase_m: f64,
}

impl ArcModel {
    /// The model of a geometry.
    pub fn from_geometry(g: &Geometry) -> Self {
        ArcModel {
            right_m_per_tick: g.meters_per_tick_right(),
            left_m_per_tick: g.meters_per_tick_left(),
            wheelbase_m: g.wheelbase_m,
        }
    }

    /// Heading change for tick totals (relative to a start where both were 0), radians.
    #[inline]
    pub fn heading(&self, totals: WheelTicks) -> f64 {
        arc_heading(
            self.right_m_per_tick,
            self.left_m_per_tick,
            self.wheelbase_m,
            totals,
        )
    }

    /// Integrates a sequence of cumulative tick knots from `start`; the first knot is the tick
    /// total at `start`. Each interval is one exact arc.
    pub fn integrate(&self, start: PoseF64, knots: &[WheelTicks]) -> PoseF64 {
        let (x, y, theta) = integrate_arcs(
            (
                self.right_m_per_tick,
                self.left_m_per_tick,
                self.wheelbase_m,
            ),
            (start.x_m, start.y_m, start.theta_rad),
            knots,
        );
        PoseF64::new(x, y, theta)
    }
}

/// The number type of an arc integration: [`ArcModel`] integrates in `f64`, [`ArcModelF32`] in
/// `f32`, with the same operations in the same order ([`integrate_arcs`]).
trait ArcFloat:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self>
{
    /// One half.
    const HALF: Self;
    /// A tick count (difference) as this type.
    fn from_ticks(t: i64) -> Self;
    /// `(sin self, cos self)`.
    fn sin_cos(self) -> (Self, Self);
    /// `sin(self)/self`.
    fn sinc(self) -> Self;
}

impl ArcFloat for f64 {
    const HALF: f64 = 0.5;
    fn from_ticks(t: i64) -> f64 {
        t as f64
    }
    fn sin_cos(self) -> (f64, f64) {
        trig::sincos(self)
    }
    fn sinc(self) -> f64 {
        sinc(self)
    }
}

impl ArcFloat for f32 {
    const HALF: f32 = 0.5;
    fn from_ticks(t: i64) -> f32 {
        t as f32
    }
    fn sin_cos(self) -> (f32, f32) {
        trig::sincos_f32(self)
    }
    fn sinc(self) -> f32 {
        sinc_f32(self)
    }
}

/// Heading change for tick totals (relative to a start where both were 0) of wheels travelling
/// `right`, `left` per tick on a wheelbase `b`, radians.
#[inline]
fn arc_heading<F: ArcFloat>(right: F, left: F, b: F, totals: WheelTicks) -> F {
    (right * F::from_ticks(totals.right) - left * F::from_ticks(totals.left)) / b
}

/// The arcs through cumulative tick `knots` (the first is the total at `start`) of the model
/// `(right, left, b)` (travel per tick of each wheel, wheelbase) from `start` `(x, y, θ)`: the
/// end `(x, y, θ)`. Each interval is one exact arc.
#[inline]
fn integrate_arcs<F: ArcFloat>(
    (right, left, b): (F, F, F),
    (mut x, mut y, theta_start): (F, F, F),
    knots: &[WheelTicks],
) -> (F, F, F) {
    let Some(first) = knots.first() else {
        return (x, y, theta_start);
    };
    let mut prev = *first;
    let mut theta_prev = theta_start;
    for &k in &knots[1..] {
        let theta = theta_start + arc_heading(right, left, b, k - *first);
        let d = k - prev;
        let ds = F::HALF * (right * F::from_ticks(d.right) + left * F::from_ticks(d.left));
        let dtheta = theta - theta_prev;
        let chord = ds * (F::HALF * dtheta).sinc();
        let (s, c) = (theta_prev + F::HALF * dtheta).sin_cos();
        x = x + chord * c;
        y = y + chord * s;
        prev = k;
        theta_prev = theta;
    }
    (x, y, theta_prev)
}

/// A planar pose in `f32`, as [`PoseF64`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PoseF32 {
    /// x, metres.
    pub x_m: f32,
    /// y, metres.
    pub y_m: f32,
    /// Heading, radians (not wrapped).
    pub theta_rad: f32,
}

/// `sin(u)/u` in `f32` (series below |u| = 1e-2, whose first omitted term `u⁶/5040` is 2e-16
/// there, far below `f32`'s 6e-8).
#[inline]
fn sinc_f32(u: f32) -> f32 {
    if libm::fabsf(u) < 1e-2 {
        let u2 = u * u;
        1.0 - u2 / 6.0 + u2 * u2 / 120.0
    } else {
        trig::sincos_f32(u).0 / u
    }
}

/// [`ArcModel`] in `f32`: the same arcs, with the model's numbers, the tick differences, the
/// heading and the positions in single precision (the Cortex-M4F's FPU). It serves the exact
/// calibration's finite-difference Jacobian, which only steers the fit (see
/// `calibration::exact`); the residuals the fit minimises are [`ArcModel`]'s.
///
/// Sine and cosine are [`trig::sincos_f32`]'s, `f32` kernels within 1.2e-7 of the true values.
/// Precision: a tick total converts exactly below 2²⁴ ticks and to 2⁻²⁴ relative above; the
/// heading, computed from the totals as in [`ArcModel`], is good to a few `f32` ulps of the
/// wheels' travel over the wheelbase; every interval adds one rounding of the positions, so an
/// end pose after ~100 knots is good to about 1e-7 m per metre travelled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArcModelF32 {
    /// Right wheel travel per tick, metres.
    pub right_m_per_tick: f32,
    /// Left wheel travel per tick, metres.
    pub left_m_per_tick: f32,
    /// Wheelbase, metres.
    pub wheelbase_m: f32,
}

impl ArcModelF32 {
    /// `model` rounded to `f32`.
    pub fn from_model(model: &ArcModel) -> Self {
        ArcModelF32 {
            right_m_per_tick: model.right_m_per_tick as f32,
            left_m_per_tick: model.left_m_per_tick as f32,
            wheelbase_m: model.wheelbase_m as f32,
        }
    }

    /// Heading change for tick totals (relative to a start where both were 0), radians.
    #[inline]
    pub fn heading(&self, totals: WheelTicks) -> f32 {
        arc_heading(
            self.right_m_per_tick,
            self.left_m_per_tick,
            self.wheelbase_m,
            totals,
        )
    }

    /// As [`ArcModel::integrate`].
    pub fn integrate(&self, start: PoseF32, knots: &[WheelTicks]) -> PoseF32 {
        let (x_m, y_m, theta_rad) = integrate_arcs(
            (
                self.right_m_per_tick,
                self.left_m_per_tick,
                self.wheelbase_m,
            ),
            (start.x_m, start.y_m, start.theta_rad),
            knots,
        );
        PoseF32 {
            x_m,
            y_m,
            theta_rad,
        }
    }
}

#[cfg(test)]
mod tests {
    use core::f64::consts::PI;

    use super::*;

    fn model() -> ArcModel {
        ArcModel::from_geometry(&Geometry::PAPER_NOMINAL)
    }

    #[test]
    fn one_arc_equals_many_small_arcs() {
        let m = model();
        let knots = [WheelTicks::new(0, 0), WheelTicks::new(300_000, 200_000)];
        let one = m.integrate(PoseF64::default(), &knots);
        let many: heapless::Vec<WheelTicks, 1001> = (0..=1000)
            .map(|i| WheelTicks::new(300 * i, 200 * i))
            .collect();
        let fine = m.integrate(PoseF64::default(), &many);
        assert!(one.distance_to(&fine) < 1e-12);
        assert!((one.theta_rad - fine.theta_rad).abs() < 1e-15);
    }

    #[test]
    fn quarter_circle_closed_form() {
        // Left wheel still, right wheel drives a quarter circle of radius b around the left wheel.
        let m = model();
        let b = m.wheelbase_m;
        let ticks = (0.5 * PI * b / m.right_m_per_tick).round() as i64;
        let end = m.integrate(
            PoseF64::default(),
            &[WheelTicks::new(0, 0), WheelTicks::new(ticks, 0)],
        );
        let theta = m.heading(WheelTicks::new(ticks, 0));
        let r = b / 2.0;
        assert!((end.x_m - r * theta.sin()).abs() < 1e-12);
        assert!((end.y_m - r * (1.0 - theta.cos())).abs() < 1e-12);
    }

    /// The `f32` model follows the `f64` one to `f32` precision: a 1 m square (4 × 25 knots) of
    /// the paper's robot ends within 1e-6 m and 1e-6 rad of the `f64` end pose (about 16 `f32`
    /// ulps of the 4 m travelled).
    #[test]
    fn f32_model_follows_f64() {
        let m = model();
        let side = (1.0 / m.right_m_per_tick).round() as i64;
        let turn = (0.25 * PI * m.wheelbase_m / m.right_m_per_tick).round() as i64;
        let mut knots = heapless::Vec::<WheelTicks, 128>::new();
        let (mut r, mut l) = (0, 0);
        knots.push(WheelTicks::new(r, l)).unwrap();
        for _ in 0..4 {
            for i in 1..=20 {
                knots
                    .push(WheelTicks::new(r + side * i / 20, l + side * i / 20))
                    .unwrap();
            }
            (r, l) = (r + side, l + side);
            for i in 1..=5 {
                knots
                    .push(WheelTicks::new(r + turn * i / 5, l - turn * i / 5))
                    .unwrap();
            }
            (r, l) = (r + turn, l - turn);
        }
        let exact = m.integrate(PoseF64::default(), &knots);
        let single = ArcModelF32::from_model(&m).integrate(PoseF32::default(), &knots);
        assert!(
            (exact.x_m - f64::from(single.x_m)).abs() < 1e-6,
            "{exact:?} {single:?}"
        );
        assert!(
            (exact.y_m - f64::from(single.y_m)).abs() < 1e-6,
            "{exact:?} {single:?}"
        );
        assert!((exact.theta_rad - f64::from(single.theta_rad)).abs() < 1e-6);
        // The square closes: the f64 end pose is near the start and has turned once.
        assert!(exact.x_m.abs() < 1e-2 && exact.y_m.abs() < 1e-2);
        assert!((exact.theta_rad - 2.0 * PI).abs() < 1e-2);
    }

    #[test]
    fn relative_pose_round_trip() {
        let origin = PoseF64::new(1.0, 2.0, 0.5);
        let p = origin.relative(&PoseF64::new(1.0 + 0.5f64.cos(), 2.0 + 0.5f64.sin(), 0.7));
        assert!((p.x_m - 1.0).abs() < 1e-12 && p.y_m.abs() < 1e-12);
        assert!((p.theta_rad - 0.2).abs() < 1e-12);
    }
}
