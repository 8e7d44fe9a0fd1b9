//! The CLI's subcommands, one module each. Each takes its clap arguments and drives the
//! simulator ([`crate::sim`]) and the odocal library.

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
