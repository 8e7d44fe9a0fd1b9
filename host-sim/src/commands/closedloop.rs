//! `host-sim closedloop`: calibration from squares driven closed-loop by the library's motion
//! controller through the simulated robot ([`crate::experiments::closedloop`]); one trial's
//! factors, or the statistics of a Monte Carlo over many.

use odocal::calibration::CalibrationError;
use odocal::kinematics::geometry::Geometry;

use crate::commands::{print_acc_header, print_acc_row};
pub use crate::experiments::closedloop::ClosedLoopArgs;
use crate::experiments::closedloop::{METHODS, trial};
use crate::experiments::montecarlo::{Acc, Rng};

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
    for t in 0..args.trials {
        for (k, (m, result)) in trial(args, &truth, t, &mut rng)?.into_iter().enumerate() {
            match result {
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
        print_acc_header();
        for (m, a) in METHODS.iter().zip(acc.iter()) {
            print_acc_row(a, m.as_str());
        }
    }
    Ok(())
}
