//! The other direction of [`super::command`]: a [`Command`] written as the line the board's
//! parser reads back as the same command. A host builds the commands it sends as values and
//! writes them with this (`command.to_string()`), so what it sends is what the board parses:
//! the round-trip test below covers every command.
//!
//! Numbers are written in Rust's shortest form that reads back to the same value (never with an
//! exponent, at most 17 significant digits: within the parser's
//! [`MAX_DIGITS`](super::number::MAX_DIGITS)); the `f32` values of `drive` and `apply online`
//! likewise, which read back through `f64` to the same `f32`. A measured length or heading keeps the unit it was
//! typed with (a bare value stays bare: its unit is the session's). Optional arguments that were
//! omitted stay omitted.

use core::fmt;

use super::command::{Command, ONLINE, UnitSetting};
use super::unit::{Angle, Length};
use crate::motion::bringup::CheckKind;
use crate::motion::identify::IdentifyMode;

impl fmt::Display for Command<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Command::Help => f.write_str("help"),
            Command::Status => f.write_str("status"),
            Command::Params => f.write_str("params"),
            Command::Set { name, value } => write!(f, "set {} {value}", name.as_str()),
            Command::Run { direction, side_m } => {
                write!(f, "run {}", direction.as_str())?;
                optional(f, side_m)
            }
            Command::Next => f.write_str("next"),
            Command::Line { length_m } => {
                f.write_str("line")?;
                optional(f, length_m)
            }
            Command::Circle {
                direction,
                radius_m,
            } => {
                write!(f, "circle {}", direction.as_str())?;
                optional(f, radius_m)
            }
            Command::Stop => f.write_str("stop"),
            Command::Clear => f.write_str("clear"),
            Command::Measure {
                run,
                x,
                y,
                theta,
                confirmed,
            } => {
                f.write_str("measure")?;
                if let Some(n) = run {
                    write!(f, " #{n}")?;
                }
                write!(f, " {} {}", Typed::length(x), Typed::length(y))?;
                if let Some(t) = theta {
                    write!(f, " {}", Typed::angle(t))?;
                }
                yes(f, confirmed)
            }
            Command::SetUnit(UnitSetting::Length(u)) => {
                write!(f, "set measure_unit {}", u.symbol())
            }
            Command::SetUnit(UnitSetting::Angle(u)) => write!(f, "set heading_unit {}", u.symbol()),
            Command::Runs => f.write_str("runs"),
            Command::Record { index, first_knot } => write!(f, "record {index} {first_knot}"),
            Command::Version => f.write_str("version"),
            Command::Drop { index } => write!(f, "drop {index}"),
            Command::DropAll { confirmed } => {
                f.write_str("drop all")?;
                yes(f, confirmed)
            }
            Command::Convention { name } => {
                f.write_str("convention")?;
                match name {
                    Some(c) => write!(f, " {}", c.as_str()),
                    None => Ok(()),
                }
            }
            Command::Calibrate { method } => {
                f.write_str("calibrate")?;
                match method {
                    Some(m) => write!(f, " {m}"),
                    None => Ok(()),
                }
            }
            Command::Apply { method, confirmed } => {
                write!(f, "apply {method}")?;
                yes(f, confirmed)
            }
            Command::ApplyFactors { e_d, e_b, e_s } => {
                write!(f, "apply {ONLINE} {e_d} {e_b} {e_s}")
            }
            Command::Save => f.write_str("save"),
            Command::ResetParams { confirmed } => {
                f.write_str("reset-params")?;
                yes(f, confirmed)
            }
            Command::Pose => f.write_str("pose"),
            Command::Bringup { kind } => f.write_str(match kind {
                CheckKind::Push => "bringup push",
                // The motor pulses are `bringup`'s default. Identification is its own command;
                // `bringup` names only the wiring checks.
                CheckKind::Pulses | CheckKind::Identify(_) => "bringup",
            }),
            Command::Identify { mode } => f.write_str(match mode {
                IdentifyMode::Lifted => "identify lifted",
                IdentifyMode::Floor => "identify floor",
            }),
            Command::OdomReset => f.write_str("odom reset"),
            Command::Stream { on: None } => f.write_str("stream off"),
            Command::Stream { on: Some(hz) } => {
                f.write_str("stream on")?;
                match hz {
                    Some(hz) => write!(f, " {hz}"),
                    None => Ok(()),
                }
            }
            Command::Echo { on } => f.write_str(if on { "echo on" } else { "echo off" }),
            Command::Drive { v_mps, w_radps } => write!(f, "drive {v_mps} {w_radps}"),
        }
    }
}

/// ` <value>` when given.
fn optional(f: &mut fmt::Formatter<'_>, value: Option<f64>) -> fmt::Result {
    match value {
        Some(v) => write!(f, " {v}"),
        None => Ok(()),
    }
}

/// ` yes` when confirmed.
fn yes(f: &mut fmt::Formatter<'_>, confirmed: bool) -> fmt::Result {
    if confirmed {
        f.write_str(" yes")
    } else {
        Ok(())
    }
}

/// A measured value as typed: the number and its unit's symbol against it (`-5.356mm`,
/// `2.5deg`), or bare.
struct Typed(f64, Option<&'static str>);

impl Typed {
    fn length(l: Length) -> Typed {
        Typed(l.value, l.unit.map(|u| u.symbol()))
    }

    fn angle(a: Angle) -> Typed {
        Typed(a.value, a.unit.map(|u| u.symbol()))
    }
}

impl fmt::Display for Typed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}{}", self.0, self.1.unwrap_or(""))
    }
}

#[cfg(test)]
mod tests {
    use std::string::ToString;
    use std::vec::Vec;

    use super::*;
    use crate::motion::run::Direction;
    use crate::protocol::param::ParamName;
    use crate::protocol::unit::{AngleUnit, LengthUnit};

    /// The commands' variants, by position: the match has no wildcard, so a new command does
    /// not compile until it is given a place here (and then a case in the round trip).
    fn variant(c: &Command<'_>) -> usize {
        match c {
            Command::Help => 0,
            Command::Status => 1,
            Command::Params => 2,
            Command::Set { .. } => 3,
            Command::Run { .. } => 4,
            Command::Next => 5,
            Command::Line { .. } => 6,
            Command::Circle { .. } => 7,
            Command::Stop => 8,
            Command::Clear => 9,
            Command::Measure { .. } => 10,
            Command::SetUnit(_) => 11,
            Command::Runs => 12,
            Command::Record { .. } => 13,
            Command::Version => 14,
            Command::Drop { .. } => 15,
            Command::DropAll { .. } => 16,
            Command::Calibrate { .. } => 17,
            Command::Apply { .. } => 18,
            Command::Save => 19,
            Command::ResetParams { .. } => 20,
            Command::Pose => 21,
            Command::Bringup { .. } => 22,
            Command::Identify { .. } => 23,
            Command::OdomReset => 24,
            Command::Stream { .. } => 25,
            Command::Echo { .. } => 26,
            Command::Drive { .. } => 27,
            Command::Convention { .. } => 28,
            Command::ApplyFactors { .. } => 29,
        }
    }
    const VARIANTS: usize = 30;

    /// Every parameter at the ends and the middle of its range (signs at ±1, whole numbers
    /// whole), as `set` commands.
    fn every_set() -> Vec<Command<'static>> {
        let mut all = Vec::new();
        for name in ParamName::ALL {
            let (min, max) = name.range();
            let values = if name.is_sign() {
                [-1.0, 1.0, 1.0]
            } else if name.is_integer() {
                [min, libm::round(0.5 * (min + max)), max]
            } else {
                [min, 0.1 * min + 0.9 * max, max]
            };
            all.extend(values.map(|value| Command::Set { name, value }));
        }
        all
    }

    /// Every `measure` form: units against the number, bare values, run numbers, headings and
    /// confirmations.
    fn every_measure() -> Vec<Command<'static>> {
        let mm = |value| Length {
            value,
            unit: Some(LengthUnit::Millimetre),
        };
        let bare = |value| Length { value, unit: None };
        std::vec![
            Command::Measure {
                run: None,
                x: mm(-5.356),
                y: mm(1e-3),
                theta: None,
                confirmed: false,
            },
            Command::Measure {
                run: Some(65_535),
                x: Length {
                    value: 0.3,
                    unit: Some(LengthUnit::Centimetre),
                },
                y: Length {
                    value: -0.1 - 0.2,
                    unit: Some(LengthUnit::Metre),
                },
                theta: Some(Angle {
                    value: -2.3,
                    unit: Some(AngleUnit::Degree),
                }),
                confirmed: true,
            },
            Command::Measure {
                run: Some(3),
                x: bare(41.8),
                y: bare(-39.5),
                theta: Some(Angle {
                    value: 0.04,
                    unit: None,
                }),
                confirmed: false,
            },
            Command::Measure {
                run: None,
                x: mm(1.0),
                y: mm(2.0),
                theta: Some(Angle {
                    value: 0.5,
                    unit: Some(AngleUnit::Radian),
                }),
                confirmed: true,
            },
            Command::Measure {
                run: None,
                x: mm(1.0),
                y: mm(2.0),
                theta: None,
                confirmed: true,
            },
        ]
    }

    /// Every other command, with every optional argument both given and omitted, and values
    /// that need many digits.
    fn every_other() -> Vec<Command<'static>> {
        std::vec![
            Command::Help,
            Command::Status,
            Command::Params,
            Command::Run {
                direction: Direction::Cw,
                side_m: None,
            },
            Command::Run {
                direction: Direction::Ccw,
                side_m: Some(1.0 / 3.0 + 1.0),
            },
            Command::Next,
            Command::Line { length_m: None },
            Command::Line {
                length_m: Some(0.1),
            },
            Command::Circle {
                direction: Direction::Ccw,
                radius_m: Some(9.999_999_999_999_998),
            },
            Command::Circle {
                direction: Direction::Cw,
                radius_m: None,
            },
            Command::Stop,
            Command::Clear,
            Command::SetUnit(UnitSetting::Length(LengthUnit::Millimetre)),
            Command::SetUnit(UnitSetting::Length(LengthUnit::Centimetre)),
            Command::SetUnit(UnitSetting::Length(LengthUnit::Metre)),
            Command::SetUnit(UnitSetting::Angle(AngleUnit::Degree)),
            Command::SetUnit(UnitSetting::Angle(AngleUnit::Radian)),
            Command::Runs,
            Command::Record {
                index: 12,
                first_knot: 0,
            },
            Command::Record {
                index: 1,
                first_knot: 40,
            },
            Command::Version,
            Command::Drop { index: 7 },
            Command::DropAll { confirmed: false },
            Command::DropAll { confirmed: true },
            Command::Calibrate { method: None },
            Command::Calibrate {
                method: Some("exact"),
            },
            Command::Convention { name: None },
            Command::Apply {
                method: "jung-chung",
                confirmed: false,
            },
            Command::Apply {
                method: "umbmark",
                confirmed: true,
            },
            Command::ApplyFactors {
                e_d: 0.995_123_45,
                e_b: 1.0,
                e_s: 1.000_000_1,
            },
            Command::ApplyFactors {
                e_d: 0.8,
                e_b: 1.25,
                e_s: 10.0 / 9.0,
            },
            Command::Save,
            Command::ResetParams { confirmed: false },
            Command::ResetParams { confirmed: true },
            Command::Pose,
            Command::Bringup {
                kind: CheckKind::Pulses,
            },
            Command::Bringup {
                kind: CheckKind::Push,
            },
            Command::Identify {
                mode: IdentifyMode::Lifted,
            },
            Command::Identify {
                mode: IdentifyMode::Floor,
            },
            Command::OdomReset,
            Command::Stream { on: None },
            Command::Stream { on: Some(None) },
            Command::Stream {
                on: Some(Some(100))
            },
            Command::Echo { on: true },
            Command::Echo { on: false },
            Command::Drive {
                v_mps: 0.3,
                w_radps: -1.0 / 3.0,
            },
            Command::Drive {
                v_mps: -2.0,
                w_radps: 10.0,
            },
        ]
    }

    /// Every command written and parsed back: the same command.
    #[test]
    fn every_command_round_trips_through_its_line() {
        let mut commands = every_other();
        commands.extend(every_measure());
        commands.extend(every_set());
        commands.extend(
            crate::motion::convention::Convention::ALL
                .map(|c| Command::Convention { name: Some(c) }),
        );
        let mut covered = [false; VARIANTS];
        for c in &commands {
            let line = c.to_string();
            assert_eq!(Command::parse(&line), Ok(*c), "`{line}`");
            covered[variant(c)] = true;
        }
        assert!(
            covered.iter().all(|&c| c),
            "a command without a case: {covered:?}"
        );
        assert_eq!(commands.len(), 58 + 3 * ParamName::ALL.len());
    }

    /// The lines a person types and the writer's agree on the spelling the docs use.
    #[test]
    fn lines_are_written_as_the_protocol_documents_them() {
        let measure = Command::Measure {
            run: Some(4),
            x: Length {
                value: -5.356,
                unit: Some(LengthUnit::Millimetre),
            },
            y: Length {
                value: 12.0,
                unit: Some(LengthUnit::Centimetre),
            },
            theta: Some(Angle {
                value: 2.5,
                unit: Some(AngleUnit::Degree),
            }),
            confirmed: true,
        };
        assert_eq!(measure.to_string(), "measure #4 -5.356mm 12cm 2.5deg yes");
        let set = Command::Set {
            name: ParamName::DiameterRight,
            value: 0.151,
        };
        assert_eq!(set.to_string(), "set d_right 0.151");
        assert_eq!(
            Command::Stream { on: Some(Some(50)) }.to_string(),
            "stream on 50"
        );
        let online = Command::ApplyFactors {
            e_d: 0.995,
            e_b: 1.01,
            e_s: 1.0,
        };
        assert_eq!(online.to_string(), "apply online 0.995 1.01 1");
    }
}
