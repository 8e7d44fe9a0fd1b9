//! Every parameter's range at both ends, generated from the protocol's parameter table
//! ([`PARAMS`]): a parameter added to the table is covered here without a new test.
//!
//! For each row the ends themselves are accepted and the first value outside each end is
//! refused, where "first" is the parameter's own step:
//! - a real number: the next `f64` beyond the end that the command parser reads as a value
//!   beyond it (the finest step it distinguishes, written in the shortest form that reads back),
//!   and one unit of the last decimal `params` prints (the step an operator types);
//! - a whole number: one beyond the end;
//! - a wiring sign (±1): 2 and -2 (and 0, inside the range but not a sign).
//!
//! Refused values are refused by the parser with the range and unit in the error, and through
//! the session with `err 6` and the setting unchanged.

#[path = "support/bench.rs"]
mod bench;

use bench::Bench;
use odocal::protocol::number::parse_f64;
use odocal::protocol::{Command, PARAMS, ParamSpec, ParseError, ValueKind};

/// Which end of a range.
#[derive(Clone, Copy, Debug)]
enum End {
    Low,
    High,
}

/// The end itself, as typed.
fn at_end(spec: &ParamSpec, end: End) -> String {
    let v = match end {
        End::Low => spec.range.0,
        End::High => spec.range.1,
    };
    format!("{v}")
}

/// The first values outside `end`, as typed (see the file's text).
fn first_outside(spec: &ParamSpec, end: End) -> Vec<String> {
    let (lo, hi) = spec.range;
    match spec.value {
        ValueKind::Real { places } => {
            let (edge, beyond): (f64, fn(f64) -> f64) = match end {
                End::Low => (lo, f64::next_down),
                End::High => (hi, f64::next_up),
            };
            // The parser is exact to 15 significant digits and within an ulp beyond: step
            // until it reads the text as a value beyond the end (at most a few ulps).
            let mut v = edge;
            let finest = loop {
                v = beyond(v);
                let text = format!("{v}");
                let read = parse_f64(&text).expect("a number");
                let outside = match end {
                    End::Low => read < edge,
                    End::High => read > edge,
                };
                if outside {
                    break text;
                }
            };
            assert!(
                (v - edge).abs() <= 4.0 * (edge.next_up() - edge).abs().max(f64::MIN_POSITIVE),
                "{}: the parser's first value beyond {edge} is {v}, more than 4 ulps away",
                spec.wire
            );
            let unit = 10f64.powi(-i32::from(places));
            let typed = match end {
                End::Low => edge - unit,
                End::High => edge + unit,
            };
            vec![
                finest,
                format!("{typed:.prec$}", prec = usize::from(places)),
            ]
        }
        ValueKind::Whole => vec![match end {
            End::Low => format!("{}", lo - 1.0),
            End::High => format!("{}", hi + 1.0),
        }],
        ValueKind::Sign => match end {
            End::Low => vec!["-2".into(), "0".into()],
            End::High => vec!["2".into()],
        },
    }
}

#[test]
fn every_parameters_first_value_outside_its_range_is_refused_by_the_parser() {
    let mut checked = 0;
    for spec in &PARAMS {
        let (lo, hi) = spec.range;
        for end in [End::Low, End::High] {
            let line = format!("set {} {}", spec.wire, at_end(spec, end));
            match Command::parse(&line) {
                Ok(Command::Set { name, value }) => {
                    assert_eq!(name, spec.name, "{line}");
                    let want = match end {
                        End::Low => lo,
                        End::High => hi,
                    };
                    assert_eq!(value, want, "{line}");
                }
                other => panic!("`{line}`: the range's own end refused: {other:?}"),
            }
            for value in first_outside(spec, end) {
                let line = format!("set {} {value}", spec.wire);
                let got = Command::parse(&line);
                match (spec.value, got) {
                    (ValueKind::Sign, Err(ParseError::BadKeyword { .. })) => {}
                    (_, Err(ParseError::OutOfRange { min, max, unit, .. })) => {
                        assert_eq!((min, max, unit), (lo, hi, spec.unit), "{line}");
                    }
                    (_, other) => panic!("`{line}` ({end:?} end {lo}..{hi}): {other:?}"),
                }
                checked += 1;
            }
        }
    }
    // Every row, both ends: 2 values a real row, 1 a whole row, 3 a sign row.
    let want: usize = PARAMS
        .iter()
        .map(|s| match s.value {
            ValueKind::Real { .. } => 4,
            ValueKind::Whole => 2,
            ValueKind::Sign => 3,
        })
        .sum();
    assert_eq!(checked, want);
}

#[test]
fn set_max_speed_one_step_above_its_maximum_is_refused() {
    // The case as an operator meets it: max_speed is 0.01..2 m/s, printed with 3 decimals.
    let mut b = Bench::new();
    for value in ["2.001", "2.0000000000000004"] {
        assert_eq!(
            b.send(&format!("set max_speed {value}")),
            "err 6: <value> must be within 0.01..2 m/s\r\n",
            "{value}"
        );
    }
    assert_eq!(
        b.send("set max_speed 2"),
        "ok max_speed = 2.000 m/s (not saved; save to keep)\r\n"
    );
}

#[test]
fn every_parameters_first_value_outside_its_range_leaves_the_setting_unchanged() {
    let mut b = Bench::new();
    for spec in &PARAMS {
        for end in [End::Low, End::High] {
            for value in first_outside(spec, end) {
                let before = b.session.settings().value(spec.name);
                let line = format!("set {} {value}", spec.wire);
                let reply = b.send(&line);
                let code = if spec.value == ValueKind::Sign {
                    "err 7: "
                } else {
                    "err 6: "
                };
                assert!(reply.starts_with(code), "`{line}`: {reply}");
                assert_eq!(b.session.settings().value(spec.name), before, "{line}");
            }
        }
    }
}
