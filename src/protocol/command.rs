//! Command parser: one text line in, one validated [`Command`] out.
//!
//! Tokens are separated by ASCII whitespace; keywords are ASCII case-insensitive. Every number is
//! checked here: malformed text (including more than 19 significant digits, see
//! [`super::number`]), NaN/infinity (including overflow such as `1e999`) and values
//! outside the documented ranges are distinct errors, so nothing downstream ever sees a
//! non-finite or absurd value. Units on the wire: metres, m/s, rad/s, degrees (headings), Hz;
//! a measured end pose carries its units (`mm`, `cm`, `m`; `deg`, `rad`), see [`super::unit`].

use super::command_values::{finite, in_range, number, sign, unit_error, whole};
use super::param::ParamName;
pub use super::parse_error::{NumberHint, ParseError};
use super::unit::{
    Angle, AngleUnit, Length, LengthUnit, angle_unit, length_unit, parse_angle, parse_length,
};
use crate::motion::bringup::CheckKind;
use crate::motion::convention::Convention;
use crate::motion::identify::IdentifyMode;
use crate::motion::run::Direction;
use crate::storage::record::{METHOD_NAME_MAX, STORED_FACTOR_RANGE};
pub use crate::util::text::keyword_eq;

/// Largest accepted `|x|`, `|y|` of a measurement, metres.
pub const MEASURE_LIMIT_M: f64 = 100.0;
/// Largest accepted `|θ|` of a measurement, degrees.
pub const MEASURE_LIMIT_DEG: f64 = 360.0;
/// Accepted square side / line length / circle radius, metres.
pub const PATH_RANGE_M: (f64, f64) = (0.1, 10.0);
/// Largest accepted `|v|` of `drive`, m/s (the controller applies its own, tighter limits).
pub const DRIVE_LIMIT_MPS: f64 = 2.0;
/// Largest accepted `|ω|` of `drive`, rad/s.
pub const DRIVE_LIMIT_RADPS: f64 = 10.0;
/// Accepted pose-stream rates, Hz.
pub const STREAM_RANGE_HZ: (u32, u32) = (1, 100);
/// The method name of factors computed elsewhere (`apply online <E_d> <E_b> <E_s>`): the word
/// after `apply` and the name the calibration is stored under.
pub const ONLINE: &str = "online";
/// Largest run number: runs keep the number they started with for the whole session (a dropped
/// run leaves a gap), so numbers go beyond the store's size.
pub const RUN_NUMBER_MAX: u32 = u16::MAX as u32;

/// A parsed command. Optional arguments are `None` when omitted (the session fills defaults).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command<'a> {
    /// `help`: list the commands.
    Help,
    /// `status`: state, pose, faults, session progress.
    Status,
    /// `params`: list every parameter and the active calibration.
    Params,
    /// `set <name> <value>`: change one parameter (validated range).
    Set {
        /// Which parameter.
        name: ParamName,
        /// The new value, within `name.range()`.
        value: f64,
    },
    /// `run cw|ccw [L]`: drive one UMBmark square.
    Run {
        /// Turn direction.
        direction: Direction,
        /// Side, metres; `None` = the planned side.
        side_m: Option<f64>,
    },
    /// `next`: start the next planned square run (what the button's short press does).
    Next,
    /// `line [d]`: drive straight for `d` metres.
    Line {
        /// Length, metres; `None` = the planned square side.
        length_m: Option<f64>,
    },
    /// `circle cw|ccw [r]`: drive one full circle.
    Circle {
        /// Turn direction.
        direction: Direction,
        /// Radius, metres; `None` = half the planned square side.
        radius_m: Option<f64>,
    },
    /// `stop`: abort any motion now.
    Stop,
    /// `clear`: clear a latched fault.
    Clear,
    /// `measure [#n] <x> <y> [theta] [yes]`: the true end pose of the last finished run, or of
    /// run `n` (which replaces its measurement); each value with its unit (written against the
    /// number or apart from it) unless the session declared one.
    Measure {
        /// Run number (`#n`, as `runs` lists it); `None` = the last finished run, if it is
        /// unmeasured.
        run: Option<usize>,
        /// True x in the run's start frame, as typed.
        x: Length,
        /// True y in the run's start frame, as typed.
        y: Length,
        /// True heading, as typed, if measured.
        theta: Option<Angle>,
        /// `yes` was typed last: keep a measurement beyond the plausibility bound.
        confirmed: bool,
    },
    /// `set measure_unit mm|cm|m` / `set heading_unit deg|rad`: the unit of the bare values of
    /// `measure` for this session (never saved).
    SetUnit(UnitSetting),
    /// `runs`: list the stored runs.
    Runs,
    /// `record <n> [first]`: run `n`'s full record (path, geometry, odometry end, measurement)
    /// and up to [`super::record::RECORD_PAGE_KNOTS`] of its tick knots from knot `first`, for a
    /// host that keeps the runs (lossless: `f64` as IEEE bits in hex).
    Record {
        /// 1-based run number (as `runs` shows it).
        index: usize,
        /// First knot of this page (0-based).
        first_knot: usize,
    },
    /// `version`: firmware and protocol version, for a host tool to check what it talks to.
    Version,
    /// `drop <n>`: delete stored run number `n` (1-based, as `runs` shows).
    Drop {
        /// 1-based run number.
        index: usize,
    },
    /// `drop all [yes]`: delete every stored run (a fresh session; also forgotten in flash),
    /// only with `yes`.
    DropAll {
        /// `yes` was typed after it.
        confirmed: bool,
    },
    /// `convention [name]`: how every measured run is read from now on (`None`: say which is
    /// in force and the choices). The runs keep what was typed.
    Convention {
        /// The convention, `None` = ask.
        name: Option<Convention>,
    },
    /// `calibrate [method]`: compute every method (or one) from the measured runs.
    Calibrate {
        /// Method name as typed (the session checks it), `None` = all.
        method: Option<&'a str>,
    },
    /// `apply <method>`: use that method's result as the active geometry (not yet saved).
    Apply {
        /// Method name as typed (the session checks it).
        method: &'a str,
        /// `yes` was typed after it: apply even with a flagged run.
        confirmed: bool,
    },
    /// `apply online <E_d> <E_b> <E_s>`: use calibration factors computed elsewhere (the PC
    /// bridge's online estimate from the robot's localization) as the active geometry, stored
    /// under the method name [`ONLINE`] (not yet saved); each factor within the range a stored
    /// record holds.
    ApplyFactors {
        /// Diameter ratio `E_d = D_R / D_L`.
        e_d: f32,
        /// Wheelbase factor `E_b = b_actual / b_nominal`.
        e_b: f32,
        /// Mean-diameter scale `E_s`.
        e_s: f32,
    },
    /// `save`: write the parameters to flash (motors must be stopped).
    Save,
    /// `reset-params [yes]`: restore the defaults in RAM (not saved); `yes` is needed when it
    /// would discard an applied calibration or an unsaved change.
    ResetParams {
        /// `yes` was typed after it.
        confirmed: bool,
    },
    /// `pose`: the odometry pose.
    Pose,
    /// `bringup [motors|push]`: the wiring check (motor pulses with the wheels off the ground,
    /// or a hand push with the motors off).
    Bringup {
        /// Which check.
        kind: CheckKind,
    },
    /// `identify [lifted|floor]`: motor identification (wheels off the ground, default, or the
    /// robot on the floor); the result becomes the speed-loop tuning.
    Identify {
        /// Where the robot is.
        mode: IdentifyMode,
    },
    /// `odom reset`: set the odometry pose to the origin.
    OdomReset,
    /// `stream on [hz]` / `stream off`.
    Stream {
        /// `Some(rate)` to start (rate `None` = default), `None` to stop.
        on: Option<Option<u32>>,
    },
    /// `echo on|off`: whether received characters are echoed back (for a person at a terminal).
    Echo {
        /// `true` = echo on.
        on: bool,
    },
    /// `drive <v_mps> <w_radps>`: velocity command with a 500 ms deadman.
    Drive {
        /// Forward speed, m/s.
        v_mps: f32,
        /// Turn rate, rad/s, CCW positive.
        w_radps: f32,
    },
}

/// A unit declared for the bare values of `measure` (`set measure_unit`, `set heading_unit`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UnitSetting {
    /// The unit of bare x and y.
    Length(LengthUnit),
    /// The unit of a bare heading.
    Angle(AngleUnit),
}

/// Checks a measured end pose, converted to metres and degrees, against the accepted ranges
/// ([`MEASURE_LIMIT_M`], [`MEASURE_LIMIT_DEG`]).
///
/// # Errors
/// [`ParseError::OutOfRange`] naming the first value outside.
pub fn check_measure_range(x_m: f64, y_m: f64, theta_deg: Option<f64>) -> Result<(), ParseError> {
    in_range(x_m, "x", -MEASURE_LIMIT_M, MEASURE_LIMIT_M)?;
    in_range(y_m, "y", -MEASURE_LIMIT_M, MEASURE_LIMIT_M)?;
    if let Some(t) = theta_deg {
        in_range(t, "theta", -MEASURE_LIMIT_DEG, MEASURE_LIMIT_DEG)?;
    }
    Ok(())
}

/// Cursor over the whitespace-separated words of a line.
struct Words<'a> {
    inner: core::str::SplitAsciiWhitespace<'a>,
}

impl<'a> Words<'a> {
    // Out of line: called from a dozen argument readers.
    #[inline(never)]
    fn next(&mut self) -> Option<&'a str> {
        self.inner.next()
    }

    /// Takes the next word if `kind` reads it (a unit typed apart from its number).
    fn take_if<T>(&mut self, kind: impl Fn(&str) -> Option<T>) -> Option<T> {
        let mut ahead = self.inner.clone();
        let found = ahead.next().and_then(kind)?;
        self.inner = ahead;
        Some(found)
    }

    fn required(&mut self, what: &'static str) -> Result<&'a str, ParseError> {
        self.next().ok_or(ParseError::MissingArgument { what })
    }

    fn end(&mut self) -> Result<(), ParseError> {
        match self.next() {
            None => Ok(()),
            Some(_) => Err(ParseError::TooManyArguments),
        }
    }
}

/// A measured length: a number with `m`, `cm`, `mm` written after it or as the next word, or a
/// bare number (its unit the session's `measure_unit`); ranges are checked once converted.
fn measured_length(
    words: &mut Words<'_>,
    word: &str,
    what: &'static str,
) -> Result<Length, ParseError> {
    let mut l =
        parse_length(word).map_err(|e| unit_error(e, word, what, NumberHint::LengthUnit))?;
    finite(l.value, what)?;
    if l.unit.is_none() {
        l.unit = words.take_if(length_unit);
    }
    Ok(l)
}

/// A measured heading: a number with `deg`, `rad` written after it or as the next word, or a
/// bare number (its unit the session's `heading_unit`).
fn measured_angle(
    words: &mut Words<'_>,
    word: &str,
    what: &'static str,
) -> Result<Angle, ParseError> {
    let mut a = parse_angle(word).map_err(|e| unit_error(e, word, what, NumberHint::AngleUnit))?;
    finite(a.value, what)?;
    if a.unit.is_none() {
        a.unit = words.take_if(angle_unit);
    }
    Ok(a)
}

/// `yes` as an optional last word (a confirmation); any other word is refused.
fn confirmation(words: &mut Words<'_>) -> Result<bool, ParseError> {
    match words.next() {
        None => Ok(false),
        Some(w) if keyword_eq(w, "yes") => Ok(true),
        Some(_) => Err(ParseError::BadKeyword {
            what: "confirmation",
            expected: "yes",
        }),
    }
}

fn optional_number(
    words: &mut Words<'_>,
    what: &'static str,
    (min, max): (f64, f64),
) -> Result<Option<f64>, ParseError> {
    words.next().map(|w| number(w, what, min, max)).transpose()
}

fn direction(word: &str) -> Result<Direction, ParseError> {
    if keyword_eq(word, "cw") {
        Ok(Direction::Cw)
    } else if keyword_eq(word, "ccw") {
        Ok(Direction::Ccw)
    } else {
        Err(ParseError::BadKeyword {
            what: "direction",
            expected: "cw|ccw",
        })
    }
}

/// A method name: 1..=[`METHOD_NAME_MAX`] bytes of `[a-z0-9_-]` (any case): no longer than the
/// parameter record stores (every method's name is shorter).
fn method_name(word: &str) -> Result<&str, ParseError> {
    let ok = word.len() <= METHOD_NAME_MAX
        && word
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_');
    if ok {
        Ok(word)
    } else {
        Err(ParseError::BadKeyword {
            what: "method",
            expected: "a method name listed by calibrate",
        })
    }
}

/// `apply online <E_d> <E_b> <E_s>`: each factor within the range a stored record holds
/// ([`STORED_FACTOR_RANGE`]), so finite as an `f32` too.
fn apply_online<'a>(words: &mut Words<'a>) -> Result<Command<'a>, ParseError> {
    let (min, max) = (*STORED_FACTOR_RANGE.start(), *STORED_FACTOR_RANGE.end());
    let mut factors = [0.0; 3];
    for (factor, what) in factors.iter_mut().zip(["E_d", "E_b", "E_s"]) {
        *factor = number(words.required(what)?, what, min, max)? as f32;
    }
    let [e_d, e_b, e_s] = factors;
    Ok(Command::ApplyFactors { e_d, e_b, e_s })
}

/// `set <name> <value>`, `set measure_unit <unit>`, `set heading_unit <unit>`.
fn set<'a>(words: &mut Words<'a>) -> Result<Command<'a>, ParseError> {
    let name_word = words.required("name")?;
    if keyword_eq(name_word, "measure_unit") {
        let unit = length_unit(words.required("value")?).ok_or(ParseError::BadKeyword {
            what: "value",
            expected: "mm|cm|m",
        })?;
        words.end()?;
        return Ok(Command::SetUnit(UnitSetting::Length(unit)));
    }
    if keyword_eq(name_word, "heading_unit") {
        let unit = angle_unit(words.required("value")?).ok_or(ParseError::BadKeyword {
            what: "value",
            expected: "deg|rad",
        })?;
        words.end()?;
        return Ok(Command::SetUnit(UnitSetting::Angle(unit)));
    }
    let name = ParamName::from_name(name_word).ok_or(ParseError::UnknownParam {
        suggestion: ParamName::nearest(name_word),
    })?;
    let value_word = words.required("value")?;
    let (min, max) = name.range();
    let value = if name.is_sign() {
        sign(value_word)
    } else if name.is_integer() {
        // Integer ranges are small enough to be exact in f64 and u32.
        whole(value_word, "value", min as u32, max as u32).map(f64::from)
    } else if name.unit() == "m" {
        // A length takes the unit suffixes `measure` takes (`151mm`, `15.1cm`, `0.151m`); a
        // bare number is in metres, the parameter's listed unit.
        measured_length(words, value_word, "value").and_then(|l| {
            let m = l.metres(Some(LengthUnit::Metre)).unwrap_or(l.value);
            in_range(m, "value", min, max)
        })
    } else if name.unit() == "deg" {
        // An angle takes `measure`'s angle suffixes (`0.2deg`, `0.0035rad`); a bare number is
        // in degrees, the parameter's listed unit.
        measured_angle(words, value_word, "value").and_then(|a| {
            let deg = a.degrees(Some(AngleUnit::Degree)).unwrap_or(a.value);
            in_range(deg, "value", min, max)
        })
    } else {
        number(value_word, "value", min, max)
    }
    // `<value>` does not say its unit; the range does (`0.01..5 m` for 385 typed in mm).
    .map_err(|e| match e {
        ParseError::OutOfRange { what, min, max, .. } => ParseError::OutOfRange {
            what,
            min,
            max,
            unit: name.unit(),
        },
        e => e,
    })?;
    Ok(Command::Set { name, value })
}

/// `measure [#n] <x> <y> [theta] [yes]`.
fn measure<'a>(words: &mut Words<'a>) -> Result<Command<'a>, ParseError> {
    let mut first = words.required("x")?;
    let run = match first.strip_prefix('#') {
        Some(n) => {
            let index = whole(n, "n", 1, RUN_NUMBER_MAX)? as usize;
            first = words.required("x")?;
            Some(index)
        }
        None => None,
    };
    let x = measured_length(words, first, "x")?;
    let y_word = words.required("y")?;
    let y = measured_length(words, y_word, "y")?;
    let (theta, confirmed) = match words.next() {
        None => (None, false),
        Some(w) if keyword_eq(w, "yes") => (None, true),
        Some(w) => (
            Some(measured_angle(words, w, "theta")?),
            confirmation(words)?,
        ),
    };
    Ok(Command::Measure {
        run,
        x,
        y,
        theta,
        confirmed,
    })
}

/// `record <n> [first]`.
fn record<'a>(words: &mut Words<'a>) -> Result<Command<'a>, ParseError> {
    let index = whole(words.required("n")?, "n", 1, RUN_NUMBER_MAX)? as usize;
    let last = crate::motion::run::MAX_KNOTS as u32 - 1;
    let first_knot = words
        .next()
        .map(|w| whole(w, "first", 0, last))
        .transpose()?
        .unwrap_or(0) as usize;
    Ok(Command::Record { index, first_knot })
}

/// `bringup [motors|push]`.
fn bringup<'a>(words: &mut Words<'a>) -> Result<Command<'a>, ParseError> {
    let kind = match words.next() {
        None => CheckKind::Pulses,
        Some(w) if keyword_eq(w, "motors") => CheckKind::Pulses,
        Some(w) if keyword_eq(w, "push") => CheckKind::Push,
        Some(_) => {
            return Err(ParseError::BadKeyword {
                what: "check",
                expected: "motors|push",
            });
        }
    };
    Ok(Command::Bringup { kind })
}

/// `identify [lifted|floor]`.
fn identify<'a>(words: &mut Words<'a>) -> Result<Command<'a>, ParseError> {
    let mode = match words.next() {
        None => IdentifyMode::Lifted,
        Some(w) if keyword_eq(w, "lifted") => IdentifyMode::Lifted,
        Some(w) if keyword_eq(w, "floor") => IdentifyMode::Floor,
        Some(_) => {
            return Err(ParseError::BadKeyword {
                what: "mode",
                expected: "lifted|floor",
            });
        }
    };
    Ok(Command::Identify { mode })
}

/// `stream on [hz]` / `stream off`.
fn stream<'a>(words: &mut Words<'a>) -> Result<Command<'a>, ParseError> {
    let mode = words.required("mode")?;
    Ok(if keyword_eq(mode, "on") {
        let (min, max) = STREAM_RANGE_HZ;
        let hz = words.next().map(|w| whole(w, "hz", min, max)).transpose()?;
        Command::Stream { on: Some(hz) }
    } else if keyword_eq(mode, "off") {
        Command::Stream { on: None }
    } else {
        return Err(ParseError::BadKeyword {
            what: "mode",
            expected: "on|off",
        });
    })
}

/// `drive <v_mps> <w_radps>`.
fn drive<'a>(words: &mut Words<'a>) -> Result<Command<'a>, ParseError> {
    let v = number(
        words.required("v_mps")?,
        "v_mps",
        -DRIVE_LIMIT_MPS,
        DRIVE_LIMIT_MPS,
    )?;
    let w = number(
        words.required("w_radps")?,
        "w_radps",
        -DRIVE_LIMIT_RADPS,
        DRIVE_LIMIT_RADPS,
    )?;
    Ok(Command::Drive {
        v_mps: v as f32,
        w_radps: w as f32,
    })
}

impl<'a> Command<'a> {
    /// Parses one line (without its terminator).
    ///
    /// # Errors
    /// A [`ParseError`] naming the first problem found; [`ParseError::Empty`] for a blank line.
    pub fn parse(line: &'a str) -> Result<Command<'a>, ParseError> {
        let mut words = Words {
            inner: line.split_ascii_whitespace(),
        };
        let Some(head) = words.next() else {
            return Err(ParseError::Empty);
        };
        let is = |name: &str| keyword_eq(head, name);
        let cmd = if is("help") || head == "?" {
            Command::Help
        } else if is("status") {
            Command::Status
        } else if is("params") {
            Command::Params
        } else if is("set") {
            set(&mut words)?
        } else if is("run") {
            let direction = direction(words.required("direction")?)?;
            let side_m = optional_number(&mut words, "side_m", PATH_RANGE_M)?;
            Command::Run { direction, side_m }
        } else if is("next") {
            Command::Next
        } else if is("line") {
            Command::Line {
                length_m: optional_number(&mut words, "length_m", PATH_RANGE_M)?,
            }
        } else if is("circle") {
            let direction = direction(words.required("direction")?)?;
            let radius_m = optional_number(&mut words, "radius_m", PATH_RANGE_M)?;
            Command::Circle {
                direction,
                radius_m,
            }
        } else if is("stop") {
            Command::Stop
        } else if is("clear") {
            Command::Clear
        } else if is("measure") {
            measure(&mut words)?
        } else if is("runs") {
            Command::Runs
        } else if is("record") {
            record(&mut words)?
        } else if is("version") {
            Command::Version
        } else if is("drop") {
            let which = words.next().ok_or(ParseError::DropWhich)?;
            if keyword_eq(which, "all") {
                Command::DropAll {
                    confirmed: confirmation(&mut words)?,
                }
            } else {
                let index = whole(which, "n", 1, RUN_NUMBER_MAX)? as usize;
                Command::Drop { index }
            }
        } else if is("convention") {
            let name = words
                .next()
                .map(|w| {
                    Convention::parse(w).ok_or(ParseError::BadKeyword {
                        what: "convention",
                        expected: Convention::NAMES,
                    })
                })
                .transpose()?;
            Command::Convention { name }
        } else if is("calibrate") {
            let method = words.next().map(method_name).transpose()?;
            Command::Calibrate { method }
        } else if is("apply") {
            let method = words.required("method")?;
            if keyword_eq(method, ONLINE) {
                apply_online(&mut words)?
            } else {
                Command::Apply {
                    method: method_name(method)?,
                    confirmed: confirmation(&mut words)?,
                }
            }
        } else if is("save") {
            Command::Save
        } else if is("reset-params") {
            Command::ResetParams {
                confirmed: confirmation(&mut words)?,
            }
        } else if is("pose") {
            Command::Pose
        } else if is("bringup") {
            bringup(&mut words)?
        } else if is("identify") {
            identify(&mut words)?
        } else if is("odom") {
            let what = words.required("action")?;
            if !keyword_eq(what, "reset") {
                return Err(ParseError::BadKeyword {
                    what: "action",
                    expected: "reset",
                });
            }
            Command::OdomReset
        } else if is("stream") {
            stream(&mut words)?
        } else if is("echo") {
            let mode = words.required("mode")?;
            let on = if keyword_eq(mode, "on") {
                true
            } else if keyword_eq(mode, "off") {
                false
            } else {
                return Err(ParseError::BadKeyword {
                    what: "mode",
                    expected: "on|off",
                });
            };
            Command::Echo { on }
        } else if is("drive") {
            drive(&mut words)?
        } else {
            return Err(ParseError::UnknownCommand);
        };
        words.end()?;
        Ok(cmd)
    }
}
