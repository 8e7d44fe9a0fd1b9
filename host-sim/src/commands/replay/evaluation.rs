//! Evaluation of a parameter set against ground truth: each run's ticks re-integrated with it
//! (exact arcs, from the first ground-truth pose), `error = truth − odometry` at every row, and
//! the means over runs per session and overall, with a square session's `E_max,syst`.

use std::fmt::Write as _;

use odocal::calibration::covariance::{
    Floor, PoseCovariance, RandomError, RandomEstimate, Uncertainty, nees,
};
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::{ArcModel, PoseF64};
use odocal::motion::run::Direction;

use super::methods::ParamSet;
use crate::sim::optiodom::{OptiRun, Session, recorded_days};

/// Errors of one evaluated run against ground truth.
#[derive(Clone, Debug)]
pub struct RunEval {
    /// Final position error, metres.
    pub final_pos_err_m: f64,
    /// |final heading error|, radians (wrapped).
    pub final_heading_err_rad: f64,
    /// RMS position error along the path, metres.
    pub path_rms_m: f64,
    /// Maximum position error along the path, metres.
    pub path_max_m: f64,
    /// The model's predicted covariance of the final position (x, y), m² (the library's
    /// `calibration::covariance`, with the set's uncertainty).
    pub final_pos_cov_m2: [[f64; 2]; 2],
    /// The final position error's normalised square against it (2 on average when right).
    pub nees: Option<f64>,
    /// The odometry path (x, y).
    pub odometry: Vec<(f64, f64)>,
    /// Position error against distance travelled (ground truth), metres.
    pub growth: Vec<(f64, f64)>,
}

/// `E_max,syst` of a session's runs with `g`: the larger distance of the CW and CCW centres of
/// gravity of the final position errors; `None` without a run in each direction.
pub fn e_max_syst(session: &Session, g: &Geometry) -> Option<f64> {
    let model = ArcModel::from_geometry(g);
    let cg = |d: Direction| {
        let errs: Vec<(f64, f64)> = session
            .runs
            .iter()
            .filter(|r| r.direction == Some(d))
            .map(|r| {
                let o = model.integrate(PoseF64::default(), &r.knots);
                (r.truth_end.x_m - o.x_m, r.truth_end.y_m - o.y_m)
            })
            .collect();
        let n = errs.len() as f64;
        (n > 0.0).then(|| {
            let x = errs.iter().map(|e| e.0).sum::<f64>() / n;
            let y = errs.iter().map(|e| e.1).sum::<f64>() / n;
            x.hypot(y)
        })
    };
    Some(cg(Direction::Cw)?.max(cg(Direction::Ccw)?))
}

/// Re-integrates `run` with `g` and compares it with ground truth at every knot; the final
/// position's covariance by the model with `u`.
pub fn evaluate_run(run: &OptiRun, g: &Geometry, u: &Uncertainty) -> RunEval {
    let model = ArcModel::from_geometry(g);
    let mut pose = PoseF64::default();
    let mut odometry = vec![(0.0, 0.0)];
    let mut growth = vec![(0.0, 0.0)];
    let (mut ss, mut max, mut dist) = (0.0, 0.0f64, 0.0);
    for j in 1..run.knots.len() {
        pose = model.integrate(pose, &run.knots[j - 1..=j]);
        let t = run.truth[j];
        dist += t.distance_to(&run.truth[j - 1]);
        let e = t.distance_to(&pose);
        ss += e * e;
        max = max.max(e);
        odometry.push((pose.x_m, pose.y_m));
        growth.push((dist, e));
    }
    let n = (run.knots.len() - 1).max(1) as f64;
    let end = run.truth_end;
    let cov = PoseCovariance::along(&model, *u, &run.knots).xy();
    let e = [end.x_m - pose.x_m, end.y_m - pose.y_m];
    RunEval {
        final_pos_cov_m2: cov,
        nees: nees(e, cov),
        final_pos_err_m: end.distance_to(&pose),
        final_heading_err_rad: odocal::calibration::wrap_angle(end.theta_rad - pose.theta_rad)
            .abs(),
        path_rms_m: (ss / n).sqrt(),
        path_max_m: max,
        odometry,
        growth,
    }
}

/// Means of the four errors over some runs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Means {
    /// Runs.
    pub n: usize,
    /// Mean final position error, metres.
    pub final_pos_err_m: f64,
    /// Mean |final heading error|, radians.
    pub final_heading_err_rad: f64,
    /// Mean path RMS error, metres.
    pub path_rms_m: f64,
    /// Mean path maximum error, metres.
    pub path_max_m: f64,
    /// Mean NEES of the final position against the model's covariance (over the runs that
    /// have one), and how many have one.
    pub nees: (f64, usize),
    /// UMBmark's `E_max,syst` of square or circle runs: the larger distance of the CW and CCW
    /// centres of gravity of the final position errors, metres (`None` for other kinds).
    pub e_max_syst_m: Option<f64>,
}

impl Means {
    fn push(&mut self, e: &RunEval) {
        self.n += 1;
        self.final_pos_err_m += e.final_pos_err_m;
        self.final_heading_err_rad += e.final_heading_err_rad;
        self.path_rms_m += e.path_rms_m;
        self.path_max_m += e.path_max_m;
        if let Some(v) = e.nees {
            self.nees.0 += v;
            self.nees.1 += 1;
        }
    }

    fn finish(mut self) -> Self {
        let n = self.n.max(1) as f64;
        self.final_pos_err_m /= n;
        self.final_heading_err_rad /= n;
        self.path_rms_m /= n;
        self.path_max_m /= n;
        self.nees.0 /= self.nees.1.max(1) as f64;
        self
    }

    pub(super) fn json(&self) -> String {
        let mut s = format!(
            "\"runs\":{},\"final_pos_err_m\":{:e},\"final_heading_err_rad\":{:e},\"path_rms_m\":{:e},\"path_max_m\":{:e}",
            self.n,
            self.final_pos_err_m,
            self.final_heading_err_rad,
            self.path_rms_m,
            self.path_max_m
        );
        if let Some(e) = self.e_max_syst_m {
            let _ = write!(s, ",\"E_max_syst_m\":{e:e}");
        }
        if self.nees.1 > 0 {
            let _ = write!(s, ",\"nees_mean\":{:e}", self.nees.0);
        }
        s
    }
}

/// The evaluation of one parameter set on some sessions.
#[derive(Clone, Debug)]
pub struct SetEval {
    /// Per evaluated run: session index, run index (0-based), errors.
    pub runs: Vec<(usize, usize, RunEval)>,
    /// Means per session (same order as the sessions).
    pub sessions: Vec<Means>,
    /// Means over all evaluated runs.
    pub overall: Means,
}

/// The geometry `set` uses on `session`.
pub fn geometry_on(set: &ParamSet, session: &Session) -> Geometry {
    set.geometry.unwrap_or(session.nominal)
}

/// How far in time `set`'s calibration lies from `session`, seconds: from the calibration
/// session recorded farthest from it (a calibration is as old as its oldest runs); `None` when
/// `set` is not calibrated or a session is undated ([`recorded_days`]).
pub fn calibration_age_s(set: &ParamSet, calib: &[Session], session: &Session) -> Option<f64> {
    let at = recorded_days(&session.id)?;
    let mut age: Option<f64> = None;
    for s in calib.iter().filter(|s| set.calib_sessions.contains(&s.id)) {
        let days = (recorded_days(&s.id)? - at).abs();
        age = Some(age.map_or(days, |a| a.max(days)));
    }
    age.map(|days| days * 86_400.0)
}

/// The uncertainty of odometry with `set` on `session`: a calibrated set's relative 1σ (raised
/// to the floor for its age on `session`, [`calibration_age_s`], unless `trust_session`), its
/// fitted `E_s` 1σ or a tape's, and the slip and scrub its own calibration runs show (`calib`:
/// the sessions it was calibrated on, each run's end residual against its geometry,
/// `RandomEstimate`); the nominal one's defaults.
pub fn uncertainty_of(
    set: &ParamSet,
    calib: &[Session],
    trust_session: bool,
    session: &Session,
) -> Uncertainty {
    let Some(c) = &set.calibration else {
        return Uncertainty::nominal(RandomError::DEFAULT);
    };
    let mut random = RandomEstimate::default();
    for s in calib.iter().filter(|s| set.calib_sessions.contains(&s.id)) {
        let model = ArcModel::from_geometry(&geometry_on(set, s));
        // A session's runs of one direction are one path (its kind and size are the session's).
        for d in [None, Some(Direction::Cw), Some(Direction::Ccw)] {
            let group = s.runs.iter().filter(|r| r.direction == d);
            random.add_group(
                &model,
                group.map(|r| (r.knots.as_slice(), (r.truth_end.x_m, r.truth_end.y_m))),
            );
        }
    }
    let q = &c.quality;
    let relative = (
        q.sigma_e_d.unwrap_or(0.0) / c.e_d,
        q.sigma_e_b.unwrap_or(0.0) / c.e_b,
    );
    let sd_s = q.sigma_e_s.filter(|s| *s > 0.0).map(|s| s / c.e_s);
    let random = random.random_error().unwrap_or(RandomError::DEFAULT);
    let floor = Floor::for_age(calibration_age_s(set, calib, session), trust_session);
    Uncertainty::calibrated(Some(relative), sd_s, random, floor)
}

/// Evaluates `set` on every run of `sessions`, its covariance with `u`.
pub fn evaluate_set(
    set: &ParamSet,
    sessions: &[Session],
    u: &dyn Fn(&Session) -> Uncertainty,
) -> SetEval {
    let mut runs = Vec::new();
    let mut per = vec![Means::default(); sessions.len()];
    let mut overall = Means::default();
    for (si, s) in sessions.iter().enumerate() {
        let g = geometry_on(set, s);
        let u = u(s);
        for (ri, r) in s.runs.iter().enumerate() {
            let e = evaluate_run(r, &g, &u);
            per[si].push(&e);
            overall.push(&e);
            runs.push((si, ri, e));
        }
    }
    let sessions_means = per
        .into_iter()
        .zip(sessions)
        .map(|(m, s)| Means {
            e_max_syst_m: e_max_syst(s, &geometry_on(set, s)),
            ..m.finish()
        })
        .collect();
    SetEval {
        runs,
        sessions: sessions_means,
        overall: overall.finish(),
    }
}
