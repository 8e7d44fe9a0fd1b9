//! What the exact fit reports per run: residuals against the fitted model, the run's scales and
//! weights, and whether it was flagged as an outlier.

use super::offset::MAX_GROUPS;
use super::problem::{HEADING, Kept, Problem, X, Y};
use super::robust::{Scales, Weight};
use super::{MAX_RUN_FITS, OUTLIER_WEIGHT};
use crate::calibration::wrap_angle;
use crate::kinematics::reference::{ArcModel, PoseF64};

/// How one run fits the result.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct RunFit {
    /// Index of the run in the input slice.
    pub index: usize,
    /// End-pose residual `measured − predicted` in x, metres, with the fitted geometry (less
    /// the end offset of the run's group, when it has one).
    pub residual_x_m: f64,
    /// End-pose residual in y, metres.
    pub residual_y_m: f64,
    /// End heading residual, radians (wrapped), when the heading was measured and used.
    pub residual_theta_rad: Option<f64>,
    /// RMS position error along the path, metres, for a run with ground truth along its path.
    pub path_rms_m: Option<f64>,
    /// Scale (robust σ) of one position component among the run's peers, metres; `None` when
    /// the run was not judged (plain fit, or fewer than [`MIN_PEERS`] peers).
    ///
    /// [`MIN_PEERS`]: super::MIN_PEERS
    pub scale_m: Option<f64>,
    /// Scale of the heading residual among the run's peers, radians (heading used).
    pub scale_heading_rad: Option<f64>,
    /// The weight the run ended with, in (0, 1]; 1 in the plain fit.
    pub weight: f64,
    /// Relative weights of the run's x, y and heading rows against its position (see the
    /// `exact` module docs, *Channel weights*); `[1, 1, 1]` is the a-priori weighting (heading by `ℓ`).
    pub channel_weights: [f64; 3],
    /// The weight ended below [`OUTLIER_WEIGHT`]: the run disagrees with its peers.
    pub outlier: bool,
    /// The end offset `(x, y)` of the run's group, metres, when one was fitted (see the `exact`
    /// module docs, *End offset*).
    pub end_offset_m: Option<[f64; 2]>,
}

impl RunFit {
    pub(super) const EMPTY: RunFit = RunFit {
        index: 0,
        residual_x_m: 0.0,
        residual_y_m: 0.0,
        residual_theta_rad: None,
        path_rms_m: None,
        scale_m: None,
        scale_heading_rad: None,
        weight: 1.0,
        channel_weights: [1.0; 3],
        outlier: false,
        end_offset_m: None,
    };
}

/// Per-run report of an exact fit: residual, weight and outlier flag of every run.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ExactFit {
    /// The robust fit was asked for.
    pub robust: bool,
    /// The runs were reweighted (robust, and at most [`MAX_WEIGHTED_RUNS`] runs).
    ///
    /// [`MAX_WEIGHTED_RUNS`]: super::MAX_WEIGHTED_RUNS
    pub reweighted: bool,
    /// Reweighting rounds (0 when the least-squares weights were already stable).
    pub reweights: u32,
    /// Runs flagged as outliers.
    pub outliers: u32,
    /// Runs in the fit (those with at least two knots).
    pub run_count: usize,
    /// Numbers fitted: the factors and two per end offset (the degrees of freedom the fit
    /// takes from the residuals).
    pub parameters: u32,
    pub(super) fits: [RunFit; MAX_RUN_FITS],
    /// The end offset of every group of closed paths (see the module docs, *End offset*), in
    /// the order of each group's first run.
    pub(super) end_offsets: [EndOffset; MAX_GROUPS],
    pub(super) end_offset_groups: usize,
}

/// The end offset of one group of closed paths of one kind and size (see the `exact` module
/// docs, *End offset*).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct EndOffset {
    /// Index of the group's first run in the runs given to the fit.
    pub first_run: usize,
    /// The offset `(x, y)` in the start frame, metres (truth − fit).
    pub offset_m: [f64; 2],
}

impl ExactFit {
    /// The fits of the first [`MAX_RUN_FITS`] runs in the fit, in input order.
    pub fn runs(&self) -> &[RunFit] {
        &self.fits[..self.run_count.min(MAX_RUN_FITS)]
    }

    /// The end offsets fitted, one per group of closed paths of one kind and size, in the order
    /// of each group's first run; empty when none was fitted. Every run's own is in its
    /// [`RunFit::end_offset_m`], for the first [`MAX_RUN_FITS`] runs.
    pub fn end_offsets(&self) -> &[EndOffset] {
        &self.end_offsets[..self.end_offset_groups.min(MAX_GROUPS)]
    }
}

impl Problem<'_, '_> {
    /// The report of run `index` for the fitted model; `kept` is what the last pass at the
    /// fitted parameters kept of an end-pose run (its residuals, which then need no
    /// re-integration).
    pub(super) fn run_fit(
        &self,
        index: usize,
        model: &ArcModel,
        kept: Option<&Kept>,
        weight: Weight,
        scales: Option<Scales>,
        end_offset_m: Option<[f64; 2]>,
    ) -> RunFit {
        let run = &self.runs[index];
        let (residual_x_m, residual_y_m, residual_theta_rad) = match kept {
            Some(k) => (
                k.rows[X],
                k.rows[Y],
                self.heading(run).map(|_| k.heading_rad),
            ),
            None => {
                let end = model.integrate(PoseF64::default(), run.knots);
                (
                    run.measured.x_m - end.x_m,
                    run.measured.y_m - end.y_m,
                    self.heading(run).map(|t| wrap_angle(t - end.theta_rad)),
                )
            }
        };
        let path_rms_m = Self::is_path(run).then(|| {
            let mut pose = PoseF64::default();
            let mut ss = 0.0;
            for j in 1..run.knots.len() {
                pose = model.integrate(pose, &run.knots[j - 1..=j]);
                let t = run.truth_path[j];
                ss += (t.x_m - pose.x_m) * (t.x_m - pose.x_m)
                    + (t.y_m - pose.y_m) * (t.y_m - pose.y_m);
            }
            libm::sqrt(ss / (run.knots.len() - 1) as f64)
        });
        let [offset_x, offset_y] = end_offset_m.unwrap_or_default();
        RunFit {
            index,
            residual_x_m: residual_x_m - offset_x,
            residual_y_m: residual_y_m - offset_y,
            residual_theta_rad,
            path_rms_m,
            scale_m: scales.map(|s| s.position_m),
            scale_heading_rad: scales.and_then(|s| s.heading_rad),
            weight: weight.run,
            channel_weights: weight.channel,
            // With the heading weighted apart, a heading row that lost its weight flags the
            // run too (its position may still count in full).
            outlier: weight.run < OUTLIER_WEIGHT
                || (self.options.heading_apart
                    && scales.is_some_and(|s| {
                        weight.channel[HEADING] < OUTLIER_WEIGHT * s.heading_channel
                    })),
            end_offset_m,
        }
    }
}
