//! `host-sim motors`: motor identification on simulated robots whose motors differ from the
//! defaults the speed loops are tuned for, and what the identified tuning changes on the floor
//! ([`crate::experiments::motors`]); prints the table.

use odocal::motion::speed::SpeedTuning;

use crate::experiments::motors::{CASES, identify, squares, worst_relative_error};

/// Command-line arguments of the `motors` subcommand.
#[derive(clap::Args, Debug, Clone)]
pub struct MotorsArgs {
    /// Side of the squares, metres.
    #[arg(long, default_value_t = 2.0)]
    pub side: f64,
    /// Relative slip noise per millisecond of travel (standard deviation; per control period at 1 kHz), as `cargo sim`'s default.
    #[arg(long, default_value_t = 0.02)]
    pub slip: f64,
}

/// Runs the `motors` subcommand.
///
/// # Errors
/// A failed identification or run.
pub fn run(args: &MotorsArgs) -> Result<(), String> {
    println!("motor identification (identify lifted) on simulated robots, true = simulated motor");
    println!(
        "gain K in m/s per duty (forward, backward), time constant tau in s, dead-band d0 in duty; \
         worst: the largest relative error of the identified values"
    );
    println!(
        "{:<20} {:>5} | {:>7} {:>7} {:>7} | {:>8} {:>7} | {:>7} {:>7} | {:>9}",
        "robot", "wheel", "K true", "K fwd", "K back", "tau true", "tau", "d0 true", "d0", "worst"
    );
    let mut tunings = Vec::new();
    for case in &CASES {
        let tuning = identify(case)?;
        for (right, est) in [(true, tuning.right), (false, tuning.left)] {
            let t = case.truth(right);
            println!(
                "{:<20} {:>5} | {:>7.4} {:>7.4} {:>7.4} | {:>8.4} {:>7.4} | {:>7.4} {:>7.4} | {:>7.2} %",
                case.name,
                if right { "right" } else { "left" },
                t.gain_forward_mps,
                est.gain_forward_mps,
                est.gain_backward_mps,
                t.time_constant_s,
                est.time_constant_s,
                t.deadband,
                est.deadband,
                100.0 * worst_relative_error(&est, &t),
            );
        }
        tunings.push(tuning);
    }
    println!();
    println!(
        "5 + 5 squares, L = {} m, slip σ = {}: default tuning → identified tuning",
        args.side, args.slip
    );
    println!(
        "{:<20} | {:>22} | {:>22} | {:>22}",
        "robot", "peak sync error, ticks", "end scatter, mm", "E_max,syst, mm"
    );
    for (case, tuning) in CASES.iter().zip(tunings) {
        let before = squares(case, SpeedTuning::DEFAULT, args.side, args.slip)?;
        let after = squares(case, tuning, args.side, args.slip)?;
        println!(
            "{:<20} | {:>9.1} → {:>9.1} | {:>9.3} → {:>9.3} | {:>9.2} → {:>9.2}",
            case.name,
            before.peak_sync_ticks,
            after.peak_sync_ticks,
            before.scatter_m * 1e3,
            after.scatter_m * 1e3,
            before.e_max_m * 1e3,
            after.e_max_m * 1e3,
        );
    }
    println!("(sync = right wheel ahead of the left against their common profile, on the legs;");
    println!(" scatter = RMS distance of the end errors from their CW/CCW centres of gravity)");
    Ok(())
}
