//! The console's receive ring: a buffer a DMA stream fills in circular mode while the CPU may
//! be stalled (a flash erase stops instruction fetch for up to a second on a single-bank part,
//! the DMA keeps running), read by the serial receive when it next runs.
//!
//! [`RingCursor`] is the reading side's arithmetic, portable and tested here; the board gives it
//! the DMA's write position (buffer length − the stream's remaining-transfer count) and the
//! stream's half-transfer and transfer-complete flags, read and cleared at every call. From
//! those it tells a byte to read, an empty ring, or an overrun: more bytes arrived since the
//! last read than the ring holds, so some were overwritten. The write position alone cannot
//! tell `k` laps apart; the flags can whenever the path from the last seen write position to
//! this one does not cross the boundary a set flag reports (a lap crosses both). When that path
//! crosses both boundaries itself the flags cannot tell (they are sticky: one flag for any
//! number of crossings), so the caller also gives the most bytes the line can have delivered
//! since the previous call (the time elapsed, from a counter that runs through a stall, at the
//! line's byte rate): if a whole extra lap fits in that, the read is an overrun too. Only such
//! a path (more than half the ring arrived since the previous read, over a stall long enough
//! for a lap) can be reported as an overrun without one.

/// How much slower than nominal the core clock can run, percent. On the internal RC oscillator
/// (the boot's fallback when the external clock does not start) the STM32F4 datasheets give the
/// factory-calibrated HSI −8 % to +4.5 % over −40…105 °C (±1 % at 25 °C); a crystal is far
/// inside that. A cycle counter on a slow clock counts fewer cycles in the same time, so a
/// bound on arrivals must take the byte time in the slowest clock's cycles.
pub const CORE_CLOCK_SLOW_PERCENT: u32 = 8;

/// The core clock's cycles per byte at `baud` (10 bits a byte, 8N1) that [`arrivable`] divides
/// by: a byte time counted by a core clock of nominal `core_hz` running
/// [`CORE_CLOCK_SLOW_PERCENT`] slow (at least 1). On a crystal the bound is then 8.7 % above
/// what can arrive: it only makes the lap test of a stall long enough for a lap a little earlier.
pub const fn cycles_per_byte_bound(core_hz: u32, baud: u32) -> u32 {
    let nominal = core_hz as u64 * 10 / if baud == 0 { 1 } else { baud as u64 };
    let slowest = nominal * (100 - CORE_CLOCK_SLOW_PERCENT as u64) / 100;
    if slowest == 0 {
        1
    } else if slowest > u32::MAX as u64 {
        u32::MAX
    } else {
        slowest as u32
    }
}

/// At least the bytes the line can have delivered in `cycles` of the core clock
/// ([`cycles_per_byte_bound`]'s `per_byte`): whole byte times, plus the ones under way at
/// either end.
pub fn arrivable(cycles: u32, per_byte: u32) -> usize {
    (cycles / per_byte.max(1)) as usize + 2
}

/// What the next read of the ring gives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RingRead {
    /// The byte at this index of the buffer is the next one received.
    Byte(usize),
    /// Nothing new.
    Empty,
    /// Bytes were overwritten before they were read; the cursor has skipped to the write
    /// position (the line being received is lost, as after a USART overrun).
    Overrun,
}

/// The reading side of a receive ring of `N` bytes (`N` even, at least 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RingCursor<const N: usize> {
    /// Index of the next byte to read.
    read: usize,
    /// The write position seen at the last call.
    seen_write: usize,
}

impl<const N: usize> Default for RingCursor<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> RingCursor<N> {
    /// A cursor for a ring the DMA starts filling at index 0.
    pub const fn new() -> Self {
        const {
            assert!(
                N >= 2 && N.is_multiple_of(2),
                "a receive ring has an even length"
            )
        };
        RingCursor {
            read: 0,
            seen_write: 0,
        }
    }

    /// Bytes received and not read yet (as far as the last call saw).
    pub fn pending(&self) -> usize {
        (self.seen_write + N - self.read) % N
    }

    /// One read. `write` is the DMA's next write index (`N` − remaining count; `N` means 0);
    /// `half` and `full` whether the stream reported crossing the middle and the end of the
    /// buffer since the previous call (the caller clears both flags as it reads them);
    /// `arrivable` at least the number of bytes that can have arrived since the previous call.
    pub fn next(&mut self, write: usize, half: bool, full: bool, arrivable: usize) -> RingRead {
        let write = write % N;
        let new = (write + N - self.seen_write) % N;
        // The boundaries the path seen_write → write crosses (unwrapped: positions
        // seen_write + 1 ..= seen_write + new).
        let end = self.seen_write + new;
        let crosses = |at: usize| self.seen_write < at && at <= end;
        let crosses_half = crosses(N / 2) || crosses(N + N / 2);
        let crosses_full = crosses(N);
        let lapped = (half && !crosses_half)
            || (full && !crosses_full)
            || (crosses_half && crosses_full && arrivable >= new + N);
        let overrun = lapped || self.pending() + new >= N;
        self.seen_write = write;
        if overrun {
            self.read = write;
            return RingRead::Overrun;
        }
        if self.read == write {
            return RingRead::Empty;
        }
        let at = self.read;
        self.read = (self.read + 1) % N;
        RingRead::Byte(at)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A DMA stream writing into a ring of 8, with its half/complete flags.
    #[derive(Default)]
    struct Dma {
        buf: [u8; 8],
        write: usize,
        half: bool,
        full: bool,
        /// Bytes received since the cursor's last call (what a clock would bound).
        arrived: usize,
    }

    impl Dma {
        fn receive(&mut self, bytes: &[u8]) {
            self.arrived += bytes.len();
            for &b in bytes {
                self.buf[self.write] = b;
                self.write = (self.write + 1) % 8;
                self.half |= self.write == 4;
                self.full |= self.write == 0;
            }
        }

        /// Reads everything the cursor gives, as the serial receive does.
        fn drain(&mut self, cursor: &mut RingCursor<8>) -> (Vec<u8>, bool) {
            let mut got = Vec::new();
            let mut overrun = false;
            loop {
                let (half, full) = (self.half, self.full);
                self.half = false;
                self.full = false;
                let arrived = core::mem::take(&mut self.arrived);
                match cursor.next(self.write, half, full, arrived) {
                    RingRead::Byte(i) => got.push(self.buf[i]),
                    RingRead::Empty => return (got, overrun),
                    RingRead::Overrun => overrun = true,
                }
            }
        }
    }

    #[test]
    fn bytes_come_out_in_order_across_the_wrap() {
        let mut dma = Dma::default();
        let mut c = RingCursor::<8>::new();
        assert_eq!(dma.drain(&mut c), (vec![], false));
        for chunk in [&b"abc"[..], b"defgh", b"i", b"jklmnop", b"q"] {
            dma.receive(chunk);
            assert_eq!(dma.drain(&mut c), (chunk.to_vec(), false), "{chunk:?}");
        }
        assert_eq!(c.pending(), 0);
    }

    #[test]
    fn a_ring_filled_to_one_less_than_its_length_loses_nothing() {
        let mut dma = Dma::default();
        let mut c = RingCursor::<8>::new();
        dma.receive(b"xyz");
        assert_eq!(dma.drain(&mut c).0, b"xyz");
        // 7 bytes while the reader is stalled (a flash erase): all kept, across the wrap.
        dma.receive(b"1234567");
        assert_eq!(dma.drain(&mut c), (b"1234567".to_vec(), false));
    }

    #[test]
    fn a_full_ring_or_a_lap_is_an_overrun_and_reading_resumes_after_it() {
        // Exactly the ring's length: the write position is back at the read position.
        let mut dma = Dma::default();
        let mut c = RingCursor::<8>::new();
        dma.receive(b"12345678");
        assert_eq!(dma.drain(&mut c), (vec![], true));
        dma.receive(b"ok");
        assert_eq!(dma.drain(&mut c), (b"ok".to_vec(), false));

        // More than a lap, ending at a position the write position alone would read as 3
        // new bytes: the flags give it away.
        for unread in 0..3 {
            let mut dma = Dma::default();
            let mut c = RingCursor::<8>::new();
            dma.receive(&b"abc"[..unread]);
            dma.receive(b"0123456789a");
            let (got, overrun) = dma.drain(&mut c);
            assert!(overrun, "{unread} unread, then 11 bytes: {got:?}");
            dma.receive(b"z");
            assert_eq!(dma.drain(&mut c), (b"z".to_vec(), false));
        }
    }

    #[test]
    fn bytes_read_one_call_at_a_time_with_arrivals_in_between() {
        // The serial receive reads a bounded number of bytes per pass; bytes keep arriving.
        let mut dma = Dma::default();
        let mut c = RingCursor::<8>::new();
        let mut got = Vec::new();
        for b in b"the quick brown fox".iter() {
            dma.receive(&[*b]);
            let (half, full) = (dma.half, dma.full);
            dma.half = false;
            dma.full = false;
            if let RingRead::Byte(i) = c.next(dma.write, half, full, 1) {
                got.push(dma.buf[i]);
            }
        }
        // Behind by nothing: every arrival was followed by one read.
        assert_eq!(got, b"the quick brown fox");
    }

    /// A stall on the internal oscillator at its slowest (8 % below nominal: the cycle counter
    /// runs slow against the line) while the PC sends without a pause at 115,200 Bd: for every
    /// byte count up to 4 laps of the board's 512-byte ring, from every start, the board's
    /// bound ([`arrivable`] of the cycles counted, with [`cycles_per_byte_bound`]) is at least
    /// what arrived, and every lap is an overrun, never a byte. On the nominal byte time the
    /// slow counter's bound falls 8 % short of what arrived: at 100 MHz a stall of 1,017 bytes
    /// (a lap and 505, the path crossing both flags) was handed over as 505 bytes.
    #[test]
    fn rx_ring_reports_every_lap_on_a_slow_clock() {
        const N: usize = 512;
        const BAUD: u32 = 115_200;
        for core_hz in [100_000_000u32, 168_000_000, 180_000_000] {
            let per_byte = cycles_per_byte_bound(core_hz, BAUD);
            // The datasheets' slowest HSI: 8 % below nominal.
            let slow_hz = f64::from(core_hz) * 0.92;
            for start in (0..N).step_by(7) {
                for count in 0..=4 * N {
                    // `count` bytes take count × 10 / BAUD s; the slow counter counts these.
                    let cycles = (count as f64 * 10.0 / f64::from(BAUD) * slow_hz) as u32;
                    let bound = arrivable(cycles, per_byte);
                    assert!(bound >= count, "{core_hz} Hz: {count} bytes, bound {bound}");
                    let crosses = |at: usize| {
                        let first = start + 1 + (at % N + N - (start + 1) % N) % N;
                        first <= start + count
                    };
                    let mut c = RingCursor::<N> {
                        read: start,
                        seen_write: start,
                    };
                    let got = c.next((start + count) % N, crosses(N / 2), crosses(N), bound);
                    if count >= N {
                        assert_eq!(got, RingRead::Overrun, "{core_hz} Hz: {count} bytes");
                    } else if count > 0 {
                        assert_eq!(got, RingRead::Byte(start), "{core_hz} Hz: {count} bytes");
                    }
                }
            }
        }
    }

    /// Every start position of a ring of the board's length (512) × every byte count from 0 to
    /// 4 × the ring arriving before the next read, with the flags the DMA would leave: fewer
    /// bytes than the ring holds are handed over, from the first one on, all of them; as many
    /// or more (one or more laps) are an overrun, never a byte. With `arrivable` exactly the
    /// count (the tightest bound a board's clock can give) both hold; with any looser bound no
    /// lap is ever handed over either.
    #[test]
    fn rx_ring_reports_every_lap() {
        const N: usize = 512;
        let mut cases = 0u32;
        for start in 0..N {
            for count in 0..=4 * N {
                // The write position passes start+1 ..= start+count (unwrapped): the first of
                // them at index `at` of the ring, if that is within the count.
                let crosses = |at: usize| {
                    let first = start + 1 + (at % N + N - (start + 1) % N) % N;
                    first <= start + count
                };
                let (half, full) = (crosses(N / 2), crosses(N));
                let write = (start + count) % N;
                for slack in [0, 1, N, 4 * N] {
                    let mut c = RingCursor::<N> {
                        read: start,
                        seen_write: start,
                    };
                    let got = c.next(write, half, full, count + slack);
                    let lap = count >= N;
                    if lap {
                        assert_eq!(got, RingRead::Overrun, "start {start}, {count} bytes");
                        assert_eq!(c.next(write, false, false, 1), RingRead::Empty);
                    } else if slack == 0 {
                        let want = if count == 0 {
                            RingRead::Empty
                        } else {
                            RingRead::Byte(start)
                        };
                        assert_eq!(got, want, "start {start}, {count} bytes");
                        assert_eq!(c.pending(), count.saturating_sub(1));
                    }
                    cases += 1;
                }
            }
        }
        assert_eq!(cases, 512 * 2049 * 4);
    }
}
