//! Reply formatting and the error-code table.
//!
//! Every command is answered by exactly one final line, `ok[ <text>]` or
//! `err <code>: <message>`, possibly preceded by data lines (which never start with `ok` or
//! `err`). Lines end with `\r\n`. Unsolicited lines start with `event ` (session events such as a
//! finished run) or `stream ` (the pose stream). Everything is written through
//! `core::fmt::Write`, so a `heapless::String<N>`, a transmit queue or a `std::String` can
//! receive it; a full `heapless::String` makes the write return `Err`, never panic.

use core::fmt::{self, Write};

use super::command::ParseError;
use super::line::LineError;

/// Line terminator of every reply line.
///
/// Format strings spell it as `\r\n` inside the literal rather than as an `{EOL}` argument: a
/// line without other arguments then compiles to a single `write_str`, and no call site pays
/// for an extra argument (−868 B of flash; docs/performance.md, Firmware footprint).
pub const EOL: &str = "\r\n";

/// Capacity that fits any single reply line, bytes.
pub const REPLY_LINE_MAX: usize = 160;

/// One reply line.
pub type ReplyLine = heapless::String<REPLY_LINE_MAX>;

/// Numeric error codes of `err <code>: <message>`; stable across versions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum ErrorCode {
    /// 1: the first word is not a command.
    UnknownCommand = 1,
    /// 2: a required argument is missing.
    MissingArgument = 2,
    /// 3: more arguments than the command takes.
    TooManyArguments = 3,
    /// 4: a number could not be read.
    BadNumber = 4,
    /// 5: a number is NaN or infinite.
    NotFinite = 5,
    /// 6: a number is outside its range.
    OutOfRange = 6,
    /// 7: a keyword argument is not one of the accepted words.
    BadKeyword = 7,
    /// 8: the line was longer than the line buffer and was ignored.
    LineTooLong = 8,
    /// 9: the line is not valid UTF-8.
    NotUtf8 = 9,
    /// 10: the robot is busy (a run or drive is in progress) or refused to start.
    Busy = 10,
    /// 11: the controller has a latched fault.
    Fault = 11,
    /// 12: `measure` without a finished, unmeasured run to fill.
    NoRun = 12,
    /// 13: `calibrate`/`apply` without measured runs in both directions.
    NotEnoughRuns = 13,
    /// 14: `drop` of a run number that does not exist.
    NoSuchRun = 14,
    /// 15: the run store is full (drop runs first).
    StoreFull = 15,
    /// 16: a calibration method failed (degenerate data, no convergence, unknown method).
    CalibrationFailed = 16,
    /// 17: parameters refused: an inconsistent geometry (`set`), or a result that the parameter
    /// record would not store (`apply`, `save`).
    InvalidParams = 17,
    /// 18: `save`/`reset-params` while the motors run.
    MotorsRunning = 18,
    /// 19: the flash operation failed.
    Storage = 19,
    /// 20: the planned runs are all done (`next`).
    PlanComplete = 20,
    /// 21: a byte of the line was lost or garbled on the wire (overrun, framing, noise).
    ReceiveError = 21,
    /// 22: a measurement is implausible for its run (e.g. typed in millimetres).
    Implausible = 22,
    /// 23: the motor identification refused its result: the response was implausible (no
    /// motion, reversed, saturated, …); the tuning is unchanged and a fault is latched.
    IdentifyRefused = 23,
    /// 24: a run (`run`, `next`, `line`, `circle`, the button) while the last finished run is
    /// not measured: measure it or drop it first.
    Unmeasured = 24,
    /// 25: the command needs a confirmation (`apply <method> yes` with a flagged run,
    /// `drop all yes`, `reset-params yes` discarding a change).
    NotConfirmed = 25,
    /// 26: a `measure` value without its unit while the session declares none (`set
    /// measure_unit`, `set heading_unit`).
    NoUnit = 26,
}

impl ErrorCode {
    /// The number on the wire (a `u32`: the replies print unsigned numbers through the `u32`
    /// formatter only).
    pub fn code(self) -> u32 {
        self as u32
    }
}

impl From<&ParseError> for ErrorCode {
    fn from(e: &ParseError) -> Self {
        match e {
            ParseError::Empty | ParseError::UnknownCommand => ErrorCode::UnknownCommand,
            ParseError::MissingArgument { .. } | ParseError::DropWhich => {
                ErrorCode::MissingArgument
            }
            ParseError::TooManyArguments => ErrorCode::TooManyArguments,
            ParseError::BadNumber { .. } => ErrorCode::BadNumber,
            ParseError::NotFinite { .. } => ErrorCode::NotFinite,
            ParseError::OutOfRange { .. } => ErrorCode::OutOfRange,
            ParseError::BadKeyword { .. } | ParseError::UnknownParam { .. } => {
                ErrorCode::BadKeyword
            }
        }
    }
}

impl From<&LineError> for ErrorCode {
    fn from(e: &LineError) -> Self {
        match e {
            LineError::TooLong => ErrorCode::LineTooLong,
            LineError::NotUtf8 => ErrorCode::NotUtf8,
            LineError::ReceiveError => ErrorCode::ReceiveError,
        }
    }
}

/// The first word of a success reply's final line (alone: `ok`).
const OK: &str = "ok";
/// The first word of an error reply's final line, before its code.
const ERR: &str = "err ";
/// The indent of a data line (a reply's lines before its final line).
pub const DATA_INDENT: &str = "  ";

/// A reply's final line as a program reads it (terminator removed): `ok[ <text>]` or
/// `err <code>: <message>`, written by [`write_ok`] and [`write_err`]. Data lines ([`data`]),
/// events and stream lines are not final lines.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FinalLine<'a> {
    /// `ok` (empty text) or `ok <text>`.
    Ok(&'a str),
    /// `err <code>: <message>`.
    Err {
        /// The error code ([`ErrorCode::code`]).
        code: u32,
        /// The message after `: `.
        message: &'a str,
    },
}

impl<'a> FinalLine<'a> {
    /// `line` as a final line, or `None` for any other line.
    pub fn parse(line: &'a str) -> Option<Self> {
        if let Some(rest) = line.strip_prefix(OK) {
            return match rest.strip_prefix(' ') {
                Some(text) => Some(FinalLine::Ok(text)),
                None if rest.is_empty() => Some(FinalLine::Ok("")),
                None => None,
            };
        }
        let (code, message) = line.strip_prefix(ERR)?.split_once(':')?;
        Some(FinalLine::Err {
            code: code.parse().ok()?,
            message: message.strip_prefix(' ').unwrap_or(message),
        })
    }

    /// Whether this is an `ok` line.
    pub fn is_ok(self) -> bool {
        matches!(self, FinalLine::Ok(_))
    }

    /// Whether this is the error `code`.
    pub fn is_err(self, code: ErrorCode) -> bool {
        matches!(self, FinalLine::Err { code: c, .. } if c == code.code())
    }

    /// The text after `ok ` or the message after `err <code>: `.
    pub fn text(self) -> &'a str {
        match self {
            FinalLine::Ok(text) | FinalLine::Err { message: text, .. } => text,
        }
    }
}

/// A data line's content (its indent removed), or `None` for any other line.
pub fn data(line: &str) -> Option<&str> {
    line.strip_prefix(DATA_INDENT)
}

/// Writes `err <code>: <message>\r\n`.
///
/// # Errors
/// Only if `out` refuses the text (e.g. a full buffer).
// Out of line: a dozen reply paths share one copy of the formatting call.
#[inline(never)]
pub fn write_err(out: &mut dyn Write, code: ErrorCode, message: &dyn fmt::Display) -> fmt::Result {
    write!(out, "{ERR}{}: {}\r\n", code.code(), message)
}

/// Writes `ok <text>\r\n` with the text `body` writes straight to `out`: for a reply built
/// piece by piece or longer than [`REPLY_LINE_MAX`] (no line buffer).
///
/// # Errors
/// Only if `out` refuses the text.
#[inline(never)]
pub fn write_ok_with(
    out: &mut dyn Write,
    body: &mut dyn FnMut(&mut dyn Write) -> fmt::Result,
) -> fmt::Result {
    write!(out, "{OK} ")?;
    body(out)?;
    out.write_str(EOL)
}

/// Writes `ok\r\n` or `ok <text>\r\n`.
///
/// # Errors
/// Only if `out` refuses the text.
pub fn write_ok(out: &mut dyn Write, text: fmt::Arguments<'_>) -> fmt::Result {
    if text.as_str() == Some("") {
        write!(out, "{OK}\r\n")
    } else {
        write_ok_with(out, &mut |out| out.write_fmt(text))
    }
}

/// Formats the error reply for a line the assembler rejected into one [`ReplyLine`].
pub fn line_error_reply(e: &LineError) -> ReplyLine {
    let mut line = ReplyLine::new();
    let _ = write_err(&mut line, ErrorCode::from(e), e);
    line
}

/// Formats the error reply for a line that did not parse into one [`ReplyLine`].
pub fn parse_error_reply(e: &ParseError) -> ReplyLine {
    let mut line = ReplyLine::new();
    let _ = write_err(&mut line, ErrorCode::from(e), e);
    line
}

/// A `core::fmt::Write` that hands every byte to `push` (e.g. a transmit-queue `enqueue`).
///
/// A byte that `push` refuses (queue full) is counted in [`ByteSink::dropped`] and skipped; the
/// write still succeeds, so a full transmit queue never interrupts the command being executed.
pub struct ByteSink<F> {
    push: F,
    /// Bytes refused by `push` so far.
    pub dropped: usize,
}

impl<F: FnMut(u8) -> bool> ByteSink<F> {
    /// A sink over `push`, which returns `false` when it cannot take the byte.
    pub fn new(push: F) -> Self {
        ByteSink { push, dropped: 0 }
    }
}

impl<F: FnMut(u8) -> bool> Write for ByteSink<F> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for b in s.bytes() {
            if !(self.push)(b) {
                self.dropped += 1;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What [`write_ok`] and [`write_err`] write, [`FinalLine::parse`] reads back; data,
    /// event and stream lines are not final lines.
    #[test]
    fn final_lines_round_trip() {
        let mut s = heapless::String::<64>::new();
        write_ok(&mut s, format_args!("")).unwrap();
        assert_eq!(FinalLine::parse(s.trim_end()), Some(FinalLine::Ok("")));
        s.clear();
        write_ok(&mut s, format_args!("run 3 started")).unwrap();
        let ok = FinalLine::parse(s.trim_end()).unwrap();
        assert!(ok.is_ok());
        assert_eq!(ok.text(), "run 3 started");
        s.clear();
        write_err(&mut s, ErrorCode::Fault, &"fault latched: stall").unwrap();
        let err = FinalLine::parse(s.trim_end()).unwrap();
        assert!(err.is_err(ErrorCode::Fault) && !err.is_err(ErrorCode::Busy) && !err.is_ok());
        assert_eq!(err.text(), "fault latched: stall");
        for other in [
            "  d_right 0.15",
            "event run 1 finished: cw",
            "stream 1 0 0 0 0 0",
            "okay",
            "err x: y",
            "err 4",
        ] {
            assert_eq!(FinalLine::parse(other), None, "{other}");
        }
        assert_eq!(data("  d_right 0.15"), Some("d_right 0.15"));
        assert_eq!(data("ok"), None);
    }

    #[test]
    fn byte_sink_counts_refused_bytes_and_never_fails() {
        let mut queue: heapless::Vec<u8, 8> = heapless::Vec::new();
        let mut sink = ByteSink::new(|b| queue.push(b).is_ok());
        // 13 bytes into an 8-byte queue: 8 taken, 5 dropped, and the write still succeeds.
        assert_eq!(write_ok(&mut sink, format_args!("saved {}", 42)), Ok(()));
        assert_eq!(sink.dropped, 13 - 8);
        assert_eq!(&queue[..], b"ok saved");
    }
}
