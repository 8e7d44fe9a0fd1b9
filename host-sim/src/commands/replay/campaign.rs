//! Which calibration sessions calibrate the evaluated drives: those of the campaign nearest in
//! time to them.
//!
//! A robot's effective geometry drifts between campaigns (tyre wear and pressure, load, a
//! remounted wheel): on the shared OptiOdom sessions the wheelbase fitted per session scatters by
//! about 2.9e-3 of `E_b` between sessions, five to ten times a session's own 1σ, and sessions
//! recorded on one evening agree where sessions six months apart do not (docs/calibration.md,
//! *Transfer*, fifth round). A calibration is therefore taken from the sessions recorded near the
//! drives it is to correct: every calibration session recorded within [`CAMPAIGN_DAYS`] of the
//! calibration session nearest in time to an evaluated session. When every calibration session
//! is far from the evaluated drives, the nearest campaign still calibrates them. Sessions without
//! a recording time ([`recorded_days`]) are always kept, and without a dated evaluated session
//! every calibration session is (`--every-date` keeps them all regardless).

use crate::sim::optiodom::{Session, recorded_days};

/// Length of a campaign, days: calibration sessions recorded within this of the one nearest to
/// the evaluated drives calibrate them together. A month: longer than a measurement campaign
/// (the shared sessions' campaigns span 11 days, December 2020 to January 2021, and one evening
/// in June 2020), shorter than the half year between them; every value from 11 to 182 days
/// selects the same sessions from the shared data.
pub const CAMPAIGN_DAYS: f64 = 30.0;

/// A calibration session left out, with how far in time it lies from the evaluated drives.
#[derive(Clone, Debug, PartialEq)]
pub struct LeftOut {
    /// Session id.
    pub id: String,
    /// Days from the evaluated session nearest to it.
    pub days: f64,
    /// Days from the evaluated drives to the calibration session nearest to them.
    pub nearest_days: f64,
}

/// The calibration sessions of the campaign nearest in time to `evals` (module docs), and the
/// sessions left out. `window_days` is the campaign's length ([`CAMPAIGN_DAYS`]).
pub fn nearest_campaign(
    calib: &[Session],
    evals: &[Session],
    window_days: f64,
) -> (Vec<Session>, Vec<LeftOut>) {
    let eval_days: Vec<f64> = evals.iter().filter_map(|s| recorded_days(&s.id)).collect();
    // Each calibration session's distance in days from the evaluated drives (None: undated).
    let distance: Vec<Option<f64>> = calib
        .iter()
        .map(|s| {
            let t = recorded_days(&s.id)?;
            eval_days
                .iter()
                .map(|e| (t - e).abs())
                .min_by(f64::total_cmp)
        })
        .collect();
    let Some(nearest) = distance.iter().flatten().copied().min_by(f64::total_cmp) else {
        return (calib.to_vec(), Vec::new());
    };
    let mut kept = Vec::new();
    let mut left_out = Vec::new();
    for (s, d) in calib.iter().zip(&distance) {
        match d {
            Some(days) if *days > nearest + window_days => left_out.push(LeftOut {
                id: s.id.clone(),
                days: *days,
                nearest_days: nearest,
            }),
            _ => kept.push(s.clone()),
        }
    }
    (kept, left_out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::optiodom::Kind;
    use odocal::kinematics::geometry::Geometry;

    fn session(id: &str) -> Session {
        Session {
            id: id.to_string(),
            kind: Kind::Square,
            nominal: Geometry::default(),
            tick_scale: 1,
            side_m: 1.0,
            runs: Vec::new(),
            truth_offset: None,
            truth_gaps: Default::default(),
        }
    }

    fn ids(v: &[Session]) -> Vec<&str> {
        v.iter().map(|s| s.id.as_str()).collect()
    }

    #[test]
    fn the_campaign_nearest_to_the_drives_calibrates_them() {
        let june = session("230620202042");
        let june_later = session("230620202144");
        let december = session("231220200029");
        let january = session("030120210001");
        let undated = session("bench-run");
        let calib = [
            june.clone(),
            june_later.clone(),
            december.clone(),
            january.clone(),
            undated,
        ];
        // A December drive: December and January (11 days) kept, June (183 days) left out,
        // the undated session kept.
        let (kept, out) = nearest_campaign(&calib, &[session("231220200134")], CAMPAIGN_DAYS);
        assert_eq!(ids(&kept), ["231220200029", "030120210001", "bench-run"]);
        assert_eq!(ids(&kept).len() + out.len(), calib.len());
        assert_eq!(out.len(), 2);
        assert!(out.iter().all(|o| o.days > 182.0 && o.nearest_days < 0.1));
        // A June drive: the other June session only (and the undated one).
        let (kept, _) = nearest_campaign(&calib, &[session("230620202000")], CAMPAIGN_DAYS);
        assert_eq!(ids(&kept), ["230620202042", "230620202144", "bench-run"]);
        // Drives of both campaigns: both calibrate.
        let (kept, out) = nearest_campaign(
            &calib,
            &[session("230620202000"), session("231220200134")],
            CAMPAIGN_DAYS,
        );
        assert_eq!(kept.len(), calib.len());
        assert!(out.is_empty());
        // A drive a year after every calibration session: the nearest campaign still calibrates.
        let (kept, _) = nearest_campaign(
            &[june.clone(), december.clone()],
            &[session("231220210000")],
            CAMPAIGN_DAYS,
        );
        assert_eq!(ids(&kept), ["231220200029"]);
        // Undated drives: every calibration session.
        let (kept, out) = nearest_campaign(&calib, &[session("free-1")], CAMPAIGN_DAYS);
        assert_eq!(kept.len(), calib.len());
        assert!(out.is_empty());
    }
}
