//! Golden tests of the pure protocol layer: parsed commands, line assembly and the exact text of
//! every parse/line error reply.

use odocal::motion::run::Direction;
use odocal::protocol::command::UnitSetting;
use odocal::protocol::reply::{line_error_reply, parse_error_reply};
use odocal::protocol::unit::{Angle, AngleUnit, Length, LengthUnit};
use odocal::protocol::{
    Command, LINE_MAX, LineAssembler, LineError, LineEvent, ParamName, ParseError, StopKey,
};

/// A measured length typed bare.
const fn bare(value: f64) -> Length {
    Length { value, unit: None }
}

/// A measured length typed with its unit.
const fn length(value: f64, unit: LengthUnit) -> Length {
    Length {
        value,
        unit: Some(unit),
    }
}

fn err_text(line: &str) -> String {
    let e = Command::parse(line).expect_err("line should not parse");
    parse_error_reply(&e).as_str().to_owned()
}

/// Every command as documented in docs/protocol.md, with the value it parses to.
const DOCUMENTED_COMMANDS: &[(&str, Command<'static>)] = &[
    ("help", Command::Help),
    ("?", Command::Help),
    ("status", Command::Status),
    ("params", Command::Params),
    (
        "set wheelbase 0.4",
        Command::Set {
            name: ParamName::Wheelbase,
            value: 0.4,
        },
    ),
    (
        "set counts_per_rev 4096",
        Command::Set {
            name: ParamName::CountsPerRev,
            value: 4096.0,
        },
    ),
    // A whole number written as a decimal or with an exponent is that number.
    (
        "set counts_per_rev 200000.0",
        Command::Set {
            name: ParamName::CountsPerRev,
            value: 200_000.0,
        },
    ),
    (
        "set counts_per_rev 2e5",
        Command::Set {
            name: ParamName::CountsPerRev,
            value: 200_000.0,
        },
    ),
    ("drop +3.0", Command::Drop { index: 3 }),
    (
        "run cw",
        Command::Run {
            direction: Direction::Cw,
            side_m: None,
        },
    ),
    (
        "RUN CCW 1.5",
        Command::Run {
            direction: Direction::Ccw,
            side_m: Some(1.5),
        },
    ),
    ("next", Command::Next),
    ("line", Command::Line { length_m: None }),
    (
        "line 3",
        Command::Line {
            length_m: Some(3.0),
        },
    ),
    (
        "circle ccw 0.75",
        Command::Circle {
            direction: Direction::Ccw,
            radius_m: Some(0.75),
        },
    ),
    ("stop", Command::Stop),
    ("clear", Command::Clear),
    (
        "measure 0.0123 -0.045",
        Command::Measure {
            run: None,
            x: bare(0.0123),
            y: bare(-0.045),
            theta: None,
            confirmed: false,
        },
    ),
    (
        "measure\t-1e-3  2E-2   -1.5 yes",
        Command::Measure {
            run: None,
            x: bare(-0.001),
            y: bare(0.02),
            theta: Some(Angle {
                value: -1.5,
                unit: None,
            }),
            confirmed: true,
        },
    ),
    (
        "measure #2 -9.1 mm -9 MM 0.2 rad",
        Command::Measure {
            run: Some(2),
            x: length(-9.1, LengthUnit::Millimetre),
            y: length(-9.0, LengthUnit::Millimetre),
            theta: Some(Angle {
                value: 0.2,
                unit: Some(AngleUnit::Radian),
            }),
            confirmed: false,
        },
    ),
    (
        "measure 1m 2m yes",
        Command::Measure {
            run: None,
            x: length(1.0, LengthUnit::Metre),
            y: length(2.0, LengthUnit::Metre),
            theta: None,
            confirmed: true,
        },
    ),
    (
        "set measure_unit mm",
        Command::SetUnit(UnitSetting::Length(LengthUnit::Millimetre)),
    ),
    (
        "set HEADING_UNIT rad",
        Command::SetUnit(UnitSetting::Angle(AngleUnit::Radian)),
    ),
    ("runs", Command::Runs),
    ("drop 3", Command::Drop { index: 3 }),
    ("calibrate", Command::Calibrate { method: None }),
    (
        "calibrate exact",
        Command::Calibrate {
            method: Some("exact"),
        },
    ),
    (
        "apply lee-x",
        Command::Apply {
            method: "lee-x",
            confirmed: false,
        },
    ),
    (
        "apply LEE-Y yes",
        Command::Apply {
            method: "LEE-Y",
            confirmed: true,
        },
    ),
    // Factors computed elsewhere: `online` is the keyword, not a method's name.
    (
        "apply online 0.995 1.01 1",
        Command::ApplyFactors {
            e_d: 0.995,
            e_b: 1.01,
            e_s: 1.0,
        },
    ),
    (
        "APPLY Online 0.99512345 1.25 8e-1",
        Command::ApplyFactors {
            e_d: 0.995_123_45,
            e_b: 1.25,
            e_s: 0.8,
        },
    ),
    ("drop all", Command::DropAll { confirmed: false }),
    ("drop ALL yes", Command::DropAll { confirmed: true }),
    (
        "measure -5.356mm -5.4cm 2.5deg",
        Command::Measure {
            run: None,
            x: length(-5.356, LengthUnit::Millimetre),
            y: length(-5.4, LengthUnit::Centimetre),
            theta: Some(Angle {
                value: 2.5,
                unit: Some(AngleUnit::Degree),
            }),
            confirmed: false,
        },
    ),
    (
        "measure #2 0.05m 1e-3 0.5rad",
        Command::Measure {
            run: Some(2),
            x: length(0.05, LengthUnit::Metre),
            y: bare(1e-3),
            theta: Some(Angle {
                value: 0.5,
                unit: Some(AngleUnit::Radian),
            }),
            confirmed: false,
        },
    ),
    ("save", Command::Save),
    ("reset-params", Command::ResetParams { confirmed: false }),
    ("reset-params yes", Command::ResetParams { confirmed: true }),
    ("pose", Command::Pose),
    ("odom reset", Command::OdomReset),
    ("stream on", Command::Stream { on: Some(None) }),
    (
        "stream on 100",
        Command::Stream {
            on: Some(Some(100)),
        },
    ),
    ("stream off", Command::Stream { on: None }),
    (
        "drive 0.25 -0.5",
        Command::Drive {
            v_mps: 0.25,
            w_radps: -0.5,
        },
    ),
    ("  stop  ", Command::Stop),
    (
        "measure #3 0.01m -0.02m",
        Command::Measure {
            run: Some(3),
            x: length(0.01, LengthUnit::Metre),
            y: length(-0.02, LengthUnit::Metre),
            theta: None,
            confirmed: false,
        },
    ),
    (
        "MEASURE #40 1 2 -3",
        Command::Measure {
            run: Some(40),
            x: bare(1.0),
            y: bare(2.0),
            theta: Some(Angle {
                value: -3.0,
                unit: None,
            }),
            confirmed: false,
        },
    ),
    ("echo on", Command::Echo { on: true }),
    ("ECHO Off", Command::Echo { on: false }),
];

#[test]
fn commands_parse_to_the_documented_values() {
    for (line, expected) in DOCUMENTED_COMMANDS {
        assert_eq!(Command::parse(line).as_ref(), Ok(expected), "line {line:?}");
    }
}

/// Malformed lines and the exact error reply each gets.
const ERROR_REPLIES: &[(&str, &str)] = &[
    ("fly", "err 1: unknown command (try help)\r\n"),
    ("run", "err 2: missing argument <direction>\r\n"),
    ("measure 0.1", "err 2: missing argument <y>\r\n"),
    ("stop now", "err 3: too many arguments\r\n"),
    (
        "measure 0.1 0.2 3 4",
        "err 7: <confirmation> must be one of yes\r\n",
    ),
    (
        "measure 1mm 2mm 3deg yes 4",
        "err 3: too many arguments\r\n",
    ),
    (
        "measure 0,1 0.2",
        "err 4: <x> is not a number (use a decimal point)\r\n",
    ),
    // A measured value may carry its unit, but only one of its kind.
    (
        "measure 0.1 0.2deg",
        "err 4: <y> has an unknown unit (m, cm or mm after the number)\r\n",
    ),
    (
        "measure 41.8in 39.5mm -0.04",
        "err 4: <x> has an unknown unit (m, cm or mm after the number)\r\n",
    ),
    (
        "measure 0.1 0.2 3mm",
        "err 4: <theta> has an unknown unit (deg or rad after the number)\r\n",
    ),
    // A unit apart from its number is its unit; a word that is no unit is the next value.
    ("measure 1 mm 2 in", "err 4: <theta> is not a number\r\n"),
    (
        "set measure_unit in",
        "err 7: <value> must be one of mm|cm|m\r\n",
    ),
    (
        "set heading_unit mm",
        "err 7: <value> must be one of deg|rad\r\n",
    ),
    // Elsewhere a unit is still named as such.
    (
        "run cw 2m",
        "err 4: <side_m> is not a number (type the number alone, without a unit)\r\n",
    ),
    ("run cw abc", "err 4: <side_m> is not a number\r\n"),
    ("drop 1.5", "err 4: <n> is not a whole number\r\n"),
    ("drop -1", "err 6: <n> must be within 1..65535\r\n"),
    (
        "set counts_per_rev 2e5.5",
        "err 4: <value> is not a number\r\n",
    ),
    (
        "set runs_per_direction 2.5",
        "err 4: <value> is not a whole number\r\n",
    ),
    ("stream on 0x10", "err 4: <hz> is not a number\r\n"),
    // 20 significant digits: more than the parser's u64 mantissa holds.
    (
        "measure 0.12345678901234567891 0",
        "err 4: <x> has too many digits (at most 19 significant)\r\n",
    ),
    ("measure nan 0", "err 5: <x> must be finite\r\n"),
    ("measure NaN 0", "err 5: <x> must be finite\r\n"),
    ("measure 0 inf", "err 5: <y> must be finite\r\n"),
    ("measure 0 -infinity", "err 5: <y> must be finite\r\n"),
    ("measure 0 -1e999mm", "err 5: <y> must be finite\r\n"),
    ("drive 1e999 0", "err 5: <v_mps> must be finite\r\n"),
    ("set max_speed inf", "err 5: <value> must be finite\r\n"),
    ("run cw 0.05", "err 6: <side_m> must be within 0.1..10\r\n"),
    (
        "circle cw 11",
        "err 6: <radius_m> must be within 0.1..10\r\n",
    ),
    ("drive 2.5 0", "err 6: <v_mps> must be within -2..2\r\n"),
    (
        "drive 0 -10.5",
        "err 6: <w_radps> must be within -10..10\r\n",
    ),
    ("stream on 101", "err 6: <hz> must be within 1..100\r\n"),
    ("stream on 0", "err 6: <hz> must be within 1..100\r\n"),
    ("drop 0", "err 6: <n> must be within 1..65535\r\n"),
    ("drop 99999999999", "err 6: <n> must be within 1..65535\r\n"),
    (
        "set wheelbase 0",
        "err 6: <value> must be within 0.01..5 m\r\n",
    ),
    // Millimetres typed for metres: the range names the unit.
    (
        "set wheelbase 385",
        "err 6: <value> must be within 0.01..5 m\r\n",
    ),
    (
        "set d_right -0.15",
        "err 6: <value> must be within 0.001..2 m\r\n",
    ),
    (
        "set runs_per_direction 7",
        "err 6: <value> must be within 1..6 runs\r\n",
    ),
    ("measure #0 0 0", "err 6: <n> must be within 1..65535\r\n"),
    (
        "measure #65536 0 0",
        "err 6: <n> must be within 1..65535\r\n",
    ),
    ("measure #x 0 0", "err 4: <n> is not a number\r\n"),
    ("measure # 0 0", "err 4: <n> is not a number\r\n"),
    ("measure #2 0", "err 2: missing argument <y>\r\n"),
    ("measure #2 0 0 1 yes 2", "err 3: too many arguments\r\n"),
    ("echo", "err 2: missing argument <mode>\r\n"),
    ("echo loud", "err 7: <mode> must be one of on|off\r\n"),
    ("run left", "err 7: <direction> must be one of cw|ccw\r\n"),
    ("stream maybe", "err 7: <mode> must be one of on|off\r\n"),
    ("odom zero", "err 7: <action> must be one of reset\r\n"),
    (
        "set color red",
        "err 7: <name> must be one of the parameters listed by params\r\n",
    ),
    (
        "set squareside 1",
        "err 7: <name> must be one of the parameters listed by params; did you mean \
         square_side?\r\n",
    ),
    (
        "drop all now",
        "err 7: <confirmation> must be one of yes\r\n",
    ),
    (
        "apply exact please",
        "err 7: <confirmation> must be one of yes\r\n",
    ),
    (
        "apply ex@ct",
        "err 7: <method> must be one of a method name listed by calibrate\r\n",
    ),
    ("apply online", "err 2: missing argument <E_d>\r\n"),
    (
        "apply online 1 2",
        "err 6: <E_b> must be within 0.8..1.25\r\n",
    ),
    ("apply online 1 1", "err 2: missing argument <E_s>\r\n"),
    ("apply online 1 1 1 yes", "err 3: too many arguments\r\n"),
    ("apply online nan 1 1", "err 5: <E_d> must be finite\r\n"),
    ("apply online 1 -inf 1", "err 5: <E_b> must be finite\r\n"),
    ("apply online 1 1 1e999", "err 5: <E_s> must be finite\r\n"),
    ("apply online 1 x 1", "err 4: <E_b> is not a number\r\n"),
    (
        "apply online 1 1 0,9",
        "err 4: <E_s> is not a number (use a decimal point)\r\n",
    ),
    (
        "apply online 1.5 1 1",
        "err 6: <E_d> must be within 0.8..1.25\r\n",
    ),
    (
        "apply online 1 1 0.79999999",
        "err 6: <E_s> must be within 0.8..1.25\r\n",
    ),
];

#[test]
fn error_replies_are_exact() {
    for (line, expected) in ERROR_REPLIES {
        assert_eq!(err_text(line), *expected, "line {line:?}");
    }
}

#[test]
fn blank_lines_are_empty_not_errors() {
    assert_eq!(Command::parse(""), Err(ParseError::Empty));
    assert_eq!(Command::parse(" \t "), Err(ParseError::Empty));
}

/// What the assembler reported, as owned values.
#[derive(Debug, PartialEq)]
enum Got {
    Line(String),
    Rejected(LineError, bool),
    Stop(StopKey),
}

/// Feeds `bytes`, collecting each event.
fn feed<const N: usize>(asm: &mut LineAssembler<N>, bytes: &[u8]) -> Vec<Got> {
    let mut out = Vec::new();
    for &b in bytes {
        if let Some(e) = asm.push(b) {
            out.push(match e {
                LineEvent::Line(t) => Got::Line(t.to_owned()),
                LineEvent::Rejected { error, stop } => Got::Rejected(error, stop),
                LineEvent::Stop(k) => Got::Stop(k),
            });
        }
    }
    out
}

/// Feeds `bytes` and returns the concatenated echo.
fn echo_of<const N: usize>(asm: &mut LineAssembler<N>, bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    for &b in bytes {
        let _ = asm.push(b);
        out.extend_from_slice(asm.echo().bytes());
    }
    out
}

fn line(s: &str) -> Got {
    Got::Line(s.to_owned())
}

#[test]
fn assembler_ends_lines_at_cr_lf_and_crlf() {
    let mut asm = LineAssembler::<LINE_MAX>::new();
    // CR (picocom, screen, minicom on Enter), LF, CR LF: one line each; CR LF is not two.
    let lines = feed(&mut asm, b"status\rparams\nrun cw 2\r\n\r\npose\r");
    assert_eq!(
        lines,
        vec![
            line("status"),
            line("params"),
            line("run cw 2"),
            line(""),
            line("pose")
        ]
    );
    // The LF completing that last CR LF is swallowed; a second LF is an empty line.
    assert_eq!(feed(&mut asm, b"\n"), vec![]);
    assert_eq!(feed(&mut asm, b"\n"), vec![line("")]);
    // LF CR is two line ends.
    assert_eq!(feed(&mut asm, b"help\n\r"), vec![line("help"), line("")]);
    assert!(asm.is_empty());
}

#[test]
fn assembler_backspace_erases() {
    let mut asm = LineAssembler::<LINE_MAX>::new();
    assert_eq!(feed(&mut asm, b"stoq\x08p\n"), vec![line("stop")]);
    assert_eq!(feed(&mut asm, b"\x7f\x7fpose\r"), vec![line("pose")]);
}

#[test]
fn ctrl_c_discards_the_line_and_asks_for_a_stop() {
    let mut asm = LineAssembler::<LINE_MAX>::new();
    assert_eq!(
        feed(&mut asm, b"measure 1.5\x03stop\r"),
        vec![Got::Stop(StopKey::CtrlC), line("stop")]
    );
    // Also in the middle of an escape sequence, and of an over-long line.
    let mut small = LineAssembler::<8>::new();
    assert_eq!(
        feed(&mut small, b"0123456789\x1b[1\x03pose\r"),
        vec![
            Got::Stop(StopKey::Escape),
            Got::Stop(StopKey::CtrlC),
            line("pose")
        ]
    );
}

#[test]
fn escape_sequences_are_consumed_whole_and_ask_for_a_stop() {
    let mut asm = LineAssembler::<LINE_MAX>::new();
    // Arrows (CSI and SS3), F5, Ctrl-Right, Home; a lone Esc; the line survives them all.
    let keys = b"st\x1b[A\x1bOBo\x1b[15~\x1b[1;5C\x1b[H\x1bp\r";
    let esc = Got::Stop(StopKey::Escape);
    assert_eq!(
        feed(&mut asm, keys),
        vec![
            Got::Stop(StopKey::Escape),
            Got::Stop(StopKey::Escape),
            Got::Stop(StopKey::Escape),
            Got::Stop(StopKey::Escape),
            Got::Stop(StopKey::Escape),
            esc,
            line("stop")
        ]
    );
    // Other control bytes never reach the line; Tab is a separator.
    assert_eq!(
        feed(&mut asm, b"\x00\x04run\tcw\x01\r"),
        vec![line("run\tcw")]
    );
    // A control byte ends a sequence and counts: CR inside a CSI still ends the line.
    assert_eq!(
        feed(&mut asm, b"pose\x1b[1\r"),
        vec![Got::Stop(StopKey::Escape), line("pose")]
    );
}

#[test]
fn receive_errors_reject_the_line_at_its_terminator() {
    let mut asm = LineAssembler::<LINE_MAX>::new();
    for at in 0..="measure 1.502".len() {
        let text = b"measure 1.502";
        let mut got = feed(&mut asm, &text[..at]);
        asm.receive_error();
        got.extend(feed(&mut asm, &text[at..]));
        got.extend(feed(&mut asm, b"\r"));
        assert_eq!(
            got,
            vec![Got::Rejected(LineError::ReceiveError, false)],
            "error before byte {at}"
        );
        // The next line is clean.
        assert_eq!(feed(&mut asm, b"pose\r"), vec![line("pose")]);
    }
    // A garbled line that still ends in the word stop is flagged, so the session stops.
    asm.receive_error();
    assert_eq!(
        feed(&mut asm, b"xx StOp\r"),
        vec![Got::Rejected(LineError::ReceiveError, true)]
    );
    assert_eq!(
        feed(&mut asm, b"stop\xff stop\r"),
        vec![Got::Rejected(LineError::NotUtf8, true)]
    );
    assert_eq!(
        feed(&mut asm, b"nonstop\xff\r"),
        vec![Got::Rejected(LineError::NotUtf8, false)]
    );
}

#[test]
fn echo_shows_what_was_accepted() {
    let mut asm = LineAssembler::<LINE_MAX>::new();
    assert_eq!(echo_of(&mut asm, b"stoq\x08p\r\n"), b"stoq\x08 \x08p\r\n");
    // Backspace on an empty line, escape sequences and control bytes echo nothing.
    assert_eq!(echo_of(&mut asm, b"\x7f\x1b[A\x00x\t\x03"), b"x ^C\r\n");
    assert_eq!(echo_of(&mut asm, b"\n"), b"\r\n");
}

#[test]
fn over_long_lines_are_rejected_whole_once() {
    let mut asm = LineAssembler::<8>::new();
    // Exactly 8 bytes fit, with either terminator.
    assert_eq!(feed(&mut asm, b"stop    \n"), vec![line("stop    ")]);
    assert_eq!(feed(&mut asm, b"stop    \r\n"), vec![line("stop    ")]);
    // 9 bytes: rejected as a whole, once, at the terminator; never a truncated "drive 1 ".
    assert_eq!(feed(&mut asm, b"drive 1 1"), vec![]);
    assert!(asm.is_overflowed());
    assert_eq!(
        feed(&mut asm, b" more text\r\n"),
        vec![Got::Rejected(LineError::TooLong, false)]
    );
    // The next line is unaffected.
    assert_eq!(feed(&mut asm, b"stop\n"), vec![line("stop")]);
}

#[test]
fn line_error_replies_are_exact() {
    assert_eq!(
        line_error_reply(&LineError::TooLong).as_str(),
        "err 8: line too long (max 80 bytes), ignored\r\n"
    );
    let mut asm = LineAssembler::<LINE_MAX>::new();
    let lines = feed(&mut asm, b"pose\xff\n");
    assert_eq!(lines, vec![Got::Rejected(LineError::NotUtf8, false)]);
    assert_eq!(
        line_error_reply(&LineError::NotUtf8).as_str(),
        "err 9: line is not valid UTF-8, ignored\r\n"
    );
    assert_eq!(
        line_error_reply(&LineError::ReceiveError).as_str(),
        "err 21: receive error (overrun, framing or noise) in this line, ignored\r\n"
    );
}

#[test]
fn every_parameter_name_round_trips() {
    for p in ParamName::ALL {
        assert_eq!(ParamName::from_name(p.as_str()), Some(p));
        let (min, max) = p.range();
        assert!(min < max, "{}", p.as_str());
        let line = format!("set {} {}", p.as_str(), max);
        assert_eq!(
            Command::parse(&line),
            Ok(Command::Set {
                name: p,
                value: max
            })
        );
    }
}

/// The `version` reply reads back as written; a device that is not an odocal board, or one that
/// does not say its protocol, reads as such.
#[test]
fn the_version_reply_reads_back() {
    use odocal::protocol::record::{PROTOCOL_VERSION, Version, parse_version, write_version};
    let mut reply = String::new();
    write_version(&mut reply).unwrap();
    let text = reply.strip_prefix("ok ").unwrap().trim_end();
    assert_eq!(
        parse_version(text),
        Some(Version {
            firmware: env!("CARGO_PKG_VERSION"),
            protocol: Some(PROTOCOL_VERSION),
        })
    );
    assert_eq!(parse_version("marlin 2.1"), None);
    assert_eq!(
        parse_version("odocal 0.1.0").map(|v| v.protocol),
        Some(None)
    );
}
