//! The CLI's subcommands, one module each. Each takes its clap arguments, runs its experiment
//! ([`crate::experiments`]) or drives the simulator ([`crate::sim`]) and the odocal library, and
//! prints.

pub mod advice;
pub mod bench;
pub mod bringup;
pub mod closedloop;
pub mod drive;
pub mod flash;
pub mod geometry;
pub mod montecarlo;
pub mod motors;
pub mod paper;
pub mod rectangle;
pub mod replay;
pub mod serial;
pub mod session;
pub mod square;
pub mod sweep;

/// `--rate-hz`: a control rate the board runs at (one of
/// [`odocal::motion::controller::RATES_HZ`]), checked by the library's own rule.
///
/// # Errors
/// Not a whole number, or not one of the rates, with the board's error text.
pub fn parse_rate_hz(s: &str) -> Result<u32, String> {
    let hz: u32 = s.parse().map_err(|e| format!("{s}: {e}"))?;
    if odocal::motion::controller::rate_supported(hz) {
        Ok(hz)
    } else {
        Err(odocal::motion::controller::RATE_RULE.to_string())
    }
}

/// Prints the header of the text table [`print_acc_row`] fills.
pub fn print_acc_header() {
    println!(
        "{:>11} {:>12} {:>12} {:>12} {:>12} {:>7}",
        "method", "E_b_err mean", "E_b_err std", "E_d_err mean", "E_d_err std", "failed"
    );
}

/// Prints one row of the text table: mean and std of a method's E_b and E_d errors, failures.
pub fn print_acc_row(acc: &crate::experiments::montecarlo::Acc, method: &str) {
    if acc.trials() == 0 {
        // Every trial failed: no statistic to show (zeros would read as a perfect result).
        let none = "-";
        println!(
            "{method:>11} {none:>12} {none:>12} {none:>12} {none:>12} {:>7}",
            acc.failed()
        );
        return;
    }
    let ((mb, sb), (md, sd)) = (acc.mean_std(0), acc.mean_std(1));
    println!(
        "{method:>11} {mb:>12.3e} {sb:>12.3e} {md:>12.3e} {sd:>12.3e} {:>7}",
        acc.failed()
    );
}
