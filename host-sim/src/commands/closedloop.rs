//! `host-sim closedloop`: calibration from squares driven closed-loop by the library's motion
//! controller through the simulated robot (motor dynamics, encoder quantisation, optional slip),
//! with optional measurement noise; one trial or a Monte Carlo over many.
//!
//! Each run's record comes from the controller exactly as on the robot (knots, odometry end
//! pose); the "measurement" is the simulated true pose when the run finished, plus `N(0, σ)` on
//! x and y (and on θ with `--heading`).

use clap::Args;
use odocal::calibration::{CalibrationError, Method, RunObservation, calibrate};
use odocal::kinematics::geometry::Geometry;
use odocal::motion::run::{Direction, Measurement, PathKind, RunRecord};

use crate::experiments::montecarlo::{Acc, Rng};
use crate::experiments::square::drive_path;
use crate::sim::robot::SimConfig;

/// Arguments of `host-sim closedloop`.
#[derive(Args, Debug)]
pub struct ClosedLoopArgs {
    /// True E_b.
    #[arg(long, default_value_t = 1.010)]
    pub eb: f64,
    /// True E_d.
    #[arg(long, default_value_t = 0.995)]
    pub ed: f64,
    /// Square side L, metres.
    #[arg(long, default_value_t = 2.0)]
    pub side: f64,
    /// Runs per direction.
    #[arg(long, default_value_t = 5)]
    pub runs: u32,
    /// Relative slip noise of each wheel per millisecond of travel (1σ; per control period at
    /// 1 kHz, scaled by √(rate / 1 kHz) per period at other rates).
    #[arg(long, default_value_t = 0.0)]
    pub slip: f64,
    /// 1σ of a measured coordinate, metres.
    #[arg(long, default_value_t = 0.0)]
    pub meas_sigma: f64,
    /// Also measure the final heading (1σ noise `--meas-sigma-rad`).
    #[arg(long)]
    pub heading: bool,
    /// 1σ of a measured heading, radians.
    #[arg(long, default_value_t = 0.0)]
    pub meas_sigma_rad: f64,
    /// Trials (Monte Carlo when > 1).
    #[arg(long, default_value_t = 1)]
    pub trials: u32,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Control rate, Hz: 1000, 2000, 4000, 5000, 8000 or 10000 (the board's `control_hz`).
    #[arg(long = "rate-hz", visible_alias = "rate", default_value_t = odocal::motion::controller::DEFAULT_RATE_HZ, value_parser = crate::commands::parse_rate_hz)]
    pub rate: u32,
}

const METHODS: [Method; 6] = Method::ALL;

/// Drives `runs` CW and CCW squares and returns the measured records.
fn drive_set(
    args: &ClosedLoopArgs,
    truth: &Geometry,
    trial: u32,
    rng: &mut Rng,
) -> Result<Vec<RunRecord>, String> {
    let nominal = Geometry::PAPER_NOMINAL;
    let mut out = Vec::new();
    for (d, direction) in [Direction::Cw, Direction::Ccw].into_iter().enumerate() {
        for i in 0..args.runs {
            let mut cfg = SimConfig::new(*truth, args.rate);
            cfg.slip_sigma = args.slip;
            cfg.seed = args
                .seed
                .wrapping_mul(1_000_003)
                .wrapping_add(u64::from(trial) * 1000 + d as u64 * 100 + u64::from(i));
            let r = drive_path(
                cfg,
                nominal,
                PathKind::Square {
                    direction,
                    side_m: args.side,
                },
            )?;
            let mut record = r.record;
            record.measured = Some(Measurement {
                x_m: r.true_end.x_m + args.meas_sigma * rng.normal(),
                y_m: r.true_end.y_m + args.meas_sigma * rng.normal(),
                theta_rad: args
                    .heading
                    .then(|| r.true_end.theta_rad + args.meas_sigma_rad * rng.normal()),
            });
            out.push(record);
        }
    }
    Ok(out)
}

/// Runs the subcommand.
pub fn run(args: &ClosedLoopArgs) -> Result<(), Box<dyn std::error::Error>> {
    let nominal = Geometry::PAPER_NOMINAL;
    let truth = nominal.with_factors(args.ed, args.eb, 1.0);
    truth
        .validate()
        .map_err(|e| format!("invalid truth: {e}"))?;
    let mut rng = Rng::new(args.seed);
    // Per method: relative E_b and E_d errors over the trials.
    let mut acc = [Acc::default(); 6];
    println!(
        "closed loop: {} trial(s) at {} Hz, L = {} m, {}+{} runs, slip σ = {}/ms, σ_meas = {} mm{}, truth E_b = {}, E_d = {}",
        args.trials,
        args.rate,
        args.side,
        args.runs,
        args.runs,
        args.slip,
        args.meas_sigma * 1e3,
        if args.heading { " (+θ)" } else { "" },
        args.eb,
        args.ed
    );
    if args.trials == 1 {
        println!("  (in parentheses: the relative error, estimate / truth − 1)");
    }
    for trial in 0..args.trials {
        let records = drive_set(args, &truth, trial, &mut rng)?;
        let obs: Vec<_> = records
            .iter()
            .filter_map(RunObservation::from_record)
            .collect();
        for (k, m) in METHODS.iter().enumerate() {
            match calibrate(&obs, &nominal, *m) {
                Ok(c) => {
                    let e = [c.e_b / args.eb - 1.0, c.e_d / truth.diameter_ratio() - 1.0];
                    acc[k].push(e[0], e[1]);
                    if args.trials == 1 {
                        println!(
                            "{:>11}  E_b = {:.7} ({:+.2e})  E_d = {:.7} ({:+.2e})  E_max {:.2} → {:.3} mm (predicted)",
                            m.as_str(),
                            c.e_b,
                            e[0],
                            c.e_d,
                            e[1],
                            c.quality.e_max_before_m.unwrap_or(f64::NAN) * 1e3,
                            c.quality.e_max_after_m.unwrap_or(f64::NAN) * 1e3
                        );
                    }
                }
                Err(e) => {
                    acc[k].fail();
                    if args.trials == 1 {
                        let hint = if matches!(e, CalibrationError::NoHeading) {
                            " (run with --heading)"
                        } else {
                            ""
                        };
                        println!("{:>11}  error: {e}{hint}", m.as_str());
                    }
                }
            }
        }
    }
    if args.trials > 1 {
        Acc::print_header();
        for (m, a) in METHODS.iter().zip(acc.iter()) {
            a.print_row(m.as_str());
        }
    }
    Ok(())
}
