//! `host-sim square`: CW and CCW squares of every side with the library's controller against the
//! simulated robot, believing the nominal geometry (the experiment: [`crate::experiments::square`]).

use odocal::kinematics::geometry::Geometry;
use odocal::motion::run::{Direction, PathKind};

use crate::experiments::square::drive_path;
use crate::sim::robot::sim_config;

/// Command-line arguments of the `square` subcommand.
#[derive(clap::Args, Debug, Clone)]
pub struct SquareArgs {
    /// True E_b of the simulated robot (b_true / b_nominal).
    #[arg(long, default_value_t = 1.010)]
    pub eb: f64,
    /// True E_d of the simulated robot (D_R / D_L).
    #[arg(long, default_value_t = 0.995)]
    pub ed: f64,
    /// Side lengths to drive, metres.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4")]
    pub sides: Vec<f64>,
    /// Relative slip noise per millisecond of travel (standard deviation; per control period at 1 kHz).
    #[arg(long, default_value_t = 0.0)]
    pub slip: f64,
    /// Seed of the slip noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Control rate, Hz: 1000, 2000, 4000, 5000, 8000 or 10000 (the board's `control_hz`).
    #[arg(long = "rate-hz", visible_alias = "rate", default_value_t = odocal::motion::controller::DEFAULT_RATE_HZ, value_parser = crate::commands::parse_rate_hz)]
    pub rate: u32,
}

/// Runs the `square` subcommand: CW and CCW squares of every side, nominal belief.
///
/// # Errors
/// Any failed run.
pub fn run(args: &SquareArgs) -> Result<(), String> {
    let nominal = Geometry::PAPER_NOMINAL;
    let cfg = sim_config(args.ed, args.eb, args.slip, args.seed, args.rate);
    println!(
        "true E_b = {}, E_d = {}; controller believes the nominal geometry; slip σ = {}",
        args.eb, args.ed, args.slip
    );
    println!(
        "{:>5} {:>4} | {:>9} {:>9} | {:>9} {:>9} | {:>9} {:>9} | {:>8} | {:>10}",
        "L m",
        "dir",
        "true x mm",
        "true y mm",
        "odo x mm",
        "odo y mm",
        "err x mm",
        "err y mm",
        "sync tk",
        "knots µm"
    );
    for &side in &args.sides {
        for direction in [Direction::Cw, Direction::Ccw] {
            let r = drive_path(
                cfg,
                nominal,
                PathKind::Square {
                    direction,
                    side_m: side,
                },
            )?;
            let o = r.record.odometry_end;
            println!(
                "{:>5} {:>4} | {:>9.3} {:>9.3} | {:>9.3} {:>9.3} | {:>9.3} {:>9.3} | {:>8.1} | {:>10.3}",
                side,
                direction.as_str(),
                r.true_end.x_m * 1e3,
                r.true_end.y_m * 1e3,
                o.x_m * 1e3,
                o.y_m * 1e3,
                (r.true_end.x_m - o.x_m) * 1e3,
                (r.true_end.y_m - o.y_m) * 1e3,
                r.peak_leg_sync_ticks,
                r.knot_error_m() * 1e6,
            );
        }
    }
    println!("(err = true − odometry at the run's end; sync = peak |wheel sync error| on legs;");
    println!(" knots = |knots integrated with the true geometry − true end position|)");
    Ok(())
}
