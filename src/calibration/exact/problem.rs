//! The model and its residuals: the runs re-integrated with the geometry of the parameters, the
//! residual rows of each run (end pose, or positions along the path) and the weighted cost.

use super::ExactOptions;
use super::robust::{Weight, weight};
use crate::calibration::{FACTOR_RANGE, RunObservation, wrap_angle};
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::{ArcModel, ArcModelF32, PoseF32, PoseF64};

/// The most models a residual row is evaluated for at once (`1 + 2n`, n ≤ 3).
pub(super) const MODELS: usize = 7;

/// Residual channels: end (or path) position x, y, and the end heading.
pub(super) const CHANNELS: usize = 3;
pub(super) const X: usize = 0;
pub(super) const Y: usize = 1;
pub(super) const HEADING: usize = 2;

/// How many runs' residual rows [`Problem::cost`] keeps for [`Problem::normal`] (runs beyond
/// are re-integrated there).
pub(super) const RESIDUAL_CACHE: usize = 32;

/// The residual rows by channel of the first [`RESIDUAL_CACHE`] runs at one set of parameters.
pub(super) type Residuals = [[f64; CHANNELS]; RESIDUAL_CACHE];

/// `d²` by channel of an end-pose run's residual rows: their squares, as [`Problem::rows`]
/// accumulates them (from zero, so bit for bit).
pub(super) fn squares(r: &[f64; CHANNELS]) -> [f64; CHANNELS] {
    let mut d2 = [0.0; CHANNELS];
    for c in 0..CHANNELS {
        d2[c] += r[c] * r[c];
    }
    d2
}

/// The problem: runs, nominal geometry, which parameters are free, options.
pub(super) struct Problem<'r, 'a> {
    pub(super) runs: &'r [RunObservation<'a>],
    pub(super) nominal: Geometry,
    pub(super) n: usize,
    pub(super) fixed_scale: f64,
    pub(super) options: ExactOptions,
}

impl Problem<'_, '_> {
    pub(super) fn geometry(&self, p: &[f64; 3]) -> Geometry {
        let e_s = if self.n == 3 { p[2] } else { self.fixed_scale };
        self.nominal.with_factors(p[0], p[1], e_s)
    }

    pub(super) fn usable(run: &RunObservation<'_>) -> bool {
        run.knots.len() >= 2
    }

    pub(super) fn is_path(run: &RunObservation<'_>) -> bool {
        !run.truth_path.is_empty()
    }

    /// The measured end heading, when it is used: with ground truth along the path only when a
    /// heading length is given (see the `exact` module docs).
    pub(super) fn heading(&self, run: &RunObservation<'_>) -> Option<f64> {
        let along_path = Self::is_path(run) && self.options.heading_length_m.is_none();
        run.measured
            .theta_rad
            .filter(|_| self.options.use_heading && !along_path)
    }

    pub(super) fn heading_length(&self, run: &RunObservation<'_>) -> f64 {
        self.options
            .heading_length_m
            .unwrap_or_else(|| self.options.heading_weight * run.characteristic_length_m())
    }

    /// Number of residual components of a run: 2 (x, y) or 3 (with the heading).
    pub(super) fn components(&self, run: &RunObservation<'_>) -> usize {
        if self.heading(run).is_some() { 3 } else { 2 }
    }

    /// Calls `row` for every residual row of `run`, with the row's value under each of
    /// `models` followed by its value under each of `models32` (at most [`MODELS`] in all).
    pub(super) fn rows(
        &self,
        run: &RunObservation<'_>,
        models: &[ArcModel],
        models32: &[ArcModelF32],
        mut row: impl FnMut(&[f64], usize),
    ) {
        let nm = models.len().min(MODELS);
        let nm32 = models32.len().min(MODELS - nm);
        let all = nm + nm32;
        let mut v = [0.0; MODELS];
        let mut end = [PoseF64::default(); MODELS];
        let mut end32 = [PoseF32::default(); MODELS];
        // The end (or knot) poses of all models, in `f64`.
        let poses = |end: &[PoseF64; MODELS], end32: &[PoseF32; MODELS]| {
            let mut out = *end;
            for (m, e) in end32[..nm32].iter().enumerate() {
                out[nm + m] = PoseF64::new(e.x_m.into(), e.y_m.into(), e.theta_rad.into());
            }
            out
        };
        let mut pose = [PoseF64::default(); MODELS];
        if Self::is_path(run) {
            let samples = (run.knots.len() - 1) as f64;
            let norm = 1.0 / libm::sqrt(samples);
            for j in 1..run.knots.len() {
                let truth = run.truth_path[j];
                let knots = &run.knots[j - 1..=j];
                for (m, model) in models[..nm].iter().enumerate() {
                    end[m] = model.integrate(end[m], knots);
                }
                for (m, model) in models32[..nm32].iter().enumerate() {
                    end32[m] = model.integrate(end32[m], knots);
                }
                pose = poses(&end, &end32);
                for m in 0..all {
                    v[m] = (truth.x_m - pose[m].x_m) * norm;
                }
                row(&v[..all], X);
                for m in 0..all {
                    v[m] = (truth.y_m - pose[m].y_m) * norm;
                }
                row(&v[..all], Y);
            }
        } else {
            for (m, model) in models[..nm].iter().enumerate() {
                end[m] = model.integrate(PoseF64::default(), run.knots);
            }
            for (m, model) in models32[..nm32].iter().enumerate() {
                end32[m] = model.integrate(PoseF32::default(), run.knots);
            }
            pose = poses(&end, &end32);
            let meas = &run.measured;
            for m in 0..all {
                v[m] = meas.x_m - pose[m].x_m;
            }
            row(&v[..all], X);
            for m in 0..all {
                v[m] = meas.y_m - pose[m].y_m;
            }
            row(&v[..all], Y);
        }
        if let Some(t) = self.heading(run) {
            let l = self.heading_length(run);
            for m in 0..all {
                v[m] = wrap_angle(t - pose[m].theta_rad) * l;
            }
            row(&v[..all], HEADING);
        }
    }

    /// Squared length `d²` of a run's residual for `model`, by channel (x, y, heading).
    pub(super) fn distance2(&self, run: &RunObservation<'_>, model: &ArcModel) -> [f64; CHANNELS] {
        self.residual(run, model).1
    }

    /// The residual rows of run `i` in `known`, when it is an end-pose run kept there (one row
    /// per channel, so its `d²` are their squares).
    pub(super) fn kept<'k>(
        i: usize,
        run: &RunObservation<'_>,
        known: Option<&'k Residuals>,
    ) -> Option<&'k [f64; CHANNELS]> {
        known.and_then(|r| r.get(i)).filter(|_| !Self::is_path(run))
    }

    /// A run's residual rows for `model` by channel (meaningful for an end-pose run, whose rows
    /// are one per channel; zero for a missing heading) and their squared length `d²` by channel.
    fn residual(
        &self,
        run: &RunObservation<'_>,
        model: &ArcModel,
    ) -> ([f64; CHANNELS], [f64; CHANNELS]) {
        let mut r = [0.0; CHANNELS];
        let mut d2 = [0.0; CHANNELS];
        self.rows(run, core::slice::from_ref(model), &[], |v, c| {
            r[c] = v[0];
            d2[c] += v[0] * v[0];
        });
        (r, d2)
    }

    /// Number of residual rows of a run (2 per knot of a path run).
    pub(super) fn row_count(&self, run: &RunObservation<'_>) -> usize {
        let pos = if Self::is_path(run) {
            2 * (run.knots.len() - 1)
        } else {
            2
        };
        pos + usize::from(self.heading(run).is_some())
    }

    /// Weighted sum of squared residuals and number of residual components; `None` for an
    /// invalid geometry. The residual rows of the first [`RESIDUAL_CACHE`] runs are kept in
    /// `residuals` when given (read by [`Problem::normal`] for the end-pose runs, which then
    /// need no `f64` re-integration at the same parameters).
    /// `known` are residual rows already computed at `p` (an end-pose run among them is not
    /// re-integrated; the cost is the same bit for bit).
    pub(super) fn cost(
        &self,
        p: &[f64; 3],
        weights: Option<&[Weight]>,
        known: Option<&Residuals>,
        mut residuals: Option<&mut Residuals>,
    ) -> Option<(f64, usize)> {
        if !(0..self.n).all(|i| FACTOR_RANGE.contains(&p[i])) {
            return None;
        }
        let model = ArcModel::from_geometry(&self.geometry(p));
        let mut ss = 0.0;
        let mut m = 0;
        for (i, run) in self.runs.iter().enumerate() {
            if Self::usable(run) {
                let (r, d2) = match Self::kept(i, run, known) {
                    Some(r) => (*r, squares(r)),
                    None => self.residual(run, &model),
                };
                if let Some(slot) = residuals.as_deref_mut().and_then(|c| c.get_mut(i)) {
                    *slot = r;
                }
                let w = weight(weights, i);
                ss += (0..CHANNELS).map(|c| w.row(c) * d2[c]).sum::<f64>();
                m += self.components(run);
            }
        }
        Some((ss, m))
    }
}
