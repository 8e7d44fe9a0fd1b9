//! Which calibration sessions calibrate the evaluated drives: those of the campaign nearest in
//! time to them.
//!
//! A robot's effective geometry drifts between campaigns (tyre wear and pressure, load, a
//! remounted wheel): on the shared OptiOdom sessions the wheelbase fitted per session scatters by
//! about 2.9e-3 of `E_b` between sessions, five to ten times a session's own 1σ, and sessions
//! recorded on one evening agree where sessions six months apart do not (docs/calibration.md,
//! *Transfer*, *The campaign*). A calibration is therefore taken from the sessions recorded near the
//! drives it is to correct. For every evaluated session, the calibration session recorded
//! nearest in time to it anchors a campaign: every calibration session recorded within
//! [`CAMPAIGN_DAYS`] of an anchor calibrates, the others are left out. However far every
//! calibration session is from the evaluated drives, the nearest one and its campaign still
//! calibrate them. Undated calibration sessions ([`recorded_days`]) are always kept; undated
//! evaluated sessions anchor nothing, so when no evaluated session is dated every calibration
//! session is kept (`--every-date` keeps them all regardless).

use crate::sim::optiodom::{Session, recorded_days};

/// Length of a campaign, days: the calibration sessions recorded within this of the one nearest
/// to an evaluated session calibrate it together. A month: longer than a measurement campaign
/// (the shared sessions' campaigns span 11 days, December 2020 to January 2021, and one evening
/// in June 2020), shorter than the half year between them; every value from 11 to 182 days
/// selects the same sessions from the shared data.
pub const CAMPAIGN_DAYS: f64 = 30.0;

/// A calibration session left out, with how far in time it lies from the campaigns that
/// calibrate.
#[derive(Clone, Debug, PartialEq)]
pub struct LeftOut {
    /// Session id.
    pub id: String,
    /// Days from the nearest anchor: a calibration session nearest in time to an evaluated one.
    pub days: f64,
}

/// The calibration sessions of the campaigns nearest in time to `evals` (module docs), and the
/// sessions left out. `window_days` is the campaign's length ([`CAMPAIGN_DAYS`]).
pub fn nearest_campaign(
    calib: &[Session],
    evals: &[Session],
    window_days: f64,
) -> (Vec<Session>, Vec<LeftOut>) {
    let calib_days: Vec<Option<f64>> = calib.iter().map(|s| recorded_days(&s.id)).collect();
    let dated = || calib_days.iter().flatten().copied();
    // The anchors: for every dated evaluated session, the dated calibration sessions nearest to
    // it (every one of them when several are equally near).
    let mut anchors: Vec<f64> = Vec::new();
    for e in evals.iter().filter_map(|e| recorded_days(&e.id)) {
        let nearest = dated().map(|t| (t - e).abs()).fold(f64::INFINITY, f64::min);
        anchors.extend(dated().filter(|t| (t - e).abs() == nearest));
    }
    if anchors.is_empty() {
        return (calib.to_vec(), Vec::new());
    }
    let mut kept = Vec::new();
    let mut left_out = Vec::new();
    for (s, t) in calib.iter().zip(&calib_days) {
        let days = t.map_or(0.0, |t| {
            anchors
                .iter()
                .map(|a| (t - a).abs())
                .fold(f64::INFINITY, f64::min)
        });
        if days > window_days {
            left_out.push(LeftOut {
                id: s.id.clone(),
                days,
            });
        } else {
            kept.push(s.clone());
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

    fn sessions(ids: &[&str]) -> Vec<Session> {
        ids.iter().map(|id| session(id)).collect()
    }

    fn ids(v: &[Session]) -> Vec<&str> {
        v.iter().map(|s| s.id.as_str()).collect()
    }

    #[test]
    fn the_campaign_nearest_to_the_drives_calibrates_them() {
        // June, June an hour later, December, January, undated.
        let calib = sessions(&[
            "230620202042",
            "230620202144",
            "231220200029",
            "030120210001",
            "bench-run",
        ]);
        // A December drive: its anchor is the December session; January (11 days) kept, June
        // (183 days) left out, the undated session kept.
        let (kept, out) = nearest_campaign(&calib, &[session("231220200134")], CAMPAIGN_DAYS);
        assert_eq!(ids(&kept), ["231220200029", "030120210001", "bench-run"]);
        assert_eq!(ids(&kept).len() + out.len(), calib.len());
        assert_eq!(out.len(), 2);
        assert!(
            out.iter().all(|o| o.days > 182.0 && o.days < 184.0),
            "{out:?}"
        );
        // A June drive at 20:00, before either June session: both June sessions (and the
        // undated one).
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
            &sessions(&["230620202042", "231220200029"]),
            &[session("231220210000")],
            CAMPAIGN_DAYS,
        );
        assert_eq!(ids(&kept), ["231220200029"]);
        // Undated drives: every calibration session.
        let (kept, out) = nearest_campaign(&calib, &[session("free-1")], CAMPAIGN_DAYS);
        assert_eq!(kept.len(), calib.len());
        assert!(out.is_empty());
    }

    #[test]
    fn the_campaign_is_measured_from_its_anchor_not_from_the_drive() {
        // A drive on 10 April; sessions 5 days before it and 30 and 31 days after it. The
        // anchor is the session of 5 April: the session of 10 May is 35 days from it and left
        // out although it is 30 days from the drive, the one of 11 May too.
        let calib = sessions(&["050420200000", "100520200000", "110520200000"]);
        let drive = [session("100420200000")];
        let (kept, out) = nearest_campaign(&calib, &drive, CAMPAIGN_DAYS);
        assert_eq!(ids(&kept), ["050420200000"]);
        assert_eq!(out.len(), 2);
        assert!((out[0].days - 35.0).abs() < 1e-9, "{out:?}");
        // The window's edge is inside: 35 days keeps the 10 May session, not the 11 May one.
        let (kept, _) = nearest_campaign(&calib, &drive, 35.0);
        assert_eq!(ids(&kept), ["050420200000", "100520200000"]);
        // A window of 0 keeps the anchor and the sessions recorded at the same minute.
        let twins = sessions(&["070420200000", "070420200000", "050420200000"]);
        let (kept, _) = nearest_campaign(&twins, &drive, 0.0);
        assert_eq!(ids(&kept), ["070420200000", "070420200000"]);
        // Two sessions equally far on either side of the drive: both anchor, both calibrate.
        let sides = sessions(&["050420200000", "150420200000", "150620200000"]);
        let (kept, _) = nearest_campaign(&sides, &drive, 0.0);
        assert_eq!(ids(&kept), ["050420200000", "150420200000"]);
    }
}
