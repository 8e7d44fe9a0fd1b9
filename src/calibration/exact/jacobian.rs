//! The analytic Jacobian of an end pose: the derivatives of the arc integration with respect to
//! the model's three numbers (travel per tick of each wheel, wheelbase), carried along in the
//! same pass over the knots (forward-mode differentiation), in `f32` or `f64`.
//!
//! One pass costs about one re-integration (one `sin`/`cos` per knot, as the integration itself,
//! and short polynomials), where central differences cost two re-integrations per factor.

use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::reference::ArcModel;
use crate::util::trig;

/// The number type of a pass.
pub(super) trait Real:
    Copy
    + core::ops::Add<Output = Self>
    + core::ops::Sub<Output = Self>
    + core::ops::Mul<Output = Self>
    + core::ops::Div<Output = Self>
    + core::ops::Neg<Output = Self>
    + PartialOrd
{
    const ZERO: Self;
    const HALF: Self;
    const ONE: Self;
    fn of(v: f64) -> Self;
    fn to_f64(self) -> f64;
    fn ticks(t: i64) -> Self;
    fn sin_cos(self) -> (Self, Self);
    fn abs(self) -> Self;
}

impl Real for f64 {
    const ZERO: f64 = 0.0;
    const HALF: f64 = 0.5;
    const ONE: f64 = 1.0;
    fn of(v: f64) -> f64 {
        v
    }
    fn to_f64(self) -> f64 {
        self
    }
    fn ticks(t: i64) -> f64 {
        t as f64
    }
    fn sin_cos(self) -> (f64, f64) {
        trig::sincos(self)
    }
    fn abs(self) -> f64 {
        libm::fabs(self)
    }
}

impl Real for f32 {
    const ZERO: f32 = 0.0;
    const HALF: f32 = 0.5;
    const ONE: f32 = 1.0;
    fn of(v: f64) -> f32 {
        v as f32
    }
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    fn ticks(t: i64) -> f32 {
        t as f32
    }
    fn sin_cos(self) -> (f32, f32) {
        trig::sincos_f32(self)
    }
    fn abs(self) -> f32 {
        libm::fabsf(self)
    }
}

/// Below this `|u|` the series of `sin u / u` and its derivative are used: their first omitted
/// terms, `u¹⁴/15!` and `14·u¹³/15!`, are below 1e-15 of the value there.
const SERIES_BELOW: f64 = 0.5;

/// `(sinc u, sinc′ u)` with `sinc u = sin u / u`.
fn sinc_and_slope<F: Real>(u: F) -> (F, F) {
    if u.abs() < F::of(SERIES_BELOW) {
        let u2 = u * u;
        // Horner in u²: Σ (−1)^k u^{2k}/(2k+1)! and Σ (−1)^k 2k u^{2k−1}/(2k+1)!.
        let s = F::ONE
            - u2 * (F::of(1.0 / 6.0)
                - u2 * (F::of(1.0 / 120.0)
                    - u2 * (F::of(1.0 / 5040.0)
                        - u2 * (F::of(1.0 / 362_880.0)
                            - u2 * (F::of(1.0 / 39_916_800.0)
                                - u2 * F::of(1.0 / 6_227_020_800.0))))));
        let d = -u
            * (F::of(1.0 / 3.0)
                - u2 * (F::of(1.0 / 30.0)
                    - u2 * (F::of(1.0 / 840.0)
                        - u2 * (F::of(1.0 / 45_360.0)
                            - u2 * (F::of(1.0 / 3_991_680.0) - u2 * F::of(1.0 / 518_918_400.0))))));
        (s, d)
    } else {
        let (sin, cos) = u.sin_cos();
        let s = sin / u;
        (s, (cos - s) / u)
    }
}

/// The end pose `(x, y, θ)` of the arcs through `knots` from the origin, and its derivatives
/// `d[q] = ∂(x, y, θ)/∂m_q` with respect to the model's numbers `m = (right, left, wheelbase)`,
/// computed in the precision `F`.
pub(super) fn end_pose_derivatives<F: Real>(
    model: &ArcModel,
    knots: &[WheelTicks],
) -> ([f64; 3], [[f64; 3]; 3]) {
    let (right, left, b) = (
        F::of(model.right_m_per_tick),
        F::of(model.left_m_per_tick),
        F::of(model.wheelbase_m),
    );
    let (mut x, mut y) = (F::ZERO, F::ZERO);
    let mut dx = [F::ZERO; 3];
    let mut dy = [F::ZERO; 3];
    let mut theta_prev = F::ZERO;
    let mut dtheta_prev = [F::ZERO; 3];
    let Some(first) = knots.first() else {
        return ([0.0; 3], [[0.0; 3]; 3]);
    };
    let mut prev = *first;
    for &k in &knots[1..] {
        let t = k - *first;
        let (tr, tl) = (F::ticks(t.right), F::ticks(t.left));
        let theta = (right * tr - left * tl) / b;
        let dtheta = [tr / b, -tl / b, -theta / b];
        let d = k - prev;
        let (dr, dl) = (F::ticks(d.right), F::ticks(d.left));
        let ds = F::HALF * (right * dr + left * dl);
        let dds = [F::HALF * dr, F::HALF * dl, F::ZERO];
        let u = F::HALF * (theta - theta_prev);
        let (sinc, slope) = sinc_and_slope(u);
        let chord = ds * sinc;
        let (s, c) = (theta_prev + u).sin_cos();
        for q in 0..3 {
            let du = F::HALF * (dtheta[q] - dtheta_prev[q]);
            let dchord = dds[q] * sinc + ds * slope * du;
            let dmid = F::HALF * (dtheta[q] + dtheta_prev[q]);
            dx[q] = dx[q] + dchord * c - chord * s * dmid;
            dy[q] = dy[q] + dchord * s + chord * c * dmid;
        }
        x = x + chord * c;
        y = y + chord * s;
        prev = k;
        theta_prev = theta;
        dtheta_prev = dtheta;
    }
    let pose = [x.to_f64(), y.to_f64(), theta_prev.to_f64()];
    let mut out = [[0.0; 3]; 3];
    for q in 0..3 {
        out[q] = [dx[q].to_f64(), dy[q].to_f64(), dtheta_prev[q].to_f64()];
    }
    (pose, out)
}

/// A 1 m square of `model`'s robot, 4 × (20 + 5) knots; `wobble` adds a count of jitter to the
/// left wheel along the sides (the tests of this module and of the solver).
#[cfg(test)]
pub(super) fn square_knots(model: &ArcModel, wobble: bool) -> std::vec::Vec<WheelTicks> {
    let side = (1.0 / model.right_m_per_tick).round() as i64;
    let turn =
        (0.25 * core::f64::consts::PI * model.wheelbase_m / model.right_m_per_tick).round() as i64;
    let mut knots = std::vec![WheelTicks::new(0, 0)];
    let (mut r, mut l) = (0, 0);
    for _ in 0..4 {
        for i in 1..=20 {
            let jitter = if wobble { i % 3 } else { 0 };
            knots.push(WheelTicks::new(
                r + side * i / 20,
                l + side * i / 20 + jitter,
            ));
        }
        (r, l) = (r + side, l + side);
        for i in 1..=5 {
            knots.push(WheelTicks::new(r + turn * i / 5, l - turn * i / 5));
        }
        (r, l) = (r + turn, l - turn);
    }
    knots
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::geometry::Geometry;
    use crate::kinematics::reference::PoseF64;

    fn square(model: &ArcModel) -> Vec<WheelTicks> {
        square_knots(model, true)
    }

    /// The series of `sinc` and its slope agree with the closed forms where both are accurate.
    #[test]
    fn sinc_series_matches_closed_form() {
        for u in [0.1f64, 0.3, 0.4999, -0.45] {
            let (s, d) = sinc_and_slope(u);
            let closed = (u.sin() / u, (u.cos() - u.sin() / u) / u);
            assert!((s - closed.0).abs() < 1e-15, "{u}");
            assert!((d - closed.1).abs() < 1e-13, "{u}: {d} {}", closed.1);
        }
    }

    /// The pose is the arc model's, and the derivatives are its central differences: to 1e-7
    /// relative in `f64` (the differences' own error, step 1e-6 of the number), 1e-4 in `f32`.
    #[test]
    fn derivatives_match_central_differences() {
        let model = ArcModel::from_geometry(&Geometry::PAPER_NOMINAL.with_factors(1.01, 0.99, 1.0));
        let knots = square(&model);
        let end = |m: &ArcModel| {
            let e = m.integrate(PoseF64::default(), &knots);
            [e.x_m, e.y_m, e.theta_rad]
        };
        let (pose, d64) = end_pose_derivatives::<f64>(&model, &knots);
        let reference = end(&model);
        for c in 0..3 {
            assert!(
                (pose[c] - reference[c]).abs() < 1e-12,
                "{pose:?} {reference:?}"
            );
        }
        let (_, d32) = end_pose_derivatives::<f32>(&model, &knots);
        for q in 0..3 {
            let numbers = |s: f64| {
                let mut m = model;
                let h = 1e-6 * s;
                match q {
                    0 => m.right_m_per_tick += h,
                    1 => m.left_m_per_tick += h,
                    _ => m.wheelbase_m += h,
                }
                m
            };
            let base = [
                model.right_m_per_tick,
                model.left_m_per_tick,
                model.wheelbase_m,
            ][q];
            let (plus, minus) = (end(&numbers(base)), end(&numbers(-base)));
            let diff = [0, 1, 2].map(|c| (plus[c] - minus[c]) / (2e-6 * base));
            let size = diff.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for c in 0..3 {
                assert!(
                    (d64[q][c] - diff[c]).abs() < 1e-7 * size,
                    "{q} {c}: {d64:?} {diff:?}"
                );
                assert!(
                    (d32[q][c] - diff[c]).abs() < 1e-4 * size,
                    "{q} {c}: {d32:?} {diff:?}"
                );
            }
        }
    }
}
