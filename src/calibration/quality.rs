//! Quality figures reported with every calibration.
//!
//! - `E_max,syst` before (UMBmark: `max(|cg_cw|, |cg_ccw|)` of the square runs' end errors) and
//!   the value predicted after: the recorded ticks re-integrated with the corrected geometry,
//!   compared with the same measurements (what the odometry would have reported on the very
//!   same physical runs);
//! - the scatter of the runs around their centres of gravity (non-systematic part);
//! - the 1σ uncertainty of `E_b`, `E_d` (and `E_s`): for the closed-form methods propagated from
//!   the standard errors of the centres of gravity through the formula (central differences),
//!   for the exact method from the residuals, `(JᵀJ)⁻¹ σ²`.

// Dense 3×3 linear algebra reads best with explicit indices.
#![allow(clippy::needless_range_loop)]

use super::stats::{SquareStats, Welford};
use super::{ClosedFormInputs, Method, RunObservation, closed_form, square_direction};
use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::ArcModel;
use crate::motion::run::Direction;
use crate::util::num::fmax;
use crate::util::trig;

/// Quality figures of one calibration.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Quality {
    /// `E_max,syst` of the square runs as driven, metres.
    pub e_max_before_m: Option<f64>,
    /// `E_max,syst` predicted with the corrected geometry, metres.
    pub e_max_after_m: Option<f64>,
    /// Scatter of the end errors around their direction's centre of gravity, metres.
    pub scatter_m: Option<f64>,
    /// 1σ of `E_b`.
    pub sigma_e_b: Option<f64>,
    /// 1σ of `E_d`.
    pub sigma_e_d: Option<f64>,
    /// 1σ of `E_s` (0 when `E_s` was not estimated).
    pub sigma_e_s: Option<f64>,
    /// RMS of the fit residuals (exact method), metres.
    pub rms_residual_m: Option<f64>,
}

impl Quality {
    /// Collects the figures; `sigma` is `[σ_E_d, σ_E_b, σ_E_s]`.
    pub fn from_runs(
        runs: &[RunObservation<'_>],
        corrected: &Geometry,
        stats: Option<&SquareStats>,
        sigma: Option<[f64; 3]>,
        rms_residual_m: Option<f64>,
    ) -> Self {
        let e_max_after_m = predicted_e_max(runs, corrected);
        Quality::new(e_max_after_m, stats, sigma, rms_residual_m)
    }

    /// Collects the figures with `E_max,syst` after the correction already known.
    pub(crate) fn new(
        e_max_after_m: Option<f64>,
        stats: Option<&SquareStats>,
        sigma: Option<[f64; 3]>,
        rms_residual_m: Option<f64>,
    ) -> Self {
        Quality {
            e_max_before_m: stats.map(SquareStats::e_max_m),
            e_max_after_m,
            scatter_m: stats.and_then(SquareStats::scatter_m),
            sigma_e_d: sigma.map(|s| s[0]),
            sigma_e_b: sigma.map(|s| s[1]),
            sigma_e_s: sigma.map(|s| s[2]),
            rms_residual_m,
        }
    }
}

/// `E_max,syst` of the square runs re-integrated with `g`; `None` without knots or without a
/// run in each direction. The end poses are the arc model's ([`ArcModel`]) to rounding, by
/// `end_pose` (fewer `f64` operations: on the Cortex-M4F each is a soft-float call).
pub fn predicted_e_max(runs: &[RunObservation<'_>], g: &Geometry) -> Option<f64> {
    let model = ArcModel::from_geometry(g);
    e_max_of(runs, |_, r| end_residual(&model, r))
}

/// A run's end residual `measured − predicted` in x, y for `model` ([`end_pose`]).
pub(crate) fn end_residual(model: &ArcModel, run: &RunObservation<'_>) -> (f64, f64) {
    let end = end_pose(model, run.knots);
    (run.measured.x_m - end[0], run.measured.y_m - end[1])
}

/// `E_max,syst` of the square runs from their end residuals `measured − predicted` (x, y),
/// which `residual` gives for a run and its index in `runs`; `None` without knots or without a
/// run in each direction.
pub(crate) fn e_max_of(
    runs: &[RunObservation<'_>],
    mut residual: impl FnMut(usize, &RunObservation<'_>) -> (f64, f64),
) -> Option<f64> {
    let mut acc = [(Welford::default(), Welford::default()); 2];
    for (i, r) in runs.iter().enumerate().filter(|(_, r)| r.knots.len() >= 2) {
        let Some((dir, _)) = square_direction(&r.path) else {
            continue;
        };
        let (dx, dy) = residual(i, r);
        let a = &mut acc[usize::from(dir == Direction::Ccw)];
        a.0.push(dx);
        a.1.push(dy);
    }
    if acc.iter().any(|a| a.0.n == 0) {
        return None;
    }
    Some(
        acc.iter()
            .map(|a| libm::hypot(a.0.mean, a.1.mean))
            .fold(0.0, fmax),
    )
}

/// Below these `|u|` [`sinc_series`] keeps two, three and five terms of the series, seven up to
/// [`SERIES_BELOW`]: the first omitted term is below 1e-18 relative in each range (the exact fit's
/// pass uses the same ranges).
const SHORT_SERIES_BELOW: f64 = 1e-3;
const SMALL_SERIES_BELOW: f64 = 1e-2;
const MEDIUM_SERIES_BELOW: f64 = 0.1;
/// Up to this `|u|` [`sinc_series`] uses the series, beyond a sine and a division.
const SERIES_BELOW: f64 = 0.5;

/// A tick count as `f64`, from `i32` when it fits (the same value; a shorter library call on the
/// M4F).
fn ticks(t: i64) -> f64 {
    match i32::try_from(t) {
        Ok(t) => f64::from(t),
        Err(_) => t as f64,
    }
}

/// `sin u / u` by its series (see [`SHORT_SERIES_BELOW`]).
fn sinc_series(u: f64) -> f64 {
    let a = libm::fabs(u);
    let u2 = u * u;
    if a < SHORT_SERIES_BELOW {
        1.0 - u2 * (1.0 / 6.0 - u2 * (1.0 / 120.0))
    } else if a < SMALL_SERIES_BELOW {
        1.0 - u2 * (1.0 / 6.0 - u2 * (1.0 / 120.0 - u2 * (1.0 / 5040.0)))
    } else if a < MEDIUM_SERIES_BELOW {
        // The first omitted term, u¹²/13!, is below 2e-22 here.
        1.0 - u2
            * (1.0 / 6.0
                - u2 * (1.0 / 120.0
                    - u2 * (1.0 / 5040.0 - u2 * (1.0 / 362_880.0 - u2 * (1.0 / 39_916_800.0)))))
    } else if a < SERIES_BELOW {
        1.0 - u2
            * (1.0 / 6.0
                - u2 * (1.0 / 120.0
                    - u2 * (1.0 / 5040.0
                        - u2 * (1.0 / 362_880.0
                            - u2 * (1.0 / 39_916_800.0 - u2 * (1.0 / 6_227_020_800.0))))))
    } else {
        trig::sin(u) / u
    }
}

/// The end pose `(x, y, θ)` of the arcs through `knots` from the origin for `model`, in `f64`:
/// [`ArcModel::integrate`]'s arcs, equal to rounding (within 1e-14 m and rad on a 1 m square,
/// test `end_pose_matches_the_arc_model`), in fewer operations, for a figure that needs an end
/// pose but not the fit's last bit (the quality's predicted `E_max`, shown to 1e-6 m): the
/// heading advanced by each interval's turn `ρ_R ΔR/b − ρ_L ΔL/b` (the wheelbase divided into the
/// travel per tick once, not into every heading), `sinc` by its series instead of a sine and a
/// division, tick counts converted from `i32` when they fit, and where two successive half turns
/// add up to less than 1e-2 rad (a leg) the mid-heading's cosine and sine are the previous ones
/// rotated by that angle (short series) instead of a sine and cosine of their own; at every
/// larger turn they are computed afresh, so rounding accumulates along one leg only.
pub(crate) fn end_pose(model: &ArcModel, knots: &[WheelTicks]) -> [f64; 3] {
    let b = model.wheelbase_m;
    let (ar, al) = (model.right_m_per_tick / b, model.left_m_per_tick / b);
    let (hr, hl) = (0.5 * model.right_m_per_tick, 0.5 * model.left_m_per_tick);
    let (mut x, mut y, mut theta) = (0.0, 0.0, 0.0);
    // Half the previous interval's turn, and the cosine and sine of its mid-heading.
    let (mut u_prev, mut c, mut s) = (0.0, 1.0, 0.0);
    let mut fresh = true;
    for pair in knots.windows(2) {
        let d = pair[1] - pair[0];
        let (dr, dl) = (ticks(d.right), ticks(d.left));
        let turn = ar * dr - al * dl;
        let ds = hr * dr + hl * dl;
        let u = 0.5 * turn;
        let chord = ds * sinc_series(u);
        // From the previous mid-heading to this one: w = u_prev + u.
        let w = u_prev + u;
        if fresh || libm::fabs(w) >= SMALL_SERIES_BELOW {
            (s, c) = trig::sincos(theta + u);
            fresh = false;
        } else {
            // Rotated by w (series: first omitted terms below 2e-18 and 2e-21).
            let w2 = w * w;
            let sw = w * (1.0 - w2 * (1.0 / 6.0 - w2 * (1.0 / 120.0)));
            let cw = 1.0 - w2 * (0.5 - w2 * (1.0 / 24.0 - w2 * (1.0 / 720.0)));
            (c, s) = (c * cw - s * sw, s * cw + c * sw);
        }
        u_prev = u;
        x += chord * c;
        y += chord * s;
        theta += turn;
    }
    [x, y, theta]
}

/// Step of the central differences through the closed-form formulas (metres or radians).
const INPUT_STEP: f64 = 1e-7;

/// 1σ of a closed-form method's `(E_d, E_b, 0)` relative to `nominal`, propagated from the
/// standard errors of the centres of gravity; `None` with fewer than two runs per direction.
pub fn closed_form_sigma(
    method: Method,
    stats: &SquareStats,
    nominal: &Geometry,
) -> Option<[f64; 3]> {
    let var = stats.input_variances(method)?;
    let inputs = stats.inputs(method).ok()?;
    let drive = &stats.geometry;
    let [sd, sb] = propagate(method, &inputs, &var, stats.side_m, drive)?;
    // Absolute factors are the relative ones times the driving geometry's (first order).
    Some([
        sd * drive.diameter_ratio(),
        sb * drive.wheelbase_m / nominal.wheelbase_m,
        0.0,
    ])
}

/// Propagates input variances through a closed-form method: `[σ_e_d, σ_e_b]` of the relative
/// factors; `None` when no input has a variance (one run per direction, or inputs the runs
/// cannot scatter): a 1σ of 0 would claim an exact result.
pub fn propagate(
    method: Method,
    inputs: &ClosedFormInputs,
    variances: &ClosedFormInputs,
    side_m: f64,
    drive: &Geometry,
) -> Option<[f64; 2]> {
    let mut vd = 0.0;
    let mut vb = 0.0;
    let mut any = false;
    for i in 0..4 {
        if variances[i] <= 0.0 {
            continue;
        }
        any = true;
        let mut up = *inputs;
        let mut dn = *inputs;
        up[i] += INPUT_STEP;
        dn[i] -= INPUT_STEP;
        let fu = closed_form(method, &up, side_m, drive).ok()?;
        let fd = closed_form(method, &dn, side_m, drive).ok()?;
        let dd = (fu.e_d - fd.e_d) / (2.0 * INPUT_STEP);
        let db = (fu.e_b - fd.e_b) / (2.0 * INPUT_STEP);
        vd += dd * dd * variances[i];
        vb += db * db * variances[i];
    }
    any.then(|| [libm::sqrt(vd), libm::sqrt(vb)])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::geometry::Geometry;
    use crate::kinematics::reference::PoseF64;

    /// The pose pass is the arc model's end pose to rounding, on a 1 m square (4 × 20 knots along
    /// the sides with a tick of jitter, 4 × 5 through the pivots) and on a 16 m one; its series
    /// of `sinc` is the closed form's to an ulp or two.
    #[test]
    fn end_pose_matches_the_arc_model() {
        let model = ArcModel::from_geometry(&Geometry::PAPER_NOMINAL.with_factors(1.01, 0.99, 1.0));
        for side_m in [1.0, 16.0] {
            let side = (side_m / model.right_m_per_tick).round() as i64;
            let turn = (0.25 * core::f64::consts::PI * model.wheelbase_m / model.right_m_per_tick)
                .round() as i64;
            let mut knots = std::vec![WheelTicks::new(0, 0)];
            let (mut r, mut l) = (0, 0);
            for _ in 0..4 {
                for i in 1..=20 {
                    knots.push(WheelTicks::new(
                        r + side * i / 20,
                        l + side * i / 20 + i % 3,
                    ));
                }
                (r, l) = (r + side, l + side);
                for i in 1..=5 {
                    knots.push(WheelTicks::new(r + turn * i / 5, l - turn * i / 5));
                }
                (r, l) = (r + turn, l - turn);
            }
            let e = model.integrate(PoseF64::default(), &knots);
            let pose = end_pose(&model, &knots);
            for (a, b) in pose.iter().zip([e.x_m, e.y_m, e.theta_rad]) {
                assert!((a - b).abs() < 1e-14 * side_m, "{pose:?} {e:?}");
            }
        }
        assert_eq!(sinc_series(0.7), trig::sin(0.7) / 0.7);
        for u in [1e-5f64, 5e-4, 2e-3, 9e-3, 0.05, 0.0999, 0.3] {
            let closed = u.sin() / u;
            assert!((sinc_series(u) - closed).abs() < 3e-16, "{u}");
        }
    }
}
