//! The Jacobian and the solver: normal equations from the analytic end-pose Jacobian or central
//! differences of re-integrations (in `f32` while iterating, `f64` at the end) and
//! Levenberg–Marquardt with fixed run weights.

use super::linalg::{Mat, solve};
use super::offset::Sums;
use super::problem::{HEADING, Kept, MODELS, Precision, Problem, RESIDUAL_CACHE, Residuals, X, Y};
use super::robust::{Weight, weight};
use super::{
    COST_TOLERANCE, COST_TOLERANCE_F32, JACOBIAN_STEP, JACOBIAN_STEP_F32, STEP_TOLERANCE,
    STEP_TOLERANCE_F32, UNCHECKED_DECREASE,
};
use crate::calibration::CalibrationError;
use crate::calibration::FACTOR_RANGE;
use crate::kinematics::reference::{ArcModel, ArcModelF32};
use crate::util::num::fmax;

/// `∂(right, left, wheelbase)/∂p_i` of the model (row `i`).
pub(super) type Numbers = [[f64; 3]; 3];

/// The end-heading rows' part of the normal equations: `JᵀWJ` and `rᵀWr` over those rows alone,
/// and how many there are (for the uncertainty by channel, see [`Problem::normal`]).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct HeadingPart {
    pub(super) a: Mat,
    pub(super) cost: f64,
    pub(super) rows: usize,
}

/// The result of one least-squares solve.
pub(super) struct Solved {
    pub(super) p: [f64; 3],
    pub(super) cost: f64,
    pub(super) iterations: u32,
    /// The residual rows at `p` (of the first [`RESIDUAL_CACHE`] runs).
    pub(super) residuals: Residuals,
}

impl Problem<'_, '_> {
    /// `JᵀWJ` and `JᵀWr` at `p`, with `J = ∂predicted/∂p` and `r` the residuals in the
    /// precision `jacobian` (see the module docs, *`f32` while iterating*).
    ///
    /// `at_p` is what [`Problem::cost`] kept at `p`: an end-pose run among it has its residual
    /// rows and the derivatives of its end pose from one pass there; another end-pose run gets
    /// that pass here; a path run is re-integrated at `p` (in `f64`) and for the central
    /// differences. The end-heading rows' own share of `JᵀWJ` and of the cost comes with them
    /// (the offsets touch position rows only, so it needs no projection).
    pub(super) fn normal(
        &self,
        p: &[f64; 3],
        weights: Option<&[Weight]>,
        jacobian: Precision,
        at_p: Option<&Residuals>,
    ) -> (Mat, [f64; 3], Numbers, HeadingPart) {
        let n = self.n;
        let mut a = [[0.0; 3]; 3];
        let mut heading_part = HeadingPart::default();
        let mut g = [0.0; 3];
        let mut sums = Sums::default();
        let h = match jacobian {
            Precision::F32 => JACOBIAN_STEP_F32,
            Precision::F64 => JACOBIAN_STEP,
        };
        // A row's values are v[0] at p (`f64`), v[1 + 2i] at p + h·e_i and v[2 + 2i] at
        // p − h·e_i (in `models[1..]` or in `models32`).
        let mut models = [ArcModel::from_geometry(&self.geometry(p)); MODELS];
        for i in 0..n {
            let mut q = *p;
            q[i] += h;
            models[1 + 2 * i] = ArcModel::from_geometry(&self.geometry(&q));
            q[i] = p[i] - h;
            models[2 + 2 * i] = ArcModel::from_geometry(&self.geometry(&q));
        }
        let mut models32 = [ArcModelF32::from_model(&models[0]); MODELS - 1];
        for (m32, m) in models32.iter_mut().zip(&models[1..]) {
            *m32 = ArcModelF32::from_model(m);
        }
        // ∂(right, left, wheelbase)/∂p_i of the model, by central differences of the geometry
        // (no integration), for the analytic end-pose Jacobian.
        let mut numbers = [[0.0; 3]; 3];
        for i in 0..n {
            let (plus, minus) = (&models[1 + 2 * i], &models[2 + 2 * i]);
            numbers[i] = [
                (plus.right_m_per_tick - minus.right_m_per_tick) / (2.0 * h),
                (plus.left_m_per_tick - minus.left_m_per_tick) / (2.0 * h),
                (plus.wheelbase_m - minus.wheelbase_m) / (2.0 * h),
            ];
        }
        let at = models[0];
        let (models, models32) = match jacobian {
            Precision::F32 => (&models[..1], &models32[..2 * n]),
            Precision::F64 => (&models[..1 + 2 * n], &models32[..0]),
        };
        for (k, run) in self.runs.iter().enumerate() {
            if !Self::usable(run) {
                continue;
            }
            let w = weight(weights, k);
            if !Self::is_path(run) {
                // An end pose: the analytic Jacobian, from the pass that gave its residual rows
                // at p (kept by the cost evaluation, or one pass here).
                let kept = match Self::kept(k, run, at_p) {
                    Some(kept) => *kept,
                    None => self.end_pass(run, &at, jacobian),
                };
                let (r, d) = (kept.rows, kept.d);
                let group = self.group(run);
                let heading = self.heading(run).map(|_| self.heading_length(run));
                for c in [X, Y, HEADING] {
                    let scale = match (c, heading) {
                        (HEADING, None) => continue,
                        (HEADING, Some(l)) => l,
                        _ => 1.0,
                    };
                    let w = w.row(c);
                    let mut j = [0.0; 3];
                    for i in 0..n {
                        j[i] = scale * (0..3).map(|q| d[q][c] * numbers[i][q]).sum::<f64>();
                    }
                    for e in 0..n {
                        g[e] += w * j[e] * r[c];
                        for f in 0..n {
                            a[e][f] += w * j[e] * j[f];
                            if c == HEADING {
                                heading_part.a[e][f] += w * j[e] * j[f];
                            }
                        }
                    }
                    if c == HEADING {
                        heading_part.cost += w * r[c] * r[c];
                        heading_part.rows += 1;
                    }
                    if let (Some(gi), X | Y) = (group, c) {
                        sums.add(gi, c, w, r[c], &j);
                    }
                }
                continue;
            }
            // A path: central differences of re-integrations, `v[0]` the row at p.
            self.rows(run, models, models32, |v, c| {
                let r = v[0];
                let w = w.row(c);
                let mut j = [0.0; 3];
                for i in 0..n {
                    // residual = measured − predicted, so ∂predicted = −∂residual.
                    j[i] = -(v[1 + 2 * i] - v[2 + 2 * i]) / (2.0 * h);
                }
                for c in 0..n {
                    g[c] += w * j[c] * r;
                    for d in 0..n {
                        a[c][d] += w * j[c] * j[d];
                    }
                }
            });
        }
        sums.project(&mut a, &mut g, n);
        (a, g, numbers, heading_part)
    }

    /// Moves the kept rows of the end-pose runs along a step `delta` by their linearisation,
    /// `r(p + δ) = r(p) − Jδ` (for a step taken without a pass at its end: the error is of order
    /// `|δ|²`, below 1e-12 m for the steps [`UNCHECKED_DECREASE`] admits); the derivatives stay
    /// those at `p`.
    fn advance(&self, kept: &mut Residuals, numbers: &Numbers, delta: &[f64; 3]) {
        for (k, run) in self.runs.iter().enumerate().take(RESIDUAL_CACHE) {
            if !Self::usable(run) || Self::is_path(run) {
                continue;
            }
            let kept = &mut kept[k];
            // The change of the predicted end pose, by channel.
            let mut dpred = [0.0; 3];
            for (c, v) in dpred.iter_mut().enumerate() {
                for i in 0..self.n {
                    *v += (0..3).map(|q| kept.d[q][c] * numbers[i][q]).sum::<f64>() * delta[i];
                }
            }
            kept.rows[X] -= dpred[X];
            kept.rows[Y] -= dpred[Y];
            if self.heading(run).is_some() {
                kept.heading_rad -= dpred[HEADING];
                kept.rows[HEADING] = kept.heading_rad * self.heading_length(run);
            }
        }
    }

    /// Levenberg–Marquardt from `p` with fixed run weights, steered by a Jacobian in the
    /// precision `jacobian`; `known` are residual rows already computed at `p`.
    pub(super) fn solve_lm(
        &self,
        mut p: [f64; 3],
        weights: Option<&[Weight]>,
        jacobian: Precision,
        known: Option<&Residuals>,
    ) -> Result<Solved, CalibrationError> {
        let n = self.n;
        // The residual rows at `p` (`known` ones, when given, are those at `p`) and at the
        // trial parameters.
        let mut at_p: Residuals = [Kept::ZERO; RESIDUAL_CACHE];
        let mut at_q: Residuals = [Kept::ZERO; RESIDUAL_CACHE];
        let start = match known {
            Some(known) => {
                at_p = *known;
                self.cost(&p, weights, Some(known), None, jacobian)
            }
            None => self.cost(&p, weights, None, Some(&mut at_p), jacobian),
        };
        // The convergence tolerances of the precision the cost is evaluated in.
        let (step_tolerance, cost_tolerance, unchecked) = match jacobian {
            // No unchecked steps in `f32`: they would move where the robust rounds settle
            // (within the weights' tolerance, but visibly in the Monte Carlo's means), and the
            // `f32` passes are cheap.
            Precision::F32 => (STEP_TOLERANCE_F32, COST_TOLERANCE_F32, COST_TOLERANCE_F32),
            Precision::F64 => (STEP_TOLERANCE, COST_TOLERANCE, UNCHECKED_DECREASE),
        };
        let (mut cost, _) = start.ok_or(CalibrationError::OutOfRange)?;
        let mut lambda = 1e-3;
        let mut iterations = 0;
        let mut converged = false;
        while iterations < self.options.max_iterations && !converged {
            iterations += 1;
            let (a, g, numbers, _) = self.normal(&p, weights, jacobian, Some(&at_p));
            loop {
                let mut aug = a;
                for (i, row) in aug.iter_mut().enumerate().take(n) {
                    row[i] += lambda * a[i][i];
                }
                let delta = solve(aug, g, n).ok_or(CalibrationError::Degenerate)?;
                let step = delta[..n].iter().fold(0.0, |s, v| fmax(s, libm::fabs(*v)));
                let mut q = p;
                for i in 0..n {
                    q[i] += delta[i];
                }
                // The decrease of the cost the linearised residuals predict for this step,
                // `2δᵀg − δᵀAδ` (see the module docs, *`f32` while iterating*): at most the
                // cost's tolerance, the fit has converged at `p`; at most `unchecked` times the
                // cost (noisy data, a step that small that the linearisation holds to far below
                // its size), the step is taken without evaluating it, and the fit has converged.
                let mut predicted = 0.0;
                for i in 0..n {
                    predicted += 2.0 * delta[i] * g[i];
                    for j in 0..n {
                        predicted -= delta[i] * a[i][j] * delta[j];
                    }
                }
                if predicted <= unchecked * cost {
                    if predicted > cost_tolerance * cost
                        && (0..n).all(|i| FACTOR_RANGE.contains(&q[i]))
                    {
                        self.advance(&mut at_p, &numbers, &delta);
                        p = q;
                        cost -= predicted;
                    }
                    converged = true;
                    break;
                }
                match self.cost(&q, weights, None, Some(&mut at_q), jacobian) {
                    Some((c, _)) if c <= cost => {
                        core::mem::swap(&mut at_p, &mut at_q);
                        // Also converged when the cost no longer changes in its 13th digit
                        // (noisy data: the minimum is flat, and LM's last steps only shuffle
                        // rounding).
                        converged = step < step_tolerance || cost - c <= cost_tolerance * cost;
                        p = q;
                        cost = c;
                        lambda = fmax(lambda * 0.1, 1e-12);
                        break;
                    }
                    _ if step < step_tolerance => {
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
        Ok(Solved {
            p,
            cost,
            iterations,
            residuals: at_p,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::geometry::Geometry;
    use crate::kinematics::reference::{PoseF32, PoseF64};
    /// The `f32` Jacobian's columns match the `f64` ones (step 1e-6) to 1e-4 of the column's
    /// size for the factors of a 1 m square run of the paper's robot (4 × 25 knots, 1 % off in
    /// `E_d` and `E_b`): measured 1.4–4.8e-5, the bound twice the largest; with the `f64` step
    /// the `f32` rounding would be at least 1e-2 of the column (measured 2.5–12 %, the reason
    /// for `h = 1e-3`).
    #[test]
    fn f32_jacobian_matches_f64() {
        let nominal = Geometry::PAPER_NOMINAL;
        let model = ArcModel::from_geometry(&nominal);
        let knots = super::super::jacobian::square_knots(&model, false);
        let p = [1.01, 0.99, 1.0];
        let end = |q: [f64; 3]| {
            let m = ArcModel::from_geometry(&nominal.with_factors(q[0], q[1], q[2]));
            let e = m.integrate(PoseF64::default(), &knots);
            [e.x_m, e.y_m, e.theta_rad]
        };
        let end32 = |q: [f64; 3]| {
            let m = ArcModel::from_geometry(&nominal.with_factors(q[0], q[1], q[2]));
            let e = ArcModelF32::from_model(&m).integrate(PoseF32::default(), &knots);
            [e.x_m, e.y_m, e.theta_rad].map(f64::from)
        };
        let column = |f: &dyn Fn([f64; 3]) -> [f64; 3], i: usize, h: f64| {
            let (mut plus, mut minus) = (p, p);
            plus[i] += h;
            minus[i] -= h;
            let (a, b) = (f(plus), f(minus));
            [0, 1, 2].map(|k| (a[k] - b[k]) / (2.0 * h))
        };
        let error = |a: [f64; 3], b: [f64; 3]| {
            let size = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            (0..3).fold(0.0f64, |m, k| m.max((a[k] - b[k]).abs())) / size
        };
        for i in 0..3 {
            let exact = column(&end, i, JACOBIAN_STEP);
            let single = column(&end32, i, JACOBIAN_STEP_F32);
            assert!(
                error(exact, single) < 1e-4,
                "factor {i}: {exact:?} {single:?}"
            );
            let fine = column(&end32, i, JACOBIAN_STEP);
            assert!(error(exact, fine) > 1e-2, "factor {i}: {exact:?} {fine:?}");
        }
    }
}
