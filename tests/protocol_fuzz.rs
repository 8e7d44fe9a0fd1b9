//! Property test: 1,000,000 random byte sequences through the line assembler and the parser.
//!
//! Properties checked on every sequence:
//! - nothing panics;
//! - the assembler never holds more than its capacity;
//! - for a line without editing bytes (backspace/DEL, interior `\r`), the assembler's verdict
//!   matches an independent oracle: the exact text if it fits, `TooLong` if not — an over-long
//!   line is never truncated and passed on;
//! - every accepted command carries only finite, in-range numbers;
//! - every rejected line formats to one `err <code>: ` reply line.
//!
//! A quarter of the sequences are raw random bytes, half are random protocol words and tricky
//! numbers, and a quarter are commands with the right arity and random numbers, so the parser's
//! deeper paths are exercised too. The generator is a seeded
//! xorshift64*, so a failure is reproducible from the printed sequence index.

use odocal::protocol::command::{
    DRIVE_LIMIT_MPS, DRIVE_LIMIT_RADPS, MEASURE_LIMIT_DEG, MEASURE_LIMIT_M, PATH_RANGE_M,
    STREAM_RANGE_HZ,
};
use odocal::protocol::reply::parse_error_reply;
use odocal::protocol::{Command, LineAssembler, LineError, ParseError};
use odocal::session::MAX_RUNS;

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
const SEPARATORS: &[&[u8]] = &[b" ", b"  ", b"\t", b"\n", b"\r\n", b"\r", b"\x08", b"\x7f"];

/// Command templates with the right number of arguments; `#` is replaced by a number word.
const TEMPLATES: &[&str] = &[
    "measure # #",
    "measure # # #",
    "drive # #",
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
];

fn template(rng: &mut Rng, buf: &mut Vec<u8>) {
    let t = TEMPLATES[rng.below(TEMPLATES.len() as u64) as usize];
    for part in t.split(' ') {
        let word = if part == "#" {
            NUMBERS[rng.below(NUMBERS.len() as u64) as usize]
        } else {
            part
        };
        buf.extend_from_slice(word.as_bytes());
        buf.push(b' ');
    }
    buf.extend_from_slice(b"\r\n");
}

fn random_sequence(rng: &mut Rng, buf: &mut Vec<u8>) {
    buf.clear();
    let mode = rng.below(4);
    if mode == 0 {
        template(rng, buf);
    } else if mode == 1 {
        let len = rng.below(3 * CAP as u64) as usize;
        for _ in 0..len {
            // Bias towards line feeds so that lines complete often.
            let b = if rng.below(16) == 0 {
                b'\n'
            } else {
                rng.next() as u8
            };
            buf.push(b);
        }
    } else {
        let words = 1 + rng.below(6);
        for _ in 0..words {
            buf.extend_from_slice(WORDS[rng.below(WORDS.len() as u64) as usize].as_bytes());
            let sep = if rng.below(3) == 0 {
                SEPARATORS[rng.below(SEPARATORS.len() as u64) as usize]
            } else {
                b" "
            };
            buf.extend_from_slice(sep);
        }
        if rng.below(8) == 0 {
            // An over-long run of digits.
            for _ in 0..rng.below(2 * CAP as u64) {
                buf.push(b'0' + rng.below(10) as u8);
            }
        }
        buf.extend_from_slice(if rng.below(2) == 0 { b"\n" } else { b"\r\n" });
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
        Command::Measure {
            x_m,
            y_m,
            theta_deg,
        } => {
            let m = (-MEASURE_LIMIT_M, MEASURE_LIMIT_M);
            within(x_m, m)
                && within(y_m, m)
                && theta_deg.is_none_or(|t| within(t, (-MEASURE_LIMIT_DEG, MEASURE_LIMIT_DEG)))
        }
        Command::Drop { index } => (1..=MAX_RUNS).contains(&index),
        Command::Stream { on: Some(Some(hz)) } => {
            (STREAM_RANGE_HZ.0..=STREAM_RANGE_HZ.1).contains(&hz)
        }
        Command::Drive { v_mps, w_radps } => {
            within(f64::from(v_mps), (-DRIVE_LIMIT_MPS, DRIVE_LIMIT_MPS))
                && within(f64::from(w_radps), (-DRIVE_LIMIT_RADPS, DRIVE_LIMIT_RADPS))
        }
        _ => true,
    };
    assert!(ok, "out-of-range value accepted: {cmd:?}");
}

/// The oracle for one raw line (bytes between two `\n`): `None` when it holds editing bytes.
fn oracle(raw: &[u8]) -> Option<Result<Vec<u8>, LineError>> {
    let body = raw.strip_suffix(b"\r").unwrap_or(raw);
    if body.iter().any(|&b| b == b'\r' || b == 0x08 || b == 0x7f) {
        return None;
    }
    if body.len() > CAP {
        return Some(Err(LineError::TooLong));
    }
    Some(match std::str::from_utf8(body) {
        Ok(_) => Ok(body.to_vec()),
        Err(_) => Err(LineError::NotUtf8),
    })
}

#[test]
fn million_random_sequences() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut asm = LineAssembler::<CAP>::new();
    let mut seq = Vec::with_capacity(4 * CAP);
    let mut raw_line: Vec<u8> = Vec::new();
    let (mut lines, mut parsed, mut oracle_checked, mut too_long) = (0u64, 0u64, 0u64, 0u64);
    for i in 0..SEQUENCES {
        random_sequence(&mut rng, &mut seq);
        for &b in &seq {
            let result = asm.push(b).map(|r| r.map(str::to_owned));
            assert!(
                asm.len() <= CAP,
                "sequence {i}: assembler holds {}",
                asm.len()
            );
            if b != b'\n' {
                raw_line.push(b);
                assert!(result.is_none());
                continue;
            }
            let result = result.expect("a line feed always completes a line");
            lines += 1;
            if let Some(expected) = oracle(&raw_line) {
                oracle_checked += 1;
                let got = result.clone().map(String::into_bytes);
                assert_eq!(got, expected, "sequence {i}: raw line {raw_line:?}");
            }
            raw_line.clear();
            match result {
                Err(LineError::TooLong) => too_long += 1,
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
    // measured counts are far above these floors (1.89 M lines, 78 k commands, 123 k over-long); the floors
    // only catch a generator that stopped producing lines, commands or over-long lines.
    assert!(lines > 500_000, "{lines} lines");
    assert!(parsed > 10_000, "{parsed} commands parsed");
    assert!(
        oracle_checked > 100_000,
        "{oracle_checked} lines checked by the oracle"
    );
    assert!(too_long > 10_000, "{too_long} over-long lines");
    println!(
        "{SEQUENCES} sequences: {lines} lines, {oracle_checked} oracle-checked, {parsed} parsed \
         commands, {too_long} over-long; assembler size {} bytes",
        size_of::<LineAssembler<CAP>>()
    );
}
