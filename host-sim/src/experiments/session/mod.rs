//! The full simulated calibration session (`cargo sim`): everything an operator does on the
//! floor, against the simulated robot, through the board's serial command path.
//!
//! 1. **Robot**: the paper's nominal robot with unknown true factors (default `E_b = 1.010`,
//!    `E_d = 0.995`), wheel slip noise per millisecond of travel, measurement noise on every measured
//!    end pose (x, y in metres, θ in degrees, as the operator enters them).
//! 2. **Track size**: a short pilot (slip only, nominal belief) gives the end-position scatter;
//!    [`odocal::calibration::track::advise`] picks the side `L` for the chosen method (or `--side`).
//! 3. **Calibration runs**: the simulated board ([`crate::sim::board::Board`]: the library's
//!    `Controller`, `Session` and `ParamAndRunStore` on simulated flash) receives protocol lines —
//!    `set square_side`, `set runs_per_direction`, then `next` and `measure x y θ` for each of
//!    the `runs` CW and `runs` CCW squares. Measurements are the simulator's true end pose in the
//!    run's start frame plus noise. Every reply is checked (`ok …`) and parsed.
//! 4. `calibrate` (every method; the reply table is parsed), `apply <method>`, `save`.
//! 5. **Reboot**: the board is powered off; a new board boots from the same simulated flash;
//!    `params` must show the saved calibration and the controller must use its geometry.
//! 6. **Verification** on the rebooted board through the serial path (same `next`/`measure`
//!    procedure), and, for every method's parameters and the nominal ones, fresh squares driven
//!    closed-loop (true end poses, no measurement noise) and the paper's rectangle test (4 CCW
//!    laps of 3.6 m × 8.7 m).
//! 7. **Parameter error against side** (paper Fig. 5): a [`crate::experiments::sweep`] at this session's
//!    measurement noise, with the paper-mode slip scaled to the scatter observed in step 3.
//!
//! Errors are `true − odometry` in the run's start frame (x forward, y left), metres.

mod serial;

pub use self::serial::{field, parse_calibration};
use self::serial::{planned_runs, send, verify};

use std::path::PathBuf;
use std::time::Instant;

use clap::{Args, Parser};
use indicatif::ProgressBar;
use odocal::calibration::Method;
use odocal::calibration::track::{TrackAdviceInput, advise};
use odocal::kinematics::geometry::Geometry;
use odocal::motion::identify::IdentifyMode;
use odocal::motion::run::{Direction, PathKind};
use odocal::motion::speed::SpeedTuning;
use odocal::protocol::{Command, ErrorCode, ParamName};
use rayon::prelude::*;

use crate::experiments::montecarlo::Rng;
use crate::experiments::rectangle::RectangleResult;
use crate::experiments::square::{drive_path_tuned, e_max_and_scatter};
use crate::experiments::sweep::{SweepArgs, SweepResult, pilot_scatter, sweep};
use crate::sim::board::Board;
use crate::sim::flash::SimParamFlash;
use crate::sim::robot::MotorArgs;
use crate::sim::robot::{SimConfig, sim_config};

/// Arguments of the simulated session (also the defaults of `cargo sim` with no subcommand).
#[derive(Args, Debug, Clone)]
pub struct SessionArgs {
    /// True E_b = b_true / b_nominal of the simulated robot (unknown to it).
    #[arg(long, default_value_t = 1.010)]
    pub eb: f64,
    /// True E_d = D_R / D_L of the simulated robot (unknown to it).
    #[arg(long, default_value_t = 0.995)]
    pub ed: f64,
    /// Seed of the slip and measurement noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Relative slip noise of each wheel's ground travel per millisecond (1σ; per control period at 1 kHz).
    #[arg(long, default_value_t = 0.02)]
    pub slip: f64,
    /// 1σ of a measured end coordinate, millimetres.
    #[arg(long, default_value_t = 2.0)]
    pub meas_mm: f64,
    /// 1σ of a measured end heading, degrees.
    #[arg(long, default_value_t = 0.2)]
    pub meas_deg: f64,
    /// Square side L, metres (default: the track-size advice for `--method`).
    #[arg(long)]
    pub side: Option<f64>,
    /// Largest side the floor allows, metres (bounds the advice).
    #[arg(long, default_value_t = 4.0)]
    pub max_side: f64,
    /// Squares per direction (UMBmark: 5).
    #[arg(long, default_value_t = 5)]
    pub runs: u8,
    /// Method applied and saved.
    #[arg(long, default_value = "exact")]
    pub method: String,
    /// Laps of the 3.6 m × 8.7 m rectangle test.
    #[arg(long, default_value_t = 4)]
    pub laps: u32,
    /// Sides of the parameter-error-against-side sweep (Fig. 5), metres.
    #[arg(long, value_delimiter = ',', default_value = "0.5,1,2,4,8")]
    pub sweep_sides: Vec<f64>,
    /// Calibrations per side in that sweep.
    #[arg(long, default_value_t = 100)]
    pub sweep_trials: u32,
    /// Output directory for plots, transcript and CSV.
    #[arg(long, default_value = "target/odocal-sim")]
    pub out: PathBuf,
    /// Control rate, Hz: 1000, 2000, 4000, 5000, 8000 or 10000 (the board's `control_hz`).
    #[arg(long = "rate-hz", visible_alias = "rate", default_value_t = odocal::motion::controller::DEFAULT_RATE_HZ, value_parser = crate::commands::parse_rate_hz)]
    pub rate: u32,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// The simulated motors; when they differ from the defaults, the session identifies them
    /// (`identify floor`) before the pilot runs.
    #[command(flatten)]
    pub motors: MotorArgs,
}

#[derive(Parser)]
struct DefaultsOnly {
    #[command(flatten)]
    args: SessionArgs,
}

impl Default for SessionArgs {
    /// The command-line defaults.
    fn default() -> Self {
        DefaultsOnly::parse_from(["session"]).args
    }
}

/// One square driven through the serial path, as traced by the simulator.
#[derive(Clone, Debug)]
pub struct RunTrace {
    /// Direction.
    pub direction: Direction,
    /// True path in the run's start frame, metres.
    pub true_path: Vec<(f64, f64)>,
    /// Odometry path in the run's start frame, metres.
    pub odometry_path: Vec<(f64, f64)>,
    /// `dx`, `dy` (measured − odometry) as the board's `measure` reply states them, metres.
    pub error: (f64, f64),
    /// Control periods the run took until the robot was at rest.
    pub periods: u64,
}

/// One row of the board's `calibrate` reply.
#[derive(Clone, Debug, PartialEq)]
pub struct CalibrationRow {
    /// Method name as the board prints it.
    pub method: String,
    /// `(E_d, E_b, E_s)`, `None` if the method failed.
    pub factors: Option<(f64, f64, f64)>,
    /// Predicted `E_max` after calibration, metres.
    pub e_max_predicted_m: Option<f64>,
    /// Failure text.
    pub failure: Option<String>,
}

impl CalibrationRow {
    /// The corrected geometry (`nominal` with the row's factors).
    pub fn geometry(&self, nominal: &Geometry) -> Option<Geometry> {
        self.factors
            .map(|(e_d, e_b, e_s)| nominal.with_factors(e_d, e_b, e_s))
    }
}

/// Verification of one set of parameters (nominal or a method's).
#[derive(Clone, Debug)]
pub struct Verification {
    /// `nominal` or the method name.
    pub label: String,
    /// The geometry the robot believed.
    pub belief: Geometry,
    /// True end errors (true − odometry) of the fresh squares, with their direction, metres.
    pub ends: Vec<(Direction, f64, f64)>,
    /// `E_max,syst` of those squares, metres.
    pub e_max_m: f64,
    /// The rectangle test with this belief.
    pub rectangle: RectangleResult,
}

/// Everything a session produced.
#[derive(Clone, Debug)]
pub struct SessionReport {
    /// The arguments.
    pub args: SessionArgs,
    /// True geometry of the simulated robot.
    pub truth: Geometry,
    /// Scatter of the pilot squares (1 m, slip only), metres.
    pub pilot_scatter_m: f64,
    /// The `identify floor` reply and events, when the motors differ from the defaults.
    pub identification: Option<String>,
    /// The advice for `--method` (side, expected relative error), if computed.
    pub advice: Option<(f64, f64)>,
    /// Side used, metres.
    pub side_m: f64,
    /// Calibration runs.
    pub runs: Vec<RunTrace>,
    /// `E_max,syst` of the calibration runs (measured), metres.
    pub e_max_before_m: f64,
    /// Scatter of the measured calibration errors around their centres of gravity, metres.
    pub scatter_m: f64,
    /// The `calibrate` table.
    pub calibration: Vec<CalibrationRow>,
    /// The geometry `apply` made active.
    pub applied: Geometry,
    /// The `params` reply after the reboot.
    pub params_after_reboot: String,
    /// Whether the rebooted board uses the saved geometry and reports the saved method.
    pub reboot_kept_calibration: bool,
    /// The geometry the rebooted controller uses.
    pub rebooted_geometry: Geometry,
    /// Verification runs on the rebooted board (serial path).
    pub after_runs: Vec<RunTrace>,
    /// `E_max,syst` of those runs (measured), metres.
    pub e_max_after_m: f64,
    /// Fresh-square and rectangle verification: nominal first, then each method that solved.
    pub verifications: Vec<Verification>,
    /// The parameter-error-against-side sweep.
    pub sweep: Option<SweepResult>,
    /// Paper-mode slip used in that sweep.
    pub sweep_slip: f64,
    /// Wall time of the 5+5 calibration runs through the serial path (incl. `measure`), s.
    pub calibration_runs_wall_s: f64,
    /// Simulated time of those runs, s.
    pub calibration_runs_sim_s: f64,
    /// Wall time of the whole session (without writing plots), s.
    pub total_wall_s: f64,
    /// Every line sent and received.
    pub transcript: String,
}

/// Runs the whole session; `pb` is advanced through its steps (use [`ProgressBar::hidden`] for
/// none).
///
/// # Errors
/// Invalid arguments, a refused command, a run that does not finish, a failed reboot check.
pub fn run_session(args: &SessionArgs, pb: &ProgressBar) -> Result<SessionReport, String> {
    let started = Instant::now();
    let method = Method::parse(&args.method).ok_or_else(|| {
        format!(
            "unknown method {}; one of {}",
            args.method,
            Method::ALL.map(Method::as_str).join("|")
        )
    })?;
    if !(1..=6).contains(&args.runs) {
        return Err("--runs must be 1..=6 (the board stores 12 runs)".into());
    }
    let nominal = Geometry::PAPER_NOMINAL;
    let mut cfg = sim_config(args.ed, args.eb, args.slip, args.seed, args.rate);
    args.motors.apply(&mut cfg)?;
    cfg.true_geometry
        .validate()
        .map_err(|e| format!("invalid truth: {e}"))?;
    let n = u64::from(args.runs);
    pb.set_length(1 + 2 * n + 2 + 2 * n + 1 + Method::ALL.len() as u64 + 1);
    let mut rng = Rng::new(args.seed ^ 0x5EED_0DD0_CA1B_0000);
    let mut log = String::new();

    // The board, and with unusual motors their identification first: the pilots and every
    // later run use the tuning it applies (and `save` stores).
    let mut flash = SimParamFlash::erased();
    let mut board = Board::boot(cfg, &mut flash, &mut log)?;
    let identification = if args.motors.any() {
        pb.set_message("identify");
        log.push_str("> identify floor\n");
        let events = board
            .identify(IdentifyMode::Floor)
            .map_err(|e| format!("identify floor failed: {}", e.replace("\r\n", "\n")))?;
        log.push_str(&events.replace("\r\n", "\n"));
        Some(events.replace("\r\n", "\n"))
    } else {
        None
    };
    let tuning = board.session.settings().tuning;

    // Track size: pilot scatter at 1 m (slip only, nominal belief), then the advice.
    pb.set_message("advice");
    let TrackPlan {
        pilot_scatter_m,
        advice,
        side_m,
    } = track_advice(args, &cfg, tuning, method)?;
    pb.inc(1);

    // Calibration runs through the serial path.
    pb.set_message("calibration runs");
    send(&mut board, &set(ParamName::SquareSide, side_m), &mut log)?;
    send(
        &mut board,
        &set(ParamName::RunsPerDirection, f64::from(args.runs)),
        &mut log,
    )?;
    let t_runs = Instant::now();
    let runs = planned_runs(&mut board, args, &mut rng, &mut log, pb)?;
    let calibration_runs_wall_s = t_runs.elapsed().as_secs_f64();
    let calibration_runs_sim_s =
        runs.iter().map(|r| r.periods).sum::<u64>() as f64 / f64::from(args.rate);
    let before: Vec<_> = runs
        .iter()
        .map(|r| (r.direction, r.error.0, r.error.1))
        .collect();
    let (e_max_before_m, scatter_m) = e_max_and_scatter(&before);

    pb.set_message("calibrate, save");
    let (calibration, applied) = calibrate_apply_save(&mut board, method, &mut log)?;
    pb.inc(1);

    // Reboot over the same flash.
    pb.set_message("reboot");
    drop(board); // power off: only the flash survives
    let (mut board, params_after_reboot, rebooted_geometry, reboot_kept_calibration) =
        reboot(&cfg, &mut flash, &applied, method, &mut log)?;
    pb.inc(1);

    // Verification on the rebooted board: the calibration runs survived the reboot; a fresh
    // set of squares is driven with the new parameters.
    pb.set_message("verification");
    send(&mut board, "drop all yes", &mut log)?;
    send(&mut board, &set(ParamName::SquareSide, side_m), &mut log)?;
    let after_runs = planned_runs(&mut board, args, &mut rng, &mut log, pb)?;
    let after: Vec<_> = after_runs
        .iter()
        .map(|r| (r.direction, r.error.0, r.error.1))
        .collect();
    let (e_max_after_m, _) = e_max_and_scatter(&after);

    // Every method's parameters (and the nominal ones) on fresh squares and the rectangle.
    pb.set_message("methods, rectangle");
    let mut beliefs = vec![("nominal".to_string(), nominal)];
    beliefs.extend(
        calibration
            .iter()
            .filter_map(|r| r.geometry(&nominal).map(|g| (r.method.clone(), g))),
    );
    let verifications = beliefs
        .par_iter()
        .map(|(label, g)| {
            let v = verify(label, *g, &cfg, tuning, side_m, args);
            pb.inc(1);
            v
        })
        .collect::<Result<Vec<_>, String>>()?;
    pb.inc((1 + Method::ALL.len()).saturating_sub(verifications.len()) as u64);

    // Parameter error against side (Fig. 5), paper-mode slip scaled to the observed scatter.
    pb.set_message("sweep");
    let (sweep_result, sweep_slip) = fig5_sweep(args, scatter_m, side_m)?;
    pb.inc(1);

    Ok(SessionReport {
        identification,
        args: args.clone(),
        truth: cfg.true_geometry,
        pilot_scatter_m,
        advice,
        side_m,
        runs,
        e_max_before_m,
        scatter_m,
        calibration,
        applied,
        params_after_reboot,
        reboot_kept_calibration,
        rebooted_geometry,
        after_runs,
        e_max_after_m,
        verifications,
        sweep: sweep_result,
        sweep_slip,
        calibration_runs_wall_s,
        calibration_runs_sim_s,
        total_wall_s: started.elapsed().as_secs_f64(),
        transcript: log,
    })
}

/// The pilot's scatter, the advice (side, expected error) and the side the session drives.
struct TrackPlan {
    pilot_scatter_m: f64,
    advice: Option<(f64, f64)>,
    side_m: f64,
}

/// The track-size advice from a pilot: three 1 m squares each way (slip only, nominal belief),
/// their scatter, the method's advised side and its expected error; the side used (`--side`,
/// else the advice).
fn track_advice(
    args: &SessionArgs,
    cfg: &SimConfig,
    tuning: SpeedTuning,
    method: Method,
) -> Result<TrackPlan, String> {
    let nominal = Geometry::PAPER_NOMINAL;
    let mut pilot = Vec::new();
    for (d, direction) in [Direction::Cw, Direction::Ccw].into_iter().enumerate() {
        for i in 0..3u64 {
            let mut c = *cfg;
            c.seed = args
                .seed
                .wrapping_mul(7919)
                .wrapping_add(900 + 10 * d as u64 + i);
            let path = PathKind::Square {
                direction,
                side_m: 1.0,
            };
            let r = drive_path_tuned(c, nominal, tuning, path)?;
            let o = r.record.odometry_end;
            pilot.push((direction, r.true_end.x_m - o.x_m, r.true_end.y_m - o.y_m));
        }
    }
    let (_, pilot_scatter_m) = e_max_and_scatter(&pilot);
    let input = TrackAdviceInput {
        belief: nominal,
        estimate: nominal,
        measurement_sigma_m: args.meas_mm * 1e-3,
        measurement_sigma_rad: args.meas_deg.to_radians(),
        observed_scatter: Some((pilot_scatter_m, 1.0)),
        runs_per_direction: u32::from(args.runs),
        max_side_m: args.max_side,
    };
    let advice = advise(&input, method).map(|a| (a.side_m, a.expected_error));
    let side_m = args
        .side
        .or(advice.map(|a| a.0))
        .ok_or("no advice for this method; give --side")?;
    Ok(TrackPlan {
        pilot_scatter_m,
        advice,
        side_m,
    })
}

/// Parameter error against side (Fig. 5) with paper-mode slip scaled to the observed scatter
/// `scatter_m` of squares of `side_m`: the sweep (when asked for) and the slip it used.
fn fig5_sweep(
    args: &SessionArgs,
    scatter_m: f64,
    side_m: f64,
) -> Result<(Option<SweepResult>, f64), String> {
    let nominal = Geometry::PAPER_NOMINAL;
    let sigma = args.meas_mm * 1e-3;
    let ns = (scatter_m * scatter_m - 2.0 * sigma * sigma)
        .max(0.0)
        .sqrt();
    let ns_at_pilot = ns * (crate::experiments::sweep::PILOT_SIDE_M / side_m).powf(1.5);
    let probe = 1e-3;
    let base = SweepArgs {
        sides: args.sweep_sides.clone(),
        meas_sigmas: vec![sigma],
        slips: vec![probe],
        trials: args.sweep_trials,
        runs: u32::from(args.runs),
        eb: args.eb,
        ed: args.ed,
        seed: args.seed,
        quiet: true,
        ..SweepArgs::default()
    };
    let truth_mean = crate::experiments::paper::true_geometry(
        &nominal,
        args.eb,
        args.ed,
        crate::experiments::paper::TruthModel::Mean,
    );
    let probe_scatter = pilot_scatter(&base, &truth_mean, probe, args.seed).unwrap_or(0.0);
    let sweep_slip = if probe_scatter > 0.0 {
        probe * ns_at_pilot / probe_scatter
    } else {
        0.0
    };
    let sweep_result = if args.sweep_trials > 0 && !args.sweep_sides.is_empty() {
        let a = SweepArgs {
            slips: vec![sweep_slip],
            ..base
        };
        Some(sweep(&a, &ProgressBar::hidden())?)
    } else {
        None
    };
    Ok((sweep_result, sweep_slip))
}

/// `calibrate`, `apply <method>` (confirmed when a run is flagged) and `save` on `board`: the
/// calibrate table's rows and the applied geometry.
fn calibrate_apply_save(
    board: &mut Board<'_>,
    method: Method,
    log: &mut String,
) -> Result<(Vec<CalibrationRow>, Geometry), String> {
    let nominal = Geometry::PAPER_NOMINAL;
    let reply = send(board, "calibrate", log)?;
    let calibration = parse_calibration(&reply);
    // A run the robust fit flags (measurement noise on few runs can make one) needs the
    // confirmation an operator would give after looking at it: the log shows both replies.
    let apply = |confirmed| {
        Command::Apply {
            method: method.as_str(),
            confirmed,
        }
        .to_string()
    };
    let reply = match send(board, &apply(false), log) {
        Err(e) if e.is(ErrorCode::NotConfirmed) => send(board, &apply(true), log)?,
        other => other?,
    };
    let applied = match (
        field(&reply, "E_d="),
        field(&reply, "E_b="),
        field(&reply, "E_s="),
    ) {
        (Some(d), Some(b), Some(s)) => nominal.with_factors(d, b, s),
        _ => return Err(format!("unreadable apply reply: {reply}")),
    };
    send(board, "save", log)?;
    Ok((calibration, applied))
}

/// Boots a new board over `flash` (the calibrated board powered off): its `params` reply, the
/// geometry its controller runs and whether that is the applied calibration of `method`.
fn reboot<'f>(
    cfg: &SimConfig,
    flash: &'f mut SimParamFlash,
    applied: &Geometry,
    method: Method,
    log: &mut String,
) -> Result<(Board<'f>, String, Geometry, bool), String> {
    log.push_str("# power off, boot\n");
    let mut cfg2 = *cfg;
    cfg2.seed = cfg.seed.wrapping_add(1);
    let mut board = Board::boot(cfg2, flash, log)?;
    let params_after_reboot = send(&mut board, "params", log)?;
    let rebooted_geometry = board.controller_geometry();
    // The `apply` reply prints the factors with 9 decimals: ~1e-9 relative.
    let same = |a: f64, b: f64| ((a - b) / b).abs() < 5e-9;
    let kept = same(rebooted_geometry.wheelbase_m, applied.wheelbase_m)
        && same(rebooted_geometry.diameter_right_m, applied.diameter_right_m)
        && same(rebooted_geometry.diameter_left_m, applied.diameter_left_m)
        && params_after_reboot.contains(&format!("calibration {}", method.as_str()));
    Ok((board, params_after_reboot, rebooted_geometry, kept))
}

/// The `set` line of one parameter, as the protocol writes it.
fn set(name: ParamName, value: f64) -> String {
    Command::Set { name, value }.to_string()
}
