//! `cargo sim` / `cargo sim session`: runs the full simulated calibration session
//! ([`crate::experiments::session`]), prints its report and writes its plots.

pub mod plots;
pub mod report;

use std::time::Instant;

pub use crate::experiments::session::{
    CalibrationRow, RunTrace, SessionArgs, SessionReport, Verification, field, parse_calibration,
    run_session,
};

/// Runs the session, prints the report and writes the plots (the `session` subcommand and
/// `cargo sim` without one).
///
/// # Errors
/// Session failures, file or drawing errors.
pub fn run(args: &SessionArgs) -> Result<(), Box<dyn std::error::Error>> {
    let started = Instant::now();
    let pb = crate::experiments::sweep::progress_bar(args.quiet, "session");
    let report = run_session(args, &pb)?;
    pb.set_message("plots");
    let written = plots::write_all(&report, &args.out)?;
    pb.finish_and_clear();
    print!("{}", report::text(&report));
    println!("\nfiles:");
    for p in &written {
        println!("  {}", p.display());
    }
    println!(
        "session wall time {:.2} s (simulation and calibration {:.2} s, plots {:.2} s)",
        started.elapsed().as_secs_f64(),
        report.total_wall_s,
        started.elapsed().as_secs_f64() - report.total_wall_s
    );
    Ok(())
}
