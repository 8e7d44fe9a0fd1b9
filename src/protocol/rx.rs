//! The console's receive loop: what the USART receive interrupt runs, as a pure function, and
//! the queue that carries its lines to the console task.
//!
//! [`drain`] reads the receiver until it reports no more data and feeds each byte to the
//! [`LineAssembler`]. A read that reports a receive error (overrun, framing, noise, parity)
//! poisons the line being received ([`LineAssembler::receive_error`]). On the STM32 the read
//! that reports an error is the status-register read followed by the data-register read, which is
//! also what clears the error flags: an overrun that is flagged while the data register is empty
//! still raises the interrupt, so an interrupt that only read data while `RXNE` was set would
//! re-enter for ever. Looping on the read until it says "empty" clears every flag.
//!
//! Echo: a line that starts while the console is idle is echoed byte by byte as it is typed. A
//! line that starts while a reply is being sent or lines are waiting (a paste, or typing during a
//! long reply) is echoed whole by the console right before its reply
//! ([`Received::write_echo`]), so echo never cuts into a reply and a pasted script reads as
//! command, reply, command, reply.
//!
//! [`InputQueue`] carries lines from the interrupt to the console task packed (a header byte and
//! the text), so a paste of many short lines fits where a queue of whole line buffers would hold
//! a few. [`InputItem`] is a [`LineEvent`] that owns its text, as the console takes it.

use core::fmt;

use heapless::String;
use heapless::spsc::{Consumer, Producer, Queue};

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
/// the bytes to `assembler`. A line is echoed as it arrives (`echo` gets the echo of each of its
/// bytes) when it starts while the console is `idle` (echo on, nothing waiting or going out)
/// and no line has completed earlier in this call (the console has not taken that one yet);
/// the decision stays with the line across calls. `on_event` gets each completed line or stop
/// key, and whether it was echoed as it arrived (if not, the console echoes it when it takes
/// it). Returns the number of reads that returned data or an error.
pub fn drain<const N: usize>(
    mut read: impl FnMut() -> RxRead,
    assembler: &mut LineAssembler<N>,
    max_reads: usize,
    idle: bool,
    mut on_event: impl FnMut(LineEvent<'_>, bool),
    mut echo: impl FnMut(&[u8]),
) -> usize {
    let mut n = 0;
    let mut queued = false;
    while n < max_reads {
        match read() {
            RxRead::Empty => break,
            RxRead::Error => assembler.receive_error(),
            RxRead::Byte(b) => {
                if assembler.at_line_start() {
                    assembler.set_echo_live(idle && !queued);
                }
                let live = assembler.echo_live();
                if let Some(e) = assembler.push(b) {
                    on_event(e, live);
                    queued = true;
                }
                if live {
                    echo(assembler.echo().bytes());
                }
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
        is_stop(&self.as_event())
    }
}

/// Whether `event` asks for an immediate stop.
pub fn is_stop(event: &LineEvent<'_>) -> bool {
    matches!(
        event,
        LineEvent::Stop(_) | LineEvent::Rejected { stop: true, .. }
    )
}

/// Header byte of a queued stop key: Ctrl-C.
const HEADER_CTRL_C: u8 = 0xfe;
/// Header byte of a queued stop key: Esc.
const HEADER_ESCAPE: u8 = 0xff;
/// Header bytes of a queued rejected line: this base plus twice the error's index plus `stop`.
const HEADER_REJECTED: u8 = 0xf0;
/// Header flag of a queued line that was not echoed as it arrived.
const HEADER_ECHO_LATER: u8 = 0x80;
// A line's header is its length, with the flag; it must stay clear of the other headers.
const _: () = assert!(LINE_MAX < HEADER_ECHO_LATER as usize);
const _: () = assert!(((HEADER_ECHO_LATER as usize) | LINE_MAX) < HEADER_REJECTED as usize);

/// The rejection reasons, in their header order.
const LINE_ERRORS: [LineError; 3] = [
    LineError::TooLong,
    LineError::NotUtf8,
    LineError::ReceiveError,
];

/// The console's input queue, bytes. A queued line takes its length plus one header byte: 711
/// bytes hold about 35 typical command lines (`set square_side 1.500`, 22 bytes) or 8 of the
/// longest ones, in the RAM a queue of 8 whole line buffers took.
pub const INPUT_QUEUE_BYTES: usize = 712;

/// Received lines and stop keys on their way from the receive interrupt to the console task:
/// a single-producer single-consumer byte queue, each item packed as a header byte and, for a
/// line, its text. [`InputQueue::split`] gives the two ends.
pub struct InputQueue<const N: usize = INPUT_QUEUE_BYTES>(Queue<u8, N>);

impl<const N: usize> InputQueue<N> {
    /// An empty queue (`const`, for a static or an RTIC resource).
    pub const fn new() -> Self {
        InputQueue(Queue::new())
    }

    /// The interrupt's end and the console's end.
    pub fn split(&mut self) -> (InputSender<'_>, InputReceiver<'_>) {
        let (p, c) = self.0.split();
        (InputSender(p), InputReceiver(c))
    }
}

impl<const N: usize> Default for InputQueue<N> {
    fn default() -> Self {
        Self::new()
    }
}

/// The receive interrupt's end of an [`InputQueue`].
pub struct InputSender<'a>(Producer<'a, u8>);

impl InputSender<'_> {
    /// Queues `event` whole, or nothing when it does not fit (returns false: the caller counts
    /// it as dropped). `echoed`: the line was echoed as it arrived.
    pub fn send(&mut self, event: &LineEvent<'_>, echoed: bool) -> bool {
        let (header, text) = match *event {
            LineEvent::Line(text) => {
                let later = if echoed { 0 } else { HEADER_ECHO_LATER };
                // A line is at most LINE_MAX bytes (the assembler's capacity).
                let Ok(len) = u8::try_from(text.len()) else {
                    return false;
                };
                if usize::from(len) > LINE_MAX {
                    return false;
                }
                (len | later, text.as_bytes())
            }
            LineEvent::Rejected { error, stop } => {
                let index = LINE_ERRORS.iter().position(|e| *e == error).unwrap_or(0) as u8;
                (HEADER_REJECTED + 2 * index + u8::from(stop), &[][..])
            }
            LineEvent::Stop(StopKey::CtrlC) => (HEADER_CTRL_C, &[][..]),
            LineEvent::Stop(StopKey::Escape) => (HEADER_ESCAPE, &[][..]),
        };
        if self.0.capacity() - self.0.len() < 1 + text.len() {
            return false;
        }
        // Room was checked, and only this end adds: every enqueue succeeds.
        let _ = self.0.enqueue(header);
        for &b in text {
            let _ = self.0.enqueue(b);
        }
        true
    }

    /// Whether nothing waits for the console.
    pub fn is_empty(&self) -> bool {
        self.0.len() == 0
    }
}

/// The console task's end of an [`InputQueue`].
pub struct InputReceiver<'a>(Consumer<'a, u8>);

/// A queued item as the console takes it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Received {
    /// The line, rejected line or stop key.
    pub item: InputItem,
    /// The line was echoed as it arrived.
    pub echoed: bool,
}

impl Received {
    /// Writes the echo of a line that was not echoed as it arrived (the line and a new line);
    /// the caller calls it when echo is on.
    ///
    /// # Errors
    /// As `out`.
    pub fn write_echo(&self, out: &mut dyn fmt::Write) -> fmt::Result {
        match &self.item {
            InputItem::Line(text) if !self.echoed => {
                out.write_str(text)?;
                out.write_str("\r\n")
            }
            _ => Ok(()),
        }
    }
}

impl InputReceiver<'_> {
    /// Whether nothing waits.
    pub fn is_empty(&self) -> bool {
        self.0.len() == 0
    }

    /// The next item, if any.
    pub fn take(&mut self) -> Option<Received> {
        let header = self.0.dequeue()?;
        let item = match header {
            HEADER_CTRL_C => InputItem::Stop(StopKey::CtrlC),
            HEADER_ESCAPE => InputItem::Stop(StopKey::Escape),
            h if h >= HEADER_REJECTED => {
                let index = usize::from((h - HEADER_REJECTED) / 2);
                InputItem::Rejected {
                    error: LINE_ERRORS
                        .get(index)
                        .copied()
                        .unwrap_or(LineError::ReceiveError),
                    stop: (h - HEADER_REJECTED) % 2 == 1,
                }
            }
            h => {
                let len = usize::from(h & !HEADER_ECHO_LATER);
                let mut bytes = heapless::Vec::<u8, LINE_MAX>::new();
                for _ in 0..len {
                    // The sender queues an item whole before the console can run.
                    let Some(b) = self.0.dequeue() else { break };
                    let _ = bytes.push(b);
                }
                let item = match String::from_utf8(bytes) {
                    Ok(text) if text.len() == len => InputItem::Line(text),
                    _ => InputItem::Rejected {
                        error: LineError::ReceiveError,
                        stop: false,
                    },
                };
                return Some(Received {
                    item,
                    echoed: h & HEADER_ECHO_LATER == 0,
                });
            }
        };
        Some(Received { item, echoed: true })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(text: &str) -> InputItem {
        InputItem::from_event(LineEvent::Line(text))
    }

    #[test]
    fn every_kind_of_item_comes_out_as_it_went_in() {
        let mut q = InputQueue::<256>::new();
        let (mut tx, mut rx) = q.split();
        let long = "x".repeat(LINE_MAX);
        let events = [
            (LineEvent::Line("set square_side 1.5"), true),
            (LineEvent::Line("status"), false),
            (LineEvent::Line(""), true),
            (LineEvent::Line("mesure 0.01 °"), false),
            (LineEvent::Line(&long), false),
            (
                LineEvent::Rejected {
                    error: LineError::TooLong,
                    stop: true,
                },
                true,
            ),
            (
                LineEvent::Rejected {
                    error: LineError::NotUtf8,
                    stop: false,
                },
                true,
            ),
            (
                LineEvent::Rejected {
                    error: LineError::ReceiveError,
                    stop: true,
                },
                true,
            ),
            (LineEvent::Stop(StopKey::CtrlC), true),
            (LineEvent::Stop(StopKey::Escape), true),
        ];
        for (event, echoed) in &events {
            assert!(tx.send(event, *echoed), "{event:?}");
        }
        for (event, echoed) in &events {
            assert_eq!(
                rx.take(),
                Some(Received {
                    item: InputItem::from_event(*event),
                    echoed: *echoed
                })
            );
        }
        assert_eq!(rx.take(), None);
        assert!(tx.is_empty());
    }

    #[test]
    fn a_full_queue_refuses_a_line_whole_and_takes_a_shorter_one() {
        // 15 bytes of room: "status" takes 7, twice; a third does not fit, a stop key does.
        let mut q = InputQueue::<16>::new();
        let (mut tx, mut rx) = q.split();
        assert!(tx.send(&LineEvent::Line("status"), true));
        assert!(tx.send(&LineEvent::Line("status"), true));
        assert!(!tx.send(&LineEvent::Line("status"), true));
        assert!(tx.send(&LineEvent::Stop(StopKey::CtrlC), true));
        assert_eq!(rx.take().map(|r| r.item), Some(line("status")));
        assert_eq!(rx.take().map(|r| r.item), Some(line("status")));
        assert_eq!(
            rx.take().map(|r| r.item),
            Some(InputItem::Stop(StopKey::CtrlC))
        );
        assert_eq!(rx.take(), None);
    }

    #[test]
    fn the_console_queue_holds_a_pasted_script_of_typical_lines() {
        // What a queue of 8 whole line buffers (7 usable) used to drop.
        let mut q = InputQueue::<INPUT_QUEUE_BYTES>::new();
        let (mut tx, mut rx) = q.split();
        let kept = (0..100)
            .take_while(|_| tx.send(&LineEvent::Line("set square_side 1.500"), false))
            .count();
        assert_eq!(kept, (INPUT_QUEUE_BYTES - 1) / 22);
        assert!(kept >= 32, "{kept}");
        assert_eq!(
            core::iter::from_fn(|| rx.take()).count(),
            kept,
            "every queued line comes out"
        );
    }

    #[test]
    fn a_deferred_line_is_echoed_whole_and_a_live_one_not_again() {
        let mut echo = String::<128>::new();
        let deferred = Received {
            item: line("params"),
            echoed: false,
        };
        deferred.write_echo(&mut echo).unwrap();
        assert_eq!(echo.as_str(), "params\r\n");
        echo.clear();
        for live in [
            Received {
                item: line("params"),
                echoed: true,
            },
            Received {
                item: InputItem::Stop(StopKey::CtrlC),
                echoed: false,
            },
        ] {
            live.write_echo(&mut echo).unwrap();
        }
        assert_eq!(echo.as_str(), "");
    }

    /// Feeds `wire` to `asm` in one interrupt, the console `idle` or not; appends the events
    /// (with whether each was echoed as it arrived) and the echo.
    fn feed(
        asm: &mut LineAssembler<LINE_MAX>,
        wire: &[u8],
        idle: bool,
        events: &mut std::vec::Vec<(InputItem, bool)>,
        echoed: &mut std::vec::Vec<u8>,
    ) {
        let mut bytes = wire.iter();
        drain(
            || bytes.next().map_or(RxRead::Empty, |&b| RxRead::Byte(b)),
            asm,
            usize::MAX,
            idle,
            |e, live| events.push((InputItem::from_event(e), live)),
            |b| echoed.extend_from_slice(b),
        );
    }

    #[test]
    fn a_paste_echoes_its_first_line_live_and_leaves_the_rest_to_the_console() {
        let (mut items, mut echoed) = (std::vec::Vec::new(), std::vec::Vec::new());
        let mut asm = LineAssembler::<LINE_MAX>::new();
        let wire = b"params\rstatus\r\nset square_side 1\x7f2\r";
        feed(&mut asm, wire, true, &mut items, &mut echoed);
        assert_eq!(
            items,
            [
                (line("params"), true),
                (line("status"), false),
                (line("set square_side 2"), false),
            ]
        );
        assert_eq!(echoed, b"params\r\n");
    }

    #[test]
    fn a_line_typed_at_an_idle_console_is_typing_until_its_end() {
        let (mut items, mut echoed) = (std::vec::Vec::new(), std::vec::Vec::new());
        let mut asm = LineAssembler::<LINE_MAX>::new();
        assert!(!asm.typing());
        // Key by key at an idle console: echoed live, typing from the first key to Enter.
        for &key in b"stat" {
            feed(&mut asm, &[key], true, &mut items, &mut echoed);
            assert!(asm.typing());
        }
        feed(&mut asm, b"us\r", true, &mut items, &mut echoed);
        assert!(!asm.typing());
        // Ctrl-C cancels the line and ends it too; Esc (a stop key, or the start of an arrow
        // key's sequence) keeps what was typed.
        feed(&mut asm, b"ru", true, &mut items, &mut echoed);
        feed(&mut asm, b"\x1b", true, &mut items, &mut echoed);
        assert!(asm.typing());
        feed(&mut asm, b"\x03", true, &mut items, &mut echoed);
        assert!(!asm.typing());
        // A line that starts while the console is busy is echoed with its reply: not typing.
        feed(&mut asm, b"par", false, &mut items, &mut echoed);
        assert!(!asm.typing());
    }

    #[test]
    fn a_line_after_a_lone_esc_decides_its_own_echo() {
        let mut asm = LineAssembler::<LINE_MAX>::new();
        let mut echoed = std::vec::Vec::new();
        let mut events = std::vec::Vec::new();
        for (wire, idle) in [(&b"\x1b"[..], false), (b"status\r", true)] {
            feed(&mut asm, wire, idle, &mut events, &mut echoed);
        }
        assert_eq!(
            events,
            [
                (InputItem::Stop(StopKey::Escape), false),
                (line("status"), true)
            ]
        );
        assert_eq!(echoed, b"status\r\n");
    }
}
