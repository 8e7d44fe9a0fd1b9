//! Line assembly: serial bytes in, complete command lines (and stop keys) out.
//!
//! Built for a person at a terminal program with its default settings (picocom, screen, minicom
//! send CR on Enter and do not echo locally) as much as for a script:
//!
//! - `\r`, `\n` and `\r\n` each end one line (a `\n` right after a `\r` is swallowed, so CR LF is
//!   one line, not a line and an empty one);
//! - Backspace (0x08) and DEL (0x7f) erase the previous byte;
//! - Ctrl-C (0x03) discards the line being typed and is reported as [`LineEvent::Stop`];
//! - Esc (0x1b) is reported as [`LineEvent::Stop`] too, and a whole escape sequence — CSI
//!   (`ESC [` parameters, intermediates, final byte: arrows, function keys, Home/End…) or SS3
//!   (`ESC O x`: arrows and F1–F4 in application mode) — is consumed and never reaches the line;
//! - every other C0 control byte (NUL, Ctrl-D, …) is dropped; Tab is kept as a word separator;
//! - a receive error ([`LineAssembler::receive_error`]: overrun, framing, noise) poisons the line
//!   being received, which is rejected at its terminator with [`LineError::ReceiveError`] rather
//!   than executed with a byte missing (`measure 1.502` must never become `1.52`);
//! - a line longer than the buffer is never truncated and executed: once it overflows, every byte
//!   up to its terminator is discarded and the terminator yields [`LineError::TooLong`], once.
//!
//! A rejected line whose last word is `stop` is flagged ([`LineEvent::Rejected::stop`]): stopping
//! is always safe, so the session stops even when the bytes before it were garbled.
//!
//! Echo: after each [`LineAssembler::push`], [`LineAssembler::echo`] says what a terminal should
//! be sent back so its user sees what was accepted (the byte, an erase, a new line, `^C`). The
//! caller sends it when echo is on (the `echo on|off` command). State is a fixed `heapless`
//! buffer plus a few flags; nothing grows.

use core::fmt;

use heapless::Vec;

/// Default line capacity, bytes (without the terminator). The longest valid command is well
/// under half of it.
pub const LINE_MAX: usize = 80;

/// Ctrl-C.
pub const CTRL_C: u8 = 0x03;
/// Escape.
pub const ESC: u8 = 0x1b;
/// Longest escape sequence consumed, bytes after the `ESC [`; a longer one ends there.
const CSI_MAX: u8 = 32;

/// Why a terminated line was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum LineError {
    /// The line was longer than the buffer; it was discarded as a whole.
    TooLong,
    /// The line is not valid UTF-8.
    NotUtf8,
    /// A byte of the line was lost or corrupted on the wire (USART overrun, framing or noise
    /// error); the line was discarded as a whole.
    ReceiveError,
}

impl fmt::Display for LineError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LineError::TooLong => write!(f, "line too long (max {LINE_MAX} bytes), ignored"),
            LineError::NotUtf8 => f.write_str("line is not valid UTF-8, ignored"),
            LineError::ReceiveError => {
                f.write_str("receive error (overrun, framing or noise) in this line, ignored")
            }
        }
    }
}

/// Which key asked for an immediate stop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum StopKey {
    /// Ctrl-C (0x03): the line being typed was discarded.
    CtrlC,
    /// Esc (0x1b), alone or starting an escape sequence (an arrow or function key); the line
    /// being typed is kept.
    Escape,
}

/// What a byte completed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineEvent<'a> {
    /// A complete line (without its terminator); may be blank.
    Line(&'a str),
    /// A terminated line that is rejected as a whole.
    Rejected {
        /// Why.
        error: LineError,
        /// The line's last word was `stop` (ASCII case-insensitive): stop anyway.
        stop: bool,
    },
    /// Ctrl-C or Esc: stop any motion now, before any queued line.
    Stop(StopKey),
}

/// What to send back to a terminal for the last byte pushed (when echo is on).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Echo {
    /// Nothing.
    #[default]
    Nothing,
    /// The byte itself.
    Byte(u8),
    /// Erase the previous character: `BS SP BS`.
    Erase,
    /// The line ended: `CR LF`.
    NewLine,
    /// The line was discarded by Ctrl-C: `^C CR LF`.
    Cancel,
}

impl Echo {
    /// The bytes to send.
    pub fn bytes(&self) -> &[u8] {
        match self {
            Echo::Nothing => &[],
            Echo::Byte(b) => core::slice::from_ref(b),
            Echo::Erase => b"\x08 \x08",
            Echo::NewLine => b"\r\n",
            Echo::Cancel => b"^C\r\n",
        }
    }
}

/// Escape-sequence state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Escape {
    /// Not in a sequence.
    #[default]
    None,
    /// `ESC` seen.
    Start,
    /// `ESC [` seen, with this many parameter/intermediate bytes after it.
    Csi(u8),
    /// `ESC O` seen: one more byte.
    Ss3,
}

/// Accumulates bytes into lines of at most `N` bytes.
#[derive(Debug)]
pub struct LineAssembler<const N: usize = LINE_MAX> {
    buf: Vec<u8, N>,
    overflowed: bool,
    /// A receive error hit the current line.
    poisoned: bool,
    /// The previous call returned a line borrowed from `buf`; clear it before the next byte.
    consumed: bool,
    /// The previous byte was a `\r` that ended a line: a `\n` now is its second half.
    after_cr: bool,
    escape: Escape,
    /// The last four bytes of the current line (kept through an overflow), lower-cased.
    tail: [u8; 4],
    /// Bytes of the current line's last word, saturating (for the `stop` check).
    word_len: u8,
    /// What to echo for the last byte.
    echo: Echo,
    /// The current line is echoed byte by byte as it arrives (decided at its first byte,
    /// [`LineAssembler::set_echo_live`]); otherwise it is echoed whole when it is executed.
    echo_live: bool,
}

impl<const N: usize> Default for LineAssembler<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> LineAssembler<N> {
    /// An empty assembler.
    pub const fn new() -> Self {
        LineAssembler {
            buf: Vec::new(),
            overflowed: false,
            poisoned: false,
            consumed: false,
            after_cr: false,
            escape: Escape::None,
            tail: [0; 4],
            word_len: 0,
            echo: Echo::Nothing,
            echo_live: true,
        }
    }

    /// Appends one byte to the current line, or marks the line overflowed.
    fn store(&mut self, byte: u8) {
        self.tail = [
            self.tail[1],
            self.tail[2],
            self.tail[3],
            byte.to_ascii_lowercase(),
        ];
        self.word_len = if byte == b' ' || byte == b'\t' {
            0
        } else {
            self.word_len.saturating_add(1)
        };
        if !self.overflowed && self.buf.push(byte).is_err() {
            // Drop what we have: this line will be rejected at its terminator.
            self.overflowed = true;
            self.buf.clear();
        }
    }

    /// Starts a new, empty line.
    fn reset_line(&mut self) {
        self.buf.clear();
        self.overflowed = false;
        self.poisoned = false;
        self.tail = [0; 4];
        self.word_len = 0;
    }

    /// Whether the current line's last word is `stop`.
    fn ends_with_stop(&self) -> bool {
        self.word_len == 4 && &self.tail == b"stop"
    }

    /// What to echo for the byte last pushed.
    pub fn echo(&self) -> Echo {
        self.echo
    }

    /// Whether the current line is echoed byte by byte as it arrives. [`crate::protocol::rx`]
    /// decides it at each line's first byte: live when the console is idle (a person typing);
    /// otherwise (a paste, or typing during a long reply) the line is echoed whole right before
    /// its reply, so echo never cuts into a reply.
    pub fn echo_live(&self) -> bool {
        self.echo_live
    }

    /// Whether a line is being typed: part of it is held and it is echoed as it arrives (a
    /// person at a terminal; [`crate::session::Session::set_typing`] holds the pose stream
    /// meanwhile).
    pub fn typing(&self) -> bool {
        self.echo_live && !self.at_line_start()
    }

    /// Sets [`LineAssembler::echo_live`] for the line that starts with the next byte.
    pub fn set_echo_live(&mut self, live: bool) {
        self.echo_live = live;
    }

    /// A receive error (overrun, framing, noise, parity) at this point of the input: the line
    /// being received has lost or garbled a byte and is rejected at its terminator.
    pub fn receive_error(&mut self) {
        if self.consumed {
            self.buf.clear();
            self.consumed = false;
        }
        // A lost byte may have been the `\n` of a CR LF: do not pair across the error.
        self.after_cr = false;
        self.escape = Escape::None;
        self.poisoned = true;
        self.echo = Echo::Nothing;
    }

    /// Feeds one byte. Returns `Some` when the byte completed a line (its text, or why it was
    /// rejected) or asked for a stop (Ctrl-C, Esc).
    pub fn push(&mut self, byte: u8) -> Option<LineEvent<'_>> {
        if self.consumed {
            self.buf.clear();
            self.consumed = false;
        }
        self.echo = Echo::Nothing;
        let after_cr = core::mem::take(&mut self.after_cr);
        match self.escape {
            Escape::None => {}
            Escape::Start => match byte {
                b'[' => {
                    self.escape = Escape::Csi(0);
                    return None;
                }
                b'O' => {
                    self.escape = Escape::Ss3;
                    return None;
                }
                // Anything else: the Esc stood alone; the byte is an ordinary one.
                _ => self.escape = Escape::None,
            },
            Escape::Csi(n) => match byte {
                // Parameter and intermediate bytes.
                0x20..=0x3f if n < CSI_MAX => {
                    self.escape = Escape::Csi(n + 1);
                    return None;
                }
                // The final byte ends the sequence.
                0x40..=0x7e => {
                    self.escape = Escape::None;
                    return None;
                }
                // A control byte or an over-long sequence ends it; the byte counts as typed.
                _ => self.escape = Escape::None,
            },
            Escape::Ss3 => {
                self.escape = Escape::None;
                if (0x20..=0x7e).contains(&byte) {
                    return None;
                }
            }
        }
        match byte {
            b'\n' if after_cr => None,
            b'\r' | b'\n' => {
                self.after_cr = byte == b'\r';
                self.echo = Echo::NewLine;
                let rejected = if self.overflowed {
                    Some(LineError::TooLong)
                } else if self.poisoned {
                    Some(LineError::ReceiveError)
                } else if core::str::from_utf8(&self.buf).is_err() {
                    Some(LineError::NotUtf8)
                } else {
                    None
                };
                if let Some(error) = rejected {
                    let stop = self.ends_with_stop();
                    self.reset_line();
                    return Some(LineEvent::Rejected { error, stop });
                }
                self.overflowed = false;
                self.poisoned = false;
                self.tail = [0; 4];
                self.word_len = 0;
                self.consumed = true;
                // Checked just above.
                core::str::from_utf8(&self.buf).ok().map(LineEvent::Line)
            }
            0x08 | 0x7f => {
                if !self.overflowed && self.buf.pop().is_some() {
                    self.echo = Echo::Erase;
                    // The tail no longer matches the buffer; the `stop` check is only a hint
                    // for rejected lines, so forgetting the last word is the safe side.
                    self.word_len = 0;
                }
                None
            }
            CTRL_C => {
                self.reset_line();
                self.echo = Echo::Cancel;
                Some(LineEvent::Stop(StopKey::CtrlC))
            }
            ESC => {
                self.escape = Escape::Start;
                Some(LineEvent::Stop(StopKey::Escape))
            }
            b'\t' => {
                self.store(byte);
                self.echo = Echo::Byte(b' ');
                None
            }
            0x00..=0x1f => None,
            _ => {
                self.store(byte);
                self.echo = Echo::Byte(byte);
                None
            }
        }
    }

    /// Bytes currently held (never more than `N`).
    pub fn len(&self) -> usize {
        if self.consumed { 0 } else { self.buf.len() }
    }

    /// Whether no partial line is held.
    pub fn is_empty(&self) -> bool {
        self.at_line_start() && self.escape == Escape::None
    }

    /// Whether the next byte starts a line: nothing of one is held (an escape sequence may be
    /// under way: it leaves no trace in the line).
    pub fn at_line_start(&self) -> bool {
        (self.consumed || self.buf.is_empty()) && !self.overflowed && !self.poisoned
    }

    /// Whether the current line has already overflowed and will be rejected.
    pub fn is_overflowed(&self) -> bool {
        self.overflowed
    }

    /// Forgets any partial line (e.g. when a new client connects).
    pub fn clear(&mut self) {
        self.reset_line();
        self.consumed = false;
        self.after_cr = false;
        self.escape = Escape::None;
        self.echo = Echo::Nothing;
    }
}
