//! Numbers with an optional unit, for the measured end pose (`measure x y [θ]`): the one reader
//! the board's parser and the PC console both use, so a value means the same in both.
//!
//! A number with its unit written right after it (`-5.356mm`, `-5.4cm`, `0.05m`, `2.5deg`,
//! `0.04rad`, any case) is read exactly in that unit. A bare number has no unit: it means
//! something only in the unit the operator declared for the session (`set measure_unit`,
//! `set heading_unit`); a unit is never inferred ([`Length::metres`], [`Angle::degrees`]).

use core::fmt;

use super::number::{NumberError, parse_f64};
use crate::util::text::keyword_eq;

/// A length unit that may follow a number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum LengthUnit {
    /// `m`.
    Metre,
    /// `cm`.
    Centimetre,
    /// `mm`.
    Millimetre,
}

impl LengthUnit {
    /// Every length unit, in the order the replies list them (smallest first for a hint).
    pub const ALL: [LengthUnit; 3] = [
        LengthUnit::Millimetre,
        LengthUnit::Centimetre,
        LengthUnit::Metre,
    ];

    /// The unit's symbol as typed.
    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Metre => "m",
            LengthUnit::Centimetre => "cm",
            LengthUnit::Millimetre => "mm",
        }
    }

    /// Metres per unit.
    pub fn metres(self) -> f64 {
        match self {
            LengthUnit::Metre => 1.0,
            LengthUnit::Centimetre => 0.01,
            LengthUnit::Millimetre => 0.001,
        }
    }
}

/// An angle unit that may follow a number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum AngleUnit {
    /// `deg`.
    Degree,
    /// `rad`.
    Radian,
}

impl AngleUnit {
    /// The unit's symbol as typed.
    pub fn symbol(self) -> &'static str {
        match self {
            AngleUnit::Degree => "deg",
            AngleUnit::Radian => "rad",
        }
    }

    /// Degrees per unit.
    pub fn degrees(self) -> f64 {
        match self {
            AngleUnit::Degree => 1.0,
            AngleUnit::Radian => 180.0 / core::f64::consts::PI,
        }
    }
}

/// A length as typed: the number and the unit written with it (`None`: bare).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Length {
    /// The number as typed.
    pub value: f64,
    /// The unit written after the number (or apart from it), if any.
    pub unit: Option<LengthUnit>,
}

impl Length {
    /// The value in metres: in its written unit, else in `declared` (the session's
    /// `measure_unit`); `None` for a bare value with nothing declared.
    pub fn metres(self, declared: Option<LengthUnit>) -> Option<f64> {
        self.unit.or(declared).map(|u| self.value * u.metres())
    }
}

/// An angle as typed: the number and the unit written with it (`None`: bare).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Angle {
    /// The number as typed.
    pub value: f64,
    /// The unit written after the number (or apart from it), if any.
    pub unit: Option<AngleUnit>,
}

impl Angle {
    /// The value in degrees: in its written unit, else in `declared` (the session's
    /// `heading_unit`); `None` for a bare value with nothing declared.
    pub fn degrees(self, declared: Option<AngleUnit>) -> Option<f64> {
        self.unit.or(declared).map(|u| self.value * u.degrees())
    }
}

/// The length unit a word names (`mm`, `cm`, `m`, any case), if any.
pub fn length_unit(word: &str) -> Option<LengthUnit> {
    LengthUnit::ALL
        .into_iter()
        .find(|u| keyword_eq(word, u.symbol()))
}

/// The angle unit a word names (`deg`, `rad`, any case), if any.
pub fn angle_unit(word: &str) -> Option<AngleUnit> {
    [AngleUnit::Degree, AngleUnit::Radian]
        .into_iter()
        .find(|u| keyword_eq(word, u.symbol()))
}

/// Why a word is not a number with a unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum UnitError {
    /// The number part is not a number.
    Number(NumberError),
    /// The text after the number is not a unit of this kind.
    UnknownUnit,
}

impl fmt::Display for UnitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            UnitError::Number(e) => write!(f, "{e}"),
            UnitError::UnknownUnit => f.write_str("unknown unit"),
        }
    }
}

/// Splits `word` into its number and the letters after it (`"-5.356mm"` → `("-5.356", "mm")`).
/// An exponent (`2e-3`) stays with the number: letters count as a unit only after the last
/// character that can end a number (a digit or a point).
pub fn split_unit(word: &str) -> (&str, &str) {
    let b = word.as_bytes();
    let mut end = b.len();
    while end > 0 && b.get(end - 1).is_some_and(u8::is_ascii_alphabetic) {
        end -= 1;
    }
    // `1e5`, `inf`, `nan`: a word that is all letters, or letters after an exponent marker
    // with nothing numeric after, is left to the number parser whole.
    if end == 0
        || !b
            .get(end - 1)
            .is_some_and(|c| c.is_ascii_digit() || *c == b'.')
    {
        return (word, "");
    }
    (
        word.get(..end).unwrap_or(word),
        word.get(end..).unwrap_or(""),
    )
}

fn number_part(number: &str) -> Result<f64, UnitError> {
    parse_f64(number).map_err(UnitError::Number)
}

/// Reads a length: a bare number, or a number with `m`, `cm` or `mm` after it.
///
/// # Errors
/// [`UnitError`] for a malformed number or a suffix that is not a length unit. The value may
/// be non-finite (the caller checks it as for any number).
pub fn parse_length(word: &str) -> Result<Length, UnitError> {
    let (number, suffix) = split_unit(word);
    let value = number_part(number)?;
    let unit = match suffix {
        "" => None,
        s => Some(length_unit(s).ok_or(UnitError::UnknownUnit)?),
    };
    Ok(Length { value, unit })
}

/// Reads an angle: a bare number, or a number with `deg` or `rad` after it.
///
/// # Errors
/// [`UnitError`] for a malformed number or a suffix that is not an angle unit. The value may
/// be non-finite (the caller checks it as for any number).
pub fn parse_angle(word: &str) -> Result<Angle, UnitError> {
    let (number, suffix) = split_unit(word);
    let value = number_part(number)?;
    let unit = match suffix {
        "" => None,
        s => Some(angle_unit(s).ok_or(UnitError::UnknownUnit)?),
    };
    Ok(Angle { value, unit })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bare_number_has_no_unit_until_one_is_declared() {
        let bare = parse_length("-5.356").unwrap();
        assert_eq!(
            bare,
            Length {
                value: -5.356,
                unit: None
            }
        );
        assert_eq!(bare.metres(None), None);
        assert_eq!(
            bare.metres(Some(LengthUnit::Millimetre)),
            Some(-5.356 * 0.001)
        );
        assert_eq!(parse_length("2e-3").map(|l| l.value), Ok(2e-3));
        let angle = parse_angle("-0.16").unwrap();
        assert_eq!(angle.degrees(None), None);
        assert_eq!(angle.degrees(Some(AngleUnit::Degree)), Some(-0.16));
        assert!((angle.degrees(Some(AngleUnit::Radian)).unwrap() + 9.167).abs() < 1e-3);
        // A written unit wins over the declared one.
        let mm = parse_length("4mm").unwrap();
        assert_eq!(mm.metres(Some(LengthUnit::Metre)), Some(4.0 * 0.001));
    }

    #[test]
    fn written_units_are_read_exactly() {
        let mm = parse_length("-5.356mm").unwrap();
        assert_eq!(mm.unit, Some(LengthUnit::Millimetre));
        assert_eq!(mm.metres(None), Some(-5.356 * 0.001));
        assert_eq!(
            parse_length("-5.4cm").unwrap().metres(None),
            Some(-5.4 * 0.01)
        );
        assert_eq!(parse_length("0.05M").unwrap().metres(None), Some(0.05));
        assert_eq!(parse_angle("2.5deg").unwrap().degrees(None), Some(2.5));
        let rad = parse_angle("0.04rad").unwrap();
        assert_eq!(rad.unit, Some(AngleUnit::Radian));
        assert!((rad.degrees(None).unwrap() - 0.04f64.to_degrees()).abs() < 1e-12);
    }

    #[test]
    fn a_wrong_kind_of_unit_or_a_bad_number_is_refused() {
        assert_eq!(parse_length("5deg"), Err(UnitError::UnknownUnit));
        assert_eq!(parse_length("5in"), Err(UnitError::UnknownUnit));
        assert_eq!(parse_angle("5mm"), Err(UnitError::UnknownUnit));
        assert_eq!(
            parse_length("mm"),
            Err(UnitError::Number(NumberError::Malformed))
        );
        assert_eq!(
            parse_length("1,5mm"),
            Err(UnitError::Number(NumberError::Malformed))
        );
        // Exponents and the special words stay numbers, never units.
        assert_eq!(parse_length("1e2").unwrap().value, 100.0);
        assert!(parse_length("nan").unwrap().value.is_nan());
        assert!(parse_length("inf").unwrap().value.is_infinite());
    }
}
