//! odocal's exact calibration: a robust Levenberg–Marquardt fit of the kinematic parameters to
//! the recorded runs.
//!
//! Parameters `p = (E_d, E_b[, E_s])` are absolute, relative to the nominal geometry:
//! `geometry(p) = nominal.with_factors(E_d, E_b, E_s)`. For every run the recorded tick knots
//! are re-integrated with [`ArcModel`] for `geometry(p)` (exact arcs, no small-angle
//! approximation), and the residual is `measured − predicted` in the start frame:
//! - a run measured at its end (the operator's tape measure): the end pose's `x`, `y` in metres
//!   and, when θ was measured, the wrapped heading residual multiplied by a length scale `ℓ` (by
//!   default [`HEADING_WEIGHT`] = 1.5 times the run's characteristic length — the side of a
//!   square —, so a heading error counts like the lateral error it produces over one and a half
//!   legs; see [`HEADING_WEIGHT`] for how it was chosen);
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
//!    whose weight ends below [`OUTLIER_WEIGHT`] = 0.5 (`u_i > c`) is flagged as an outlier: with
//!    the scales taken from a few peers that happens to about 0.8 % of clean runs (simulated 5 + 5
//!    squares measured to 2 mm and 2 mrad: 16 of 2000);
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
//! An option ([`ExactOptions::channel_weights`], off by default: on the shared OptiOdom sessions
//! the weights it estimates moved the factors towards the end positions, and the calibration
//! transferred worse to the paths it did not see, docs/calibration.md, *Transfer*; in simulation,
//! where the model is exact, it helps when the heading is measured worse than its a-priori
//! weight assumes). How much an end heading counts against an end position is not known
//! beforehand: slip in the turns, a jerk at the start and the way the end pose is measured make
//! the heading scatter by a different amount than `x` and `y`, and `x` and `y` themselves differ
//! (along and across the last leg of a square or a line). Weighting the heading by `ℓ` alone fixes their ratio a priori; a
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
//! ## Heading apart
//!
//! An option ([`ExactOptions::heading_apart`], off by default). A slipping start turns a run
//! about its start point: a closed path ends where it would have, and only its end heading
//! carries the slip. One weight per run then discards its good end position with its bad
//! heading. With the option the position rows get the Cauchy weight of the x and y components
//! alone and the heading row one of its own, from its own residual in units of its peers'
//! heading scale; a run whose heading row ends below [`OUTLIER_WEIGHT`] is flagged as well. In
//! the Monte Carlo with 5 % slipping starts it keeps the spread of `E_b` where it is without
//! them, at any heading weight; on the shared OptiOdom sessions it transfers worse (their start
//! transients are systematic and the paths a calibration is used for start with them too),
//! docs/calibration.md, *Transfer*, *Heading weight and end offset*.
//!
//! ## End offset
//!
//! On by default ([`ExactOptions::end_offset`]; chosen by transfer, docs/calibration.md,
//! *Transfer*, *Heading weight and end offset*). The end positions of a session's squares can share an offset that no
//! wheel geometry makes: on the shared OptiOdom 1.7 m squares +16 to +20 mm along the first
//! leg, in both turn directions. A wheelbase or diameter error moves CW and CCW ends apart;
//! a common offset (where the start is read, how the robot stops) moves them together, and the
//! fit without it reads part of it as geometry. With the option, the closed paths (squares,
//! circles) measured at their end with their heading, of one kind and size ([`PEER_LENGTH_RATIO`])
//! and with runs in both directions, share an offset `(x, y)` fitted besides the factors: for
//! given factors it is their weighted mean residual, so the fit minimises the residuals about it
//! (variable projection: the cost and the normal equations less each group's mean, two degrees
//! of freedom per group). Without headings the offset would take what CW and CCW ends share of
//! `E_d` and `E_b` too, so runs without a heading get none. The position then says less about
//! the wheelbase and the heading more. It transfers better with motion-capture headings and with
//! end poses measured by hand to 2–3 mm and 14–17 mrad alike; in the Monte Carlo with random
//! slipping starts and 10 mrad headings the factors scatter more (`E_b` spread 7.3e-4 by
//! default against 5.8e-4 with the heading at `L` and no offset). Each run reports its group's
//! offset ([`RunFit::end_offset_m`]).
//!
//! # `f32` while iterating
//!
//! The fit iterates in `f32` (the Cortex-M4F's FPU; an `f64` operation is a soft-float call
//! there) and ends with a solve in `f64`, which defines the result.
//!
//! For a run measured at its end, one pass over its knots (`jacobian::end_pose_derivatives`)
//! integrates the arcs and carries along the derivatives of the end pose with respect to the
//! model's three numbers (travel per tick of each wheel, wheelbase: forward mode, per knot the
//! one sine and cosine the integration needs and short series for `sinc` and its slope); they
//! are chained with `∂(numbers)/∂p` by central differences of the geometry (no integration) into
//! the Jacobian `J = ∂predicted/∂p`. The cost evaluation keeps what that pass gives (residual
//! rows and derivatives, `problem::Kept`) for the first runs, so an accepted step costs
//! one pass per run: its cost and the next iteration's normal equations; the kept rows also give
//! each solve's start cost, the robust rounds' residuals, the 1σ and the per-run report.
//!
//! While the fit iterates (the plain fit and every reweighting round) the passes are `f32`:
//! residuals, cost and Jacobian. An end pose integrated in `f32` is good to about 1e-6 m on a
//! 2 m square (the heading from tick totals to about 2⁻²⁴ of the wheels' travel over the
//! wheelbase, and one rounding of the position per knot), the derivatives to 1e-4 of a column
//! (test `derivatives_match_central_differences`). Those solves stop at the `f32` resolution
//! ([`STEP_TOLERANCE_F32`], [`COST_TOLERANCE_F32`]), and the robust rounds weigh the runs by their
//! `f32` residuals (the weights' tolerance, 1e-3, is far coarser). The fit then ends with one
//! solve in `f64` from the `f32` solution, with the weights it was fitted with: `f64` passes
//! (residuals and the analytic Jacobian, whose `f64` derivatives match the central differences to
//! 1e-7 of a column, their own error); from that close it takes one to three iterations, and it
//! ends where the fit with `f64` throughout ends, to its tolerances. The weights and scales
//! reported are recomputed from its `f64` residuals (in ideal kinematics they are 1 to rounding).
//! (An `f32` Jacobian alone stops where `J̃ᵀWr = 0`, not at the cost's minimum `JᵀWr = 0`; the
//! two are `(JᵀWJ)⁻¹EᵀWr` apart, `E` the Jacobian's error: on the recorded OptiOdom sessions
//! 4e-8–1e-7 relative in `E_b` on squares and up to 2e-4 on the end poses of two free paths,
//! more than the product's 1e-5. Hence the last solve in `f64`.)
//!
//! Every solve, in either precision, has converged when the decrease of the cost that the
//! linearised residuals predict for the next step, `2δᵀg − δᵀAδ`, is below the cost's tolerance
//! times the cost (noisy data at its flat minimum: no step can gain more than rounding, so it is
//! not evaluated; Levenberg–Marquardt would otherwise reject it for a rounding rise of the cost
//! and shrink it by tenfold rejections, one pass each, until it fell below the step tolerance),
//! when an accepted step moves no parameter by more than the step tolerance or lowers the cost by
//! less than its tolerance. In the `f64` solve a step predicted to lower the cost by at most
//! [`UNCHECKED_DECREASE`] of it is the last: it is taken without a pass at its end, and the kept
//! rows follow it by their linearisation (on noisy data this saves the last `f64` pass per run;
//! in ideal kinematics the cost is rounding and every step is evaluated).
//!
//! A run with ground truth along its path (residuals at every knot) keeps central differences of
//! re-integrations, two per fitted factor and run in every iteration, its rows at `p` in `f64`.
//! While the fit iterates those run in `f32` ([`ArcModelF32`] with
//! [`crate::util::trig::sincos_f32`]), with the step `h =` [`JACOBIAN_STEP_F32`] `= 1e-3` in
//! each (dimensionless, ≈ 1) factor. An end pose in `f32` is good to about `ε ≈ 1e-7` m per metre
//! travelled, so a column's error is the rounding `ε/h` plus the truncation `O(h²)`. Measured on
//! a 1 m square (test `f32_jacobian_matches_f64`, largest error of a column against the `f64`
//! one relative to the column's size, for `E_d`, `E_b`, `E_s`): 2–10e-3 at `h = 1e-5`, 2–7e-4
//! at `1e-4` (rounding), 1.4–4.8e-5 at `1e-3`, 0.3–1.3e-4 at `3e-3`, 0.2–1.3e-3 at `1e-2`
//! (truncation); the `f64` Jacobian's `h = 1e-6` would leave 2.5–12 %. The last solve's central
//! differences are `f64` ([`ArcModel`], step [`JACOBIAN_STEP`] `= 1e-6`: truncation 1e-12,
//! rounding 1e-10 relative).
//!
//! Normal equations are accumulated run by run (3×3), so memory does not
//! grow with the number of knots; the weights take one number per run (up to
//! [`MAX_WEIGHTED_RUNS`] runs are reweighted; a larger set is fitted plainly and says so in
//! [`ExactFit::reweighted`]).
//!
//! # Uncertainty
//!
//! The weights act as the rows' relative precisions, and the end-heading rows and the position
//! rows each get their own variance per weighted component, from their own weighted sum of
//! squares: `s_h² = Σ_heading rows w r² / (M_h − n M_h/M)` and `s_p²` likewise from the rest,
//! whose degrees of freedom also pay for the end offsets (`M_h` heading rows of `M`). With
//! `A = JᵀWJ` and `A_h` its heading rows' part, the covariance is
//! `A⁻¹ (s_p² (A − A_h) + s_h² A_h) A⁻¹`. The heading's a priori length scale `ℓ` is chosen by
//! transfer, not by the noise, so its rows' scatter in metres can be several times the
//! positions' (on the shared 231220200029 squares heading residuals of 3–20 mrad times
//! `ℓ` = 2.55 m against position residuals of 2–23 mm): one variance for all
//! rows would understate the uncertainty of what the headings determine (`E_b`) and overstate
//! that of what the positions determine (`E_s` from lines). With one variance for both, or
//! either share under one degree of freedom, it is `A⁻¹ s²`, `s² = Σ w r² / (M − n)`, the plain
//! fit's `(JᵀJ)⁻¹ σ²` when every weight is 1.
//!
//! Parts: `options` (what the fit is asked for), `problem` (the model and its residuals),
//! `solver` (the normal equations and Levenberg–Marquardt), `jacobian` (the analytic end-pose Jacobian), `linalg` (the 3×3 solve), `robust` (the run
//! and channel weights), `report` (the per-run report) and `fit` (the fit from start to result:
//! the reweighting rounds, the degeneracy and range checks, the 1σ).
//!
//! [`ArcModel`]: crate::kinematics::reference::ArcModel
//! [`ArcModelF32`]: crate::kinematics::reference::ArcModelF32
//! [`RunObservation::truth_path`]: crate::calibration::RunObservation::truth_path
//! [`CalibrationError::Degenerate`]: crate::calibration::CalibrationError::Degenerate

// Dense 3×3 linear algebra reads best with explicit indices.
#![allow(clippy::needless_range_loop)]

mod fit;
mod jacobian;
mod linalg;
mod offset;
mod options;
mod problem;
mod report;
mod robust;
mod solver;

pub use fit::calibrate_exact;
pub(crate) use linalg::solve;
pub use options::{ExactOptions, ScaleFit};
pub use report::{EndOffset, ExactFit, RunFit};

/// Central-difference step for the `f64` Jacobian, in units of the (≈ 1) factors.
pub const JACOBIAN_STEP: f64 = 1e-6;

/// Central-difference step for the `f32` Jacobian, in units of the (≈ 1) factors (see the module
/// docs, *`f32` while iterating*).
pub const JACOBIAN_STEP_F32: f64 = 1e-3;

/// Converged when no parameter moves by more than this in one step.
pub const STEP_TOLERANCE: f64 = 1e-12;

/// Converged when an accepted step lowers the cost by less than this fraction.
pub const COST_TOLERANCE: f64 = 1e-13;

/// The `f32` solves (see the module docs, *`f32` while iterating*) have converged when no
/// parameter moves by more than this in one step: about the `f32` resolution of the (≈ 1)
/// factors, below which the `f32` cost cannot tell one step from the next.
pub const STEP_TOLERANCE_F32: f64 = 1e-7;

/// The `f32` solves have converged when an accepted step lowers the cost (or the next step is
/// predicted to lower it) by less than this fraction: the `f32` cost's rounding, measured on the
/// recorded squares of qemu-bench, where steps predicted to gain 1e-5 of the cost were rejected
/// for a rise of the `f32` cost (each a pass over the runs, and no closer to the minimum).
pub const COST_TOLERANCE_F32: f64 = 2e-5;

/// A step whose predicted decrease of the cost is at most this fraction of the cost is the last
/// one, taken without evaluating the cost there (see the module docs, *`f32` while iterating*):
/// its size in the residuals, `|Jδ|`, is below 3e-5 of theirs, so the linearisation's error,
/// of order `|δ|²`, is far below rounding; the rows and derivatives kept are those of the
/// point before it.
pub const UNCHECKED_DECREASE: f64 = 1e-9;

/// Default multiplier `k` of a run's characteristic length `L` in its heading residual's length
/// scale `ℓ = k·L` ([`ExactOptions::heading_weight`]): 1.5, a heading error counts like the
/// lateral error it makes over one and a half legs. Chosen by leave-one-session-out transfer
/// with end poses measured as by hand (the table: docs/calibration.md, *Transfer*, *Heading weight and end offset*).
pub const HEADING_WEIGHT: f64 = 1.5;

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
