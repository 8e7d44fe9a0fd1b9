//! The USART2 receive interrupt's loop (`protocol::rx::drain`) against a USART double that
//! models the STM32F4 status bits the way RM0090 describes them: RXNE, ORE, FE, NE; an error
//! flag is cleared by reading SR then DR; the interrupt is pending while RXNE or ORE is set
//! (RXNEIE). The read closure does what the firmware's does (stm32f4xx-hal `Rx::read`: SR, and on
//! an error DR too).

use odocal::protocol::rx::{InputItem, RxRead, drain};
use odocal::protocol::{LineAssembler, LineError};

#[derive(Clone, Copy, PartialEq, Debug)]
enum Fault {
    Overrun,
    Framing,
    Noise,
}

/// SR/DR of a USART receiving `wire`, with `fault` injected at byte `at`.
struct Usart {
    wire: Vec<u8>,
    pos: usize,
    rxne: bool,
    ore: bool,
    fe: bool,
    ne: bool,
    dr: u8,
}

impl Usart {
    fn new(wire: &[u8]) -> Self {
        Usart {
            wire: wire.to_vec(),
            pos: 0,
            rxne: false,
            ore: false,
            fe: false,
            ne: false,
            dr: 0,
        }
    }
    /// The shift register delivers the next byte; with a fault it is flagged (FE/NE: the byte
    /// lands in DR with the flag; ORE: DR still holds the unread previous byte, the new one is
    /// lost).
    fn deliver(&mut self, fault: Option<Fault>) -> bool {
        let Some(&b) = self.wire.get(self.pos) else {
            return false;
        };
        self.pos += 1;
        match fault {
            Some(Fault::Overrun) => {
                self.ore = true;
            }
            Some(Fault::Framing) => {
                self.fe = true;
                self.dr = b;
                self.rxne = true;
            }
            Some(Fault::Noise) => {
                self.ne = true;
                self.dr = b;
                self.rxne = true;
            }
            None => {
                self.dr = b;
                self.rxne = true;
            }
        }
        true
    }
    fn interrupt_pending(&self) -> bool {
        self.rxne || self.ore
    }
    /// The firmware's read: SR; on an error flag, DR (which clears the flags) and an error.
    fn read(&mut self) -> RxRead {
        if self.ore || self.fe || self.ne {
            self.ore = false;
            self.fe = false;
            self.ne = false;
            self.rxne = false;
            return RxRead::Error;
        }
        if self.rxne {
            self.rxne = false;
            return RxRead::Byte(self.dr);
        }
        RxRead::Empty
    }
}

/// Delivers `wire` one byte per interrupt, `fault` at byte `at`; returns what reached the queue.
fn run(wire: &[u8], fault: Option<(usize, Fault)>) -> Vec<InputItem> {
    let mut usart = Usart::new(wire);
    let mut asm = LineAssembler::<80>::new();
    let mut items = Vec::new();
    let mut i = 0;
    loop {
        let f = fault.and_then(|(at, f)| (at == i).then_some(f));
        if !usart.deliver(f) {
            break;
        }
        i += 1;
        // The interrupt runs while pending; one entry must clear it (no storm).
        let mut entries = 0;
        while usart.interrupt_pending() {
            entries += 1;
            assert!(entries <= 1, "interrupt re-entered (ORE {})", usart.ore);
            drain(
                || usart.read(),
                &mut asm,
                32,
                false,
                |e, _| items.push(InputItem::from_event(e)),
                |_| {},
            );
        }
    }
    items
}

#[test]
fn every_receive_error_at_every_position_rejects_the_line() {
    let wire = b"set counts_per_rev 200000\r";
    assert_eq!(
        run(wire, None),
        vec![InputItem::from_event(odocal::protocol::LineEvent::Line(
            "set counts_per_rev 200000"
        ))]
    );
    for fault in [Fault::Overrun, Fault::Framing, Fault::Noise] {
        // Every byte of the command, the terminator excluded (a lost terminator joins the
        // next line, which is then rejected instead).
        for at in 0..wire.len() - 1 {
            let items = run(wire, Some((at, fault)));
            assert_eq!(
                items,
                vec![InputItem::Rejected {
                    error: LineError::ReceiveError,
                    stop: false
                }],
                "{fault:?} at byte {at}"
            );
        }
        // A fault on the terminator: no line yet; the next line carries the error.
        let mut wire2 = wire.to_vec();
        wire2.extend_from_slice(b"pose\r");
        let items = run(&wire2, Some((wire.len() - 1, fault)));
        assert_eq!(
            items,
            vec![InputItem::Rejected {
                error: LineError::ReceiveError,
                stop: false
            }],
            "{fault:?} on the terminator"
        );
    }
}

#[test]
fn an_overrun_with_rxne_clear_is_cleared_in_one_interrupt() {
    // ORE set while RXNE is clear (the byte in DR was read, then two arrived back to back):
    // the RXNEIE interrupt is pending; a loop that only reads while RXNE is set never clears it.
    let mut usart = Usart::new(b"");
    usart.ore = true;
    let mut asm = LineAssembler::<80>::new();
    assert!(usart.interrupt_pending());
    let reads = drain(|| usart.read(), &mut asm, 32, false, |_, _| {}, |_| {});
    assert_eq!(reads, 1);
    assert!(!usart.interrupt_pending());
    // And the line it hit is rejected at its terminator.
    let mut items = Vec::new();
    for &b in b"stop\r" {
        if let Some(e) = asm.push(b) {
            items.push(InputItem::from_event(e));
        }
    }
    assert_eq!(
        items,
        vec![InputItem::Rejected {
            error: LineError::ReceiveError,
            stop: true
        }]
    );
}
