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
    /// `(sinc u, sinc′ u)` with `sinc u = sin u / u`.
    fn sinc_and_slope(self) -> (Self, Self);
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
        // The same value; from `i32` the conversion is a short library call on the M4F.
        match i32::try_from(t) {
            Ok(t) => f64::from(t),
            Err(_) => t as f64,
        }
    }
    fn sin_cos(self) -> (f64, f64) {
        trig::sincos(self)
    }
    fn abs(self) -> f64 {
        libm::fabs(self)
    }
    fn sinc_and_slope(self) -> (f64, f64) {
        sinc_and_slope(self)
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
        // The same value; from `i32` the conversion is one FPU instruction on the M4F (from `i64`
        // a library call).
        match i32::try_from(t) {
            Ok(t) => t as f32,
            Err(_) => t as f32,
        }
    }
    fn sin_cos(self) -> (f32, f32) {
        trig::sincos_f32(self)
    }
    fn abs(self) -> f32 {
        libm::fabsf(self)
    }
    fn sinc_and_slope(self) -> (f32, f32) {
        let u = self;
        if libm::fabsf(u) < 0.5 {
            // One series for every |u| below 0.5: the first omitted terms, u¹⁰/11! and
            // 10·u⁹/11!, are below 3e-11 and 5e-10 of the values there, far below `f32`'s 6e-8.
            let u2 = u * u;
            let s = 1.0
                - u2 * (1.0 / 6.0
                    - u2 * (1.0 / 120.0 - u2 * (1.0 / 5040.0 - u2 * (1.0 / 362_880.0))));
            let d =
                -u * (1.0 / 3.0 - u2 * (1.0 / 30.0 - u2 * (1.0 / 840.0 - u2 * (1.0 / 45_360.0))));
            (s, d)
        } else {
            let (sin, cos) = trig::sincos_f32(u);
            let s = sin / u;
            (s, (cos - s) / u)
        }
    }
}

/// Below this `|u|` the series of `sin u / u` and its derivative are used: their first omitted
/// terms, `u¹⁴/15!` and `14·u¹³/15!`, are below 1e-15 of the value there.
const SERIES_BELOW: f64 = 0.5;

/// Below this `|u|` (the knots of straight legs) two terms of each series suffice: the first
/// omitted ones, `u⁶/7!` and `6·u⁵/7!`, are below 2e-22 and 1.2e-18 (4e-15 of the slope) there.
const SHORT_SERIES_BELOW: f64 = 1e-3;

/// `(sinc u, sinc′ u)` with `sinc u = sin u / u`, the shortest series that is exact to
/// rounding for `|u|` (the `f64` pass).
fn sinc_and_slope<F: Real>(u: F) -> (F, F) {
    let a = u.abs();
    if a < F::of(SHORT_SERIES_BELOW) {
        let u2 = u * u;
        let s = F::ONE - u2 * (F::of(1.0 / 6.0) - u2 * F::of(1.0 / 120.0));
        let d = -u * (F::of(1.0 / 3.0) - u2 * F::of(1.0 / 30.0));
        return (s, d);
    }
    if a < F::of(SMALL_SERIES_BELOW) {
        // The first omitted terms, u⁸/9! and 8·u⁷/9!, are below 3e-22 and 3e-19 here.
        let u2 = u * u;
        let s =
            F::ONE - u2 * (F::of(1.0 / 6.0) - u2 * (F::of(1.0 / 120.0) - u2 * F::of(1.0 / 5040.0)));
        let d = -u * (F::of(1.0 / 3.0) - u2 * (F::of(1.0 / 30.0) - u2 * F::of(1.0 / 840.0)));
        return (s, d);
    }
    if a < F::of(MEDIUM_SERIES_BELOW) {
        // The first omitted terms, u¹²/13! and 12·u¹¹/13!, are below 2e-22 and 2e-20 here.
        let u2 = u * u;
        let s = F::ONE
            - u2 * (F::of(1.0 / 6.0)
                - u2 * (F::of(1.0 / 120.0)
                    - u2 * (F::of(1.0 / 5040.0)
                        - u2 * (F::of(1.0 / 362_880.0) - u2 * F::of(1.0 / 39_916_800.0)))));
        let d = -u
            * (F::of(1.0 / 3.0)
                - u2 * (F::of(1.0 / 30.0)
                    - u2 * (F::of(1.0 / 840.0)
                        - u2 * (F::of(1.0 / 45_360.0) - u2 * F::of(1.0 / 3_991_680.0)))));
        return (s, d);
    }
    if a < F::of(SERIES_BELOW) {
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

/// Below this `|u|` (the knots of legs driven with some wobble) [`sinc_and_slope`] (and the quality's
/// pose pass, `quality::end_pose`) keep three terms of each series.
const SMALL_SERIES_BELOW: f64 = 1e-2;

/// Below this `|u|` (the knots of pivots split into a few intervals) [`sinc_and_slope`] (and the quality's
/// pose pass, `quality::end_pose`) drop the last term of each series.
const MEDIUM_SERIES_BELOW: f64 = 0.1;

/// The end pose `(x, y, θ)` of the arcs through `knots` from the origin, and its derivatives
/// `d[q] = ∂(x, y, θ)/∂m_q` with respect to the model's numbers `m = (right, left, wheelbase)`,
/// computed in the precision `F`.
///
/// Per knot `k` (tick totals `R_k`, `L_k` from the first knot, `ΔR`, `ΔL` since the previous):
/// the heading `θ_k = (ρ_R R_k − ρ_L L_k)/b`, the travel `ds = (ρ_R ΔR + ρ_L ΔL)/2`, the half
/// turn `u = (θ_k − θ_{k−1})/2`, the mid-heading `m = θ_{k−1} + u` and the chord `ds·sinc u`
/// along it. With `∂θ_k/∂(ρ_R, ρ_L, b) = (R_k, −L_k, −θ_k)/b`, the derivatives of the chord and
/// of `m` are linear in `ΔR`, `ΔL`, `R_k + R_{k−1}`, `L_k + L_{k−1}`, `u` and `m`, with the
/// common factor `1/b` (and ½) taken out of the sums: per knot the integration's one sine and
/// cosine, the two series, and a dozen products into nine running sums.
pub(super) fn end_pose_derivatives<F: Real>(
    model: &ArcModel,
    knots: &[WheelTicks],
) -> ([f64; 3], [[f64; 3]; 3]) {
    let (right, left, b) = (
        F::of(model.right_m_per_tick),
        F::of(model.left_m_per_tick),
        F::of(model.wheelbase_m),
    );
    let Some(first) = knots.first() else {
        return ([0.0; 3], [[0.0; 3]; 3]);
    };
    let (mut x, mut y) = (F::ZERO, F::ZERO);
    // Σ ΔR·sinc·(cos m, sin m) and Σ ΔL·sinc·(cos m, sin m): the chord's travel terms.
    let (mut sxr, mut syr, mut sxl, mut syl) = (F::ZERO, F::ZERO, F::ZERO, F::ZERO);
    // b/½ times the remaining terms of ∂x, ∂y for ρ_R, ρ_L, and b times those for b.
    let (mut txr, mut tyr, mut txl, mut tyl) = (F::ZERO, F::ZERO, F::ZERO, F::ZERO);
    let (mut txb, mut tyb) = (F::ZERO, F::ZERO);
    let (mut tr_prev, mut tl_prev) = (F::ZERO, F::ZERO);
    let mut theta_prev = F::ZERO;
    let mut prev = *first;
    for &k in &knots[1..] {
        let t = k - *first;
        let (tr, tl) = (F::ticks(t.right), F::ticks(t.left));
        let theta = (right * tr - left * tl) / b;
        let d = k - prev;
        let (dr, dl) = (F::ticks(d.right), F::ticks(d.left));
        let ds = F::HALF * (right * dr + left * dl);
        let u = F::HALF * (theta - theta_prev);
        let (sinc, slope) = u.sinc_and_slope();
        let chord = ds * sinc;
        let m = theta_prev + u;
        let (s, c) = m.sin_cos();
        let (qc, qs) = (chord * c, chord * s);
        x = x + qc;
        y = y + qs;
        // ∂chord = ½ΔR·sinc + ds·sinc′·∂u, ∂u = ½ΔR/b, ∂m = ½(R_k + R_{k−1})/b (ρ_R; ρ_L with
        // the signs of L); for b: ∂u = −u/b, ∂m = −m/b.
        let (ac, as_) = (sinc * c, sinc * s);
        sxr = sxr + dr * ac;
        syr = syr + dr * as_;
        sxl = sxl + dl * ac;
        syl = syl + dl * as_;
        let p = ds * slope;
        let (pc, ps) = (p * c, p * s);
        let (mr, ml) = (tr + tr_prev, tl + tl_prev);
        txr = txr + (dr * pc - mr * qs);
        tyr = tyr + (dr * ps + mr * qc);
        txl = txl + (ml * qs - dl * pc);
        tyl = tyl - (dl * ps + ml * qc);
        txb = txb + (m * qs - u * pc);
        tyb = tyb - (u * ps + m * qc);
        prev = k;
        theta_prev = theta;
        (tr_prev, tl_prev) = (tr, tl);
    }
    let inv_b = F::ONE / b;
    let half_b = F::HALF * inv_b;
    let d = [
        [
            F::HALF * sxr + half_b * txr,
            F::HALF * syr + half_b * tyr,
            tr_prev * inv_b,
        ],
        [
            F::HALF * sxl + half_b * txl,
            F::HALF * syl + half_b * tyl,
            -(tl_prev * inv_b),
        ],
        [inv_b * txb, inv_b * tyb, -(theta_prev * inv_b)],
    ];
    let pose = [x.to_f64(), y.to_f64(), theta_prev.to_f64()];
    (pose, d.map(|row| row.map(F::to_f64)))
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
