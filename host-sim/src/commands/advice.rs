//! `host-sim advice`: track-size advice (paper §2.3) for the paper robot, every method.
//!
//! Prints, per method, the expected relative error of `E_b`/`E_d` at each candidate side and the
//! recommended side, from [`odocal::calibration::track`] (the same function the serial
//! `calibrate` command uses).

use clap::Args;
use odocal::calibration::Method;
use odocal::calibration::track::{CANDIDATE_SIDES_M, TrackAdviceInput, advise, evaluate};
use odocal::kinematics::geometry::Geometry;

use crate::experiments::paper::{TruthModel, true_geometry};

/// Arguments of `host-sim advice`.
#[derive(Args, Debug)]
pub struct AdviceArgs {
    /// Estimated true E_b.
    #[arg(long, default_value_t = 1.010)]
    pub eb: f64,
    /// Estimated true E_d.
    #[arg(long, default_value_t = 0.995)]
    pub ed: f64,
    /// 1σ of a measured coordinate, metres.
    #[arg(long, default_value_t = 0.005)]
    pub meas_sigma: f64,
    /// 1σ of a measured heading, radians.
    #[arg(long, default_value_t = 0.005)]
    pub meas_sigma_rad: f64,
    /// Observed scatter of the end positions, metres (0 = unknown).
    #[arg(long, default_value_t = 0.0)]
    pub scatter: f64,
    /// Side the scatter was observed at, metres.
    #[arg(long, default_value_t = 2.0)]
    pub scatter_side: f64,
    /// Runs per direction.
    #[arg(long, default_value_t = 5)]
    pub runs: u32,
    /// Largest side the floor allows, metres.
    #[arg(long, default_value_t = 16.0)]
    pub max_side: f64,
}

/// Runs the subcommand.
pub fn run(args: &AdviceArgs) -> Result<(), Box<dyn std::error::Error>> {
    let nominal = Geometry::PAPER_NOMINAL;
    let input = TrackAdviceInput {
        belief: nominal,
        estimate: true_geometry(&nominal, args.eb, args.ed, TruthModel::Mean),
        measurement_sigma_m: args.meas_sigma,
        measurement_sigma_rad: args.meas_sigma_rad,
        observed_scatter: (args.scatter > 0.0).then_some((args.scatter, args.scatter_side)),
        runs_per_direction: args.runs,
        max_side_m: args.max_side,
    };
    println!(
        "expected relative parameter error sqrt(bias² + σ² of E_b and E_d) of each method against the \
         square side L ({} + {} runs)",
        args.runs, args.runs
    );
    print!("{:>11}", "L/m:");
    for l in CANDIDATE_SIDES_M.iter().filter(|&&l| l <= args.max_side) {
        print!(" {l:>8}");
    }
    println!("   best");
    for m in Method::ALL {
        print!("{:>11}", m.as_str());
        for &l in CANDIDATE_SIDES_M.iter().filter(|&&l| l <= args.max_side) {
            match evaluate(&input, m, l) {
                Some(a) => print!(" {:>8.1e}", a.expected_error),
                None => print!(" {:>8}", "-"),
            }
        }
        match advise(&input, m) {
            Some(a) => println!("   L = {} m ({:.1e})", a.side_m, a.expected_error),
            None => println!("   -"),
        }
    }
    Ok(())
}
