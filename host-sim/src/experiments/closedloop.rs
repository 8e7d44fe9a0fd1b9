//! The closed-loop experiment (`host-sim closedloop`): calibration from squares driven closed-loop by the library's motion
//! controller through the simulated robot (motor dynamics, encoder quantisation, optional slip),
//! with optional measurement noise; one trial or a Monte Carlo over many.
//!
//! Each run's record comes from the controller exactly as on the robot (knots, odometry end
//! pose); the "measurement" is the simulated true pose when the run finished, plus `N(0, σ)` on
//! x and y (and on θ with `--heading`).

use clap::Args;
use odocal::calibration::{Calibration, CalibrationError, Method, RunObservation, calibrate};
use odocal::kinematics::geometry::Geometry;
use odocal::motion::run::{Direction, Measurement, PathKind, RunRecord};

use crate::experiments::montecarlo::Rng;
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

/// The methods every trial is calibrated with.
pub const METHODS: [Method; 6] = Method::ALL;

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

/// One method's calibration of a trial, or why it failed.
pub type MethodResult = (Method, Result<Calibration, CalibrationError>);

/// One trial: `runs` CW and CCW squares driven closed-loop with `truth` (seeds from `args.seed`
/// and `trial`), measured with noise from `rng`, calibrated with every method of [`METHODS`].
///
/// # Errors
/// A run that failed.
pub fn trial(
    args: &ClosedLoopArgs,
    truth: &Geometry,
    trial: u32,
    rng: &mut Rng,
) -> Result<Vec<MethodResult>, String> {
    let nominal = Geometry::PAPER_NOMINAL;
    let records = drive_set(args, truth, trial, rng)?;
    let obs: Vec<_> = records
        .iter()
        .filter_map(RunObservation::from_record)
        .collect();
    Ok(METHODS
        .iter()
        .map(|m| (*m, calibrate(&obs, &nominal, *m)))
        .collect())
}
