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

use super::exact::end_pose;
use super::stats::{SquareStats, Welford};
use super::{ClosedFormInputs, Method, RunObservation, closed_form, square_direction};
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::ArcModel;
use crate::motion::run::Direction;
use crate::util::num::fmax;

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
/// run in each direction. The end poses are the arc model's ([`ArcModel`]) to rounding, by the
/// exact fit's pose pass (`exact::end_pose`, a third fewer instructions on the Cortex-M4F).
pub fn predicted_e_max(runs: &[RunObservation<'_>], g: &Geometry) -> Option<f64> {
    let model = ArcModel::from_geometry(g);
    e_max_of(runs, |_, r| end_residual(&model, r))
}

/// A run's end residual `measured − predicted` in x, y for `model` (`exact::end_pose`).
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
/// factors.
pub fn propagate(
    method: Method,
    inputs: &ClosedFormInputs,
    variances: &ClosedFormInputs,
    side_m: f64,
    drive: &Geometry,
) -> Option<[f64; 2]> {
    let mut vd = 0.0;
    let mut vb = 0.0;
    for i in 0..4 {
        if variances[i] <= 0.0 {
            continue;
        }
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
    Some([libm::sqrt(vd), libm::sqrt(vb)])
}
