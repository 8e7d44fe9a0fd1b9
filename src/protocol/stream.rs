//! The pose stream's line (`stream on [hz]`), both ways: the board writes a [`StreamSample`]
//! with [`StreamSample::write`], a host reads it back with [`StreamSample::parse`].
//!
//! `stream <t_s> <x_m> <y_m> <theta_deg> <v_right_mps> <v_left_mps>`: the board's time in
//! seconds with microseconds, the odometry pose (metres with 6 decimals, the heading in degrees
//! wrapped to (−180, 180] with 4) and the mean wheel speeds since the previous line (m/s, 4
//! decimals).

use core::fmt::{self, Write};

use super::reply::EOL;
use super::token::STREAM;
use crate::util::decimal::Decimal;
use crate::util::trig::wrap_deg;

/// One line of the pose stream.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreamSample {
    /// The board's time, µs since boot.
    pub t_us: u64,
    /// Odometry x, metres.
    pub x_m: f64,
    /// Odometry y, metres.
    pub y_m: f64,
    /// Odometry heading, radians (as written: degrees, wrapped).
    pub theta_rad: f64,
    /// Mean right wheel speed since the previous line, m/s.
    pub v_right_mps: f64,
    /// Mean left wheel speed since the previous line, m/s.
    pub v_left_mps: f64,
}

impl StreamSample {
    /// Writes the line, its terminator included.
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    pub fn write(&self, out: &mut dyn Write) -> fmt::Result {
        write!(
            out,
            "{STREAM}{}.{:06} {} {} {} {} {}{EOL}",
            // Both casts are exact (the quotient is below 2^64 / 10^6 < 2^63, the remainder
            // below 10^6): the replies print integers through the `i64` and `u32` formatters.
            (self.t_us / 1_000_000) as i64,
            (self.t_us % 1_000_000) as u32,
            Decimal::signed(self.x_m, 6),
            Decimal::signed(self.y_m, 6),
            Decimal::signed(wrap_deg(self.theta_rad.to_degrees()), 4),
            Decimal::signed(self.v_right_mps, 4),
            Decimal::signed(self.v_left_mps, 4)
        )
    }

    /// Reads a stream line (its terminator optional); `None` for any other line or a malformed
    /// one.
    pub fn parse(line: &str) -> Option<StreamSample> {
        let mut w = line.strip_prefix(STREAM)?.split_ascii_whitespace();
        let (s, us) = w.next()?.split_once('.')?;
        let us: u64 = if us.len() == 6 {
            us.parse().ok()?
        } else {
            return None;
        };
        let t_us = s
            .parse::<u64>()
            .ok()?
            .checked_mul(1_000_000)?
            .checked_add(us)?;
        let mut next = || {
            let v = super::number::parse_f64(w.next()?).ok()?;
            v.is_finite().then_some(v)
        };
        let sample = StreamSample {
            t_us,
            x_m: next()?,
            y_m: next()?,
            theta_rad: next()?.to_radians(),
            v_right_mps: next()?,
            v_left_mps: next()?,
        };
        w.next().is_none().then_some(sample)
    }
}

#[cfg(test)]
mod tests {
    use std::string::String;

    use super::*;

    /// What the board writes, a host reads back: the time exactly, the rest to the decimals
    /// written (half a unit of the last one).
    #[test]
    fn a_stream_line_reads_back_what_was_written() {
        let sample = StreamSample {
            t_us: 12_345_678_901,
            x_m: -1.234_567_4,
            y_m: 0.000_000_4,
            theta_rad: -3.0,
            v_right_mps: 0.299_96,
            v_left_mps: -0.1,
        };
        let mut line = String::new();
        sample.write(&mut line).unwrap();
        assert_eq!(
            line,
            "stream 12345.678901 -1.234567 +0.000000 -171.8873 +0.3000 -0.1000\r\n"
        );
        let read = StreamSample::parse(line.trim_end()).unwrap();
        assert_eq!(read.t_us, sample.t_us);
        assert!((read.x_m - sample.x_m).abs() <= 0.5e-6);
        assert!((read.y_m - sample.y_m).abs() <= 0.5e-6);
        assert!((read.theta_rad - sample.theta_rad).abs() <= 0.5e-4_f64.to_radians());
        assert!((read.v_right_mps - sample.v_right_mps).abs() <= 0.5e-4);
        assert!((read.v_left_mps - sample.v_left_mps).abs() <= 0.5e-4);
    }

    #[test]
    fn other_or_malformed_lines_are_not_samples() {
        for line in [
            "event boot: ok",
            "stream 1.5 0 0 0 0 0",
            "stream 1.500000 0 0 0 0",
            "stream 1.500000 0 0 0 0 0 7",
            "stream 1.500000 0 nan 0 0 0",
            "stream x.500000 0 0 0 0 0",
        ] {
            assert_eq!(StreamSample::parse(line), None, "{line}");
        }
        assert!(StreamSample::parse("stream 1.500000 0 0 0 0 0").is_some());
    }
}
