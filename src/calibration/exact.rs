//! odocal's exact calibration: a Levenberg–Marquardt least-squares fit of the kinematic
//! parameters to the recorded runs.
//!
//! Parameters `p = (E_d, E_b[, E_s])` are absolute, relative to the nominal geometry:
//! `geometry(p) = nominal.with_factors(E_d, E_b, E_s)`. For every run the recorded tick knots
//! are re-integrated with [`ArcModel`] for `geometry(p)` (exact arcs, no small-angle
//! approximation), and the residual is `measured − predicted` end pose in the start frame:
//! `x`, `y` in metres and, when θ was measured, the wrapped heading residual multiplied by a
//! length scale `ℓ` (by default the run's characteristic length — the side of a square — so a
//! heading error counts like the lateral error it produces over one leg). Any path works:
//! squares, lines, circles, free loops; runs may have been driven with different geometries,
//! because the fit starts from raw ticks.
//!
//! `E_s` (the mean diameter) is only fitted when a straight-line run is present (or when asked
//! to): squares alone determine it poorly. Otherwise it stays at the first run's driving value.
//!
//! Jacobian: central differences with step `h = 1e-6` in each (dimensionless, ≈ 1) parameter:
//! truncation error `O(h²) ≈ 1e-12` relative, rounding about `1e-16·|pose|/h ≈ 1e-10` m; the
//! Jacobian only steers the iteration, the fixed point `Jᵀr = 0` is where the residuals are
//! smallest. Normal equations are accumulated run by run (3×3), so memory does not grow with the
//! number of runs or knots. 1σ uncertainty: `(JᵀJ)⁻¹ σ²` with `σ² = Σr² / (m − n)`.

// Dense 3×3 linear algebra reads best with explicit indices.
#![allow(clippy::needless_range_loop)]

use super::quality::Quality;
use super::stats::SquareStats;
use super::{
    Calibration, CalibrationError, FACTOR_RANGE, Method, RunObservation, factors_of, wrap_angle,
};
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::{ArcModel, PoseF64};
use crate::motion::run::PathKind;

/// Central-difference step for the Jacobian, in units of the (≈ 1) factors.
pub const JACOBIAN_STEP: f64 = 1e-6;

/// Converged when no parameter moves by more than this in one step.
pub const STEP_TOLERANCE: f64 = 1e-12;

/// Converged when an accepted step lowers the cost by less than this fraction.
pub const COST_TOLERANCE: f64 = 1e-13;

/// When the mean diameter `E_s` is fitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ScaleFit {
    /// Only when a straight-line run is present.
    Auto,
    /// Always.
    Always,
    /// Never: keep the first run's driving scale.
    Never,
}

/// Options of the exact method.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExactOptions {
    /// When `E_s` is fitted.
    pub scale: ScaleFit,
    /// Use measured headings as residuals.
    pub use_heading: bool,
    /// Length scale of heading residuals, metres; `None` = each run's characteristic length.
    pub heading_length_m: Option<f64>,
    /// Iteration limit.
    pub max_iterations: u32,
}

impl Default for ExactOptions {
    fn default() -> Self {
        ExactOptions {
            scale: ScaleFit::Auto,
            use_heading: true,
            heading_length_m: None,
            max_iterations: 100,
        }
    }
}

type Mat = [[f64; 3]; 3];

/// Solves `a x = b` for the leading `n × n` block (Gaussian elimination, partial pivoting).
/// `None` when the matrix is singular to working precision.
pub(crate) fn solve(mut a: Mat, mut b: [f64; 3], n: usize) -> Option<[f64; 3]> {
    let scale = (0..n).fold(0.0, |m, i| libm::fmax(m, libm::fabs(a[i][i])));
    if !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    for c in 0..n {
        let mut piv = c;
        for r in c + 1..n {
            if libm::fabs(a[r][c]) > libm::fabs(a[piv][c]) {
                piv = r;
            }
        }
        if libm::fabs(a[piv][c]) <= 1e-14 * scale {
            return None;
        }
        a.swap(c, piv);
        b.swap(c, piv);
        for r in c + 1..n {
            let f = a[r][c] / a[c][c];
            for k in c..n {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0; 3];
    for c in (0..n).rev() {
        let mut s = b[c];
        for k in c + 1..n {
            s -= a[c][k] * x[k];
        }
        x[c] = s / a[c][c];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The problem: runs, nominal geometry, which parameters are free, options.
struct Problem<'r, 'a> {
    runs: &'r [RunObservation<'a>],
    nominal: Geometry,
    n: usize,
    fixed_scale: f64,
    options: ExactOptions,
}

impl Problem<'_, '_> {
    fn geometry(&self, p: &[f64; 3]) -> Geometry {
        let e_s = if self.n == 3 { p[2] } else { self.fixed_scale };
        self.nominal.with_factors(p[0], p[1], e_s)
    }

    /// Residuals of one run for geometry `g`: up to 3 values, and how many.
    fn residuals(&self, run: &RunObservation<'_>, model: &ArcModel) -> ([f64; 3], usize) {
        let end = model.integrate(PoseF64::default(), run.knots);
        let m = &run.measured;
        let mut r = [m.x_m - end.x_m, m.y_m - end.y_m, 0.0];
        match m.theta_rad {
            Some(t) if self.options.use_heading => {
                let l = self
                    .options
                    .heading_length_m
                    .unwrap_or_else(|| run.characteristic_length_m());
                r[2] = wrap_angle(t - end.theta_rad) * l;
                (r, 3)
            }
            _ => (r, 2),
        }
    }

    fn usable(run: &RunObservation<'_>) -> bool {
        run.knots.len() >= 2
    }

    /// Sum of squared residuals and number of residuals; `None` for an invalid geometry.
    fn cost(&self, p: &[f64; 3]) -> Option<(f64, usize)> {
        if !(0..self.n).all(|i| FACTOR_RANGE.contains(&p[i])) {
            return None;
        }
        let model = ArcModel::from_geometry(&self.geometry(p));
        let mut ss = 0.0;
        let mut m = 0;
        for run in self.runs.iter().filter(|r| Self::usable(r)) {
            let (r, k) = self.residuals(run, &model);
            ss += r[..k].iter().map(|v| v * v).sum::<f64>();
            m += k;
        }
        Some((ss, m))
    }

    /// `JᵀJ` and `Jᵀr` at `p`, with `J = ∂predicted/∂p`.
    fn normal(&self, p: &[f64; 3]) -> (Mat, [f64; 3]) {
        let mut a = [[0.0; 3]; 3];
        let mut g = [0.0; 3];
        let model0 = ArcModel::from_geometry(&self.geometry(p));
        let mut plus = [ArcModel::from_geometry(&self.nominal); 3];
        let mut minus = plus;
        for i in 0..self.n {
            let mut q = *p;
            q[i] += JACOBIAN_STEP;
            plus[i] = ArcModel::from_geometry(&self.geometry(&q));
            q[i] = p[i] - JACOBIAN_STEP;
            minus[i] = ArcModel::from_geometry(&self.geometry(&q));
        }
        for run in self.runs.iter().filter(|r| Self::usable(r)) {
            let (r0, k) = self.residuals(run, &model0);
            let mut j = [[0.0; 3]; 3]; // j[row][param]
            for i in 0..self.n {
                let (rp, _) = self.residuals(run, &plus[i]);
                let (rm, _) = self.residuals(run, &minus[i]);
                for row in 0..k {
                    // residual = measured − predicted, so ∂predicted = −∂residual.
                    j[row][i] = -(rp[row] - rm[row]) / (2.0 * JACOBIAN_STEP);
                }
            }
            for row in 0..k {
                for c in 0..self.n {
                    g[c] += j[row][c] * r0[row];
                    for d in 0..self.n {
                        a[c][d] += j[row][c] * j[row][d];
                    }
                }
            }
        }
        (a, g)
    }
}

/// Fits the parameters; see the module docs.
///
/// # Errors
/// `NoRuns` when no run has at least two knots, `Degenerate` when the parameters are not
/// determined by the runs, `NotConverged`, `OutOfRange`, `InvalidGeometry`.
pub fn calibrate_exact(
    runs: &[RunObservation<'_>],
    nominal: &Geometry,
    options: &ExactOptions,
) -> Result<Calibration, CalibrationError> {
    let first = runs
        .iter()
        .find(|r| Problem::usable(r))
        .ok_or(CalibrationError::NoRuns)?;
    let has_line = runs.iter().any(|r| matches!(r.path, PathKind::Line { .. }));
    let fit_scale = match options.scale {
        ScaleFit::Auto => has_line,
        ScaleFit::Always => true,
        ScaleFit::Never => false,
    };
    let (d0, b0, s0) = factors_of(&first.geometry, nominal);
    let problem = Problem {
        runs,
        nominal: *nominal,
        n: if fit_scale { 3 } else { 2 },
        fixed_scale: s0,
        options: *options,
    };
    let n = problem.n;
    let mut p = [d0, b0, s0];
    let (mut cost, m) = problem.cost(&p).ok_or(CalibrationError::OutOfRange)?;
    if m <= n {
        return Err(CalibrationError::Degenerate);
    }
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let mut converged = false;
    while iterations < options.max_iterations && !converged {
        iterations += 1;
        let (a, g) = problem.normal(&p);
        loop {
            let mut aug = a;
            for (i, row) in aug.iter_mut().enumerate().take(n) {
                row[i] += lambda * a[i][i];
            }
            let delta = solve(aug, g, n).ok_or(CalibrationError::Degenerate)?;
            let step = delta[..n]
                .iter()
                .fold(0.0, |s, v| libm::fmax(s, libm::fabs(*v)));
            let mut q = p;
            for i in 0..n {
                q[i] += delta[i];
            }
            match problem.cost(&q) {
                Some((c, _)) if c <= cost => {
                    // Also converged when the cost no longer changes in its 13th digit (noisy
                    // data: the minimum is flat, and LM's last steps only shuffle rounding).
                    converged = step < STEP_TOLERANCE || cost - c <= COST_TOLERANCE * cost;
                    p = q;
                    cost = c;
                    lambda = libm::fmax(lambda * 0.1, 1e-12);
                    break;
                }
                _ if step < STEP_TOLERANCE => {
                    // At the noise floor of the cost: no smaller step can improve it.
                    converged = true;
                    break;
                }
                _ => {
                    lambda *= 10.0;
                    if lambda > 1e12 {
                        return Err(CalibrationError::NotConverged);
                    }
                }
            }
        }
    }
    if !converged {
        return Err(CalibrationError::NotConverged);
    }
    let geometry = problem.geometry(&p);
    geometry
        .validate()
        .map_err(|_| CalibrationError::InvalidGeometry)?;
    let (e_d, e_b, e_s) = factors_of(&geometry, nominal);
    if !(FACTOR_RANGE.contains(&e_d) && FACTOR_RANGE.contains(&e_b) && FACTOR_RANGE.contains(&e_s))
    {
        return Err(CalibrationError::OutOfRange);
    }
    // Uncertainty from the residual scatter.
    let (a, _) = problem.normal(&p);
    let dof = (m - n) as f64;
    let sigma2 = cost / dof;
    let mut sigma = [None; 3];
    for (i, s) in sigma.iter_mut().enumerate().take(n) {
        let mut e = [0.0; 3];
        e[i] = 1.0;
        if let Some(col) = solve(a, e, n) {
            *s = Some(libm::sqrt(libm::fmax(col[i], 0.0) * sigma2));
        }
    }
    let sigma_out = sigma[0]
        .zip(sigma[1])
        .map(|(d, b)| [d, b, sigma[2].unwrap_or(0.0)]);
    let stats = SquareStats::from_runs(runs, false).ok();
    let rms = libm::sqrt(cost / m as f64);
    let quality = Quality::from_runs(runs, &geometry, stats.as_ref(), sigma_out, Some(rms));
    Ok(Calibration {
        method: Method::Exact,
        e_d,
        e_b,
        e_s,
        geometry,
        quality,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solve_3x3_and_singular() {
        let a = [[4.0, 1.0, 2.0], [1.0, 3.0, 0.0], [2.0, 0.0, 5.0]];
        let x = solve(a, [7.0, 4.0, 7.0], 3).unwrap();
        // The system was built from x = (1, 1, 1).
        for v in x {
            assert!((v - 1.0).abs() < 1e-14);
        }
        let singular = [[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 0.0, 0.0]];
        assert!(solve(singular, [1.0, 2.0, 0.0], 2).is_none());
    }
}
