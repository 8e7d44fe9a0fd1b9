//! Lee, Jung & Chung 2011 ("Accurate calibration of kinematic parameters for two wheel
//! differential mobile robots", J. Mech. Sci. Tech. 25(6)), eq. (11) and (12), as printed:
//!
//! ```text
//! (11) α = (x_cw + x_ccw)/(−4L) + π b / (4 (−4L²/(x_cw − x_ccw) − b/2))
//! (12) α = (y_cw − y_ccw)/(−4L) + π b / (4 (−4L²/(y_cw + y_ccw) − b/2))
//! ```
//!
//! β, `E_d` and `E_b(α)` are UMBmark's ([`super::umbmark`]). The extra term models the
//! orientation error `α_εd` that unequal wheels add to a 90° turn (paper eq. 6–10); it equals
//! `(π/4)(E_d − 1)` to first order (see [`extra_term_x`]).
//!
//! Assumption of the derivation (paper eq. 6, 9): the diameter error `ε_d` is added to the
//! *right* wheel only, so the mean diameter changes with `E_d` and an in-place turn is affected
//! by it. When the mean diameter is kept (odocal's model and the issue's simulation), an
//! in-place turn is not affected to first order and the extra term over-corrects
//! (`docs/calibration.md`).
//!
//! The extra term is evaluated as `π b d / (4 (−4L² − (b/2) d))` with `d = x_cw − x_ccw` — eq.
//! (11) multiplied through by `d` — so `d = 0` gives 0 instead of dividing by zero.

use super::umbmark::{alpha_beta_x, alpha_beta_y, from_alpha_beta};
use super::{CalibrationError, Factors};

/// `π b d / (4 (−4L² − (b/2) d))`: the second term of eq. (11)/(12) for `d` = the
/// denominator's difference (`x_cw − x_ccw` or `y_cw + y_ccw`).
///
/// # Errors
/// [`CalibrationError::Degenerate`] when the denominator vanishes.
pub fn extra_term(d: f64, side_m: f64, wheelbase_m: f64) -> Result<f64, CalibrationError> {
    let den = 4.0 * (-4.0 * side_m * side_m - 0.5 * wheelbase_m * d);
    if !den.is_finite() || den == 0.0 {
        return Err(CalibrationError::Degenerate);
    }
    Ok(core::f64::consts::PI * wheelbase_m * d / den)
}

/// The second term of eq. (11).
///
/// # Errors
/// As [`extra_term`].
pub fn extra_term_x(
    x_cw: f64,
    x_ccw: f64,
    side_m: f64,
    wheelbase_m: f64,
) -> Result<f64, CalibrationError> {
    extra_term(x_cw - x_ccw, side_m, wheelbase_m)
}

/// Lee et al. eq. (11), x-based.
///
/// # Errors
/// `Degenerate` at a singularity, `OutOfRange` outside 0.5..=2.
pub fn lee_x(
    x_cw: f64,
    x_ccw: f64,
    side_m: f64,
    wheelbase_m: f64,
) -> Result<Factors, CalibrationError> {
    let (a, beta) = alpha_beta_x(x_cw, x_ccw, side_m);
    let alpha = a + extra_term(x_cw - x_ccw, side_m, wheelbase_m)?;
    from_alpha_beta(alpha, beta, side_m, wheelbase_m)
}

/// Lee et al. eq. (12), y-based.
///
/// # Errors
/// `Degenerate` at a singularity, `OutOfRange` outside 0.5..=2.
pub fn lee_y(
    y_cw: f64,
    y_ccw: f64,
    side_m: f64,
    wheelbase_m: f64,
) -> Result<Factors, CalibrationError> {
    let (a, beta) = alpha_beta_y(y_cw, y_ccw, side_m);
    let alpha = a + extra_term(y_cw + y_ccw, side_m, wheelbase_m)?;
    from_alpha_beta(alpha, beta, side_m, wheelbase_m)
}
