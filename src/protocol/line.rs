//! Line assembly: serial bytes in, complete command lines out.
//!
//! A line ends at `\n`; one `\r` right before it is dropped, so both `\n` and `\r\n` work.
//! Backspace (0x08) and DEL (0x7f) erase the previous byte, for people typing in a terminal.
//! A line longer than the buffer is never truncated and executed: once it overflows, every byte
//! up to its terminator is discarded and the terminator yields [`LineError::TooLong`], exactly
//! once. State is a fixed `heapless` buffer plus one flag; nothing grows.

use core::fmt;

use heapless::Vec;

/// Default line capacity, bytes (without the terminator). The longest valid command is well
/// under half of it.
pub const LINE_MAX: usize = 80;

/// Why a terminated line was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum LineError {
    /// The line was longer than the buffer; it was discarded as a whole.
    TooLong,
    /// The line is not valid UTF-8.
    NotUtf8,
}

impl fmt::Display for LineError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LineError::TooLong => write!(f, "line too long (max {LINE_MAX} bytes), ignored"),
            LineError::NotUtf8 => f.write_str("line is not valid UTF-8, ignored"),
        }
    }
}

/// Accumulates bytes into lines of at most `N` bytes.
#[derive(Debug, Default)]
pub struct LineAssembler<const N: usize = LINE_MAX> {
    buf: Vec<u8, N>,
    overflowed: bool,
    /// The previous call returned a line borrowed from `buf`; clear it before the next byte.
    consumed: bool,
    /// A `\r` was received and not yet stored: it is dropped if `\n` follows.
    pending_cr: bool,
}

impl<const N: usize> LineAssembler<N> {
    /// An empty assembler.
    pub const fn new() -> Self {
        LineAssembler {
            buf: Vec::new(),
            overflowed: false,
            consumed: false,
            pending_cr: false,
        }
    }

    /// Appends one byte to the current line, or marks the line overflowed.
    fn store(&mut self, byte: u8) {
        if !self.overflowed && self.buf.push(byte).is_err() {
            // Drop what we have: this line will be rejected at its terminator.
            self.overflowed = true;
            self.buf.clear();
        }
    }

    /// Feeds one byte. Returns `Some` when the byte completed a line: the line's text (without
    /// terminator) or why it was rejected.
    pub fn push(&mut self, byte: u8) -> Option<Result<&str, LineError>> {
        if self.consumed {
            self.buf.clear();
            self.consumed = false;
        }
        if byte != b'\n' && core::mem::take(&mut self.pending_cr) {
            self.store(b'\r');
        }
        match byte {
            b'\n' => {
                self.pending_cr = false;
                if self.overflowed {
                    self.overflowed = false;
                    self.buf.clear();
                    return Some(Err(LineError::TooLong));
                }
                self.consumed = true;
                Some(core::str::from_utf8(&self.buf).map_err(|_| LineError::NotUtf8))
            }
            0x08 | 0x7f => {
                if !self.overflowed {
                    self.buf.pop();
                }
                None
            }
            b'\r' => {
                self.pending_cr = true;
                None
            }
            _ => {
                self.store(byte);
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
        self.len() == 0 && !self.overflowed && !self.pending_cr
    }

    /// Whether the current line has already overflowed and will be rejected.
    pub fn is_overflowed(&self) -> bool {
        self.overflowed
    }

    /// Forgets any partial line.
    pub fn clear(&mut self) {
        self.buf.clear();
        self.overflowed = false;
        self.consumed = false;
        self.pending_cr = false;
    }
}
