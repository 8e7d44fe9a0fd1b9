//! Property test: 1,000,000 random byte sequences through the line assembler and the parser.
//!
//! The input alphabet is what a terminal and a noisy wire produce: printable text, CR, LF and
//! CR LF, Tab, Backspace/DEL, Ctrl-C, lone Esc, CSI and SS3 escape sequences (arrows, function
//! keys, over-long ones), other control bytes, invalid UTF-8, and receive errors (overrun,
//! framing, noise) between bytes.
//!
//! Properties checked on every sequence:
//! - nothing panics; the assembler never holds more than its capacity;
//! - every Ctrl-C yields `Stop(CtrlC)` and every Esc `Stop(Escape)`, whatever state it arrives in;
//! - every CR ends a line, and so does every LF except the one right after a CR;
//! - each line's verdict matches an independent two-phase oracle (escape sequences removed, then
//!   editing applied): the exact text if it fits, `TooLong` if not — an over-long line is never
//!   truncated and passed on —, `ReceiveError` if a receive error hit it, `NotUtf8`; a rejected
//!   line's `stop` flag says whether its last word was `stop`;
//! - every accepted command carries only finite, in-range numbers;
//! - every rejected line formats to one `err <code>: ` reply line.
//!
//! A quarter of the sequences are raw random bytes, half are random protocol words, tricky
//! numbers and terminal keys, and a quarter are commands with the right arity and random
//! numbers, so the parser's deeper paths are exercised too. The generator is a seeded
//! xorshift64*, so a failure is reproducible from the printed sequence index.

use odocal::protocol::command::{
    DRIVE_LIMIT_MPS, DRIVE_LIMIT_RADPS, PATH_RANGE_M, RUN_NUMBER_MAX, STREAM_RANGE_HZ,
};
use odocal::protocol::reply::parse_error_reply;
use odocal::protocol::{Command, LineAssembler, LineError, LineEvent, ParseError, StopKey};
use odocal::storage::record::STORED_FACTOR_RANGE;

const SEQUENCES: u64 = 1_000_000;
const CAP: usize = 40;

#[path = "support/rng.rs"]
mod rng;
use rng::Rng;

const WORDS: &[&str] = &[
    "help",
    "status",
    "params",
    "set",
    "run",
    "next",
    "line",
    "circle",
    "stop",
    "measure",
    "runs",
    "drop",
    "calibrate",
    "apply",
    "online",
    "save",
    "reset-params",
    "pose",
    "odom",
    "reset",
    "stream",
    "on",
    "off",
    "drive",
    "cw",
    "ccw",
    "CW",
    "exact",
    "lee-x",
    "d_right",
    "wheelbase",
    "counts_per_rev",
    "max_speed",
    "runs_per_direction",
    "0",
    "-0",
    "1",
    "2.5",
    "-3.75",
    "1e3",
    "1e-400",
    "1e999",
    "-1e999",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "infinity",
    "+5",
    ".5",
    "5.",
    "0x10",
    "1_0",
    "12",
    "13",
    "100",
    "101",
    "4294967296",
    "99999999999999999999",
    "-",
    "+",
    "e",
    "é",
    "\u{0}",
    "7",
    "0.001",
    "-100",
    "360",
    "-360.0001",
];
/// A receive error between bytes (not a byte value).
const RX_ERROR: u16 = 0x100;

const SEPARATORS: &[&[u8]] = &[
    b" ", b"  ", b"\t", b"\n", b"\r\n", b"\r", b"\x08", b"\x7f", b"\x03", b"\x1b",
];
/// Terminal keys: arrows, Home/End, function keys (CSI and SS3), Alt-x, an over-long CSI.
const KEYS: &[&[u8]] = &[
    b"\x1b[A",
    b"\x1b[B",
    b"\x1b[C",
    b"\x1b[D",
    b"\x1b[1;5C",
    b"\x1b[15~",
    b"\x1b[H",
    b"\x1bOP",
    b"\x1bOA",
    b"\x1bx",
    b"\x1b[0000000000000000000000000000000000000000A",
    b"\x03",
    b"\x00",
    b"\x04",
];

/// Command templates with the right number of arguments; `#` is replaced by a number word.
const TEMPLATES: &[&str] = &[
    "measure # #",
    "measure # # #",
    "drive # #",
    "apply online # # #",
    "set max_speed #",
    "set counts_per_rev #",
    "set d_left #",
    "run cw #",
    "run ccw #",
    "line #",
    "circle cw #",
    "stream on #",
    "drop #",
];
const NUMBERS: &[&str] = &[
    "0",
    "-0",
    "1",
    "2.5",
    "-3.75",
    "1e3",
    "1e-400",
    "1e999",
    "nan",
    "inf",
    "+5",
    ".5",
    "5.",
    "0x10",
    "12",
    "13",
    "100",
    "101",
    "4294967296",
    "7",
    "0.001",
    "-100",
    "360",
    "-360.0001",
    "0.3",
    "-1.5",
    "1e-3",
    "2E0",
    "10",
    "10.000001",
    "6",
    "5",
    "0.995",
    "1.25",
    "0.8",
];

fn template(rng: &mut Rng, buf: &mut Vec<u16>) {
    let t = TEMPLATES[rng.below(TEMPLATES.len() as u64) as usize];
    for part in t.split(' ') {
        let word = if part == "#" {
            NUMBERS[rng.below(NUMBERS.len() as u64) as usize]
        } else {
            part
        };
        bytes(buf, word.as_bytes());
        buf.push(u16::from(b' '));
    }
    bytes(buf, if rng.below(2) == 0 { b"\r" } else { b"\r\n" });
}

fn bytes(buf: &mut Vec<u16>, b: &[u8]) {
    buf.extend(b.iter().map(|&b| u16::from(b)));
}

fn random_sequence(rng: &mut Rng, buf: &mut Vec<u16>) {
    buf.clear();
    let mode = rng.below(4);
    if mode == 0 {
        template(rng, buf);
    } else if mode == 1 {
        let len = rng.below(3 * CAP as u64) as usize;
        for _ in 0..len {
            // Bias towards terminators so that lines complete often.
            let b = match rng.below(32) {
                0 | 1 => u16::from(b'\n'),
                2 | 3 => u16::from(b'\r'),
                4 => RX_ERROR,
                _ => u16::from(rng.next() as u8),
            };
            buf.push(b);
        }
    } else {
        let words = 1 + rng.below(6);
        for _ in 0..words {
            bytes(
                buf,
                WORDS[rng.below(WORDS.len() as u64) as usize].as_bytes(),
            );
            let sep = match rng.below(12) {
                0..=3 => SEPARATORS[rng.below(SEPARATORS.len() as u64) as usize],
                4 => KEYS[rng.below(KEYS.len() as u64) as usize],
                _ => b" ",
            };
            bytes(buf, sep);
            if rng.below(40) == 0 {
                buf.push(RX_ERROR);
            }
        }
        if rng.below(8) == 0 {
            // An over-long run of digits.
            for _ in 0..rng.below(2 * CAP as u64) {
                buf.push(u16::from(b'0') + rng.below(10) as u16);
            }
        }
        bytes(
            buf,
            match rng.below(3) {
                0 => b"\n",
                1 => b"\r",
                _ => b"\r\n",
            },
        );
    }
}

fn within(v: f64, (min, max): (f64, f64)) -> bool {
    v.is_finite() && v >= min && v <= max
}

fn check_command(cmd: &Command<'_>) {
    let ok = match *cmd {
        Command::Set { name, value } => within(value, name.range()),
        Command::Run { side_m, .. } => side_m.is_none_or(|v| within(v, PATH_RANGE_M)),
        Command::Line { length_m } => length_m.is_none_or(|v| within(v, PATH_RANGE_M)),
        Command::Circle { radius_m, .. } => radius_m.is_none_or(|v| within(v, PATH_RANGE_M)),
        // Ranges of measured values are checked once their unit is known (the session's).
        Command::Measure {
            run, x, y, theta, ..
        } => {
            let any = (f64::MIN, f64::MAX);
            run.is_none_or(|n| (1..=RUN_NUMBER_MAX as usize).contains(&n))
                && within(x.value, any)
                && within(y.value, any)
                && theta.is_none_or(|t| within(t.value, any))
        }
        Command::Drop { index } => (1..=RUN_NUMBER_MAX as usize).contains(&index),
        Command::Stream { on: Some(Some(hz)) } => {
            (STREAM_RANGE_HZ.0..=STREAM_RANGE_HZ.1).contains(&hz)
        }
        Command::ApplyFactors { e_d, e_b, e_s } => [e_d, e_b, e_s]
            .iter()
            .all(|&e| STORED_FACTOR_RANGE.contains(&f64::from(e))),
        Command::Drive { v_mps, w_radps } => {
            within(f64::from(v_mps), (-DRIVE_LIMIT_MPS, DRIVE_LIMIT_MPS))
                && within(f64::from(w_radps), (-DRIVE_LIMIT_RADPS, DRIVE_LIMIT_RADPS))
        }
        _ => true,
    };
    assert!(ok, "out-of-range value accepted: {cmd:?}");
}

/// The verdict of the oracle for one line: its inputs after the previous terminator (or
/// Ctrl-C), without its own terminator.
#[derive(Debug, PartialEq)]
enum Verdict {
    Line(Vec<u8>),
    Rejected(LineError, Option<bool>),
}

/// Phase 1: removes escape sequences (`ESC [` up to 32 parameter/intermediate bytes and a final
/// byte, `ESC O` and one printable byte, or a lone `ESC`). A control byte or a receive error
/// ends a sequence; the control byte counts as typed.
fn strip_escapes(raw: &[u16]) -> Vec<u16> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < raw.len() {
        if raw[i] != 0x1b {
            out.push(raw[i]);
            i += 1;
            continue;
        }
        i += 1; // the ESC
        match raw.get(i) {
            Some(&0x5b) => {
                i += 1;
                let mut n = 0;
                while n < 32 && raw.get(i).is_some_and(|&b| (0x20..=0x3f).contains(&b)) {
                    i += 1;
                    n += 1;
                }
                if raw.get(i).is_some_and(|&b| (0x40..=0x7e).contains(&b)) {
                    i += 1;
                }
            }
            Some(&0x4f) => {
                i += 1;
                if raw.get(i).is_some_and(|&b| (0x20..=0x7e).contains(&b)) {
                    i += 1;
                }
            }
            _ => {}
        }
    }
    out
}

/// Phase 2: editing, overflow, receive errors, UTF-8.
fn oracle(raw: &[u16]) -> Verdict {
    let keys = strip_escapes(raw);
    let mut line: Vec<u8> = Vec::new();
    let mut typed: Vec<u8> = Vec::new(); // everything stored, never truncated
    let (mut overflowed, mut poisoned, mut edited) = (false, false, false);
    for &k in &keys {
        match k {
            RX_ERROR => poisoned = true,
            0x08 | 0x7f => {
                edited = true;
                if !overflowed {
                    line.pop();
                }
            }
            0x09 => {
                typed.push(b'\t');
                if !overflowed {
                    line.push(b'\t');
                }
            }
            0x00..=0x1f => {}
            b => {
                let b = b as u8;
                typed.push(b);
                if !overflowed {
                    line.push(b);
                }
            }
        }
        if line.len() > CAP {
            overflowed = true;
            line.clear();
        }
    }
    let last_word_is_stop = typed
        .split(|&b| b == b' ' || b == b'\t')
        .next_back()
        .is_some_and(|w| w.eq_ignore_ascii_case(b"stop"));
    // After a backspace the flag is only a hint: not checked.
    let stop = (!edited).then_some(last_word_is_stop);
    if overflowed {
        Verdict::Rejected(LineError::TooLong, stop)
    } else if poisoned {
        Verdict::Rejected(LineError::ReceiveError, stop)
    } else if std::str::from_utf8(&line).is_err() {
        Verdict::Rejected(LineError::NotUtf8, stop)
    } else {
        Verdict::Line(line)
    }
}

#[test]
fn million_random_sequences() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut asm = LineAssembler::<CAP>::new();
    let mut seq = Vec::with_capacity(4 * CAP);
    let mut raw_line: Vec<u16> = Vec::new();
    let mut prev: u16 = 0;
    let (mut lines, mut parsed, mut too_long, mut stops, mut poisoned) =
        (0u64, 0u64, 0u64, 0u64, 0u64);
    for i in 0..SEQUENCES {
        random_sequence(&mut rng, &mut seq);
        for &input in &seq {
            let last = std::mem::replace(&mut prev, input);
            if input == RX_ERROR {
                asm.receive_error();
                raw_line.push(RX_ERROR);
                continue;
            }
            let b = input as u8;
            let result = asm.push(b).map(|e| match e {
                LineEvent::Line(t) => Ok(t.to_owned()),
                LineEvent::Rejected { error, stop } => Err((Some(error), stop)),
                LineEvent::Stop(k) => Err((None, k == StopKey::CtrlC)),
            });
            assert!(
                asm.len() <= CAP,
                "sequence {i}: assembler holds {}",
                asm.len()
            );
            match b {
                0x03 => {
                    assert_eq!(result, Some(Err((None, true))), "sequence {i}: Ctrl-C");
                    stops += 1;
                    raw_line.clear();
                    continue;
                }
                0x1b => {
                    assert_eq!(result, Some(Err((None, false))), "sequence {i}: Esc");
                    stops += 1;
                    raw_line.push(input);
                    continue;
                }
                b'\n' if last == u16::from(b'\r') => {
                    assert_eq!(result, None, "sequence {i}: LF after CR");
                    continue;
                }
                b'\r' | b'\n' => {}
                _ => {
                    assert_eq!(
                        result, None,
                        "sequence {i}: byte {b:#x} completed something"
                    );
                    raw_line.push(input);
                    continue;
                }
            }
            let result = result.expect("a line terminator always completes a line");
            lines += 1;
            let expected = oracle(&raw_line);
            let got = match &result {
                Ok(text) => Verdict::Line(text.clone().into_bytes()),
                Err((Some(e), stop)) => Verdict::Rejected(
                    *e,
                    match expected {
                        Verdict::Rejected(_, None) => None,
                        _ => Some(*stop),
                    },
                ),
                Err((None, _)) => panic!("sequence {i}: a terminator gave a stop"),
            };
            assert_eq!(got, expected, "sequence {i}: raw line {raw_line:?}");
            raw_line.clear();
            match result {
                Err((Some(LineError::TooLong), _)) => too_long += 1,
                Err((Some(LineError::ReceiveError), _)) => poisoned += 1,
                Err(_) => {}
                Ok(text) => {
                    assert!(text.len() <= CAP);
                    match Command::parse(&text) {
                        Ok(cmd) => {
                            parsed += 1;
                            check_command(&cmd);
                        }
                        Err(ParseError::Empty) => {}
                        Err(e) => {
                            let reply = parse_error_reply(&e);
                            assert!(reply.starts_with("err "), "{reply}");
                            assert!(reply.ends_with("\r\n"), "{reply}");
                        }
                    }
                }
            }
        }
    }
    // Sanity of the generator itself: the run must exercise every branch many times. The
    // floors only catch a generator that stopped producing lines, commands, over-long lines,
    // stop keys or receive errors (measured counts are printed).
    assert!(lines > 500_000, "{lines} lines");
    assert!(parsed > 10_000, "{parsed} commands parsed");
    assert!(too_long > 10_000, "{too_long} over-long lines");
    assert!(stops > 10_000, "{stops} stop keys");
    assert!(poisoned > 10_000, "{poisoned} lines with receive errors");
    println!(
        "{SEQUENCES} sequences: {lines} lines (all oracle-checked), {parsed} parsed commands, \
         {too_long} over-long, {poisoned} with receive errors, {stops} stop keys; assembler size \
         {} bytes",
        size_of::<LineAssembler<CAP>>()
    );
}
