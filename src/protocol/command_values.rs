//! The values of a command's words: numbers within their ranges, whole numbers, signs, and the
//! errors that name what was wrong with a word ([`super::command`]'s parser reads every number
//! through these).

use super::number::{NumberError, parse_f64};
use super::parse_error::{NumberHint, ParseError};
use super::unit::UnitError;

/// The error for `word`, which is not a number for `what`.
#[inline(never)]
pub(super) fn bad_number(word: &str, what: &'static str) -> ParseError {
    let b = word.as_bytes();
    let starts_numeric = b
        .first()
        .is_some_and(|c| c.is_ascii_digit() || matches!(c, b'.' | b'-' | b'+'));
    let hint = if !starts_numeric {
        NumberHint::None
    } else if b.contains(&b',') {
        NumberHint::Comma
    } else if b.last().is_some_and(u8::is_ascii_alphabetic) {
        NumberHint::Unit
    } else {
        NumberHint::None
    };
    ParseError::BadNumber { what, hint }
}

/// Reads a finite `f64` within `[min, max]`.
#[inline(never)]
pub(super) fn number(
    word: &str,
    what: &'static str,
    min: f64,
    max: f64,
) -> Result<f64, ParseError> {
    let value = parse_f64(word).map_err(|e| match e {
        NumberError::TooManyDigits => ParseError::BadNumber {
            what,
            hint: NumberHint::Digits,
        },
        NumberError::Malformed => bad_number(word, what),
    })?;
    in_range(value, what, min, max)
}

/// Reads a whole number within `[min, max]`: digits, or any number whose value is whole
/// (`200000.0`, `2e5`); a fraction is refused as such, a negative value as out of range.
pub(super) fn whole(word: &str, what: &'static str, min: u32, max: u32) -> Result<u32, ParseError> {
    let out_of_range = ParseError::OutOfRange {
        what,
        min: f64::from(min),
        max: f64::from(max),
        unit: "",
    };
    let value = if !word.is_empty() && word.bytes().all(|b| b.is_ascii_digit()) {
        // All digits: the only possible parse failure is overflow, which is out of range.
        word.parse::<u32>().map_err(|_| out_of_range)?
    } else {
        let value = number(word, what, f64::NEG_INFINITY, f64::INFINITY)?;
        if libm::trunc(value) != value {
            return Err(ParseError::BadNumber {
                what,
                hint: NumberHint::Fraction,
            });
        }
        if !(f64::from(min)..=f64::from(max)).contains(&value) {
            return Err(out_of_range);
        }
        // Whole and within a u32 range: exact.
        value as u32
    };
    if !(min..=max).contains(&value) {
        return Err(out_of_range);
    }
    Ok(value)
}

/// A wiring sign: `1`, `+1` or `-1`.
pub(super) fn sign(word: &str) -> Result<f64, ParseError> {
    match word {
        "1" | "+1" => Ok(1.0),
        "-1" => Ok(-1.0),
        _ => Err(ParseError::BadKeyword {
            what: "value",
            expected: "1|-1",
        }),
    }
}

/// Checks a value read with its unit against `[min, max]` (in the base unit).
pub(super) fn in_range(
    value: f64,
    what: &'static str,
    min: f64,
    max: f64,
) -> Result<f64, ParseError> {
    if !value.is_finite() {
        return Err(ParseError::NotFinite { what });
    }
    if !(min..=max).contains(&value) {
        return Err(ParseError::OutOfRange {
            what,
            min,
            max,
            unit: "",
        });
    }
    Ok(value)
}

/// The error for a word that [`super::unit`] refused.
pub(super) fn unit_error(
    e: UnitError,
    word: &str,
    what: &'static str,
    hint: NumberHint,
) -> ParseError {
    match e {
        UnitError::Number(NumberError::TooManyDigits) => ParseError::BadNumber {
            what,
            hint: NumberHint::Digits,
        },
        UnitError::Number(NumberError::Malformed) => match bad_number(word, what) {
            // A unit after a malformed number is not the problem.
            ParseError::BadNumber {
                hint: NumberHint::Unit,
                ..
            } => ParseError::BadNumber {
                what,
                hint: NumberHint::None,
            },
            e => e,
        },
        UnitError::UnknownUnit => ParseError::BadNumber { what, hint },
    }
}

/// A finite number as typed, for a measured value.
pub(super) fn finite(value: f64, what: &'static str) -> Result<f64, ParseError> {
    in_range(value, what, f64::NEG_INFINITY, f64::INFINITY)
}
