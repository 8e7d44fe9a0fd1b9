//! The model and its residuals: the runs re-integrated with the geometry of the parameters, the
//! residual rows of each run (end pose, or positions along the path) and the weighted cost.

use super::jacobian::end_pose_derivatives;
use super::offset::{Groups, Sums};
use super::robust::{Weight, weight};
use super::{ExactOptions, MAX_RUN_FITS};
use crate::calibration::{FACTOR_RANGE, RunObservation, wrap_angle};
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::{ArcModel, ArcModelF32, PoseF32, PoseF64};

/// The precision of a pass over the runs (see the `exact` module docs, *`f32` while iterating*).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Precision {
    /// `f32` ([`ArcModelF32`]): the residuals and the Jacobian that steer the iterations.
    F32,
    /// `f64` ([`ArcModel`]): the residuals and the Jacobian that define where the fit ends, and
    /// its 1σ.
    F64,
}

/// The most models a residual row is evaluated for at once (`1 + 2n`, n ≤ 3).
pub(super) const MODELS: usize = 7;

/// Residual channels: end (or path) position x, y, and the end heading.
pub(super) const CHANNELS: usize = 3;
pub(super) const X: usize = 0;
pub(super) const Y: usize = 1;
pub(super) const HEADING: usize = 2;

/// How many runs' residual rows and end-pose derivatives [`Problem::cost`] keeps for
/// [`Problem::normal`] (runs beyond get a pass of their own there): the most runs a fit reports
/// ([`MAX_RUN_FITS`]; the board holds 12).
pub(super) const RESIDUAL_CACHE: usize = MAX_RUN_FITS;

/// What one pass over an end-pose run at a set of parameters keeps
/// ([`Problem::end_pass`]): its residual rows and the derivatives of its predicted end pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Kept {
    /// The residual rows by channel (x, y, `ℓ`·heading; zero for a heading not used).
    pub(super) rows: [f64; CHANNELS],
    /// `d[q][c] = ∂(x, y, θ)_c/∂m_q` of the predicted end pose, `m = (right, left, wheelbase)`
    /// the model's numbers (see `jacobian::end_pose_derivatives`).
    pub(super) d: [[f64; 3]; 3],
    /// The wrapped heading residual, radians (zero for a heading not used).
    pub(super) heading_rad: f64,
}

impl Kept {
    pub(super) const ZERO: Kept = Kept {
        rows: [0.0; CHANNELS],
        d: [[0.0; 3]; 3],
        heading_rad: 0.0,
    };
}

/// What [`Problem::cost`] kept of the first [`RESIDUAL_CACHE`] runs at one set of parameters
/// (meaningful for the end-pose runs among them).
pub(super) type Residuals = [Kept; RESIDUAL_CACHE];

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
    /// The groups of runs that share an end offset ([`Problem::offset_groups`]).
    pub(super) groups: Groups,
}

impl Problem<'_, '_> {
    pub(super) fn geometry(&self, p: &[f64; 3]) -> Geometry {
        let e_s = if self.n == 3 { p[2] } else { self.fixed_scale };
        self.nominal.with_factors(p[0], p[1], e_s)
    }

    pub(super) fn usable(run: &RunObservation<'_>) -> bool {
        run.knots.len() >= 2
    }

    /// Whether the run is fitted along its whole path (never without the `mocap` feature).
    pub(super) fn is_path(run: &RunObservation<'_>) -> bool {
        cfg!(feature = "mocap") && !run.truth_path.is_empty()
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
                let pose = poses(&end, &end32);
                for m in 0..all {
                    v[m] = (truth.x_m - pose[m].x_m) * norm;
                }
                row(&v[..all], X);
                for m in 0..all {
                    v[m] = (truth.y_m - pose[m].y_m) * norm;
                }
                row(&v[..all], Y);
                if self.heading(run).is_some() {
                    let l = self.heading_length(run) * norm;
                    for m in 0..all {
                        v[m] = wrap_angle(truth.theta_rad - pose[m].theta_rad) * l;
                    }
                    row(&v[..all], HEADING);
                }
            }
            return;
        }
        for (m, model) in models[..nm].iter().enumerate() {
            end[m] = model.integrate(PoseF64::default(), run.knots);
        }
        for (m, model) in models32[..nm32].iter().enumerate() {
            end32[m] = model.integrate(PoseF32::default(), run.knots);
        }
        let pose = poses(&end, &end32);
        let meas = &run.measured;
        for m in 0..all {
            v[m] = meas.x_m - pose[m].x_m;
        }
        row(&v[..all], X);
        for m in 0..all {
            v[m] = meas.y_m - pose[m].y_m;
        }
        row(&v[..all], Y);
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
        self.residual(run, model, Precision::F64)
    }

    /// The residual rows of run `i` in `known`, when it is an end-pose run kept there (one row
    /// per channel, so its `d²` are their squares).
    pub(super) fn kept<'k>(
        i: usize,
        run: &RunObservation<'_>,
        known: Option<&'k Residuals>,
    ) -> Option<&'k Kept> {
        known.and_then(|r| r.get(i)).filter(|_| !Self::is_path(run))
    }

    /// One pass over an end-pose run for `model` in the precision `precision`: its residual
    /// rows and the derivatives of its end pose (`jacobian::end_pose_derivatives`, which
    /// integrates the same arcs as [`ArcModel::integrate`], equal to rounding).
    pub(super) fn end_pass(
        &self,
        run: &RunObservation<'_>,
        model: &ArcModel,
        precision: Precision,
    ) -> Kept {
        let (pose, d) = match precision {
            Precision::F32 => end_pose_derivatives::<f32>(model, run.knots),
            Precision::F64 => end_pose_derivatives::<f64>(model, run.knots),
        };
        let meas = &run.measured;
        let mut kept = Kept {
            rows: [meas.x_m - pose[X], meas.y_m - pose[Y], 0.0],
            d,
            heading_rad: 0.0,
        };
        if let Some(t) = self.heading(run) {
            let a = t - pose[HEADING];
            // In `f32` (a residual good to 1e-6 m anyway) an angle within ±π is its own wrap;
            // `wrap_angle` (a sine, a cosine and an arctangent in soft-float `f64`) only beyond.
            let plain = precision == Precision::F32 && libm::fabs(a) <= core::f64::consts::PI;
            kept.heading_rad = if plain { a } else { wrap_angle(a) };
            kept.rows[HEADING] = kept.heading_rad * self.heading_length(run);
        }
        kept
    }

    /// The squared length `d²` by channel of a run's residual rows for `model` (zero for a
    /// missing heading), the run re-integrated in the precision `precision`.
    fn residual(
        &self,
        run: &RunObservation<'_>,
        model: &ArcModel,
        precision: Precision,
    ) -> [f64; CHANNELS] {
        let mut d2 = [0.0; CHANNELS];
        let model32 = [ArcModelF32::from_model(model)];
        let (models, models32) = match precision {
            Precision::F64 => (core::slice::from_ref(model), &model32[..0]),
            Precision::F32 => (&[][..], &model32[..]),
        };
        self.rows(run, models, models32, |v, c| {
            d2[c] += v[0] * v[0];
        });
        d2
    }

    /// Number of residual rows of a run (2 per knot of a path run).
    pub(super) fn row_count(&self, run: &RunObservation<'_>) -> usize {
        let per_pose = 2 + usize::from(self.heading(run).is_some());
        if Self::is_path(run) {
            per_pose * (run.knots.len() - 1)
        } else {
            per_pose
        }
    }

    /// Weighted sum of squared residuals and number of residual components; `None` for an
    /// invalid geometry. With `residuals` given, every end-pose run is evaluated by
    /// [`Problem::end_pass`] and what it keeps of the first [`RESIDUAL_CACHE`] runs goes there
    /// (read by [`Problem::normal`], which then needs no pass of its own at the same
    /// parameters); without, the runs are only re-integrated.
    /// `known` are residual rows already computed at `p` (an end-pose run among them is not
    /// re-integrated; the cost is the same bit for bit). The runs are re-integrated in the
    /// precision `precision` (see the module docs, *`f32` while iterating*).
    pub(super) fn cost(
        &self,
        p: &[f64; 3],
        weights: Option<&[Weight]>,
        known: Option<&Residuals>,
        mut residuals: Option<&mut Residuals>,
        precision: Precision,
    ) -> Option<(f64, usize)> {
        if !(0..self.n).all(|i| FACTOR_RANGE.contains(&p[i])) {
            return None;
        }
        let model = ArcModel::from_geometry(&self.geometry(p));
        let mut ss = 0.0;
        let mut m = 0;
        let mut sums = Sums::default();
        for (i, run) in self.runs.iter().enumerate() {
            if Self::usable(run) {
                let group = self.group(run);
                let kept = match Self::kept(i, run, known) {
                    Some(k) => Some(*k),
                    None if (residuals.is_some() || group.is_some()) && !Self::is_path(run) => {
                        Some(self.end_pass(run, &model, precision))
                    }
                    None => None,
                };
                let d2 = match &kept {
                    Some(k) => squares(&k.rows),
                    None => self.residual(run, &model, precision),
                };
                let slot = residuals.as_deref_mut().and_then(|c| c.get_mut(i));
                if let (Some(slot), Some(k)) = (slot, kept) {
                    *slot = k;
                }
                let w = weight(weights, i);
                ss += (0..CHANNELS).map(|c| w.row(c) * d2[c]).sum::<f64>();
                m += self.components(run);
                if let (Some(g), Some(k)) = (group, kept) {
                    sums.add_position(g, w, &k.rows);
                }
            }
        }
        Some((ss - sums.cost_reduction(), m))
    }
}
