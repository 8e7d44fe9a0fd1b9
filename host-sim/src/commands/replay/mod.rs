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
//! can do), and `exact-mocap`, **the default here**: the robust exact fit of the end poses read
//! as motion capture measures them, the end heading (good to a milliradian) weighted by three
//! times the run's length and an end offset per group of closed paths fitted besides the
//! factors ([`methods::EXACT_MOCAP`]; chosen by transfer, docs/calibration.md, *Transfer*).
//! `exact` is what the board computes from the same end poses. Without `--method` every one is
//! evaluated; with it, that one and `nominal`.
//!
//! **Calibration** uses each session's nominal geometry as the belief the runs were driven with;
//! the result is absolute, so sessions with different nominal values can be mixed. It reads the
//! ground truth turned by the session's measured motion-capture heading offset into the robot's
//! own start frame ([`crate::sim::optiodom::heading_offset`]; `--raw-truth`: as recorded),
//! and every run from its recorded start, as every evaluated path is driven and measured
//! (`--from-anchor`: every run that rolls at least 1 m from its anchor, 0.1 m of wheel travel
//! after its start, its start transient left out, [`crate::sim::optiodom::anchor`]; the
//! leave-one-session-out transfer in docs/calibration.md chose the start). Of the `--calibrate`
//! sessions only those of the campaign nearest in time to the evaluated sessions calibrate
//! ([`campaign`]: recorded within `--campaign-days` of the calibration session nearest in time
//! to an evaluated one; the others are named on stderr and missing from `calib_sessions`;
//! `--every-date` keeps all). `E_b`, `E_d`, `E_s` are reported relative to the nominal geometry
//! of the first session that calibrates (or the first
//! evaluated one's when nothing is calibrated), for every row, `nominal` included.
//!
//! **Evaluation** re-integrates each evaluated run's ticks with the parameter set (exact arcs,
//! from the first ground-truth pose) and compares with ground truth at every row, `error = truth
//! − odometry`: final position error, |final heading error| (wrapped), RMS and maximum position
//! error along the path; per session and overall the means over runs.
//!
//! `--format json` prints one object per line per (parameter set, evaluated run) with the keys
//! `method, default, calib_sessions, session, kind, run, final_pos_err_m, final_pos_cov_m2,
//! nees, final_heading_err_rad, path_rms_m, path_max_m, E_b, E_d, E_s, D_R_m, D_L_m, b_m`
//! (`final_pos_cov_m2`: the 2×2 x/y covariance of the final position the library's
//! `calibration::covariance` predicts for the parameter set, [`evaluation::uncertainty_of`];
//! `nees`: the final position error's normalised square against it), then one summary object per
//! parameter set with `"session": "all"`, `"kind": "all"`, `"run": "all"`, the means over the
//! evaluated runs (`nees_mean` among them) and, under `sessions`, the means per session. The `method` a user gets by
//! default here (`exact-mocap`) carries `"default": true`. The same lines go to `<out>/replay.jsonl`; next to
//! it, each evaluated free-path run gets a plot of its paths (ground truth, nominal odometry,
//! calibrated odometry) and of the position error along it.
//!
//! The command is split by concept: [`campaign`] chooses the calibration sessions by date,
//! [`methods`] names the parameter sets and calibrates them,
//! [`evaluation`] replays runs against the ground truth, and [`format`] writes the text table and
//! the JSON lines.

pub mod campaign;
pub mod evaluation;
pub mod format;
pub mod methods;
pub mod pooled;

use std::fs;
use std::path::{Path, PathBuf};

use clap::Args;

use crate::commands::paper::Format;
use crate::sim::optiodom::{Kind, Session, read_session};
use crate::sim::plot::{Figure, Series, Style, write_svg};

use self::campaign::{CAMPAIGN_DAYS, nearest_campaign};
pub use self::evaluation::{
    Means, RunEval, SetEval, e_max_syst, evaluate_run, evaluate_set, geometry_on, uncertainty_of,
};
pub use self::format::json_lines;
use self::format::print_text;
pub use self::methods::{
    EXACT_LS, EXACT_PATH, EndNoise, FitOptions, GEOMETRY, NOMINAL, ParamSet, Pool, ScaleRuns,
    calibrate_method, calibrated_methods, calibrated_sets, default_method, parse_geometry,
};
use odocal::calibration::covariance::{RandomError, Uncertainty};

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
    /// Which runs let the exact fits fit E_s: straight lines, or paths when every run is read
    /// along its path (default: free paths among squares and circles do not); lines and any
    /// path (paths); none (never).
    #[arg(long, value_enum, default_value_t = ScaleRuns::default())]
    pub scale_from: ScaleRuns,
    /// How the exact fits combine several calibration sessions: one fit of all their runs, or
    /// every session alone and a random-effects mean over sessions.
    #[arg(long, value_enum, default_value_t = Pool::default())]
    pub pool: Pool,
    /// Length scale of heading residuals in the exact fits, metres (default: each run's length).
    #[arg(long)]
    pub heading_length: Option<f64>,
    /// Multiplier of each run's length in the exact fits' heading residuals (the side of a
    /// square, the radius of a circle, the wheel travel of a line or turn; default: 3 for
    /// `exact-mocap`, the library's odocal::calibration::exact::HEADING_WEIGHT for the others).
    #[arg(long)]
    pub heading_weight: Option<f64>,
    /// Calibrate against the ground truth as recorded, without turning it by the session's
    /// measured motion-capture heading offset.
    #[arg(long)]
    pub raw_truth: bool,
    /// Calibrate every run that rolls at least 1 m from its anchor, 0.1 m of wheel travel after
    /// its start, leaving its start transient out (default: from the recorded start, as every
    /// evaluated path is driven and measured).
    #[arg(long)]
    pub from_anchor: bool,
    /// Weight the robust fits' residual channels (x, y, heading) by their own scatter among a
    /// run's peers (default: the heading by the run's length, a priori).
    #[arg(long)]
    pub channel_weights: bool,
    /// Give the robust fits' end-heading rows a Cauchy weight of their own (default: the
    /// library's, one weight per run from all its channels).
    #[arg(long)]
    pub heading_apart: bool,
    /// Fit an end-position offset common to the closed paths of one kind and size measured
    /// with their heading (the library's default).
    #[arg(long, conflicts_with = "no_end_offset")]
    pub end_offset: bool,
    /// Do not fit the end offset (every end position as measured).
    #[arg(long)]
    pub no_end_offset: bool,
    /// Measure the calibration runs' end poses as an operator does by hand: add Gaussian noise
    /// of `MM` millimetres to x and y and `MRAD` milliradians to the heading of every end-pose
    /// run (not to runs read along their paths), one draw per session and run for a
    /// `--noise-seed` (the board's context; docs/calibration.md, *Transfer*, *Heading weight and end offset*).
    #[arg(long, value_delimiter = ',', value_name = "MM,MRAD")]
    pub end_noise: Vec<f64>,
    /// Seed of `--end-noise`.
    #[arg(long, default_value_t = 1)]
    pub noise_seed: u64,
    /// Length of a campaign in days: the calibration sessions recorded within this of the
    /// calibration session nearest in time to an evaluated session calibrate, the others are
    /// left out (the session ids are their recording times, DDMMYYYYhhmm; undated sessions
    /// always count).
    #[arg(long, default_value_t = CAMPAIGN_DAYS, value_name = "DAYS")]
    pub campaign_days: f64,
    /// Calibrate on every --calibrate session, whenever it was recorded.
    #[arg(long)]
    pub every_date: bool,
    /// The predicted covariance (`final_pos_cov_m2`, `nees`) with the calibration's own 1σ of
    /// E_d and E_b, not raised to the drift measured between sessions.
    #[arg(long)]
    pub trust_session_sd: bool,
}

fn read_all(dirs: &[PathBuf]) -> Result<Vec<Session>, String> {
    dirs.iter().map(|d| read_session(d)).collect()
}

fn plot_free_runs(
    out: &Path,
    sessions: &[Session],
    nominal: &ParamSet,
    calibrated: Option<&ParamSet>,
) -> Result<Vec<PathBuf>, Box<dyn std::error::Error>> {
    let mut written = Vec::new();
    // The plots show errors only.
    let no_covariance = Uncertainty::nominal(RandomError::NONE);
    for s in sessions.iter().filter(|s| s.kind == Kind::Free) {
        for (i, r) in s.runs.iter().enumerate() {
            let truth: Vec<(f64, f64)> = r.truth.iter().map(|p| (p.x_m, p.y_m)).collect();
            let nom = evaluate_run(r, &geometry_on(nominal, s), &no_covariance);
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
                let e = evaluate_run(r, &geometry_on(c, s), &no_covariance);
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
    if !(args.campaign_days.is_finite() && args.campaign_days >= 0.0) {
        return Err("--campaign-days: expected a non-negative number of days".into());
    }
    let calib = if args.every_date {
        calib
    } else {
        let (kept, left_out) = nearest_campaign(&calib, &evals, args.campaign_days);
        for o in &left_out {
            eprintln!(
                "calibration: session {} left out: recorded {:.0} days from the calibration \
                 session nearest in time to an evaluated one (another campaign; \
                 --campaign-days {}, --every-date keeps it)",
                o.id, o.days, args.campaign_days
            );
        }
        kept
    };
    let reference = calib
        .first()
        .or(evals.first())
        .map(|s| s.nominal)
        .ok_or("no session")?;
    let fit = FitOptions {
        heading: !args.no_heading,
        fit_scale: args.fit_scale,
        scale_from: args.scale_from,
        pool: args.pool,
        heading_length_m: args.heading_length,
        heading_weight: args.heading_weight,
        recorded_truth: args.raw_truth,
        from_start: !args.from_anchor,
        channel_weights: args.channel_weights,
        heading_apart: args.heading_apart || FitOptions::default().heading_apart,
        end_offset: !args.no_end_offset && (args.end_offset || FitOptions::default().end_offset),
        end_noise: match args.end_noise[..] {
            [] => None,
            [mm, mrad] if mm >= 0.0 && mrad >= 0.0 && mm.is_finite() && mrad.is_finite() => {
                Some(EndNoise {
                    position_m: mm * 1e-3,
                    heading_rad: mrad * 1e-3,
                    seed: args.noise_seed,
                })
            }
            _ => return Err("--end-noise: expected MM,MRAD, two non-negative numbers".into()),
        },
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
    let evals_of: Vec<SetEval> = sets
        .iter()
        .map(|s| {
            evaluate_set(s, &evals, &|e| {
                uncertainty_of(s, &calib, args.trust_session_sd, e)
            })
        })
        .collect();
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
