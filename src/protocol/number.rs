//! Decimal number parser for the command line, without `core`'s `f64::from_str`.
//!
//! `core`'s parser (Eisel-Lemire with a 10 KB power-of-five table, plus a big-decimal
//! fallback) is exact for any input but costs about 13 KB of flash. Protocol numbers are short
//! (a line holds at most [`crate::protocol::LINE_MAX`] bytes), so this parser keeps the same
//! grammar and takes one shortcut:
//!
//! `[+-]` then `inf`, `infinity` or `nan` (any case), or `digits[.digits]` / `.digits` with an
//! optional exponent `e|E[+-]digits`. Up to 19 significant digits (leading zeros and trailing
//! zeros of the digit string do not count) are collected in a `u64` mantissa `m`; more are
//! rejected as [`NumberError::TooManyDigits`]. With the decimal exponent `k`, the result is
//! `m × 10^k` or `m ÷ 10^−k` with `10^|k|` exactly representable (`|k| ≤ 22`; for larger `k`
//! powers of ten move into `m` while `m ≤ 2^53`): one correctly rounded operation, so for `m < 2^53` (every input with ≤ 15 significant digits) the result
//! is bit for bit the one of `str::parse::<f64>`. With 16..19 digits the conversion of `m`
//! rounds once more (≤ 1 ulp apart); beyond `|k| ≤ 22` the scaling is repeated in steps of
//! `10^22` (a few ulp), which only matters for values no command accepts, except that a value
//! within a few ulp of `f64::MAX` may be classified finite/infinite differently.
//! Overflow gives ±infinity and NaN/infinity are returned as values, as `str::parse` does; the
//! caller rejects them.

use core::fmt;

use crate::util::text::keyword_eq;

/// Largest number of significant digits accepted (all of them fit in a `u64`).
pub const MAX_DIGITS: u32 = 19;

/// Why a word is not a number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum NumberError {
    /// Not of the form `[+-]digits[.digits][e[+-]digits]`, `inf`, `infinity` or `nan`.
    Malformed,
    /// More than [`MAX_DIGITS`] significant digits.
    TooManyDigits,
}

impl fmt::Display for NumberError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            NumberError::Malformed => "malformed number",
            NumberError::TooManyDigits => "too many significant digits",
        })
    }
}

/// `10^k` for `k = 0..=22`: every power of ten that is exact in an `f64`.
const EXACT_POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// Mantissa digits collected so far.
struct Mantissa {
    value: u64,
    digits: u32,
    /// Zeros seen after the last non-zero digit, not yet multiplied in.
    pending_zeros: u32,
}

impl Mantissa {
    fn push(&mut self, d: u8) -> Result<(), NumberError> {
        if d == 0 {
            if self.digits > 0 {
                self.pending_zeros += 1;
            }
            return Ok(());
        }
        let step = self.pending_zeros + 1;
        self.digits += step;
        if self.digits > MAX_DIGITS {
            return Err(NumberError::TooManyDigits);
        }
        // digits ≤ 19 after this push, so the product stays below 10^19 < 2^64.
        let scale = 10u64.pow(step);
        self.value = self.value * scale + u64::from(d);
        self.pending_zeros = 0;
        Ok(())
    }
}

/// Parses one word as an `f64` (see the module documentation for the grammar and exactness).
///
/// # Errors
/// [`NumberError::Malformed`] for text outside the grammar, [`NumberError::TooManyDigits`] for
/// more than [`MAX_DIGITS`] significant digits.
pub fn parse_f64(word: &str) -> Result<f64, NumberError> {
    let (negative, rest) = match word.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, word.strip_prefix('+').unwrap_or(word)),
    };
    let magnitude = if keyword_eq(rest, "inf") || keyword_eq(rest, "infinity") {
        f64::INFINITY
    } else if keyword_eq(rest, "nan") {
        f64::NAN
    } else {
        finite_magnitude(rest.as_bytes())?
    };
    Ok(if negative { -magnitude } else { magnitude })
}

/// The value a host meant by an `f32` argument it wrote as text (a command's `f32` is written
/// in its shortest form): the `f64` this parser reads from the decimal of fewest places, up to
/// 9, that reads back as `x` (`0.995_f32` gives `0.995`, not `0.995000004768…`); `x` widened
/// exactly when no such decimal exists (magnitudes far from 1).
pub fn f32_as_written(x: f32) -> f64 {
    let wide = f64::from(x);
    for pow in &EXACT_POW10[..10] {
        // `round(..)` is whole and below 2^53 where it matters, so the quotient is the correctly
        // rounded decimal, as `scale` divides it.
        let decimal = libm::round(wide * pow) / pow;
        if decimal as f32 == x {
            return decimal;
        }
    }
    wide
}

/// `digits[.digits][e[+-]digits]` (at least one mantissa digit) without sign.
fn finite_magnitude(text: &[u8]) -> Result<f64, NumberError> {
    let mut mantissa = Mantissa {
        value: 0,
        digits: 0,
        pending_zeros: 0,
    };
    let mut exp10: i32 = 0;
    let mut any_digit = false;
    let mut i = 0;
    while let Some(&b) = text.get(i).filter(|b| b.is_ascii_digit()) {
        mantissa.push(b - b'0')?;
        any_digit = true;
        i += 1;
    }
    if text.get(i) == Some(&b'.') {
        i += 1;
        while let Some(&b) = text.get(i).filter(|b| b.is_ascii_digit()) {
            mantissa.push(b - b'0')?;
            any_digit = true;
            exp10 = exp10.saturating_sub(1);
            i += 1;
        }
    }
    if !any_digit {
        return Err(NumberError::Malformed);
    }
    if matches!(text.get(i), Some(b'e' | b'E')) {
        i += 1;
        let negative = match text.get(i) {
            Some(b'-') => {
                i += 1;
                true
            }
            Some(b'+') => {
                i += 1;
                false
            }
            _ => false,
        };
        let start = i;
        let mut e: i32 = 0;
        while let Some(&b) = text.get(i).filter(|b| b.is_ascii_digit()) {
            // Saturate far beyond any finite f64 (|k| ≤ 343 matters).
            e = (e * 10 + i32::from(b - b'0')).min(100_000);
            i += 1;
        }
        if i == start {
            return Err(NumberError::Malformed);
        }
        exp10 = if negative { exp10 - e } else { exp10 + e };
    }
    if i != text.len() {
        return Err(NumberError::Malformed);
    }
    if mantissa.value == 0 {
        return Ok(0.0);
    }
    let mut k = exp10.saturating_add_unsigned(mantissa.pending_zeros);
    let mut m = mantissa.value;
    // Trailing zeros taken out of the digit string can push k past 22 (`1.50000e20`); move
    // them back into the mantissa while it stays exact in an f64 (Clinger's fast path).
    while k > 22 && m <= (1u64 << 53) / 10 {
        m *= 10;
        k -= 1;
    }
    Ok(scale(m as f64, k))
}

/// `m · 10^k`: exact scaling by `10^|k|` for `|k| ≤ 22`, repeated steps of `10^22` beyond.
fn scale(mut m: f64, mut k: i32) -> f64 {
    // 10^-343 · (2^64) underflows to zero and 10^310 overflows: stop early.
    k = k.clamp(-400, 400);
    while k > 22 {
        m *= EXACT_POW10[22];
        k -= 22;
    }
    while k < -22 {
        m /= EXACT_POW10[22];
        k += 22;
    }
    let pow = EXACT_POW10[k.unsigned_abs() as usize];
    if k >= 0 { m * pow } else { m / pow }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grammar_examples() {
        assert_eq!(parse_f64("2.5"), Ok(2.5));
        assert_eq!(parse_f64("-3.75"), Ok(-3.75));
        assert_eq!(parse_f64("+5"), Ok(5.0));
        assert_eq!(parse_f64(".5"), Ok(0.5));
        assert_eq!(parse_f64("5."), Ok(5.0));
        assert_eq!(parse_f64("2E-2"), Ok(0.02));
        assert_eq!(parse_f64("1e+3"), Ok(1000.0));
        assert!(parse_f64("-0").is_ok_and(|v| v == 0.0 && v.is_sign_negative()));
        assert_eq!(parse_f64("1e999"), Ok(f64::INFINITY));
        assert_eq!(parse_f64("-Infinity"), Ok(f64::NEG_INFINITY));
        assert!(parse_f64("NaN").is_ok_and(f64::is_nan));
        assert_eq!(parse_f64("1e-400"), Ok(0.0));
        for bad in [
            "", "+", "-", ".", "e5", "1e", "1e+", "0x10", "1_0", "1.2.3", "é", "inff", "1 ",
        ] {
            assert_eq!(parse_f64(bad), Err(NumberError::Malformed), "{bad:?}");
        }
    }

    #[test]
    fn an_f32_reads_as_the_decimal_it_was_written_as() {
        use std::string::ToString;
        for x in [
            0.995_f32,
            1.01,
            1.0,
            0.8,
            1.25,
            0.995_123_45,
            1.000_000_1,
            0.999_999_94,
            1.0 / 3.0,
            -0.5,
            0.0,
        ] {
            let wide = f32_as_written(x);
            assert_eq!(wide as f32, x, "{x}");
            // What the writer writes (the shortest form), read back by this parser.
            assert_eq!(parse_f64(&x.to_string()), Ok(wide), "{x}");
        }
        assert_eq!(f32_as_written(0.995), 0.995);
        // No decimal of 9 places: widened as it is.
        assert_eq!(f32_as_written(1e-12), f64::from(1e-12_f32));
        assert_eq!(f32_as_written(f32::MAX), f64::from(f32::MAX));
        assert!(f32_as_written(f32::NAN).is_nan());
    }

    #[test]
    fn digit_limit_counts_significant_digits_only() {
        // 19 significant digits plus leading and trailing zeros: accepted.
        assert_eq!(
            parse_f64("000.1234567890123456789000"),
            Ok(0.123_456_789_012_345_68)
        );
        assert_eq!(parse_f64("100000000000000000000"), Ok(1e20));
        assert_eq!(
            parse_f64("99999999999999999999"),
            Err(NumberError::TooManyDigits)
        );
        assert_eq!(
            parse_f64("1.0000000000000000001"),
            Err(NumberError::TooManyDigits)
        );
    }
}
