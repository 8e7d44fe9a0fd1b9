//! What the operator types: a length or a measured end pose, read with the library's unit
//! reader the board uses (a unit is never inferred).

use odocal::protocol::unit::{AngleUnit, LengthUnit, parse_length};

/// The unit symbols the board reads after a number (`protocol::unit`), for joining a unit
/// typed apart from its number.
fn unit_symbols() -> impl Iterator<Item = &'static str> {
    LengthUnit::ALL
        .into_iter()
        .map(LengthUnit::symbol)
        .chain([AngleUnit::Degree, AngleUnit::Radian].map(AngleUnit::symbol))
}

/// Plausible ranges of the lengths the session asks for, metres: a robot's wheel diameter
/// (20 mm to 0.5 m), its wheelbase (5 cm to 2 m), a square's side (the board's 0.1..10 m).
pub(super) const WHEEL_DIAMETER_M: (f64, f64) = (0.02, 0.5);
/// See [`WHEEL_DIAMETER_M`].
pub(super) const WHEELBASE_M: (f64, f64) = (0.05, 2.0);
/// See [`WHEEL_DIAMETER_M`].
pub(super) const SQUARE_SIDE_M: (f64, f64) = odocal::protocol::command::PATH_RANGE_M;

/// A length typed by the operator, in metres, read by the library's reader the board uses
/// (`protocol::unit::parse_length`: `150mm`, `15cm`, `0.15m`, the unit against the number or
/// apart from it); a bare number is refused, as the board refuses it: a unit is never inferred.
/// The refusal proposes the units that make the number plausible for a length within
/// `plausible` (metres): `150` → `150mm`, `0.15` → `0.15m` for a wheel diameter.
pub(super) fn length(typed: &str, plausible: (f64, f64)) -> Result<f64, String> {
    // A unit typed apart from its number (`38.5 cm`) joins it.
    let word: String = typed.split_whitespace().collect();
    let word = word.as_str();
    if word.contains(',') && !word.contains('.') {
        return Err(format!("`{word}` is not a number (use a decimal point)"));
    }
    match parse_length(word) {
        Ok(l) if !l.value.is_finite() => Err(format!("`{word}` is not finite")),
        Ok(l) => l.metres(None).ok_or_else(|| {
            let fits: Vec<String> = LengthUnit::ALL
                .into_iter()
                .filter(|u| {
                    let m = l.value * u.metres();
                    m >= plausible.0 && m <= plausible.1
                })
                .map(|u| format!("{word}{}", u.symbol()))
                .collect();
            match fits.as_slice() {
                [] => format!("`{word}` has no unit: write mm, cm or m after it"),
                some => format!("`{word}` has no unit: {}?", some.join(" or ")),
            }
        }),
        Err(e) => Err(format!(
            "`{word}`: {e} (a number, with mm, cm or m after it if not metres)"
        )),
    }
}

/// The words of a typed measurement as the board reads them: a unit typed apart (`41.8 mm`)
/// joins its number, a comma or semicolon that separates the values (`41.8mm, -39.5mm`) is
/// dropped (a comma inside a number stays, for the board to name), and `°` is written `deg`.
pub(super) fn measurement_words(text: &str) -> Vec<String> {
    let mut words: Vec<String> = Vec::new();
    for w in text.split_whitespace() {
        let w = w.trim_end_matches([',', ';']);
        let w = match w.strip_suffix('°') {
            Some(n) => format!("{n}deg"),
            None => w.to_string(),
        };
        let unit = unit_symbols().any(|u| u.eq_ignore_ascii_case(&w));
        match words.last_mut() {
            Some(last) if unit && last.parse::<f64>().is_ok() => last.push_str(&w),
            _ if !w.is_empty() => words.push(w),
            _ => {}
        }
    }
    words
}

#[cfg(test)]
mod tests {
    use super::{WHEEL_DIAMETER_M, WHEELBASE_M, length, measurement_words};

    #[test]
    fn a_measurement_is_passed_on_as_the_board_reads_it() {
        for (typed, words) in [
            ("0.0418 -0.0395 0.3", ["0.0418", "-0.0395", "0.3"]),
            ("41.8mm -39.5mm 0.3", ["41.8mm", "-39.5mm", "0.3"]),
            ("41.8 mm -39.5 MM 0.3 deg", ["41.8mm", "-39.5MM", "0.3deg"]),
            ("41.8mm, -39.5mm, 0.3°", ["41.8mm", "-39.5mm", "0.3deg"]),
            (
                "4.18cm; -3.95 cm 0.01 rad",
                ["4.18cm", "-3.95cm", "0.01rad"],
            ),
        ] {
            assert_eq!(measurement_words(typed), words, "{typed}");
        }
        assert_eq!(measurement_words("-0,009 -0,009"), ["-0,009", "-0,009"]);
    }

    #[test]
    fn a_length_is_read_with_the_boards_unit_reader() {
        assert_eq!(length("150mm", WHEEL_DIAMETER_M).unwrap(), 150.0 * 0.001);
        assert_eq!(
            length("0.385", WHEELBASE_M).unwrap_err(),
            "`0.385` has no unit: 0.385m?"
        );
        assert_eq!(length("0.385 m", WHEELBASE_M).unwrap(), 0.385);
        assert_eq!(length("38.5cm", WHEELBASE_M).unwrap(), 38.5 * 0.01);
        assert_eq!(length(" 38.5 cm ", WHEELBASE_M).unwrap(), 38.5 * 0.01);
        assert_eq!(
            length("0,15", WHEEL_DIAMETER_M).unwrap_err(),
            "`0,15` is not a number (use a decimal point)"
        );
        assert!(
            length("15in", WHEEL_DIAMETER_M)
                .unwrap_err()
                .starts_with("`15in`: ")
        );
    }

    /// The unit proposed makes the number a plausible length of its kind: never `0.15mm` for a
    /// wheel diameter.
    #[test]
    fn the_unit_proposed_is_plausible_for_the_quantity() {
        for (typed, plausible, hint) in [
            ("0.15", WHEEL_DIAMETER_M, "`0.15` has no unit: 0.15m?"),
            ("150", WHEEL_DIAMETER_M, "`150` has no unit: 150mm?"),
            ("15", WHEEL_DIAMETER_M, "`15` has no unit: 15cm?"),
            ("38.5", WHEELBASE_M, "`38.5` has no unit: 38.5cm?"),
            ("385", WHEELBASE_M, "`385` has no unit: 385mm?"),
            ("1", WHEELBASE_M, "`1` has no unit: 1m?"),
            (
                "9000",
                WHEEL_DIAMETER_M,
                "`9000` has no unit: write mm, cm or m after it",
            ),
        ] {
            assert_eq!(length(typed, plausible).unwrap_err(), hint, "{typed}");
        }
    }
}
