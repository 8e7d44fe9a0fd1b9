//! `host-sim sweep`: the Monte Carlo over square sides and noise levels that checks the
//! track-size advice ([`crate::experiments::sweep`]); prints its tables and writes its files.

pub use crate::experiments::sweep::SweepArgs;
use crate::experiments::sweep::{SWEEP_METHODS, progress_bar, sweep, write_outputs};

/// Runs the subcommand.
pub fn run(a: &SweepArgs) -> Result<(), Box<dyn std::error::Error>> {
    let started = std::time::Instant::now();
    let pb = progress_bar(a.quiet, "sweep");
    let result = sweep(a, &pb)?;
    pb.finish_and_clear();
    println!(
        "sweep: {} trials per cell, {}+{} runs, truth E_b = {}, E_d = {}, {} threads, {:.1} s",
        a.trials,
        a.runs,
        a.runs,
        a.eb,
        a.ed,
        rayon::current_num_threads(),
        started.elapsed().as_secs_f64()
    );
    println!(
        "error = RMS over trials of sqrt(ΔE_b² + ΔE_d²); advice = expected error of track::evaluate"
    );
    let mut last = (f64::NAN, f64::NAN);
    for c in &result.cells {
        if (c.meas_sigma_m, c.slip) != last {
            last = (c.meas_sigma_m, c.slip);
            println!(
                "\nσ_meas = {} mm, slip σ = {}:\n{:>6} {}",
                c.meas_sigma_m * 1e3,
                c.slip,
                "L/m",
                SWEEP_METHODS
                    .iter()
                    .map(|m| format!("{:>21}", format!("{} (advice)", m.as_str())))
                    .collect::<String>()
            );
        }
        print!("{:>6}", c.side_m);
        for st in &c.methods {
            let p = st.predicted.map_or("-".to_string(), |p| format!("{p:.1e}"));
            print!("{:>21}", format!("{:.1e} ({p})", st.rms_error));
        }
        println!();
    }
    println!("\nbest side per method: sweep vs track::advise");
    println!(
        "{:>9} {:>7} {:>9} {:>11} | {:>18} | {:>18} {:>12} | {:>18}",
        "σ_meas mm",
        "slip",
        "scatter mm",
        "method",
        "sweep best L (err)",
        "advice L on grid",
        "err there",
        "advise() L (pred)"
    );
    for b in &result.best {
        let f =
            |v: Option<(f64, f64)>| v.map_or("-".to_string(), |(l, e)| format!("{l} m ({e:.1e})"));
        println!(
            "{:>9} {:>7} {:>9.2} {:>11} | {:>18} | {:>18} {:>12} | {:>18}",
            b.meas_sigma_m * 1e3,
            b.slip,
            b.pilot_scatter_m * 1e3,
            b.method.as_str(),
            f(b.sweep),
            f(b.advice_on_grid),
            b.sweep_at_advice.map_or("-".into(), |e| format!("{e:.1e}")),
            f(b.advice),
        );
    }
    for p in write_outputs(&result, &a.out)? {
        println!("wrote {}", p.display());
    }
    Ok(())
}
