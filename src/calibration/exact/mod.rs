//! odocal's exact calibration: a robust Levenberg–Marquardt fit of `(E_d, E_b[, E_s])` to the
//! recorded runs. Every run's tick knots are re-integrated with [`ArcModel`] for the candidate
//! geometry (exact arcs, no small-angle approximation) and compared with what was measured: the
//! end pose (x, y and, when measured, the heading weighted by a length), or the ground truth
//! along the path. Runs that disagree with their peers are down-weighted (Cauchy weights by
//! IRLS) and flagged; closed paths of one kind and size may share an end offset.
//!
//! The model, the robust weighting, the end offset, the 1σ and the measurements behind every
//! constant here are in docs/calibration.md, "The exact fit".
//!
//! [`ArcModel`]: crate::kinematics::reference::ArcModel

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
/// robot's within 2 %), and the fit fails with [`CalibrationError::Degenerate`](crate::calibration::CalibrationError::Degenerate) instead of
/// returning whatever value its minimum drifted to. Measured on the OptiOdom sessions: 1e-4–7e-3
/// for squares, circles and lines; 0.02–0.03 for `E_b` and `E_s` of two free paths fitted
/// along their paths (their ratio is known far better: the turns fix `E_s/E_b`); 6.5 for `E_b`
/// of straight lines and in-place turns fitted along their paths, which a turn in place does not
/// move.
pub const MAX_FACTOR_SIGMA: f64 = 0.1;
