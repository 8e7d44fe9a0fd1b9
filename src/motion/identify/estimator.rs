//! The estimator: from the frozen statistics, one common slope per wheel (the time constant),
//! the steady speeds per step, gain and dead-band per direction, the coast deceleration, and
//! the checks that the fit describes a plausible motor.

use super::plan::Identify;
use super::report::{IdentifyFailure, IdentifyProblem, IdentifyReport, MotorFit};
use super::stats::WheelLog;
use super::{MAX_RELATIVE_RESIDUAL, MIN_TOP_SLOPE_RATIO};
use crate::motion::speed::MotorParams;
use crate::motion::wheel::Wheel;
use crate::util::num::fmax;

impl Identify {
    /// The fit of both wheels (see the `identify` module docs) from the statistics of a finished
    /// identification ([`Identify::is_finished`]), where they are: a report with both motors'
    /// parameters, or the failure the fit detects (slope, residual, saturation, parameters out of
    /// range). Not for the control period: about 52,000 instructions of soft-float `f64` and
    /// `libm` on the Cortex-M4F.
    ///
    /// # Errors
    /// The wheel and [`IdentifyProblem`] when the fit does not describe a plausible motor;
    /// [`IdentifyProblem::Implausible`] (right wheel) for an identification not finished yet,
    /// whose statistics are incomplete.
    pub fn fit(&self) -> Result<IdentifyReport, IdentifyFailure> {
        if !self.is_finished() {
            return Err(IdentifyFailure {
                wheel: Wheel::Right,
                problem: IdentifyProblem::Implausible,
            });
        }
        let block_hz = f64::from(self.rate_hz) / f64::from(self.block_periods);
        Ok(IdentifyReport {
            mode: self.mode,
            right: fit_wheel(
                &self.logs[0],
                &self.levels[0],
                self.m_per_tick.0 * block_hz,
                block_hz,
            )
            .map_err(|problem| IdentifyFailure {
                wheel: Wheel::Right,
                problem,
            })?,
            left: fit_wheel(
                &self.logs[1],
                &self.levels[1],
                self.m_per_tick.1 * block_hz,
                block_hz,
            )
            .map_err(|problem| IdentifyFailure {
                wheel: Wheel::Left,
                problem,
            })?,
        })
    }
}

/// Fits one wheel's two directions driven at the duty steps `levels`; `mps_per_count` converts
/// counts per block to m/s, `block_hz` is the block rate.
fn fit_wheel(
    log: &WheelLog,
    levels: &[f32; 3],
    mps_per_count: f64,
    block_hz: f64,
) -> Result<MotorFit, IdentifyProblem> {
    let bad = IdentifyProblem::Implausible;
    // Common slope over the six steps, one intercept per step.
    let (cxx, cxy, cyy) = log.pooled;
    let (n, groups) = (f64::from(log.pairs), f64::from(log.steps));
    if cxx <= 0.0 || n <= groups + 1.0 {
        return Err(bad);
    }
    let a = cxy / cxx;
    if !(a > 0.0 && a < 1.0) {
        return Err(bad);
    }
    let residual = libm::sqrt(fmax(cyy - a * cxy, 0.0) / (n - groups - 1.0)) * mps_per_count;
    let tau = -1.0 / (block_hz * libm::log(a));
    let mut gains = [0.0f64; 2];
    let mut deadbands = [0.0f64; 2];
    let mut top = 0.0f64;
    let mut coast = 0.0f64;
    let mut coast_from = 0.0f64;
    for (d, (means, c)) in log.step_means.iter().zip(log.coast.iter()).enumerate() {
        // Steady speed of each step, m/s (magnitude: the sign was checked per step).
        let v = means.map(|(mx, my)| {
            libm::fabs((f64::from(my) - a * f64::from(mx)) / (1.0 - a)) * mps_per_count
        });
        let u = levels.map(f64::from);
        let slope_lo = (v[1] - v[0]) / (u[1] - u[0]);
        let slope_hi = (v[2] - v[1]) / (u[2] - u[1]);
        if slope_lo.is_nan() || slope_lo <= 0.0 {
            return Err(bad);
        }
        if slope_hi < MIN_TOP_SLOPE_RATIO * slope_lo {
            return Err(IdentifyProblem::Saturated);
        }
        // Least-squares line through the three steps: |v| = K (u − d0).
        let (um, vm) = ((u[0] + u[1] + u[2]) / 3.0, (v[0] + v[1] + v[2]) / 3.0);
        let (mut suu, mut suv) = (0.0, 0.0);
        for i in 0..3 {
            suu += (u[i] - um) * (u[i] - um);
            suv += (u[i] - um) * (v[i] - vm);
        }
        let k = suv / suu;
        gains[d] = k;
        deadbands[d] = um - vm / k;
        top = fmax(top, v[2]);
        // Coast from the top step's speed, as a deceleration.
        let [xx, xy, mx, my] = c.map(f64::from);
        if xx <= 0.0 {
            return Err(bad);
        }
        let ac = xy / xx;
        if !(ac > 0.0 && ac < 1.0) {
            return Err(bad);
        }
        // dv/dt = −(v − v∞)/τ_c: v∞ (the fixed point, beyond zero with constant friction)
        // and τ_c are the same for the block sums as for the continuous speed.
        let v_inf = (my - ac * mx) / (1.0 - ac);
        let tau_c = -1.0 / (block_hz * libm::log(ac));
        let sign = if d == 0 { 1.0 } else { -1.0 };
        let v0 = sign * v[2] / mps_per_count;
        coast += 0.5 * sign * (v0 - v_inf) * mps_per_count / tau_c;
        coast_from += 0.5 * v[2];
    }
    if residual > MAX_RELATIVE_RESIDUAL * top {
        return Err(bad);
    }
    // A dead-band estimate a little below zero is noise on a motor without one.
    let deadband = 0.5 * (deadbands[0] + deadbands[1]);
    if deadband < -0.02 {
        return Err(bad);
    }
    let params = MotorParams {
        gain_forward_mps: gains[0] as f32,
        gain_backward_mps: gains[1] as f32,
        time_constant_s: tau as f32,
        deadband: fmax(deadband, 0.0) as f32,
    };
    params.validate().map_err(|_| bad)?;
    Ok(MotorFit {
        params,
        coast_decel_mps2: coast as f32,
        coast_from_mps: coast_from as f32,
        residual_mps: residual as f32,
    })
}
