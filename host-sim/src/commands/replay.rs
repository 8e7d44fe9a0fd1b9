//! `host-sim replay`: calibrate on OptiOdom sessions of any kind and evaluate any parameter set
//! against ground truth on any sessions.
//!
//! ```text
//! cargo sim replay --calibrate <session dir>... --evaluate <session dir>...
//!     [--method M] [--geometry D_R,D_L,b] [--format text|json] [--out DIR]
//! cargo sim replay <calibration session> [<evaluation session>...]      # the older form
//! ```
//!
//! **Parameter sets** (`method`): `nominal` (each evaluated session's own `Di`, `Li`), `geometry`
//! (`--geometry`, absolute metres), and every method calibrated on the `--calibrate` sessions:
//! the closed forms (`umbmark-x`, `umbmark-y`, `lee-x`, `lee-y`, `jung-chung`; they read the
//! square runs only, all of one side and one driving geometry), `exact` — the library's default,
//! the robust exact fit of the end poses of every run (squares give `E_b`, `E_d`; Ivanjko's lines
//! add `E_s`), free paths fitted along their whole path (an end pose of a path that need not
//! close says little) —, `exact-ls` (the same fit by plain least squares) and `exact-path` (the robust
//! exact fit to the ground truth along every run's whole path, as a user with a motion-capture log
//! can do). Without `--method` every one is evaluated; with it, that one and `nominal`.
//!
//! **Calibration** uses each session's nominal geometry as the belief the runs were driven with;
//! the result is absolute, so sessions with different nominal values can be mixed. It reads the
//! ground truth turned by the session's measured motion-capture heading offset into the robot's
//! own start frame ([`crate::sim::optiodom`], *The motion-capture heading offset*; `--raw-truth`:
//! as recorded), and every run that rolls at least 1 m from its anchor, 0.1 m of wheel travel
//! after its start, so that a slipping start does not read as a wheelbase error (*The start
//! transient*; `--from-start`: from the recorded start). `E_b`, `E_d`,
//! `E_s` are reported relative to the first calibration session's nominal geometry (or the first
//! evaluated one's when nothing is calibrated), for every row, `nominal` included.
//!
//! **Evaluation** re-integrates each evaluated run's ticks with the parameter set (exact arcs,
//! from the first ground-truth pose) and compares with ground truth at every row, `error = truth
//! − odometry`: final position error, |final heading error| (wrapped), RMS and maximum position
//! error along the path; per session and overall the means over runs.
//!
//! `--format json` prints one object per line per (parameter set, evaluated run) with the keys
//! `method, default, calib_sessions, session, kind, run, final_pos_err_m, final_heading_err_rad,
//! path_rms_m, path_max_m, E_b, E_d, E_s, D_R_m, D_L_m, b_m`, then one summary object per
//! parameter set with `"session": "all"`, `"kind": "all"`, `"run": "all"`, the means over the
//! evaluated runs and, under `sessions`, the means per session. The `method` a user gets by
//! default (`exact`) carries `"default": true`. The same lines go to `<out>/replay.jsonl`; next to
//! it, each evaluated free-path run gets a plot of its paths (ground truth, nominal odometry,
//! calibrated odometry) and of the position error along it.

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use clap::Args;
use odocal::calibration::{
    Calibration, ExactOptions, Method, ScaleFit, calibrate_with, factors_of,
};
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::{ArcModel, PoseF64};
use odocal::motion::run::Direction;

use crate::commands::paper::Format;
use crate::sim::optiodom::{
    ANCHOR_MIN_TRAVEL_M, Kind, OptiRun, START_TRAVEL_M, Session, TruthGaps, read_session,
};
use crate::sim::plot::{Figure, Series, Style, write_svg};

/// Arguments of `host-sim replay`.
#[derive(Args, Debug)]
pub struct ReplayArgs {
    /// Older form: the calibration session, then the evaluation sessions (default: itself).
    pub sessions: Vec<PathBuf>,
    /// Session folders to calibrate on (any kind; e.g. ../shared/data/optiodom/diff/square/231220200029).
    #[arg(long, num_args = 1..)]
    pub calibrate: Vec<PathBuf>,
    /// Session folders to evaluate on (default: the calibration sessions, in-sample).
    #[arg(long, num_args = 1..)]
    pub evaluate: Vec<PathBuf>,
    /// Evaluate only this parameter set (and `nominal`): nominal, umbmark-x, umbmark-y, lee-x,
    /// lee-y, jung-chung, exact, exact-ls, exact-path.
    #[arg(long)]
    pub method: Option<String>,
    /// Also evaluate this absolute geometry: right and left wheel diameter and wheelbase, metres.
    #[arg(long, value_name = "D_R,D_L,b")]
    pub geometry: Option<String>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Text)]
    pub format: Format,
    /// Folder for replay.jsonl and the free-path plots.
    #[arg(long, default_value = "target/odocal-sim/replay")]
    pub out: PathBuf,
    /// Do not use the ground-truth heading in the exact fits (Jung & Chung then fails).
    #[arg(long)]
    pub no_heading: bool,
    /// Always fit the mean diameter E_s in the exact fits (squares constrain it weakly).
    #[arg(long)]
    pub fit_scale: bool,
    /// Length scale of heading residuals in the exact fits, metres (default: each run's length).
    #[arg(long)]
    pub heading_length: Option<f64>,
    /// Calibrate against the ground truth as recorded, without turning it by the session's
    /// measured motion-capture heading offset.
    #[arg(long)]
    pub raw_truth: bool,
    /// Calibrate from each run's recorded start, its start transient included (default: from
    /// 0.1 m of wheel travel on, for runs whose wheels roll at least 1 m).
    #[arg(long)]
    pub from_start: bool,
}

/// A parameter set name beyond the library's methods.
pub const EXACT_LS: &str = "exact-ls";
/// The exact fit along the ground-truth path.
pub const EXACT_PATH: &str = "exact-path";
/// The uncalibrated row.
pub const NOMINAL: &str = "nominal";
/// The `--geometry` row.
pub const GEOMETRY: &str = "geometry";

/// Every calibrated parameter set, in display order.
pub fn calibrated_methods() -> Vec<&'static str> {
    let mut v: Vec<&'static str> = Method::ALL.iter().map(|m| m.as_str()).collect();
    v.extend([EXACT_LS, EXACT_PATH]);
    v
}

/// The name of the method a user gets by default.
pub fn default_method() -> &'static str {
    Method::Exact.as_str()
}

/// One parameter set to evaluate.
#[derive(Clone, Debug)]
pub struct ParamSet {
    /// `nominal`, `geometry` or a method name.
    pub method: String,
    /// Ids of the sessions it was calibrated on.
    pub calib_sessions: Vec<String>,
    /// The absolute geometry; `None` = each evaluated session's own nominal.
    pub geometry: Option<Geometry>,
    /// The calibration result, for calibrated sets.
    pub calibration: Option<Calibration>,
}

/// Options of the exact fits.
#[derive(Clone, Copy, Debug)]
pub struct FitOptions {
    /// Use ground-truth headings.
    pub heading: bool,
    /// Always fit E_s.
    pub fit_scale: bool,
    /// Heading residual length scale.
    pub heading_length_m: Option<f64>,
    /// Calibrate against the ground truth as recorded (not turned by its heading offset).
    pub recorded_truth: bool,
    /// Calibrate from each run's first knot, not from its anchor.
    pub from_start: bool,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            heading: true,
            fit_scale: false,
            heading_length_m: None,
            recorded_truth: false,
            from_start: false,
        }
    }
}

/// Calibrates `method` on `sessions` (relative to the first one's nominal geometry).
///
/// # Errors
/// The library's reason, or an unknown method name.
pub fn calibrate_method(
    sessions: &[Session],
    method: &str,
    fit: &FitOptions,
) -> Result<Calibration, String> {
    let first = sessions.first().ok_or("no calibration session")?;
    // A free path is fitted along its whole path by every exact fit: its end pose alone (a few
    // numbers from a path of metres that need not close) does not determine the factors.
    let along_path = |kind: Kind| method == EXACT_PATH || kind == Kind::Free;
    let lib_method = match method {
        EXACT_LS | EXACT_PATH => Method::Exact,
        m => Method::parse(m).ok_or_else(|| format!("unknown method {m:?}"))?,
    };
    let obs: Vec<_> = sessions
        .iter()
        .flat_map(|s| {
            s.runs.iter().map(move |r| {
                let mut o = r.observation(
                    s.kind,
                    s.side_m,
                    &s.nominal,
                    along_path(s.kind),
                    fit.recorded_truth,
                    fit.from_start,
                );
                if !fit.heading {
                    o.measured.theta_rad = None;
                }
                o
            })
        })
        .collect();
    let options = ExactOptions {
        scale: if fit.fit_scale {
            ScaleFit::Always
        } else {
            ScaleFit::Auto
        },
        use_heading: fit.heading,
        heading_length_m: fit.heading_length_m,
        robust: method != EXACT_LS,
        ..ExactOptions::default()
    };
    calibrate_with(&obs, &first.nominal, lib_method, &options).map_err(|e| e.to_string())
}

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

/// Re-integrates `run` with `g` and compares it with ground truth at every knot.
pub fn evaluate_run(run: &OptiRun, g: &Geometry) -> RunEval {
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
    RunEval {
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
    }

    fn finish(mut self) -> Self {
        let n = self.n.max(1) as f64;
        self.final_pos_err_m /= n;
        self.final_heading_err_rad /= n;
        self.path_rms_m /= n;
        self.path_max_m /= n;
        self
    }

    fn json(&self) -> String {
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

/// Evaluates `set` on every run of `sessions`.
pub fn evaluate_set(set: &ParamSet, sessions: &[Session]) -> SetEval {
    let mut runs = Vec::new();
    let mut per = vec![Means::default(); sessions.len()];
    let mut overall = Means::default();
    for (si, s) in sessions.iter().enumerate() {
        let g = geometry_on(set, s);
        for (ri, r) in s.runs.iter().enumerate() {
            let e = evaluate_run(r, &g);
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

/// Parses `D_R,D_L,b` (metres) into a geometry with `counts_per_rev` of `like`.
///
/// # Errors
/// A message when the text is not three positive numbers or the geometry is invalid.
pub fn parse_geometry(text: &str, like: &Geometry) -> Result<Geometry, String> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("--geometry {text:?}: expected D_R,D_L,b in metres"))?;
    let [dr, dl, b] = v[..] else {
        return Err(format!(
            "--geometry {text:?}: expected three numbers D_R,D_L,b in metres"
        ));
    };
    let g = Geometry {
        diameter_right_m: dr,
        diameter_left_m: dl,
        wheelbase_m: b,
        counts_per_rev: like.counts_per_rev,
    };
    g.validate()
        .map_err(|e| format!("--geometry {text:?}: {e}"))?;
    Ok(g)
}

fn read_all(dirs: &[PathBuf]) -> Result<Vec<Session>, String> {
    dirs.iter().map(|d| read_session(d)).collect()
}

fn json_str(s: &str) -> String {
    let mut o = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => o.push_str("\\\""),
            '\\' => o.push_str("\\\\"),
            c if (c as u32) < 0x20 => {
                let _ = write!(o, "\\u{:04x}", c as u32);
            }
            c => o.push(c),
        }
    }
    o.push('"');
    o
}

/// The JSON fields shared by a parameter set's rows: method, default, calib_sessions, factors.
fn set_fields(set: &ParamSet, g: &Geometry, reference: &Geometry) -> String {
    let (e_d, e_b, e_s) = factors_of(g, reference);
    let calib = set
        .calib_sessions
        .iter()
        .map(|s| json_str(s))
        .collect::<Vec<_>>()
        .join(",");
    format!(
        "\"method\":{},\"default\":{},\"calib_sessions\":[{calib}],\"E_b\":{e_b:.9},\"E_d\":{e_d:.9},\"E_s\":{e_s:.9},\"D_R_m\":{:.9},\"D_L_m\":{:.9},\"b_m\":{:.9}",
        json_str(&set.method),
        set.method == default_method(),
        g.diameter_right_m,
        g.diameter_left_m,
        g.wheelbase_m
    )
}

/// The JSON lines of one evaluated parameter set: one per run, then the summary.
pub fn json_lines(
    set: &ParamSet,
    eval: &SetEval,
    sessions: &[Session],
    reference: &Geometry,
) -> Vec<String> {
    let mut out = Vec::new();
    for (si, ri, e) in &eval.runs {
        let s = &sessions[*si];
        out.push(format!(
            "{{{},\"session\":{},\"kind\":\"{}\",\"run\":{},\"final_pos_err_m\":{:e},\"final_heading_err_rad\":{:e},\"path_rms_m\":{:e},\"path_max_m\":{:e}}}",
            set_fields(set, &geometry_on(set, s), reference),
            json_str(&s.id),
            s.kind.as_str(),
            ri + 1,
            e.final_pos_err_m,
            e.final_heading_err_rad,
            e.path_rms_m,
            e.path_max_m
        ));
    }
    let per = sessions
        .iter()
        .zip(&eval.sessions)
        .map(|(s, m)| {
            let offset = s.truth_offset.map_or_else(String::new, |o| {
                format!(",\"truth_heading_offset_rad\":{:e}", o.heading_rad)
            });
            format!(
                "{}:{{\"kind\":\"{}\",{}{offset}}}",
                json_str(&s.id),
                s.kind.as_str(),
                m.json()
            )
        })
        .collect::<Vec<_>>()
        .join(",");
    // A nominal row's factors differ per session; the summary reports the first session's.
    let g = sessions.first().map_or(*reference, |s| geometry_on(set, s));
    out.push(format!(
        "{{{},\"session\":\"all\",\"kind\":\"all\",\"run\":\"all\",{},\"sessions\":{{{per}}}}}",
        set_fields(set, &g, reference),
        eval.overall.json()
    ));
    out
}

/// The calibrated parameter sets `names` on `calib` (errors on stderr, the set skipped).
pub fn calibrated_sets(calib: &[Session], names: &[&str], fit: &FitOptions) -> Vec<ParamSet> {
    let ids: Vec<String> = calib.iter().map(|s| s.id.clone()).collect();
    let mut sets = Vec::new();
    for name in names {
        match calibrate_method(calib, name, fit) {
            Ok(c) => sets.push(ParamSet {
                method: (*name).to_string(),
                calib_sessions: ids.clone(),
                geometry: Some(c.geometry),
                calibration: Some(c),
            }),
            Err(e) => eprintln!("{name}: not calibrated on {}: {e}", ids.join(", ")),
        }
    }
    sets
}

fn plot_free_runs(
    out: &Path,
    sessions: &[Session],
    nominal: &ParamSet,
    calibrated: Option<&ParamSet>,
) -> Result<Vec<PathBuf>, Box<dyn std::error::Error>> {
    let mut written = Vec::new();
    for s in sessions.iter().filter(|s| s.kind == Kind::Free) {
        for (i, r) in s.runs.iter().enumerate() {
            let truth: Vec<(f64, f64)> = r.truth.iter().map(|p| (p.x_m, p.y_m)).collect();
            let nom = evaluate_run(r, &geometry_on(nominal, s));
            let mut paths = vec![
                Series::new("ground truth", truth, Style::Line, 0),
                Series::new(
                    "odometry, nominal",
                    nom.odometry.clone(),
                    Style::ThinLine,
                    1,
                ),
            ];
            let mut errors = vec![Series::new("nominal", nom.growth.clone(), Style::Line, 1)];
            if let Some(c) = calibrated {
                let e = evaluate_run(r, &geometry_on(c, s));
                let label = format!("odometry, {} ({})", c.method, c.calib_sessions.join("+"));
                paths.push(Series::new(label, e.odometry, Style::Line, 2));
                errors.push(Series::new(c.method.clone(), e.growth, Style::Line, 2));
            }
            let stem = format!("{}-run-{:02}", s.id, i + 1);
            let path_svg = out.join(format!("{stem}-path.svg"));
            write_svg(
                &path_svg,
                &Figure {
                    title: format!("{} run {}: ground truth and odometry", s.id, i + 1),
                    x_label: "x [m]".into(),
                    y_label: "y [m]".into(),
                    equal_aspect: true,
                    series: paths,
                    ..Figure::default()
                },
            )?;
            let err_svg = out.join(format!("{stem}-error.svg"));
            write_svg(
                &err_svg,
                &Figure {
                    title: format!("{} run {}: position error along the path", s.id, i + 1),
                    x_label: "distance travelled (ground truth) [m]".into(),
                    y_label: "position error [m]".into(),
                    series: errors,
                    ..Figure::default()
                },
            )?;
            written.extend([path_svg, err_svg]);
        }
    }
    Ok(written)
}

fn print_fit(c: &Calibration, calib: &[Session]) {
    let Some(f) = &c.fit else {
        return;
    };
    // Run index → (session, run, start heading error) in the order the observations were built.
    let labels: Vec<(String, usize, Option<f64>)> = calib
        .iter()
        .flat_map(|s| {
            s.runs
                .iter()
                .enumerate()
                .map(move |(i, r)| (s.id.clone(), i + 1, r.start_heading_error(&s.nominal)))
        })
        .collect();
    println!(
        "    per run: residual (truth − fit) x, y [mm], θ [mrad], path RMS [mm], weight, channel weights x y θ, start θ [mrad]{}",
        if f.reweighted {
            ""
        } else {
            " (not reweighted)"
        }
    );
    for r in f.runs() {
        let (sid, run, start) = labels.get(r.index).cloned().unwrap_or_default();
        println!(
            "      {sid} run {run:>2}: {:>8.1} {:>8.1} {:>8} {:>8} {:>6.3}  {:>5.2} {:>5.2} {:>5.2} {:>8}{}",
            r.residual_x_m * 1e3,
            r.residual_y_m * 1e3,
            r.residual_theta_rad
                .map_or_else(|| "-".to_string(), |t| format!("{:.1}", t * 1e3)),
            r.path_rms_m
                .map_or_else(|| "-".to_string(), |v| format!("{:.1}", v * 1e3)),
            r.weight,
            r.channel_weights[0],
            r.channel_weights[1],
            r.channel_weights[2],
            start.map_or_else(|| "-".to_string(), |t| format!("{:+.1}", t * 1e3)),
            if r.outlier { "  outlier" } else { "" }
        );
    }
    if f.run_count > f.runs().len() {
        println!("      ({} more runs)", f.run_count - f.runs().len());
    }
}

/// Runs the subcommand.
pub fn run(args: &ReplayArgs) -> Result<(), Box<dyn std::error::Error>> {
    let (calib_dirs, eval_dirs): (Vec<PathBuf>, Vec<PathBuf>) = if args.calibrate.is_empty() {
        match args.sessions.split_first() {
            Some((c, rest)) => (vec![c.clone()], rest.to_vec()),
            None if !args.evaluate.is_empty() => (Vec::new(), Vec::new()),
            None => return Err(
                "give --calibrate <session dir>... and/or --evaluate <session dir>... (see --help)"
                    .into(),
            ),
        }
    } else {
        if !args.sessions.is_empty() {
            return Err(
                "give sessions either with --calibrate/--evaluate or positionally, not both".into(),
            );
        }
        (args.calibrate.clone(), Vec::new())
    };
    let eval_dirs = if args.evaluate.is_empty() {
        eval_dirs
    } else {
        args.evaluate.clone()
    };
    let calib = read_all(&calib_dirs)?;
    let evals = if eval_dirs.is_empty() {
        eprintln!("no --evaluate sessions: evaluating on the calibration sessions (in-sample)");
        calib.clone()
    } else {
        read_all(&eval_dirs)?
    };
    let reference = calib
        .first()
        .or(evals.first())
        .map(|s| s.nominal)
        .ok_or("no session")?;
    let fit = FitOptions {
        heading: !args.no_heading,
        fit_scale: args.fit_scale,
        heading_length_m: args.heading_length,
        recorded_truth: args.raw_truth,
        from_start: args.from_start,
    };
    let all = calibrated_methods();
    let names: Vec<&str> = match args.method.as_deref() {
        None => all.clone(),
        Some(NOMINAL) => Vec::new(),
        Some(m) => {
            let name = all
                .iter()
                .copied()
                .find(|n| n.eq_ignore_ascii_case(m))
                .ok_or_else(|| {
                    format!("unknown method {m:?}: one of nominal, {}", all.join(", "))
                })?;
            vec![name]
        }
    };
    let mut sets = vec![ParamSet {
        method: NOMINAL.into(),
        calib_sessions: Vec::new(),
        geometry: None,
        calibration: None,
    }];
    if let Some(text) = &args.geometry {
        sets.push(ParamSet {
            method: GEOMETRY.into(),
            calib_sessions: Vec::new(),
            geometry: Some(parse_geometry(text, &reference)?),
            calibration: None,
        });
    }
    if !calib.is_empty() {
        sets.extend(calibrated_sets(&calib, &names, &fit));
    }
    let evals_of: Vec<SetEval> = sets.iter().map(|s| evaluate_set(s, &evals)).collect();
    let mut lines = Vec::new();
    for (set, ev) in sets.iter().zip(&evals_of) {
        lines.extend(json_lines(set, ev, &evals, &reference));
    }
    fs::create_dir_all(&args.out)?;
    let jsonl = args.out.join("replay.jsonl");
    fs::write(&jsonl, lines.join("\n") + "\n")?;
    let plotted = sets
        .iter()
        .find(|s| s.method == default_method())
        .or_else(|| {
            sets.iter()
                .find(|s| s.calibration.is_some() || s.method == GEOMETRY)
        });
    let svgs = plot_free_runs(&args.out, &evals, &sets[0], plotted)?;
    match args.format {
        Format::Json => {
            for l in &lines {
                println!("{l}");
            }
        }
        Format::Text => print_text(&sets, &evals_of, &calib, &evals, &reference, &fit),
    }
    eprintln!("wrote {}", jsonl.display());
    for s in svgs {
        eprintln!("wrote {}", s.display());
    }
    Ok(())
}

fn print_text(
    sets: &[ParamSet],
    evals_of: &[SetEval],
    calib: &[Session],
    evals: &[Session],
    reference: &Geometry,
    fit: &FitOptions,
) {
    let ids = |v: &[Session]| {
        v.iter()
            .map(|s| format!("{} ({})", s.id, s.kind.as_str()))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if !calib.is_empty() {
        println!("calibrated on {}", ids(calib));
        let offsets = calib
            .iter()
            .map(|s| {
                s.truth_offset.map_or_else(
                    || format!("{} not measured (no rows along a path)", s.id),
                    |o| {
                        format!(
                            "{} {:+.1} mrad ({} rows)",
                            s.id,
                            o.heading_rad * 1e3,
                            o.samples
                        )
                    },
                )
            })
            .collect::<Vec<_>>()
            .join(", ");
        println!(
            "  ground truth heading offset (direction of motion − recorded heading): {offsets}; {}",
            if fit.recorded_truth {
                "the fits read the truth as recorded"
            } else {
                "the fits read the truth turned onto the direction of motion"
            }
        );
        let runs = calib.iter().map(|s| s.runs.len()).sum::<usize>();
        let anchored = calib
            .iter()
            .flat_map(|s| &s.runs)
            .filter(|r| r.anchor > 0)
            .count();
        if fit.from_start {
            println!("  every calibration run measured from its recorded start (--from-start)");
        } else {
            println!(
                "  {anchored} of {runs} calibration runs measured from {START_TRAVEL_M} m of wheel travel on, leaving their start transient out (runs rolling under {ANCHOR_MIN_TRAVEL_M} m keep their start; --from-start: every run from its start)"
            );
        }
    }
    println!(
        "evaluated on {} (error = truth − odometry, means over runs)",
        ids(evals)
    );
    let mut listed: Vec<&str> = Vec::new();
    for s in calib.iter().chain(evals) {
        let g = s.truth_gaps;
        if g != TruthGaps::default() && !listed.contains(&s.id.as_str()) {
            listed.push(&s.id);
            println!(
                "  {}: rows without ground truth (motion-capture dropouts): {} interpolated between their neighbours, {} cut from run ends",
                s.id, g.interpolated, g.cut
            );
        }
    }
    println!(
        "  {:<11} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "method", "E_b", "E_d", "E_s", "sd E_b", "final mm", "head mrad", "rms mm", "max mm"
    );
    for (set, ev) in sets.iter().zip(evals_of) {
        let g = evals.first().map_or(*reference, |s| geometry_on(set, s));
        let (e_d, e_b, e_s) = factors_of(&g, reference);
        let sd = set
            .calibration
            .and_then(|c| c.quality.sigma_e_b)
            .map_or_else(|| "-".to_string(), |s| format!("{s:.5}"));
        let m = &ev.overall;
        println!(
            "  {:<11} {e_b:>9.5} {e_d:>9.5} {e_s:>9.5} {sd:>9} {:>9.1} {:>9.1} {:>9.1} {:>9.1}{}",
            set.method,
            m.final_pos_err_m * 1e3,
            m.final_heading_err_rad * 1e3,
            m.path_rms_m * 1e3,
            m.path_max_m * 1e3,
            if set.method == default_method() {
                "  (default)"
            } else {
                ""
            }
        );
        if evals.len() > 1 || ev.sessions.iter().any(|m| m.e_max_syst_m.is_some()) {
            for (s, m) in evals.iter().zip(&ev.sessions) {
                println!(
                    "      {:<20} {:>49.1} {:>9.1} {:>9.1} {:>9.1}{}",
                    s.id,
                    m.final_pos_err_m * 1e3,
                    m.final_heading_err_rad * 1e3,
                    m.path_rms_m * 1e3,
                    m.path_max_m * 1e3,
                    m.e_max_syst_m
                        .map_or_else(String::new, |e| format!("  E_max,syst {:.1} mm", e * 1e3))
                );
            }
        }
        if let Some(c) = &set.calibration {
            print_fit(c, calib);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geometry_text_is_checked() {
        let like = Geometry::PAPER_NOMINAL;
        let g = parse_geometry("0.084, 0.0841,0.2", &like).unwrap();
        assert_eq!(g.diameter_left_m, 0.0841);
        assert_eq!(g.counts_per_rev, like.counts_per_rev);
        for bad in [
            "0.084,0.084",
            "a,b,c",
            "0.084,-0.084,0.2",
            "0.084,0.084,0.2,1",
        ] {
            assert!(parse_geometry(bad, &like).is_err(), "{bad}");
        }
    }

    #[test]
    fn json_strings_are_escaped() {
        assert_eq!(json_str("a\"b\\c\n"), "\"a\\\"b\\\\c\\u000a\"");
    }
}
