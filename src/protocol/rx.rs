//! The console's receive loop: what the USART receive interrupt runs, as a pure function.
//!
//! [`drain`] reads the receiver until it reports no more data and feeds each byte to the
//! [`LineAssembler`]. A read that reports a receive error (overrun, framing, noise, parity)
//! poisons the line being received ([`LineAssembler::receive_error`]). On the STM32 the read
//! that reports an error is the status-register read followed by the data-register read, which is
//! also what clears the error flags: an overrun that is flagged while the data register is empty
//! still raises the interrupt, so an interrupt that only read data while `RXNE` was set would
//! re-enter for ever. Looping on the read until it says "empty" clears every flag.
//!
//! [`InputItem`] is a [`LineEvent`] that owns its text, for the queue from the interrupt to the
//! console task.

use heapless::String;

use super::line::{LINE_MAX, LineAssembler, LineError, LineEvent, StopKey};

/// One read from a serial receiver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RxRead {
    /// A received byte.
    Byte(u8),
    /// The receiver reported an error (the byte, if any, is lost); its flags are now clear.
    Error,
    /// Nothing (more) to read.
    Empty,
}

/// Reads at most `max_reads` times from `read` (until it returns [`RxRead::Empty`]), feeding
/// the bytes to `assembler`; calls `on_event` for each completed line or stop key and `echo`
/// with the echo of every byte (the caller sends it when echo is on). Returns the number of
/// reads that returned data or an error.
pub fn drain<const N: usize>(
    mut read: impl FnMut() -> RxRead,
    assembler: &mut LineAssembler<N>,
    max_reads: usize,
    mut on_event: impl FnMut(LineEvent<'_>),
    mut echo: impl FnMut(&[u8]),
) -> usize {
    let mut n = 0;
    while n < max_reads {
        match read() {
            RxRead::Empty => break,
            RxRead::Error => assembler.receive_error(),
            RxRead::Byte(b) => {
                if let Some(e) = assembler.push(b) {
                    on_event(e);
                }
                echo(assembler.echo().bytes());
            }
        }
        n += 1;
    }
    n
}

/// A [`LineEvent`] with its text owned, for a queue.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum InputItem {
    /// A complete line.
    Line(String<LINE_MAX>),
    /// A rejected line; `stop` when its last word was `stop`.
    Rejected {
        /// Why.
        error: LineError,
        /// Stop anyway.
        stop: bool,
    },
    /// Ctrl-C or Esc.
    Stop(StopKey),
}

impl InputItem {
    /// The owned form of `event`.
    pub fn from_event(event: LineEvent<'_>) -> Self {
        match event {
            LineEvent::Line(text) => {
                let mut owned = String::new();
                // A line is at most LINE_MAX bytes, so it always fits.
                let _ = owned.push_str(text);
                InputItem::Line(owned)
            }
            LineEvent::Rejected { error, stop } => InputItem::Rejected { error, stop },
            LineEvent::Stop(key) => InputItem::Stop(key),
        }
    }

    /// The borrowed form.
    pub fn as_event(&self) -> LineEvent<'_> {
        match self {
            InputItem::Line(text) => LineEvent::Line(text),
            InputItem::Rejected { error, stop } => LineEvent::Rejected {
                error: *error,
                stop: *stop,
            },
            InputItem::Stop(key) => LineEvent::Stop(*key),
        }
    }

    /// Whether this item asks for an immediate stop (Ctrl-C, Esc, or a garbled line ending in
    /// `stop`).
    pub fn is_stop(&self) -> bool {
        matches!(
            self,
            InputItem::Stop(_) | InputItem::Rejected { stop: true, .. }
        )
    }
}

/// Whether `event` asks for an immediate stop.
pub fn is_stop(event: &LineEvent<'_>) -> bool {
    matches!(
        event,
        LineEvent::Stop(_) | LineEvent::Rejected { stop: true, .. }
    )
}
