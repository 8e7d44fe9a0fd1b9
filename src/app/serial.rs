//! The serial port's interrupt (priority 2 on the board): received bytes become lines on their
//! way to the console task, echoed as they are typed; the echo and the console's replies go out.

use core::sync::atomic::Ordering;

use heapless::spsc::Consumer;

use super::Handoff;
use crate::protocol::LineAssembler;
use crate::protocol::line::LineEvent;
use crate::protocol::rx::{self, InputSender, RxRead};

/// Where the receive puts completed lines and stop keys for the console task.
pub trait LineQueue {
    /// Queues `event` whole, or nothing when it does not fit (returns false: counted as
    /// dropped). `echoed`: the line was echoed as it arrived.
    fn send(&mut self, event: &LineEvent<'_>, echoed: bool) -> bool;
    /// Whether nothing waits for the console.
    fn is_empty(&self) -> bool;
}

impl LineQueue for InputSender<'_> {
    fn send(&mut self, event: &LineEvent<'_>, echoed: bool) -> bool {
        InputSender::send(self, event, echoed)
    }

    fn is_empty(&self) -> bool {
        InputSender::is_empty(self)
    }
}

/// Takes at most `max_reads` reads from `read` into `assembler`. A line starting while the
/// console is idle (echo on, no output pending, nothing queued, no line executing) is echoed
/// as it arrives through `echo`; any other line is echoed with its reply. Completed lines and
/// stop keys go to `lines`; a stop key (or a rejected line ending in one) also requests the
/// stop that the next control period carries out, before the console takes any queued line. A
/// line that does not fit is counted for the console to report. `output_pending`: echo or
/// replies are still on their way out.
pub fn receive<Q: LineQueue, const N: usize>(
    handoff: &Handoff,
    assembler: &mut LineAssembler<N>,
    read: impl FnMut() -> RxRead,
    max_reads: usize,
    output_pending: bool,
    lines: &mut Q,
    echo: impl FnMut(&[u8]),
) {
    let idle = handoff.echo()
        && !output_pending
        && lines.is_empty()
        && !handoff.console_busy.load(Ordering::SeqCst);
    rx::drain(
        read,
        assembler,
        max_reads,
        idle,
        |event, echoed| {
            if rx::is_stop(&event) {
                handoff.stop_request.store(true, Ordering::Relaxed);
            }
            if !lines.send(&event, echoed) {
                handoff.lines_dropped.fetch_add(1, Ordering::Relaxed);
            }
        },
        echo,
    );
    handoff.typing.store(assembler.typing(), Ordering::Relaxed);
}

/// A serial transmitter, one byte at a time.
pub trait TxPort {
    /// Whether the transmit register takes a byte now.
    fn ready(&mut self) -> bool;
    /// Writes `byte` to the transmit register (only when [`TxPort::ready`]).
    fn write(&mut self, byte: u8);
    /// Asks for the transmit interrupt when the register is free (`true`), or not (`false`).
    fn interrupt_when_ready(&mut self, on: bool);
}

/// Fills the transmitter while it takes bytes: the echo first (it belongs in front of any
/// reply), then the console's replies; keeps the transmit interrupt on while either has bytes
/// left.
pub fn transmit<const N: usize>(
    port: &mut impl TxPort,
    echo_out: &mut heapless::Deque<u8, N>,
    replies: &mut Consumer<'_, u8>,
) {
    while port.ready() {
        let Some(byte) = echo_out.pop_front().or_else(|| replies.dequeue()) else {
            break;
        };
        port.write(byte);
    }
    port.interrupt_when_ready(!echo_out.is_empty() || replies.ready());
}

#[cfg(test)]
mod tests {
    use heapless::spsc::Queue;

    use super::*;
    use crate::protocol::rx::InputQueue;

    /// A transmitter that takes `room` bytes, then is busy.
    struct Port {
        room: usize,
        sent: Vec<u8>,
        interrupt: bool,
    }

    impl TxPort for Port {
        fn ready(&mut self) -> bool {
            self.sent.len() < self.room
        }
        fn write(&mut self, byte: u8) {
            self.sent.push(byte);
        }
        fn interrupt_when_ready(&mut self, on: bool) {
            self.interrupt = on;
        }
    }

    #[test]
    fn the_echo_goes_out_before_queued_replies_and_the_interrupt_stays_on_while_bytes_wait() {
        let mut echo = heapless::Deque::<u8, 8>::new();
        let mut q = Queue::<u8, 8>::new();
        let (mut p, mut c) = q.split();
        for &b in b"ok" {
            p.enqueue(b).unwrap();
        }
        for &b in b"ab" {
            echo.push_back(b).unwrap();
        }
        let mut port = Port {
            room: 3,
            sent: Vec::new(),
            interrupt: false,
        };
        transmit(&mut port, &mut echo, &mut c);
        assert_eq!(port.sent, b"abo");
        assert!(port.interrupt);
        port.room = 10;
        transmit(&mut port, &mut echo, &mut c);
        assert_eq!(port.sent, b"abok");
        assert!(!port.interrupt);
    }

    #[test]
    fn a_stop_key_requests_a_stop_and_a_full_queue_counts_the_lines_lost() {
        let handoff = Handoff::new();
        let mut assembler: LineAssembler = LineAssembler::new();
        let mut queue = InputQueue::<9>::new();
        let (mut lines, mut taken) = queue.split();
        let mut bytes = b"status\rparams\r\x03".iter();
        let mut echoed = Vec::new();
        receive(
            &handoff,
            &mut assembler,
            || bytes.next().map_or(RxRead::Empty, |&b| RxRead::Byte(b)),
            usize::MAX,
            false,
            &mut lines,
            |b| echoed.extend_from_slice(b),
        );
        // 8 bytes of room: `status` (7 with its header) fits, `params` does not, the stop key
        // (1) does.
        assert_eq!(handoff.lines_dropped.load(Ordering::Relaxed), 1);
        assert!(handoff.stop_request.load(Ordering::Relaxed));
        assert!(taken.take().is_some_and(|r| r.echoed));
        assert!(taken.take().is_some_and(|r| r.item.is_stop()));
        // The console was idle for `status` only: it was echoed as it arrived.
        assert_eq!(echoed, b"status\r\n");
    }
}
