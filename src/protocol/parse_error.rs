//! Why a command line did not parse ([`ParseError`], one error code each, see
//! `docs/protocol.md`) and how the reply words it.

use core::fmt;

use super::number::MAX_DIGITS;
use super::param::ParamName;
use crate::util::decimal::Plain;

/// Why a line did not parse. Each variant maps to one error code (see `docs/protocol.md`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum ParseError {
    /// The line holds no command (only whitespace); the session ignores it silently.
    Empty,
    /// The first word is not a command.
    UnknownCommand,
    /// A required argument is missing.
    MissingArgument {
        /// Name of the missing argument.
        what: &'static str,
    },
    /// `drop` without saying which run.
    DropWhich,
    /// More arguments than the command takes.
    TooManyArguments,
    /// A number could not be read.
    BadNumber {
        /// Name of the argument.
        what: &'static str,
        /// What the word seems to hold besides a number.
        hint: NumberHint,
    },
    /// A number is NaN or infinite (or overflows to infinity).
    NotFinite {
        /// Name of the argument.
        what: &'static str,
    },
    /// A number is outside its accepted range.
    OutOfRange {
        /// Name of the argument.
        what: &'static str,
        /// Smallest accepted value.
        min: f64,
        /// Largest accepted value.
        max: f64,
        /// Unit of the range, shown after it (`""` where the argument's name carries it).
        unit: &'static str,
    },
    /// A keyword argument is not one of the accepted words.
    BadKeyword {
        /// Name of the argument.
        what: &'static str,
        /// The accepted words, `|`-separated.
        expected: &'static str,
    },
    /// `set` of a name that is not a parameter.
    UnknownParam {
        /// The parameter nearest the typed name (edit distance), if one is near.
        suggestion: Option<ParamName>,
    },
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParseError::Empty => f.write_str("empty line"),
            ParseError::UnknownCommand => f.write_str("unknown command (try help)"),
            ParseError::MissingArgument { what } => write!(f, "missing argument <{what}>"),
            ParseError::DropWhich => f.write_str("drop <n> drops run n, drop all yes every run"),
            ParseError::TooManyArguments => f.write_str("too many arguments"),
            ParseError::BadNumber { what, hint } => {
                write!(f, "<{what}> ")?;
                f.write_str(match hint {
                    NumberHint::None => "is not a number",
                    NumberHint::Unit => "is not a number (type the number alone, without a unit)",
                    NumberHint::Comma => "is not a number (use a decimal point)",
                    NumberHint::Fraction => "is not a whole number",
                    NumberHint::LengthUnit => "has an unknown unit (m, cm or mm after the number)",
                    NumberHint::AngleUnit => "has an unknown unit (deg or rad after the number)",
                    NumberHint::Digits => {
                        return write!(f, "has too many digits (at most {MAX_DIGITS} significant)");
                    }
                })
            }
            ParseError::NotFinite { what } => write!(f, "<{what}> must be finite"),
            ParseError::OutOfRange {
                what,
                min,
                max,
                unit,
            } => {
                write!(
                    f,
                    "<{what}> must be within {}..{}",
                    Plain(*min),
                    Plain(*max)
                )?;
                if !unit.is_empty() {
                    write!(f, " {unit}")?;
                }
                Ok(())
            }
            ParseError::BadKeyword { what, expected } => {
                write!(f, "<{what}> must be one of {expected}")
            }
            ParseError::UnknownParam { suggestion } => {
                f.write_str("<name> must be one of the parameters listed by params")?;
                match suggestion {
                    Some(p) => write!(f, "; did you mean {}?", p.as_str()),
                    None => Ok(()),
                }
            }
        }
    }
}

/// What a word that is not a number seems to hold besides one, for the reply's hint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum NumberHint {
    /// Nothing recognisable.
    None,
    /// A number followed by a unit (`41.8mm`, `90deg`).
    Unit,
    /// A decimal comma (`0,25`).
    Comma,
    /// A number with a fraction where a whole number is needed (`drop 1.5`).
    Fraction,
    /// More significant digits than the parser keeps ([`super::number::MAX_DIGITS`]).
    Digits,
    /// A number followed by something that is not a length unit (where one may be written).
    LengthUnit,
    /// A number followed by something that is not an angle unit (where one may be written).
    AngleUnit,
}
