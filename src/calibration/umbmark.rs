//! UMBmark (Borenstein & Feng 1996): E_b and E_d from the centres of gravity of the square
//! runs' end errors.
//!
//! Assumptions (as in the original): wheelbase error and unequal diameters act independently
//! (superposition); small angles (`sin α ≈ α`, `cos α ≈ 1`); the robot drives 4 legs of `L` and
//! 4 in-place 90° turns, CW and CCW, open loop. Inputs are the centres of gravity of
//! `true − odometry` in the start frame (see [`super::stats`] for why our frame needs no
//! mapping); `b` is the wheelbase used while driving, and the result is a correction relative to
//! the driving geometry.
//!
//! ```text
//! x-based: α = (x_cw + x_ccw)/(−4L),  β = (x_cw − x_ccw)/(−4L)
//! y-based: α = (y_cw − y_ccw)/(−4L),  β = (y_cw + y_ccw)/(−4L)
//! R = (L/2)/sin(β/2),  E_d = (R + b/2)/(R − b/2),  E_b = (π/2)/(π/2 − α)
//! ```
//!
//! `E_d` is evaluated as `(L + b·sin(β/2))/(L − b·sin(β/2))` — the same expression multiplied
//! through by `sin(β/2)` — so `β = 0` gives `E_d = 1` exactly instead of `∞/∞`.

use core::f64::consts::FRAC_PI_2;

use super::{CalibrationError, Factors};

/// `(α, β)` of the x-based variant, radians.
pub fn alpha_beta_x(x_cw: f64, x_ccw: f64, side_m: f64) -> (f64, f64) {
    (
        (x_cw + x_ccw) / (-4.0 * side_m),
        (x_cw - x_ccw) / (-4.0 * side_m),
    )
}

/// `(α, β)` of the y-based variant, radians.
pub fn alpha_beta_y(y_cw: f64, y_ccw: f64, side_m: f64) -> (f64, f64) {
    (
        (y_cw - y_ccw) / (-4.0 * side_m),
        (y_cw + y_ccw) / (-4.0 * side_m),
    )
}

/// `E_d = (R + b/2)/(R − b/2)` with `R = (L/2)/sin(β/2)`, evaluated without dividing by
/// `sin(β/2)`; `wheelbase_m` is the `b` of the formula (Jung & Chung pass `E_b·b`).
///
/// # Errors
/// [`CalibrationError::Degenerate`] when `R ≤ b/2` (the leg curves tighter than the wheelbase)
/// or an input is not finite.
pub fn diameter_ratio(beta: f64, side_m: f64, wheelbase_m: f64) -> Result<f64, CalibrationError> {
    let s = crate::util::trig::sin(0.5 * beta);
    let num = side_m + wheelbase_m * s;
    let den = side_m - wheelbase_m * s;
    if !(num.is_finite() && den.is_finite()) || num <= 0.0 || den <= 0.0 {
        return Err(CalibrationError::Degenerate);
    }
    Ok(num / den)
}

/// `E_b = (π/2)/(π/2 − α)`.
///
/// # Errors
/// [`CalibrationError::Degenerate`] when `α ≥ π/2` or `α` is not finite.
pub fn wheelbase_factor(alpha: f64) -> Result<f64, CalibrationError> {
    let den = FRAC_PI_2 - alpha;
    if !den.is_finite() || den <= 0.0 {
        return Err(CalibrationError::Degenerate);
    }
    Ok(FRAC_PI_2 / den)
}

/// UMBmark's factors from `α`, `β`.
///
/// # Errors
/// `Degenerate` at a singularity, `OutOfRange` outside 0.5..=2.
pub fn from_alpha_beta(
    alpha: f64,
    beta: f64,
    side_m: f64,
    wheelbase_m: f64,
) -> Result<Factors, CalibrationError> {
    if !(side_m.is_finite() && side_m > 0.0) {
        return Err(CalibrationError::Degenerate);
    }
    Factors {
        e_d: diameter_ratio(beta, side_m, wheelbase_m)?,
        e_b: wheelbase_factor(alpha)?,
    }
    .check()
}

/// UMBmark, x-based.
///
/// # Errors
/// As [`from_alpha_beta`].
pub fn umbmark_x(
    x_cw: f64,
    x_ccw: f64,
    side_m: f64,
    wheelbase_m: f64,
) -> Result<Factors, CalibrationError> {
    let (a, b) = alpha_beta_x(x_cw, x_ccw, side_m);
    from_alpha_beta(a, b, side_m, wheelbase_m)
}

/// UMBmark, y-based.
///
/// # Errors
/// As [`from_alpha_beta`].
pub fn umbmark_y(
    y_cw: f64,
    y_ccw: f64,
    side_m: f64,
    wheelbase_m: f64,
) -> Result<Factors, CalibrationError> {
    let (a, b) = alpha_beta_y(y_cw, y_ccw, side_m);
    from_alpha_beta(a, b, side_m, wheelbase_m)
}
