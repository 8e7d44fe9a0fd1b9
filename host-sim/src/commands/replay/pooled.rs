//! The exact fits over several sessions as a random-effects meta-analysis (`--pool sessions`):
//! each calibration session is fitted alone, and the sessions' factors are combined with weights
//! `1/(σ_s² + τ²)`, `σ_s` the session's own 1σ and `τ²` the variance *between* sessions,
//! estimated from the same factors (DerSimonian–Laird, method of moments). The model: every
//! session (a day, a floor, a load) has its own geometry, scattered by `τ` about the robot's;
//! a session with many runs then cannot outweigh the others by more than its precision allows,
//! and once `τ` dominates the sessions count alike, however many runs each has. Measured by
//! transfer (docs/calibration.md, *Transfer*) and rejected: the default pools the runs.
//!
//! Combined per factor, each from the sessions that determine it: the diameter ratio `E_d`
//! from every session, the turning `E_b/E_s` (what squares, circles and turns in place measure)
//! from every session, and the mean diameter `E_s` only from sessions whose fit determined it
//! (lines, paths); without one it stays at the first session's driving scale. The 1σ of the
//! turning is taken as that of `E_b` (it is smaller when `E_s` was fitted with it; the between-
//! session variance dominates either way).

use odocal::calibration::factors_of;
use odocal::kinematics::geometry::Geometry;

use super::methods::{FitOptions, ParamSet, calibrate_method};
use crate::sim::optiodom::Session;

/// One session's factors (absolute, relative to the common reference) with their 1σ.
struct SessionFactors {
    e_d: (f64, f64),
    turning: (f64, f64),
    e_s: Option<(f64, f64)>,
}

/// DerSimonian–Laird random-effects mean of `(value, σ)` pairs, with the between-session
/// variance `τ²` it used; `None` without values.
pub fn random_effects_mean(values: &[(f64, f64)]) -> Option<(f64, f64)> {
    let k = values.len();
    if k == 0 {
        return None;
    }
    // A σ of 0 (a factor that fitted to rounding) would take every weight: floor it.
    let w: Vec<f64> = values
        .iter()
        .map(|(_, s)| 1.0 / (s * s).max(1e-18))
        .collect();
    let sw: f64 = w.iter().sum();
    let fixed = values.iter().zip(&w).map(|((y, _), w)| w * y).sum::<f64>() / sw;
    let q: f64 = values
        .iter()
        .zip(&w)
        .map(|((y, _), w)| w * (y - fixed) * (y - fixed))
        .sum();
    let c = sw - w.iter().map(|w| w * w).sum::<f64>() / sw;
    let tau2 = if k > 1 && c > 0.0 {
        ((q - (k - 1) as f64) / c).max(0.0)
    } else {
        0.0
    };
    let ws: Vec<f64> = values
        .iter()
        .map(|(_, s)| 1.0 / (s * s + tau2).max(1e-18))
        .collect();
    let mean =
        values.iter().zip(&ws).map(|((y, _), w)| w * y).sum::<f64>() / ws.iter().sum::<f64>();
    Some((mean, tau2))
}

/// Calibrates `method` on every session alone and combines the factors over sessions (module
/// docs). Sessions the method cannot calibrate alone are left out, with their reason on stderr.
///
/// # Errors
/// When no session could be calibrated, or the combined geometry is invalid.
pub fn calibrate_pooled(
    sessions: &[Session],
    method: &str,
    fit: &FitOptions,
) -> Result<ParamSet, String> {
    let reference = sessions.first().ok_or("no calibration session")?.nominal;
    let mut factors = Vec::new();
    for s in sessions {
        match calibrate_method(std::slice::from_ref(s), method, fit) {
            Ok(c) => {
                let (e_d, e_b, e_s) = factors_of(&c.geometry, &reference);
                let q = &c.quality;
                let sd = q.sigma_e_d.unwrap_or(f64::INFINITY);
                let sb = q.sigma_e_b.unwrap_or(f64::INFINITY);
                let fitted_scale = q.sigma_e_s.is_some_and(|s| s > 0.0);
                factors.push(SessionFactors {
                    e_d: (e_d, sd),
                    turning: (e_b / e_s, sb),
                    e_s: fitted_scale.then(|| (e_s, q.sigma_e_s.unwrap_or(f64::INFINITY))),
                });
            }
            Err(e) => eprintln!("{method}: session {} left out of the pooled fit: {e}", s.id),
        }
    }
    let pick = |f: &dyn Fn(&SessionFactors) -> Option<(f64, f64)>| -> Vec<(f64, f64)> {
        factors
            .iter()
            .filter_map(f)
            .filter(|(_, s)| s.is_finite())
            .collect()
    };
    let (e_d, _) = random_effects_mean(&pick(&|f| Some(f.e_d)))
        .ok_or_else(|| format!("{method}: no session could be calibrated alone"))?;
    let (turning, _) = random_effects_mean(&pick(&|f| Some(f.turning)))
        .ok_or_else(|| format!("{method}: no session determined E_b"))?;
    // Every session is driven with its own nominal geometry: the first one's driving scale is 1.
    let e_s = random_effects_mean(&pick(&|f| f.e_s)).map_or(1.0, |(m, _)| m);
    let geometry: Geometry = reference.with_factors(e_d, turning * e_s, e_s);
    geometry.validate().map_err(|e| format!("{method}: {e}"))?;
    Ok(ParamSet {
        method: method.to_string(),
        calib_sessions: sessions.iter().map(|s| s.id.clone()).collect(),
        geometry: Some(geometry),
        calibration: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random_effects_weighs_sessions_alike_when_they_disagree() {
        // Agreeing sessions: the inverse-variance mean, no between-session variance.
        let (m, tau2) = random_effects_mean(&[(1.0, 0.1), (1.0, 0.2)]).unwrap();
        assert_eq!((m, tau2), (1.0, 0.0));
        // Precise sessions far apart: τ² dominates, the plain mean of the sessions.
        let (m, tau2) = random_effects_mean(&[(1.0, 1e-4), (2.0, 1e-3), (3.0, 1e-4)]).unwrap();
        assert!(tau2 > 0.5, "{tau2}");
        assert!((m - 2.0).abs() < 1e-3, "{m}");
        // One session: its value.
        assert_eq!(random_effects_mean(&[(1.5, 0.1)]).unwrap().0, 1.5);
        assert!(random_effects_mean(&[]).is_none());
    }
}
