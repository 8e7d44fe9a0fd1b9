//! odocal's exact calibration: a robust Levenberg–Marquardt fit of the kinematic parameters to
//! the recorded runs.
//!
//! Parameters `p = (E_d, E_b[, E_s])` are absolute, relative to the nominal geometry:
//! `geometry(p) = nominal.with_factors(E_d, E_b, E_s)`. For every run the recorded tick knots
//! are re-integrated with [`ArcModel`] for `geometry(p)` (exact arcs, no small-angle
//! approximation), and the residual is `measured − predicted` in the start frame:
//! - a run measured at its end (the operator's tape measure): the end pose's `x`, `y` in metres
//!   and, when θ was measured, the wrapped heading residual multiplied by a length scale `ℓ` (by
//!   default the run's characteristic length — the side of a square — so a heading error counts
//!   like the lateral error it produces over one leg);
//! - a run with ground truth along the whole path ([`RunObservation::truth_path`], e.g. a
//!   motion-capture log): the position error at every knot, each divided by `√N` (`N` knots after
//!   the start), so that the run adds the *mean* squared position error along its path to the
//!   cost — one path weighs like one end pose, however finely it was sampled. Along a path a
//!   heading error already shows as the position errors that follow it, and a free path has no
//!   length that would weigh a separate heading term fairly against them (its characteristic
//!   length, tens of metres, would let the end heading swamp the path), so the end heading is
//!   added (times `ℓ`) only when [`ExactOptions::heading_length_m`] gives `ℓ`. An in-place turn
//!   recorded as a path therefore adds nothing about `E_b` by itself.
//!
//! Any path works: squares, lines, circles, free loops; runs may have been driven with different
//! geometries, because the fit starts from raw ticks. `E_s` (the mean diameter) is only fitted
//! when a straight-line run or a run with ground truth along its path is present (or when asked
//! to): end poses of squares and closed loops determine it poorly. Otherwise it stays at the first
//! run's driving value.
//!
//! # Robust fit
//!
//! One run whose start slipped (the wheels spin in a jerk, odometry turns by tens of mrad more
//! than the robot) is far from the others in heading, and a plain least-squares fit follows it.
//! The default fit ([`ExactOptions::robust`]) is an M-estimate with Cauchy weights computed by
//! iteratively reweighted least squares (IRLS), run by run:
//!
//! 1. the plain least-squares fit gives the start;
//! 2. each run `i` has residual channels `c`: x and y (end pose; for a path run the mean squared
//!    position error along it) and, when used, the heading (times `ℓ`), with squared residuals
//!    `d_ic²`. Under the model `d_ic²/σ_c²` is χ² with `k_c` degrees of freedom (1 for x, y or
//!    the heading alone, 2 for x and y pooled), so `z_ic = d_ic² / med(χ²_{k_c})` has median
//!    `σ_c²`;
//! 3. the scales come from the runs' own scatter: `σ_c² = median(z_jc) · M/(M − n)` over run
//!    `i`'s *peers* `j` — the runs of the same kind of path (square, line, circle), measured the
//!    same way (end pose or path), with characteristic lengths within a factor
//!    [`PEER_LENGTH_RATIO`] (longer paths scatter more, so a 15 m path is never judged against
//!    1.7 m squares); `M/(M − n)` corrects for the `n` fitted parameters (`M` residual components
//!    in all). The median ignores up to half of the peers being outliers. A run with fewer than
//!    [`MIN_PEERS`] peers (itself included) has no scale and keeps weight 1. No scale is taken
//!    below the rounding error of the measurement, `resolution/√12`
//!    ([`ExactOptions::resolution_m`], [`ExactOptions::resolution_rad`] times `ℓ`), so that runs
//!    that fit to rounding are not sorted by rounding errors and a channel that happens to fit
//!    perfectly cannot take unbounded weight (see *Channel weights*);
//! 4. `u_i² = Σ_c d_ic²/σ_c² / k_i` (the run's mean squared residual component in units of the
//!    scales, 1 on average under the model; `k_i` = 2 or 3 components) gives the Cauchy weight
//!    `w_i = 1 / (1 + u_i²/c²)`,
//!    `c =` [`CAUCHY_C`] `= 2.3849` (95 % efficiency at the normal model). The Cauchy loss
//!    redescends: a run 10 σ off keeps about 5 % of its weight, so its pull on the factors is
//!    about half that of a run at 1 σ, where a plain fit lets it pull ten times as hard. A run
//!    whose weight ends below [`OUTLIER_WEIGHT`] = 0.5 (`u_i > c`) is flagged as an outlier: under
//!    the model that happens to fewer than 0.4 % of runs;
//! 5. the weighted fit is repeated from the current parameters with the new weights, and the
//!    weights recomputed, until no weight changes by more than [`WEIGHT_TOLERANCE`] (1e-3: a
//!    weight known to 0.1 % moves the factors by a small fraction of their 1σ) and no channel
//!    weight (below) by more than [`CHANNEL_TOLERANCE`] (1 % of itself). On 5 + 5 noisy
//!    squares this takes 2–3 rounds and 2–3 times the solver iterations of the plain fit, 5–6
//!    rounds (5 times the iterations) when one run is an outlier. The scales are medians, which
//!    jump when two residuals swap places, so on rare data the scales and weights can cycle
//!    between two states instead of settling. After [`FREEZE_SCALES_AFTER`] rounds the scales and
//!    channel weights are therefore held at their last values and only the run weights are
//!    iterated: with fixed scales each round is a majorise–minimise step of one fixed Cauchy
//!    objective, which never increases, so the run weights converge. Data that settle earlier
//!    (every case measured: 2–6 rounds) never reach this point and are unaffected.
//!
//! Runs that fit the model all get weights close to 1, and where the runs fit exactly (ideal
//! kinematics) the weights are 1 to rounding and the result is the plain fit's. The weight of
//! every run is reported with its residual ([`ExactFit`]). [`ExactOptions::plain`] is the plain
//! least-squares fit.
//!
//! ## Channel weights
//!
//! How much an end heading counts against an end position is not known beforehand: slip in the
//! turns, a jerk at the start and the way the end pose is measured make the heading scatter by a
//! different amount than `x` and `y`, and `x` and `y` themselves differ (along and across the last
//! leg of a square or a line). Weighting the heading by `ℓ` alone fixes their ratio a priori; a
//! session whose headings scatter twice as much as that ratio assumes lets them pull the factors
//! four times as hard as their precision deserves. The robust fit therefore treats the noise
//! level of each channel as unknown and estimates it from the same peers (variance components,
//! alternating with the run weights in the same IRLS loop, [`ExactOptions::channel_weights`]):
//! the rows of channel `c` are weighted by `σ_p²/σ_c²`, `σ_p²` the pooled position scale of the
//! peers (so the fit stays in metres of position, and runs of different kinds keep the relative
//! weight they had). This is the maximum-likelihood weighting of a diagonal noise model, with
//! robust (median) variance estimates; with the scales a priori equal it is the fit above.
//!
//! - Only an end pose gets x, y apart; a path's knots share no axes, its position stays pooled.
//! - Channel weights need at least [`MIN_CHANNEL_PEERS`] = 6 peers (one UMBmark session, 3 CW +
//!   3 CCW): a variance ratio estimated from medians of `k` runs is known only to within a factor
//!   of 21 (its 10–90 % range when both variances are equal) at `k` = 6, 41 at 5 and 106 at 3.
//!   Below that the a-priori weighting (by `ℓ`) is kept: fewer runs would replace it by noise.
//! - The resolution floors bound the weight of a channel that fits perfectly; with ideal
//!   kinematics every residual is zero, and any positive weights give the same exact answer.
//! - Not modelled: correlations between the channels (a full 3×3 covariance per peer group,
//!   mirrored between CW and CCW, is 6 numbers from 6–10 runs: in simulation it widened the spread
//!   of `E_b` by 22 % against the a-priori weighting, where the diagonal one costs 5 %), and a
//!   per-run start-heading offset (a free rotation of every run about its start point absorbs the
//!   end heading of every closed path, so in-place turns and circles lose the information that
//!   calibrates `E_b` best; it is the occasional slipping start, which the run weights handle).
//!
//! # Jacobian in `f32`
//!
//! The residuals `r`, the cost, the normal equations, the solve and the convergence test are
//! `f64`. The Jacobian `J = ∂predicted/∂p` is central differences of re-integrations, and those
//! are most of the fit's work (two per fitted factor and run in every iteration). While the fit
//! iterates they run in `f32` ([`ArcModelF32`] with [`crate::util::trig::sincos_f32`]: the
//! Cortex-M4F's FPU instead of soft-float), with the step `h =` [`JACOBIAN_STEP_F32`] `= 1e-3` in
//! each (dimensionless, ≈ 1) factor. An end pose in `f32` is good to about `ε ≈ 1e-7` m per metre
//! travelled, so a column's error is the rounding `ε/h` plus the truncation `O(h²)`. Measured on
//! a 1 m square (test `f32_jacobian_matches_f64`, largest error of a column against the `f64`
//! one relative to the column's size, for `E_d`, `E_b`, `E_s`): 2–10e-3 at `h = 1e-5`, 2–7e-4
//! at `1e-4` (rounding), 1.4–4.8e-5 at `1e-3`, 0.3–1.3e-4 at `3e-3`, 0.2–1.3e-3 at `1e-2`
//! (truncation); the `f64` Jacobian's `h = 1e-6` would leave 2.5–12 %.
//!
//! An approximate Jacobian `J̃ = J + E` steers Levenberg–Marquardt as well as `J` does: a step is
//! accepted only when the `f64` cost does not rise, and near the solution each Gauss–Newton step
//! contracts the error by `O(|E|/|J|)` (besides the usual term of the residuals' curvature), about
//! 5e-5, so it converges as fast. But it stops where `J̃ᵀWr = 0`, not where the cost is least
//! (`JᵀWr = 0`): the two coincide where the runs fit exactly (`r = 0`, ideal kinematics), and with
//! noisy runs they are `(JᵀWJ)⁻¹EᵀWr` apart. On the recorded OptiOdom sessions (read from their
//! recorded starts) that moved `E_b` by 4e-8–1e-7 relative on squares, 3e-5 on the path fit of the
//! line session and 2e-4 on the end poses of two free paths (3 factors from 6 numbers; on long
//! paths the `f32` heading error grows with the distance driven). The fit therefore ends with one
//! more solve, from the `f32` solution and with the weights it was fitted with, whose Jacobian is
//! `f64` ([`ArcModel`], step [`JACOBIAN_STEP`] `= 1e-6`: truncation 1e-12, rounding 1e-10
//! relative): it starts that close to the minimum that it takes two iterations, and it ends where
//! an all-`f64` fit ends, to the convergence tolerances: plain fits of the recorded sessions agree
//! to the nine printed digits (2–3e-8 on the free paths' flat minimum), the bench's robust fit of
//! 10 squares to 2e-11; other robust fits differ by up to 7e-8 (6e-7, 1e-5 of its 1σ, for the line
//! session's path fit), as their reweighting rounds start from the `f32` solutions and the weights
//! settle within their tolerance at slightly different values. The 1σ comes from the `f64`
//! Jacobian.
//!
//! Normal equations are accumulated run by run (3×3), so memory does not
//! grow with the number of knots; the weights take one number per run (up to
//! [`MAX_WEIGHTED_RUNS`] runs are reweighted; a larger set is fitted plainly and says so in
//! [`ExactFit::reweighted`]). 1σ uncertainty: the weights act as the rows' relative precisions,
//! `(JᵀWJ)⁻¹ s²` with `s² = Σ_i w_i Σ_c λ_ic d_ic² / (M − n)` (`λ_ic` the channel weights; the
//! plain fit's `(JᵀJ)⁻¹ σ²` when every weight is 1).

// Dense 3×3 linear algebra reads best with explicit indices.
#![allow(clippy::needless_range_loop)]

use super::quality::Quality;
use super::stats::SquareStats;
use super::{
    Calibration, CalibrationError, FACTOR_RANGE, Method, RunObservation, factors_of, wrap_angle,
};
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::{ArcModel, ArcModelF32, PoseF32, PoseF64};
use crate::motion::run::PathKind;
use crate::util::num::{fmax, fmin};

/// Central-difference step for the `f64` Jacobian, in units of the (≈ 1) factors.
pub const JACOBIAN_STEP: f64 = 1e-6;

/// Central-difference step for the `f32` Jacobian, in units of the (≈ 1) factors (see the module
/// docs, *Jacobian in `f32`*).
pub const JACOBIAN_STEP_F32: f64 = 1e-3;

/// Converged when no parameter moves by more than this in one step.
pub const STEP_TOLERANCE: f64 = 1e-12;

/// Converged when an accepted step lowers the cost by less than this fraction.
pub const COST_TOLERANCE: f64 = 1e-13;

/// Cauchy constant `c` of the robust weights (95 % efficiency at the normal model).
pub const CAUCHY_C: f64 = 2.3849;

/// Fewest peers (the run itself included) whose scatter gives a run's scale.
pub const MIN_PEERS: usize = 3;

/// Fewest peers (the run itself included) whose scatter weights a run's residual channels.
pub const MIN_CHANNEL_PEERS: usize = 6;

/// Runs are peers when their characteristic lengths differ by at most this factor.
pub const PEER_LENGTH_RATIO: f64 = 1.2;

/// Most runs the robust fit reweights.
pub const MAX_WEIGHTED_RUNS: usize = 128;

/// Most runs whose fit is reported in [`ExactFit`] (the board stores 12).
pub const MAX_RUN_FITS: usize = 16;

/// Most reweighting rounds of the robust fit.
pub const MAX_REWEIGHTS: u32 = 100;

/// Reweighting rounds after which the robust fit holds the scales and channel weights and
/// iterates the run weights alone (see the module docs).
pub const FREEZE_SCALES_AFTER: u32 = MAX_REWEIGHTS / 2;

/// The robust fit has converged when no run's weight changes by more than this.
pub const WEIGHT_TOLERANCE: f64 = 1e-3;

/// The robust fit has converged when no channel weight changes by more than this fraction: a
/// channel weight is an estimate known to a factor of a few at best (see the module docs), so
/// iterating it closer than 1 % changes nothing a user can see.
pub const CHANNEL_TOLERANCE: f64 = 1e-2;

/// A run whose weight ends below this is flagged as an outlier (`u > c`).
pub const OUTLIER_WEIGHT: f64 = 0.5;

/// The largest 1σ a fitted factor may keep: a factor known no better than 10 % has not been
/// determined by the runs (a real robot's factors are within a few per cent of 1, the OptiOdom
/// robot's within 2 %), and the fit fails with [`CalibrationError::Degenerate`] instead of
/// returning whatever value its minimum drifted to. Measured on the OptiOdom sessions: 1e-4–7e-3
/// for squares, circles and lines; 0.02–0.03 for `E_b` and `E_s` of two free paths fitted
/// along their paths (their ratio is known far better: the turns fix `E_s/E_b`); 6.5 for `E_b`
/// of straight lines and in-place turns fitted along their paths, which a turn in place does not
/// move.
pub const MAX_FACTOR_SIGMA: f64 = 0.1;

/// When the mean diameter `E_s` is fitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ScaleFit {
    /// Only when a straight-line run or a run with ground truth along its path is present.
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
    /// Iteration limit of each least-squares solve.
    pub max_iterations: u32,
    /// Robust fit (Cauchy weights per run, see the module docs); `false` = plain least squares.
    pub robust: bool,
    /// In the robust fit, weight the heading channel by the runs' own scatter (position against
    /// heading variance among a run's peers, see the module docs); `false` = by `ℓ` alone.
    pub channel_weights: bool,
    /// Resolution of a measured position, metres: no channel's scale is taken below its
    /// rounding error `resolution/√12`.
    pub resolution_m: f64,
    /// Resolution of a measured heading, radians (as [`ExactOptions::resolution_m`]).
    pub resolution_rad: f64,
}

impl Default for ExactOptions {
    /// The robust fit, headings used, `E_s` when a line or a path run is present.
    fn default() -> Self {
        ExactOptions {
            scale: ScaleFit::Auto,
            use_heading: true,
            heading_length_m: None,
            max_iterations: 100,
            robust: true,
            channel_weights: true,
            resolution_m: 1e-3,
            resolution_rad: 0.1 * core::f64::consts::PI / 180.0,
        }
    }
}

impl ExactOptions {
    /// The plain least-squares fit (every run weight 1), otherwise as [`ExactOptions::default`].
    pub fn plain() -> Self {
        ExactOptions {
            robust: false,
            channel_weights: false,
            ..ExactOptions::default()
        }
    }
}

/// How one run fits the result.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct RunFit {
    /// Index of the run in the input slice.
    pub index: usize,
    /// End-pose residual `measured − predicted` in x, metres, with the fitted geometry.
    pub residual_x_m: f64,
    /// End-pose residual in y, metres.
    pub residual_y_m: f64,
    /// End heading residual, radians (wrapped), when the heading was measured and used.
    pub residual_theta_rad: Option<f64>,
    /// RMS position error along the path, metres, for a run with ground truth along its path.
    pub path_rms_m: Option<f64>,
    /// Scale (robust σ) of one position component among the run's peers, metres; `None` when
    /// the run was not judged (plain fit, or fewer than [`MIN_PEERS`] peers).
    pub scale_m: Option<f64>,
    /// Scale of the heading residual among the run's peers, radians (heading used).
    pub scale_heading_rad: Option<f64>,
    /// The weight the run ended with, in (0, 1]; 1 in the plain fit.
    pub weight: f64,
    /// Relative weights of the run's x, y and heading rows against its position (see the
    /// module docs, *Channel weights*); `[1, 1, 1]` is the a-priori weighting (heading by `ℓ`).
    pub channel_weights: [f64; 3],
    /// The weight ended below [`OUTLIER_WEIGHT`]: the run disagrees with its peers.
    pub outlier: bool,
}

impl RunFit {
    const EMPTY: RunFit = RunFit {
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
    };
}

/// Per-run report of an exact fit: residual, weight and outlier flag of every run.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ExactFit {
    /// The robust fit was asked for.
    pub robust: bool,
    /// The runs were reweighted (robust, and at most [`MAX_WEIGHTED_RUNS`] runs).
    pub reweighted: bool,
    /// Reweighting rounds (0 when the least-squares weights were already stable).
    pub reweights: u32,
    /// Runs flagged as outliers.
    pub outliers: u32,
    /// Runs in the fit (those with at least two knots).
    pub run_count: usize,
    fits: [RunFit; MAX_RUN_FITS],
}

impl ExactFit {
    /// The fits of the first [`MAX_RUN_FITS`] runs in the fit, in input order.
    pub fn runs(&self) -> &[RunFit] {
        &self.fits[..self.run_count.min(MAX_RUN_FITS)]
    }
}

type Mat = [[f64; 3]; 3];

/// Solves `a x = b` for the leading `n × n` block (Gaussian elimination, partial pivoting).
/// `None` when the matrix is singular to working precision.
pub(crate) fn solve(mut a: Mat, mut b: [f64; 3], n: usize) -> Option<[f64; 3]> {
    let scale = (0..n).fold(0.0, |m, i| fmax(m, libm::fabs(a[i][i])));
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
        // Element by element, not `a.swap(c, piv)` (nor whole-row assignments): those may
        // overlap (`c == piv`) and compile to `memmove`, 1.5 KiB of flash the firmware
        // otherwise does without.
        for k in 0..3 {
            let t = a[c][k];
            a[c][k] = a[piv][k];
            a[piv][k] = t;
        }
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

/// The most models a residual row is evaluated for at once (`1 + 2n`, n ≤ 3).
const MODELS: usize = 7;

/// The precision of the Jacobian's re-integrations (see the module docs, *Jacobian in `f32`*).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Jacobian {
    /// `f32` ([`ArcModelF32`], step [`JACOBIAN_STEP_F32`]): steers the iterations.
    F32,
    /// `f64` ([`ArcModel`], step [`JACOBIAN_STEP`]): defines where the fit ends, and its 1σ.
    F64,
}

/// Median of χ² with `k` degrees of freedom, `k` = 1, 2, 3.
fn chi2_median(k: usize) -> f64 {
    match k {
        1 => 0.454_936_423_119_572_8,
        2 => core::f64::consts::LN_2 * 2.0,
        _ => 2.365_973_884_375_338,
    }
}

/// Median of a non-empty slice (sorts it).
///
/// An insertion sort: the slices hold one value per run (at most [`MAX_WEIGHTED_RUNS`]), where
/// its few hundred comparisons cost nothing beside one re-integration, and it is 60 bytes of code
/// where `sort_unstable_by` brings about 3 KiB to the firmware. The median does not depend on the
/// sort: `total_cmp` orders equal values only when their bits are equal.
fn median(v: &mut [f64]) -> f64 {
    for i in 1..v.len() {
        let mut j = i;
        while j > 0 && v[j - 1].total_cmp(&v[j]).is_gt() {
            v.swap(j - 1, j);
            j -= 1;
        }
    }
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The weights of one run in the fit: its robust weight and the relative weight of its heading
/// row against its position rows (the channel weight, see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Weight {
    run: f64,
    channel: [f64; CHANNELS],
}

impl Weight {
    const ONE: Weight = Weight {
        run: 1.0,
        channel: [1.0; CHANNELS],
    };

    /// The weight of a residual row of channel `c`.
    fn row(self, c: usize) -> f64 {
        self.run * self.channel[c]
    }
}

/// Residual channels: end (or path) position x, y, and the end heading.
const CHANNELS: usize = 3;
const X: usize = 0;
const Y: usize = 1;
const HEADING: usize = 2;

/// Weights of run `i`: 1 without weights.
fn weight(weights: Option<&[Weight]>, i: usize) -> Weight {
    weights.map_or(Weight::ONE, |w| w[i])
}

/// The problem: runs, nominal geometry, which parameters are free, options.
struct Problem<'r, 'a> {
    runs: &'r [RunObservation<'a>],
    nominal: Geometry,
    n: usize,
    fixed_scale: f64,
    options: ExactOptions,
}

/// The robust scales of one run's residual components.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Scales {
    position_m: f64,
    heading_rad: Option<f64>,
}

/// The result of one least-squares solve.
struct Solved {
    p: [f64; 3],
    cost: f64,
    iterations: u32,
}

impl Problem<'_, '_> {
    fn geometry(&self, p: &[f64; 3]) -> Geometry {
        let e_s = if self.n == 3 { p[2] } else { self.fixed_scale };
        self.nominal.with_factors(p[0], p[1], e_s)
    }

    fn usable(run: &RunObservation<'_>) -> bool {
        run.knots.len() >= 2
    }

    fn is_path(run: &RunObservation<'_>) -> bool {
        !run.truth_path.is_empty()
    }

    /// The measured end heading, when it is used: with ground truth along the path only when a
    /// heading length is given (see the module docs).
    fn heading(&self, run: &RunObservation<'_>) -> Option<f64> {
        let along_path = Self::is_path(run) && self.options.heading_length_m.is_none();
        run.measured
            .theta_rad
            .filter(|_| self.options.use_heading && !along_path)
    }

    fn heading_length(&self, run: &RunObservation<'_>) -> f64 {
        self.options
            .heading_length_m
            .unwrap_or_else(|| run.characteristic_length_m())
    }

    /// Number of residual components of a run: 2 (x, y) or 3 (with the heading).
    fn components(&self, run: &RunObservation<'_>) -> usize {
        if self.heading(run).is_some() { 3 } else { 2 }
    }

    /// Calls `row` for every residual row of `run`, with the row's value under each of
    /// `models` followed by its value under each of `models32` (at most [`MODELS`] in all).
    fn rows(
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
    fn distance2(&self, run: &RunObservation<'_>, model: &ArcModel) -> [f64; CHANNELS] {
        let mut d2 = [0.0; CHANNELS];
        self.rows(run, core::slice::from_ref(model), &[], |v, c| {
            d2[c] += v[0] * v[0]
        });
        d2
    }

    /// Number of residual rows of a run (2 per knot of a path run).
    fn row_count(&self, run: &RunObservation<'_>) -> usize {
        let pos = if Self::is_path(run) {
            2 * (run.knots.len() - 1)
        } else {
            2
        };
        pos + usize::from(self.heading(run).is_some())
    }

    /// Weighted sum of squared residuals and number of residual components; `None` for an
    /// invalid geometry.
    fn cost(&self, p: &[f64; 3], weights: Option<&[Weight]>) -> Option<(f64, usize)> {
        if !(0..self.n).all(|i| FACTOR_RANGE.contains(&p[i])) {
            return None;
        }
        let model = ArcModel::from_geometry(&self.geometry(p));
        let mut ss = 0.0;
        let mut m = 0;
        for (i, run) in self.runs.iter().enumerate() {
            if Self::usable(run) {
                let d2 = self.distance2(run, &model);
                let w = weight(weights, i);
                ss += (0..CHANNELS).map(|c| w.row(c) * d2[c]).sum::<f64>();
                m += self.components(run);
            }
        }
        Some((ss, m))
    }

    /// `JᵀWJ` and `JᵀWr` at `p`, with `J ≈ ∂predicted/∂p` by central differences of
    /// re-integrations in the precision `jacobian` and `r` the `f64` residuals (see the module
    /// docs, *Jacobian in `f32`*).
    fn normal(
        &self,
        p: &[f64; 3],
        weights: Option<&[Weight]>,
        jacobian: Jacobian,
    ) -> (Mat, [f64; 3]) {
        let n = self.n;
        let mut a = [[0.0; 3]; 3];
        let mut g = [0.0; 3];
        let h = match jacobian {
            Jacobian::F32 => JACOBIAN_STEP_F32,
            Jacobian::F64 => JACOBIAN_STEP,
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
        let (models, models32) = match jacobian {
            Jacobian::F32 => (&models[..1], &models32[..2 * n]),
            Jacobian::F64 => (&models[..1 + 2 * n], &models32[..0]),
        };
        for (k, run) in self.runs.iter().enumerate() {
            if !Self::usable(run) {
                continue;
            }
            let w = weight(weights, k);
            self.rows(run, models, models32, |v, c| {
                let w = w.row(c);
                let mut j = [0.0; 3];
                for i in 0..n {
                    // residual = measured − predicted, so ∂predicted = −∂residual.
                    j[i] = -(v[1 + 2 * i] - v[2 + 2 * i]) / (2.0 * h);
                }
                for c in 0..n {
                    g[c] += w * j[c] * v[0];
                    for d in 0..n {
                        a[c][d] += w * j[c] * j[d];
                    }
                }
            });
        }
        (a, g)
    }

    /// Levenberg–Marquardt from `p` with fixed run weights, steered by a Jacobian in the
    /// precision `jacobian`.
    fn solve_lm(
        &self,
        mut p: [f64; 3],
        weights: Option<&[Weight]>,
        jacobian: Jacobian,
    ) -> Result<Solved, CalibrationError> {
        let n = self.n;
        let (mut cost, _) = self.cost(&p, weights).ok_or(CalibrationError::OutOfRange)?;
        let mut lambda = 1e-3;
        let mut iterations = 0;
        let mut converged = false;
        while iterations < self.options.max_iterations && !converged {
            iterations += 1;
            let (a, g) = self.normal(&p, weights, jacobian);
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
                match self.cost(&q, weights) {
                    Some((c, _)) if c <= cost => {
                        // Also converged when the cost no longer changes in its 13th digit
                        // (noisy data: the minimum is flat, and LM's last steps only shuffle
                        // rounding).
                        converged = step < STEP_TOLERANCE || cost - c <= COST_TOLERANCE * cost;
                        p = q;
                        cost = c;
                        lambda = fmax(lambda * 0.1, 1e-12);
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
        Ok(Solved {
            p,
            cost,
            iterations,
        })
    }

    /// Whether runs `a` and `b` are peers (see the module docs).
    fn peers(a: &RunObservation<'_>, b: &RunObservation<'_>) -> bool {
        let (la, lb) = (a.characteristic_length_m(), b.characteristic_length_m());
        core::mem::discriminant(&a.path) == core::mem::discriminant(&b.path)
            && Self::is_path(a) == Self::is_path(b)
            && fmax(la, lb) <= PEER_LENGTH_RATIO * fmin(la, lb)
    }

    /// Robust weights and scales of the runs at `p` (weights into `weights`, scales into
    /// `scales`, both indexed like `runs`; at most [`MAX_WEIGHTED_RUNS`] runs). Returns whether
    /// every weight stayed within its tolerance of the weight it replaced ([`WEIGHT_TOLERANCE`]
    /// for run weights, [`CHANNEL_TOLERANCE`] relative for channel weights).
    /// With `frozen`, the scales and channel weights are kept and only the run weights are
    /// recomputed.
    fn reweight(
        &self,
        p: &[f64; 3],
        weights: &mut [Weight; MAX_WEIGHTED_RUNS],
        scales: &mut [Option<Scales>; MAX_WEIGHTED_RUNS],
        frozen: bool,
    ) -> bool {
        let mut stable = true;
        let model = ArcModel::from_geometry(&self.geometry(p));
        let runs = &self.runs[..self.runs.len().min(MAX_WEIGHTED_RUNS)];
        // Squared x, y and (ℓ-scaled) heading residuals of every run.
        let mut d2 = [[0.0; CHANNELS]; MAX_WEIGHTED_RUNS];
        let mut m = 0;
        for (i, run) in runs.iter().enumerate() {
            if Self::usable(run) {
                d2[i] = self.distance2(run, &model);
                m += self.components(run);
            }
        }
        let dof = if m > self.n {
            m as f64 / (m - self.n) as f64
        } else {
            1.0
        };
        let mut buf = [0.0; MAX_WEIGHTED_RUNS];
        // σ² of one component of `channels` (summed, all of one kind) from the squared
        // residuals of `run`'s peers, not below the measurement's rounding, and the number of
        // peers it came from; `None` with fewer than `MIN_PEERS` peers.
        let mut scale2 = |run: &RunObservation<'_>, channels: &[usize]| -> Option<(f64, usize)> {
            let heading = channels.contains(&HEADING);
            let k = channels.len();
            let mut count = 0;
            for (j, other) in runs.iter().enumerate() {
                let has = !heading || self.heading(other).is_some();
                if Self::usable(other) && has && Self::peers(run, other) {
                    buf[count] = channels.iter().map(|&c| d2[j][c]).sum::<f64>() / chi2_median(k);
                    count += 1;
                }
            }
            let floor = if heading {
                self.options.resolution_rad * self.heading_length(run)
            } else {
                self.options.resolution_m
            };
            (count >= MIN_PEERS).then(|| {
                let s2 = median(&mut buf[..count]) * dof;
                (fmax(s2, floor * floor / 12.0), count)
            })
        };
        for (i, run) in runs.iter().enumerate() {
            let old = weights[i];
            if frozen {
                // The channel variances the held weights and scales were made from.
                let (Some(held), true) = (scales[i], Self::usable(run)) else {
                    continue;
                };
                let sp2 = held.position_m * held.position_m;
                let mut s2 = [sp2; CHANNELS];
                s2[X] = sp2 / old.channel[X];
                s2[Y] = sp2 / old.channel[Y];
                if let Some(h) = held.heading_rad {
                    let sh = h * self.heading_length(run);
                    s2[HEADING] = sh * sh;
                }
                let u2 = (0..CHANNELS).map(|c| d2[i][c] / s2[c]).sum::<f64>()
                    / self.components(run) as f64;
                let run_weight = 1.0 / (1.0 + u2 / (CAUCHY_C * CAUCHY_C));
                stable &= libm::fabs(run_weight - old.run) <= WEIGHT_TOLERANCE;
                weights[i].run = run_weight;
                continue;
            }
            weights[i] = Weight::ONE;
            scales[i] = None;
            if !Self::usable(run) {
                continue;
            }
            let Some((sp2, peers)) = scale2(run, &[X, Y]) else {
                continue;
            };
            // Channel scales: x and y apart for an end pose with enough peers (a path's knots
            // share no axes), the heading whenever it is used.
            let mut s2 = [sp2; CHANNELS];
            let channels =
                self.options.channel_weights && !Self::is_path(run) && peers >= MIN_CHANNEL_PEERS;
            if channels {
                let (Some((sx2, _)), Some((sy2, _))) = (scale2(run, &[X]), scale2(run, &[Y]))
                else {
                    continue;
                };
                s2[X] = sx2;
                s2[Y] = sy2;
            }
            let mut sh2 = None;
            let mut heading_peers = 0;
            if self.heading(run).is_some() {
                let Some((s, count)) = scale2(run, &[HEADING]) else {
                    continue;
                };
                s2[HEADING] = s;
                sh2 = Some(s);
                heading_peers = count;
            }
            let u2 =
                (0..CHANNELS).map(|c| d2[i][c] / s2[c]).sum::<f64>() / self.components(run) as f64;
            // Each channel weighted by the pooled position variance over its own, so that the
            // fit stays in metres of position across runs of different kinds.
            let mut channel = [1.0; CHANNELS];
            if channels {
                channel[X] = sp2 / s2[X];
                channel[Y] = sp2 / s2[Y];
                if heading_peers >= MIN_CHANNEL_PEERS {
                    channel[HEADING] = sp2 / s2[HEADING];
                }
            }
            let new = Weight {
                run: 1.0 / (1.0 + u2 / (CAUCHY_C * CAUCHY_C)),
                channel,
            };
            stable &= libm::fabs(new.run - old.run) <= WEIGHT_TOLERANCE
                && (0..CHANNELS).all(|c| {
                    let (a, b) = (old.channel[c], new.channel[c]);
                    libm::fabs(a - b) <= CHANNEL_TOLERANCE * fmax(a, b)
                });
            weights[i] = new;
            scales[i] = Some(Scales {
                position_m: libm::sqrt(sp2),
                heading_rad: sh2.map(|s| libm::sqrt(s) / self.heading_length(run)),
            });
        }
        stable
    }

    /// The report of run `index` for the fitted model.
    fn run_fit(
        &self,
        index: usize,
        model: &ArcModel,
        weight: Weight,
        scales: Option<Scales>,
    ) -> RunFit {
        let run = &self.runs[index];
        let end = model.integrate(PoseF64::default(), run.knots);
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
        RunFit {
            index,
            residual_x_m: run.measured.x_m - end.x_m,
            residual_y_m: run.measured.y_m - end.y_m,
            residual_theta_rad: self.heading(run).map(|t| wrap_angle(t - end.theta_rad)),
            path_rms_m,
            scale_m: scales.map(|s| s.position_m),
            scale_heading_rad: scales.and_then(|s| s.heading_rad),
            weight: weight.run,
            channel_weights: weight.channel,
            outlier: weight.run < OUTLIER_WEIGHT,
        }
    }
}

/// Fits the parameters; see the module docs.
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
    let problem = Problem {
        runs,
        nominal: *nominal,
        n: if fit_scale { 3 } else { 2 },
        fixed_scale: s0,
        options: *options,
    };
    let n = problem.n;
    let p0 = [d0, b0, s0];
    let (_, m) = problem
        .cost(&p0, None)
        .ok_or(CalibrationError::OutOfRange)?;
    let rows: usize = runs
        .iter()
        .filter(|r| Problem::usable(r))
        .map(|r| problem.row_count(r))
        .sum();
    if rows <= n {
        return Err(CalibrationError::Degenerate);
    }
    // The plain least-squares fit: the result, or the robust fit's start.
    let mut solved = problem.solve_lm(p0, None, Jacobian::F32)?;
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
            if problem.reweight(&solved.p, &mut weights, &mut scales, frozen) {
                break;
            }
            if reweights >= MAX_REWEIGHTS {
                return Err(CalibrationError::NotConverged);
            }
            reweights += 1;
            fitted_with[..len].copy_from_slice(&weights[..len]);
            solved = problem.solve_lm(solved.p, Some(&weights[..len]), Jacobian::F32)?;
            iterations += solved.iterations;
        }
    }
    let len = runs.len().min(MAX_WEIGHTED_RUNS);
    // The `f32` Jacobian's fixed point is off the cost's minimum by about its columns' error
    // times the residuals (see the module docs); the last solve ends at the minimum with the
    // `f64` Jacobian, from a start that close it takes one or two iterations.
    let fitted_with = (reweighted && reweights > 0).then_some(&fitted_with[..len]);
    solved = problem.solve_lm(solved.p, fitted_with, Jacobian::F64)?;
    iterations += solved.iterations;
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
    // Uncertainty from the weighted residual scatter, the weights as relative precisions.
    let (a, _) = problem.normal(&p, w, Jacobian::F64);
    let sigma2 = if m > n {
        cost / (m - n) as f64
    } else {
        f64::NAN
    };
    let mut sigma = [None; 3];
    for (i, s) in sigma.iter_mut().enumerate().take(n).filter(|_| m > n) {
        let mut e = [0.0; 3];
        e[i] = 1.0;
        if let Some(col) = solve(a, e, n) {
            *s = Some(libm::sqrt(fmax(col[i], 0.0) * sigma2));
        }
    }
    if sigma.iter().flatten().any(|s| *s > MAX_FACTOR_SIGMA) {
        return Err(CalibrationError::Degenerate);
    }
    let sigma_out = sigma[0]
        .zip(sigma[1])
        .map(|(d, b)| [d, b, sigma[2].unwrap_or(0.0)]);
    // Per-run report, and the weighted mean square of the residual components.
    let model = ArcModel::from_geometry(&geometry);
    let mut fit = ExactFit {
        robust: options.robust,
        reweighted,
        reweights,
        outliers: 0,
        run_count: 0,
        fits: [RunFit::EMPTY; MAX_RUN_FITS],
    };
    let mut weighted_components = 0.0;
    for (i, run) in runs.iter().enumerate() {
        if !Problem::usable(run) {
            continue;
        }
        let wi = weight(w, i);
        weighted_components += wi.run * problem.components(run) as f64;
        let scale = if reweighted { scales[i] } else { None };
        let rf = problem.run_fit(i, &model, wi, scale);
        if rf.outlier {
            fit.outliers += 1;
        }
        if fit.run_count < MAX_RUN_FITS {
            fit.fits[fit.run_count] = rf;
        }
        fit.run_count += 1;
    }
    let stats = SquareStats::from_runs(runs, false).ok();
    let rms = libm::sqrt(cost / weighted_components);
    let quality = Quality::from_runs(runs, &geometry, stats.as_ref(), sigma_out, Some(rms));
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

    /// The `f32` Jacobian's columns match the `f64` ones (step 1e-6) to 1e-4 of the column's
    /// size for the factors of a 1 m square run of the paper's robot (4 × 25 knots, 1 % off in
    /// `E_d` and `E_b`): measured 1.4–4.8e-5, the bound twice the largest; with the `f64` step
    /// the `f32` rounding would be at least 1e-2 of the column (measured 2.5–12 %, the reason
    /// for `h = 1e-3`).
    #[test]
    fn f32_jacobian_matches_f64() {
        use crate::kinematics::encoder::WheelTicks;
        let nominal = Geometry::PAPER_NOMINAL;
        let model = ArcModel::from_geometry(&nominal);
        let side = (1.0 / model.right_m_per_tick).round() as i64;
        let turn = (0.25 * core::f64::consts::PI * model.wheelbase_m / model.right_m_per_tick)
            .round() as i64;
        let mut knots = vec![WheelTicks::new(0, 0)];
        let (mut r, mut l) = (0, 0);
        for _ in 0..4 {
            for i in 1..=20 {
                knots.push(WheelTicks::new(r + side * i / 20, l + side * i / 20));
            }
            (r, l) = (r + side, l + side);
            for i in 1..=5 {
                knots.push(WheelTicks::new(r + turn * i / 5, l - turn * i / 5));
            }
            (r, l) = (r + turn, l - turn);
        }
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

    /// The insertion sort gives std's order: the sorted slice and the median are bit for bit
    /// those of `sort_unstable_by(f64::total_cmp)`, for every length up to the most runs, with
    /// repeated values, signed zeros and infinities among the values.
    #[test]
    fn median_matches_std_sort() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        for n in 1..=MAX_WEIGHTED_RUNS {
            for _ in 0..4 {
                let mut v: Vec<f64> = (0..n)
                    .map(|_| {
                        state ^= state << 13;
                        state ^= state >> 7;
                        state ^= state << 17;
                        match state % 16 {
                            0 => 0.0,
                            1 => -0.0,
                            2 => f64::INFINITY,
                            3 => 1.5,
                            _ => (state >> 11) as f64 * 1e-12 - 4.0e3,
                        }
                    })
                    .collect();
                let mut reference = v.clone();
                reference.sort_unstable_by(f64::total_cmp);
                let m = median(&mut v);
                let bits = |s: &[f64]| s.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&v), bits(&reference), "n = {n}");
                let expected = if n % 2 == 1 {
                    reference[n / 2]
                } else {
                    0.5 * (reference[n / 2 - 1] + reference[n / 2])
                };
                assert_eq!(m.to_bits(), expected.to_bits(), "n = {n}");
            }
        }
    }
}
