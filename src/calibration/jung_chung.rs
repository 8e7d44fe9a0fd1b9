//! Jung & Chung 2012: E_b and E_d from the final *heading* errors of the square runs.
//!
//! Needs θ measured at the end of every run. With `θ_cw`, `θ_ccw` the centres of gravity of the
//! heading errors (`true − odometry`, radians):
//!
//! ```text
//! α_Eb = (θ_cw − θ_ccw)/8,  β = (θ_cw + θ_ccw)/8,  α_Ed = π b β/(4L)
//! E_b = (π/2)/(π/2 − (α_Eb + α_Ed)),  R = (L/2)/sin(β/2),  E_d = (R + E_b·b/2)/(R − E_b·b/2)
//! ```
//!
//! Like Lee 2011 it models the effect of unequal wheels on the turns (`α_Ed`); `b` is the
//! wheelbase used while driving, and the result is relative to the driving geometry.

use super::umbmark::{diameter_ratio, wheelbase_factor};
use super::{CalibrationError, Factors};

/// Jung & Chung 2012 from the heading-error centres of gravity.
///
/// # Errors
/// `Degenerate` at a singularity, `OutOfRange` outside 0.5..=2.
pub fn jung_chung(
    theta_cw: f64,
    theta_ccw: f64,
    side_m: f64,
    wheelbase_m: f64,
) -> Result<Factors, CalibrationError> {
    if !(side_m.is_finite() && side_m > 0.0) {
        return Err(CalibrationError::Degenerate);
    }
    let alpha_eb = (theta_cw - theta_ccw) / 8.0;
    let beta = (theta_cw + theta_ccw) / 8.0;
    let alpha_ed = core::f64::consts::PI * wheelbase_m * beta / (4.0 * side_m);
    let e_b = wheelbase_factor(alpha_eb + alpha_ed)?;
    let e_d = diameter_ratio(beta, side_m, e_b * wheelbase_m)?;
    Factors { e_d, e_b }.check()
}
