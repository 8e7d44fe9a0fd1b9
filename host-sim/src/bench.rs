//! `host-sim bench`: host wall-clock speed of the simulator.
//!
//! - **Session**: a full simulated 5 + 5 UMBmark session — five CW and five CCW squares driven
//!   closed-loop by the library's controller through the simulated robot at the control rate
//!   (motor lag, encoder quantisation), each "measured" at its true end pose, then calibrated
//!   with every method. Timed per phase and repeated; the minimum is the figure of merit (least
//!   disturbed by other load on the machine), the median is shown too.
//! - **Monte Carlo**: `host-sim montecarlo` with 1,000 trials (paper-mode kinematic squares with
//!   slip and measurement noise, five calibration methods per trial), timed as a whole; its
//!   result table is printed as well.
//!
//! Goals (issue 8): session ≤ 0.1 s at 1 kHz, Monte Carlo ≤ 10 s. They are reported, not
//! enforced: wall-clock time depends on the machine and its load.

use std::time::{Duration, Instant};

use clap::Args;
use odocal::calibration::{Method, RunObservation, calibrate};
use odocal::geometry::Geometry;
use odocal::run::{Direction, Measurement, PathKind, RunRecord};

use crate::montecarlo::{self, MonteCarloArgs};
use crate::paper::Format;
use crate::robot::SimConfig;
use crate::square::drive_path;

/// Session goal, seconds.
const SESSION_GOAL_S: f64 = 0.1;
/// Monte Carlo goal, seconds.
const MONTE_CARLO_GOAL_S: f64 = 10.0;

/// Arguments of `host-sim bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Repetitions of the session (the minimum and the median are reported).
    #[arg(long, default_value_t = 5)]
    pub repeat: u32,
    /// Square side L, metres.
    #[arg(long, default_value_t = 2.0)]
    pub side: f64,
    /// Control rate, Hz.
    #[arg(long, default_value_t = 1000)]
    pub rate: u32,
    /// Monte Carlo trials (0 skips the Monte Carlo).
    #[arg(long, default_value_t = 1000)]
    pub trials: u32,
}

/// Timing of one simulated session.
#[derive(Clone, Copy, Debug)]
struct SessionTiming {
    drive: Duration,
    calibrate: Duration,
    periods: u64,
    calibrated: usize,
}

impl SessionTiming {
    fn total(&self) -> Duration {
        self.drive + self.calibrate
    }
}

/// Drives and calibrates one 5 + 5 session.
fn session(
    args: &BenchArgs,
    nominal: &Geometry,
    truth: &Geometry,
) -> Result<SessionTiming, String> {
    let t0 = Instant::now();
    let mut records: Vec<RunRecord> = Vec::with_capacity(10);
    let mut periods = 0;
    for direction in [Direction::Cw, Direction::Ccw] {
        for i in 0..5u64 {
            let mut cfg = SimConfig::new(*truth, args.rate);
            cfg.seed = 1 + i;
            let r = drive_path(
                cfg,
                *nominal,
                PathKind::Square {
                    direction,
                    side_m: args.side,
                },
            )?;
            periods += r.periods;
            let mut record = r.record;
            record.measured = Some(Measurement {
                x_m: r.true_end.x_m,
                y_m: r.true_end.y_m,
                theta_rad: Some(r.true_end.theta_rad),
            });
            records.push(record);
        }
    }
    let t1 = Instant::now();
    let obs: Vec<_> = records
        .iter()
        .filter_map(RunObservation::from_record)
        .collect();
    let mut calibrated = 0;
    for m in Method::ALL {
        if std::hint::black_box(calibrate(&obs, nominal, m)).is_ok() {
            calibrated += 1;
        }
    }
    let t2 = Instant::now();
    Ok(SessionTiming {
        drive: t1 - t0,
        calibrate: t2 - t1,
        periods,
        calibrated,
    })
}

fn verdict(seconds: f64, goal: f64) -> &'static str {
    if seconds <= goal { "within" } else { "ABOVE" }
}

/// Runs the subcommand.
///
/// # Errors
/// A session that could not be driven, or a failed Monte Carlo.
pub fn run(args: &BenchArgs) -> Result<(), Box<dyn std::error::Error>> {
    let nominal = Geometry::PAPER_NOMINAL;
    let truth = nominal.with_factors(0.995, 1.010, 1.0);
    let mut runs = Vec::new();
    for _ in 0..args.repeat.max(1) {
        runs.push(session(args, &nominal, &truth)?);
    }
    runs.sort_by_key(SessionTiming::total);
    let best = runs[0];
    let median = runs[runs.len() / 2];
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    println!(
        "session (5 CW + 5 CCW closed-loop squares of {} m at {} Hz, then all {} methods):",
        args.side,
        args.rate,
        Method::ALL.len()
    );
    println!(
        "  min {:.1} ms (driving {:.1} ms = {} periods, {:.0} ns/period; calibration {:.1} ms, {} methods succeeded), median {:.1} ms of {} runs",
        ms(best.total()),
        ms(best.drive),
        best.periods,
        best.drive.as_secs_f64() * 1e9 / best.periods.max(1) as f64,
        ms(best.calibrate),
        best.calibrated,
        ms(median.total()),
        runs.len()
    );
    println!(
        "  goal <= {:.0} ms: {}",
        SESSION_GOAL_S * 1e3,
        verdict(best.total().as_secs_f64(), SESSION_GOAL_S)
    );

    if args.trials > 0 {
        let mc = MonteCarloArgs {
            trials: args.trials,
            side: args.side,
            runs: 5,
            meas_sigma: 0.005,
            slip: 0.002,
            substeps: 20,
            eb: 1.010,
            ed: 0.995,
            seed: 1,
            format: Format::Text,
        };
        println!(
            "Monte Carlo (`host-sim montecarlo --trials {}`):",
            args.trials
        );
        let t0 = Instant::now();
        montecarlo::run(&mc)?;
        let s = t0.elapsed().as_secs_f64();
        println!(
            "  {} trials in {:.2} s ({:.2} ms per trial); goal <= {:.0} s: {}",
            args.trials,
            s,
            s * 1e3 / f64::from(args.trials),
            MONTE_CARLO_GOAL_S,
            verdict(s, MONTE_CARLO_GOAL_S)
        );
    }
    Ok(())
}
