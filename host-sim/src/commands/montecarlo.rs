//! `host-sim montecarlo`: repeated paper-mode calibrations with measurement and slip noise
//! ([`crate::experiments::montecarlo`]), as a text table or JSON lines.

use crate::commands::{print_acc_header, print_acc_row};
pub use crate::experiments::montecarlo::MonteCarloArgs;
use crate::experiments::montecarlo::simulate;
use crate::experiments::paper::Format;

/// Runs the subcommand.
pub fn run(args: &MonteCarloArgs) -> Result<(), Box<dyn std::error::Error>> {
    let results = simulate(args)?;
    if args.format == Format::Text {
        println!(
            "{} trials, L = {} m, {}+{} runs, σ_meas = {} mm{}, slip σ = {} per substep ({} substeps/segment){}, truth E_b = {}, E_d = {}",
            args.trials,
            args.side,
            args.runs,
            args.runs,
            args.meas_sigma * 1e3,
            if args.heading {
                format!(" and {} mrad", args.meas_sigma_rad * 1e3)
            } else {
                String::new()
            },
            args.slip,
            args.substeps,
            if args.slip_start > 0.0 {
                format!(
                    ", slipping start P = {} of ±{} mrad",
                    args.slip_start,
                    args.slip_start_rad * 1e3
                )
            } else {
                String::new()
            },
            args.eb,
            args.ed
        );
        print_acc_header();
    }
    for (m, a) in &results {
        let (mb, sb) = a.mean_std(0);
        let (md, sd) = a.mean_std(1);
        match args.format {
            Format::Text => print_acc_row(a, m),
            Format::Json => println!(
                "{{\"L\":{},\"method\":\"{}\",\"trials\":{},\"E_b_err_mean\":{mb:e},\"E_b_err_std\":{sb:e},\"E_d_err_mean\":{md:e},\"E_d_err_std\":{sd:e},\"failed\":{}}}",
                args.side,
                m,
                a.trials(),
                a.failed()
            ),
        }
    }
    Ok(())
}
