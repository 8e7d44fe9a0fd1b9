//! The exact fit from start to result: the plain fit, the reweighting rounds, the final `f64`
//! solve, the degeneracy and range checks, the 1σ and the per-run report.

use super::linalg::{Mat, solve};
use super::offset::MAX_GROUPS;
use super::problem::{Precision, Problem, Residuals, X, Y};
use super::report::{EndOffset, ExactFit, RunFit};
use super::robust::{Scales, Weight, weight};
use super::solver::HeadingPart;
use super::{
    ExactOptions, FREEZE_SCALES_AFTER, MAX_FACTOR_SIGMA, MAX_REWEIGHTS, MAX_RUN_FITS,
    MAX_WEIGHTED_RUNS, ScaleFit,
};
use crate::calibration::quality::{Quality, e_max_of, end_residual};
use crate::calibration::stats::SquareStats;
use crate::calibration::{
    Calibration, CalibrationError, FACTOR_RANGE, Method, RunObservation, factors_of,
};
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::ArcModel;
use crate::motion::run::PathKind;
use crate::util::num::fmax;

/// The variance of one weighted residual component of the position rows and of the end-heading
/// rows, each from its own weighted sum of squares over its share of the degrees of freedom
/// (the factors' `n` shared in proportion to the rows, the offsets' `fitted − n` all the
/// positions'). One variance for both (`cost / (m − fitted)`) when either share is under one
/// degree of freedom or there is no heading row; `None` without a degree of freedom.
fn channel_variances(
    cost: f64,
    m: usize,
    fitted: usize,
    n: usize,
    heading: &HeadingPart,
) -> Option<(f64, f64)> {
    if m <= fitted {
        return None;
    }
    let pooled = cost / (m - fitted) as f64;
    let (mh, mf) = (heading.rows as f64, m as f64);
    let dof_heading = mh - n as f64 * mh / mf;
    let dof_position = (m - fitted) as f64 - dof_heading;
    if heading.rows == 0 || dof_heading < 1.0 || dof_position < 1.0 {
        return Some((pooled, pooled));
    }
    let position_cost = fmax(cost - heading.cost, 0.0);
    Some((position_cost / dof_position, heading.cost / dof_heading))
}

/// Fits the parameters; see the `exact` module docs.
///
/// # Errors
/// `NoRuns` when no run has at least two knots, `Degenerate` when the parameters are not
/// determined by the runs (a singular system, or a factor's 1σ above [`MAX_FACTOR_SIGMA`]),
/// `NotConverged`, `OutOfRange`, `InvalidGeometry`.
pub fn calibrate_exact(
    runs: &[RunObservation<'_>],
    nominal: &Geometry,
    options: &ExactOptions,
) -> Result<Calibration, CalibrationError> {
    let first = runs
        .iter()
        .find(|r| Problem::usable(r))
        .ok_or(CalibrationError::NoRuns)?;
    let sees_scale = runs
        .iter()
        .any(|r| matches!(r.path, PathKind::Line { .. }) || Problem::is_path(r));
    let fit_scale = match options.scale {
        ScaleFit::Auto => sees_scale,
        ScaleFit::Always => true,
        ScaleFit::Never => false,
    };
    let (d0, b0, s0) = factors_of(&first.geometry, nominal);
    let mut problem = Problem {
        runs,
        nominal: *nominal,
        n: if fit_scale { 3 } else { 2 },
        fixed_scale: s0,
        options: *options,
        groups: Default::default(),
    };
    problem.groups = problem.offset_groups();
    let n = problem.n;
    // Two offsets per group are fitted besides the factors.
    let fitted = n + 2 * problem.groups.count();
    let p0 = [d0, b0, s0];
    if !(0..n).all(|i| FACTOR_RANGE.contains(&p0[i])) {
        return Err(CalibrationError::OutOfRange);
    }
    // Residual components.
    let m: usize = runs
        .iter()
        .filter(|r| Problem::usable(r))
        .map(|r| problem.components(r))
        .sum();
    let rows: usize = runs
        .iter()
        .filter(|r| Problem::usable(r))
        .map(|r| problem.row_count(r))
        .sum();
    if rows <= fitted {
        return Err(CalibrationError::Degenerate);
    }
    // The plain least-squares fit: the result, or the robust fit's start.
    let mut solved = problem.solve_lm(p0, None, Precision::F32, None)?;
    let mut iterations = solved.iterations;
    let reweighted = options.robust && runs.len() <= MAX_WEIGHTED_RUNS;
    // Weights and scales indexed like `runs`, and the weights `solved` was fitted with.
    let mut weights = [Weight::ONE; MAX_WEIGHTED_RUNS];
    let mut scales = [None; MAX_WEIGHTED_RUNS];
    let mut fitted_with = [Weight::ONE; MAX_WEIGHTED_RUNS];
    let mut reweights = 0;
    if reweighted {
        let len = runs.len();
        loop {
            // The weights computed at the fitted parameters are those they were fitted with:
            // the fixed point of IRLS.
            let frozen = reweights >= FREEZE_SCALES_AFTER;
            let known = Some(&solved.residuals);
            if problem.reweight(&solved.p, known, &mut weights, &mut scales, frozen) {
                break;
            }
            if reweights >= MAX_REWEIGHTS {
                return Err(CalibrationError::NotConverged);
            }
            reweights += 1;
            fitted_with[..len].copy_from_slice(&weights[..len]);
            solved = problem.solve_lm(solved.p, Some(&weights[..len]), Precision::F32, known)?;
            iterations += solved.iterations;
        }
    }
    let len = runs.len().min(MAX_WEIGHTED_RUNS);
    // The `f32` Jacobian's fixed point is off the cost's minimum by about its columns' error
    // times the residuals (see the `exact` module docs); the last solve ends at the minimum with
    // the `f64` Jacobian, from a start that close it takes one or two iterations.
    let fitted_with = (reweighted && reweights > 0).then_some(&fitted_with[..len]);
    solved = problem.solve_lm(solved.p, fitted_with, Precision::F64, None)?;
    iterations += solved.iterations;
    if reweighted {
        // The weights and scales reported (and the 1σ's): those at the fitted parameters from
        // its `f64` residuals; the rounds' came from `f32` residuals, good to about 1e-6 m, which
        // in ideal kinematics would leave weights 1e-8 below 1 where these are 1 to rounding.
        let frozen = reweights >= FREEZE_SCALES_AFTER;
        let known = Some(&solved.residuals);
        problem.reweight(&solved.p, known, &mut weights, &mut scales, frozen);
    }
    let w = reweighted.then_some(&weights[..len]);
    let p = solved.p;
    let cost = solved.cost;
    let geometry = problem.geometry(&p);
    geometry
        .validate()
        .map_err(|_| CalibrationError::InvalidGeometry)?;
    // An unfitted E_s is the driving scale the fit held, reported as it was held (the geometry's
    // mean diameter would give it back only to rounding).
    let (e_d, e_b, fitted_e_s) = factors_of(&geometry, nominal);
    let e_s = if n == 3 {
        fitted_e_s
    } else {
        problem.fixed_scale
    };
    if !(FACTOR_RANGE.contains(&e_d) && FACTOR_RANGE.contains(&e_b) && FACTOR_RANGE.contains(&e_s))
    {
        return Err(CalibrationError::OutOfRange);
    }
    // Uncertainty from the weighted residual scatter, the weights as relative precisions, by
    // channel (see the module docs, *Uncertainty*).
    let (a, _, _, heading) = problem.normal(&p, w, Precision::F64, Some(&solved.residuals));
    let sigma = factor_sigmas(
        &a,
        &heading,
        channel_variances(cost, m, fitted, n, &heading),
        n,
    );
    if sigma.iter().flatten().any(|s| *s > MAX_FACTOR_SIGMA) {
        return Err(CalibrationError::Degenerate);
    }
    let sigma_out = sigma[0]
        .zip(sigma[1])
        .map(|(d, b)| [d, b, sigma[2].unwrap_or(0.0)]);
    // Per-run report, and the weighted mean square of the residual components.
    let model = ArcModel::from_geometry(&geometry);
    let known = Some(&solved.residuals);
    let (fit, weighted_components) =
        problem.report(&model, w, known, (reweighted, reweights), &scales);
    let stats = SquareStats::from_runs(runs, false).ok();
    let rms = libm::sqrt(cost / weighted_components);
    // E_max after the correction from the kept residual rows (the same end poses to rounding).
    let e_max_after_m = e_max_of(runs, |i, run| match Problem::kept(i, run, known) {
        Some(k) => (k.rows[X], k.rows[Y]),
        None => end_residual(&model, run),
    });
    let quality = Quality::new(e_max_after_m, stats.as_ref(), sigma_out, Some(rms));
    Ok(Calibration {
        method: Method::Exact,
        e_d,
        e_b,
        e_s,
        geometry,
        quality,
        iterations,
        fit: Some(fit),
    })
}

/// The factors' 1σ from the normal matrix `a` (its heading rows' part in `heading`) and the
/// position and heading variances of one weighted residual component (see the module docs,
/// *Uncertainty*); `None` where not determined.
fn factor_sigmas(
    a: &Mat,
    heading: &HeadingPart,
    variances: Option<(f64, f64)>,
    n: usize,
) -> [Option<f64>; 3] {
    let mut sigma = [None; 3];
    if let Some((s2_position, s2_heading)) = variances {
        for (i, s) in sigma.iter_mut().enumerate().take(n) {
            let mut e = [0.0; 3];
            e[i] = 1.0;
            if let Some(col) = solve(*a, e, n) {
                // colᵀ (s²_pos·A_pos + s²_head·A_head) col with A_pos = A − A_head, and
                // colᵀ A col = col[i]; one variance for both gives s²·col[i].
                let head: f64 = (0..n)
                    .map(|e| {
                        (0..n)
                            .map(|f| col[e] * heading.a[e][f] * col[f])
                            .sum::<f64>()
                    })
                    .sum();
                let var = s2_position * (col[i] - head) + s2_heading * head;
                *s = Some(libm::sqrt(fmax(var, 0.0)));
            }
        }
    }
    sigma
}

impl Problem<'_, '_> {
    /// The per-run report at the fitted `model` (weights `w`, the kept residual rows `known`,
    /// whether and how often the fit was reweighted, the runs' scales), and the weighted count of
    /// residual components.
    fn report(
        &self,
        model: &ArcModel,
        w: Option<&[Weight]>,
        known: Option<&Residuals>,
        (reweighted, reweights): (bool, u32),
        scales: &[Option<Scales>],
    ) -> (ExactFit, f64) {
        let mut fit = ExactFit {
            robust: self.options.robust,
            reweighted,
            reweights,
            outliers: 0,
            run_count: 0,
            parameters: (self.n + 2 * self.groups.count()) as u32,
            fits: [RunFit::EMPTY; MAX_RUN_FITS],
            end_offsets: [EndOffset::default(); MAX_GROUPS],
            end_offset_groups: 0,
        };
        let offsets = self.offsets(w, known, model);
        fit.end_offset_groups = self.groups.count();
        for (g, e) in fit
            .end_offsets
            .iter_mut()
            .enumerate()
            .take(fit.end_offset_groups)
        {
            *e = EndOffset {
                first_run: self.groups.first(g),
                offset_m: offsets[g],
            };
        }
        let mut weighted_components = 0.0;
        for (i, run) in self.runs.iter().enumerate() {
            if !Problem::usable(run) {
                continue;
            }
            let wi = weight(w, i);
            weighted_components += wi.run * self.components(run) as f64;
            let scale = if reweighted {
                scales.get(i).copied().flatten()
            } else {
                None
            };
            let kept = Problem::kept(i, run, known);
            let offset = self.group(run).map(|g| offsets[g]);
            let rf = self.run_fit(i, model, kept, wi, scale, offset);
            if rf.outlier {
                fit.outliers += 1;
            }
            if fit.run_count < MAX_RUN_FITS {
                fit.fits[fit.run_count] = rf;
            }
            fit.run_count += 1;
        }
        (fit, weighted_components)
    }
}
