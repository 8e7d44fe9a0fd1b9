//! The console's receive half on every board: USART2 RX by DMA1 stream 5 (channel 4: RM0090
//! Table 42, the same request mapping in RM0390 and RM0383) in circular mode into a RAM ring, so
//! bytes keep arriving while the CPU is stalled by a flash erase (one flash bank: an erase stops
//! instruction fetch, and with it every interrupt, for up to a second on a 16 KiB sector and two
//! on a 128 KiB one; the DMA and the USART keep running from RAM). The serial receive reads the
//! ring when it runs: the app pends it every millisecond (`CONSOLE_RX_POLLED`), and after a
//! stall it drains what arrived.
//!
//! The ring holds [`RX_RING_BYTES`]: at 115,200 baud (11.5 bytes per millisecond) that is 44 ms
//! of a continuous stream, about 100 s of typing. More than that between two reads (a long
//! paste during an erase) is an overrun, reported like the USART's own (the line being
//! received is lost). USART framing and noise errors are not reported in this mode: the DMA
//! takes the byte, and a garbled line fails the parser instead.

use core::ptr::addr_of_mut;

use embedded_hal_nb::serial;
use stm32f4xx_hal::pac::{self, DMA1, USART2};
use stm32f4xx_hal::rcc::{Enable, Rcc};
use stm32f4xx_hal::serial::{Rx, RxListen};

use crate::app::rx_ring::{self, RingCursor, RingRead};

/// Bytes of the receive ring (even: the DMA's half-transfer flag marks its middle).
pub const RX_RING_BYTES: usize = 512;

/// The console's baud rate; a byte is 10 bits on the line (8N1).
pub const CONSOLE_BAUD: u32 = 115_200;

/// DMA1 stream of USART2 RX.
const STREAM: usize = 5;
/// DMA1 channel of USART2 RX on that stream.
const CHANNEL: u8 = 4;

/// The ring the DMA writes. Only the DMA writes it and only [`ConsoleRx::read`] reads it
/// (volatile, at indices the DMA has passed).
static mut RING: [u8; RX_RING_BYTES] = [0; RX_RING_BYTES];

/// Bytes were lost before they were read: overwritten in the ring, or (in interrupt mode) a
/// receive error of the USART.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RingOverrun;

impl serial::Error for RingOverrun {
    fn kind(&self) -> serial::ErrorKind {
        serial::ErrorKind::Overrun
    }
}

/// The console's receive half: the DMA-filled ring and its reading cursor, or (when the stream
/// did not start) USART2's RX interrupt.
pub struct ConsoleRx {
    mode: Mode,
    // USART2's receive half: read directly in interrupt mode; owned (its pin and the receiver)
    // while the DMA reads it otherwise.
    rx: Rx<USART2>,
}

/// How the bytes arrive.
enum Mode {
    /// DMA1 stream 5 fills the ring.
    Dma {
        cursor: RingCursor<RX_RING_BYTES>,
        dma: DMA1,
        /// Core cycles per byte on the line (rounded down: the bound errs high).
        cycles_per_byte: u32,
        /// DWT.CYCCNT at the previous read: it counts through a flash stall, so the bytes
        /// that can have arrived since are bounded by the time elapsed.
        last_cycles: u32,
    },
    /// The RX interrupt: the stream did not start (a part or an emulator without the DMA
    /// controller; the boot log says so).
    Interrupt,
}

impl ConsoleRx {
    /// Starts the DMA stream into the ring and lets USART2 request it for every received byte
    /// (its RX interrupt stays off: the DMA takes each byte). If the stream does not read back
    /// as enabled, receives by the RX interrupt instead.
    pub fn start(mut rx: Rx<USART2>, dma: DMA1, rcc: &mut Rcc, sysclk_hz: u32) -> Self {
        DMA1::enable(rcc);
        let st = dma.st(STREAM);
        // RM0090 §10.3.17: a stream is configured while disabled.
        st.cr().modify(|_, w| w.en().disabled());
        while st.cr().read().en().is_enabled() {}
        // SAFETY: USART2 is initialised and owned here through `rx`; only its data register's
        // address is taken, and CR3's DMAR bit set below (nothing else writes CR3 after
        // `Serial::new`).
        let usart = unsafe { &*pac::USART2::ptr() };
        let data_register = usart.dr().as_ptr() as u32;
        // SAFETY: any 32-bit value is a peripheral address to the stream; this one is USART2's
        // data register.
        st.par().write(|w| unsafe { w.pa().bits(data_register) });
        // The ring is a static in SRAM (reachable by DMA1); from here on only the DMA writes it,
        // and `read` reads it volatile.
        let ring = addr_of_mut!(RING) as u32;
        // SAFETY: as above, the ring's address.
        st.m0ar().write(|w| unsafe { w.m0a().bits(ring) });
        st.ndtr().write(|w| w.ndt().set(RX_RING_BYTES as u16));
        // Direct mode (FIFO off), byte to byte, memory incremented, circular, high priority.
        st.fcr().reset();
        dma.hifcr().write(|w| {
            w.ctcif5().clear();
            w.chtif5().clear();
            w.cteif5().clear();
            w.cdmeif5().clear();
            w.cfeif5().clear()
        });
        st.cr().write(|w| {
            w.chsel().set(CHANNEL);
            w.dir().peripheral_to_memory();
            w.minc().set_bit();
            w.circ().set_bit();
            w.pl().high();
            w.en().enabled()
        });
        if !st.cr().read().en().is_enabled() {
            defmt::warn!("console: the receive DMA did not start, receiving by interrupt");
            rx.listen();
            return ConsoleRx {
                mode: Mode::Interrupt,
                rx,
            };
        }
        usart.cr3().modify(|_, w| w.dmar().set_bit());
        ConsoleRx {
            mode: Mode::Dma {
                cursor: RingCursor::new(),
                dma,
                cycles_per_byte: rx_ring::cycles_per_byte_bound(sysclk_hz, CONSOLE_BAUD),
                last_cycles: cortex_m::peripheral::DWT::cycle_count(),
            },
            rx,
        }
    }
}

impl serial::ErrorType for ConsoleRx {
    type Error = RingOverrun;
}

impl serial::Read<u8> for ConsoleRx {
    fn read(&mut self) -> nb::Result<u8, RingOverrun> {
        let Mode::Dma {
            cursor,
            dma,
            cycles_per_byte,
            last_cycles,
        } = &mut self.mode
        else {
            // Any receive error (overrun, framing, noise, parity) is reported as a lost line.
            return self.rx.read().map_err(|e| e.map(|_| RingOverrun));
        };
        // The position, the flags, the position again: when both positions agree no byte
        // moved in between, so the flags belong to that position (a flag read without the
        // crossing it reports, or the reverse, would look like a lap).
        let remaining = || usize::from(dma.st(STREAM).ndtr().read().ndt().bits());
        let mut before = remaining();
        let (half, full, after) = loop {
            let flags = dma.hisr().read();
            let after = remaining();
            if after == before {
                break (flags.htif5().is_half(), flags.tcif5().is_complete(), after);
            }
            before = after;
        };
        if half || full {
            dma.hifcr().write(|w| {
                w.chtif5().clear();
                w.ctcif5().clear()
            });
        }
        let write = RX_RING_BYTES - after.min(RX_RING_BYTES);
        // The bytes the time since the previous read can hold on the slowest core clock
        // (CYCCNT wraps after 23 s at 180 MHz, the fastest of these parts; reads come every
        // millisecond).
        let now = cortex_m::peripheral::DWT::cycle_count();
        let arrivable = rx_ring::arrivable(now.wrapping_sub(*last_cycles), *cycles_per_byte);
        *last_cycles = now;
        match cursor.next(write, half, full, arrivable) {
            RingRead::Byte(i) => {
                // SAFETY: `i` < RX_RING_BYTES, a byte the DMA has written and will not write
                // again before it has gone round the ring (which `next` reports as an overrun).
                let byte = unsafe { addr_of_mut!(RING).cast::<u8>().add(i).read_volatile() };
                Ok(byte)
            }
            RingRead::Empty => Err(nb::Error::WouldBlock),
            RingRead::Overrun => Err(nb::Error::Other(RingOverrun)),
        }
    }
}
