//! The board's time of a pose on the PC's clock.
//!
//! Every `stream` line carries the board's time `t_b` of its pose (SysTick, µs resolution).
//! Its arrival on the PC at `t_pc` (the PC's realtime clock, which ROS stamps use) is later by
//! the transfer delay: the line's own bytes on the wire (10 bits a byte at the link's baud rate,
//! known per line and taken off first) plus the variable part (the board's UART queue, the USB
//! adapter's latency timer, the PC's scheduling), which is never negative. So
//! `t_pc - wire - t_b = offset + delay` with `delay ≥ 0`, and the smallest such value over a
//! window estimates `offset` (the minimum-delay filter of clock synchronisation). The window
//! slides (10 s by default) so that a slow drift between the board's crystal and the PC's clock
//! is followed; the stamp of a pose is `t_b + offset`. What each line's `delay` was above that
//! minimum is its jitter, kept in statistics for the operator and the diagnostics.

use std::collections::VecDeque;

/// Maps board times to the PC's clock (see the module's text).
#[derive(Debug)]
pub struct ClockMap {
    /// Seconds of wire time per byte (0 on a pseudo-terminal: no wire).
    byte_s: f64,
    window_s: f64,
    /// `(t_b, t_pc - wire - t_b)` of the window's lines, with the minimum kept at the front.
    samples: VecDeque<(f64, f64)>,
    /// Jitter (delay above the current minimum) of every line so far, seconds.
    jitter: Vec<f64>,
    last_board: Option<f64>,
    /// The board's time is the clock (`--use-sim-time`): no offset, no jitter.
    board_time: bool,
}

/// Statistics of the mapping so far.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClockStats {
    /// The current offset `t_pc - t_b`, seconds.
    pub offset_s: f64,
    /// Lines mapped.
    pub lines: usize,
    /// Median, 99th percentile and largest jitter, seconds.
    pub jitter_median_s: f64,
    pub jitter_p99_s: f64,
    pub jitter_max_s: f64,
}

impl ClockMap {
    /// A map for a link at `baud` (`None`: a pseudo-terminal, no wire time), following drift
    /// over `window_s` seconds.
    pub fn new(baud: Option<u32>, window_s: f64) -> ClockMap {
        ClockMap {
            byte_s: baud.map_or(0.0, |b| 10.0 / f64::from(b)),
            window_s,
            samples: VecDeque::new(),
            jitter: Vec::new(),
            last_board: None,
            board_time: false,
        }
    }

    /// The identity map: the board's time is the ROS time (a simulation's clock).
    pub fn board() -> ClockMap {
        ClockMap {
            board_time: true,
            ..ClockMap::new(None, 0.0)
        }
    }

    /// A line of `len` bytes (its line end included) with board time `t_board` arrived at
    /// `t_pc`: returns the PC time of the board's instant `t_board`. A board time that goes
    /// backwards (the board was reset) restarts the map.
    pub fn map(&mut self, t_board: f64, t_pc: f64, len: usize) -> f64 {
        if self.board_time {
            self.last_board = Some(t_board);
            self.samples.clear();
            self.samples.push_back((t_board, 0.0));
            self.jitter.push(0.0);
            return t_board;
        }
        if self.last_board.is_some_and(|last| t_board < last) {
            self.samples.clear();
        }
        self.last_board = Some(t_board);
        let d = t_pc - len as f64 * self.byte_s - t_board;
        // Keep the window's candidates for its minimum: a sample older than the window leaves,
        // and one that is not below a newer one never becomes the minimum.
        while self
            .samples
            .front()
            .is_some_and(|&(t, _)| t < t_board - self.window_s)
        {
            self.samples.pop_front();
        }
        while self.samples.back().is_some_and(|&(_, old)| old >= d) {
            self.samples.pop_back();
        }
        self.samples.push_back((t_board, d));
        let offset = self.samples.front().map_or(d, |&(_, o)| o);
        self.jitter.push(d - offset);
        t_board + offset
    }

    /// The board time of PC time `t_pc` (the current offset; `None` before the first line).
    pub fn board_time_of(&self, t_pc: f64) -> Option<f64> {
        self.samples.front().map(|&(_, o)| t_pc - o)
    }

    /// The statistics so far (`None` before the first line).
    pub fn stats(&self) -> Option<ClockStats> {
        let offset_s = self.samples.front()?.1;
        let mut j = self.jitter.clone();
        j.sort_by(f64::total_cmp);
        let at = |q: f64| j[((j.len() - 1) as f64 * q).round() as usize];
        Some(ClockStats {
            offset_s,
            lines: j.len(),
            jitter_median_s: at(0.5),
            jitter_p99_s: at(0.99),
            jitter_max_s: at(1.0),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_smallest_delay_sets_the_offset_and_the_rest_is_jitter() {
        // Board 1000 s behind the PC; delays 3, 1, 2 ms above the wire time of 60 bytes.
        let mut m = ClockMap::new(Some(115_200), 10.0);
        let wire = 60.0 * 10.0 / 115_200.0;
        let off = 1000.0;
        let a = m.map(1.00, 1.00 + off + wire + 0.003, 60);
        assert!(
            (a - (1.00 + off + 0.003)).abs() < 1e-9,
            "first line: its own delay"
        );
        let b = m.map(1.01, 1.01 + off + wire + 0.001, 60);
        assert!((b - (1.01 + off + 0.001)).abs() < 1e-9);
        let c = m.map(1.02, 1.02 + off + wire + 0.002, 60);
        assert!(
            (c - (1.02 + off + 0.001)).abs() < 1e-9,
            "stamped with the minimum"
        );
        let s = m.stats().unwrap();
        assert!((s.offset_s - (off + 0.001)).abs() < 1e-9);
        assert!((s.jitter_max_s - 0.001).abs() < 1e-9, "{s:?}");
    }

    #[test]
    fn an_old_minimum_leaves_the_window_and_a_reset_restarts() {
        let mut m = ClockMap::new(None, 1.0);
        m.map(0.0, 5.0, 10);
        // 2 s later every line is 4 ms late: the old minimum has left the window.
        m.map(2.0, 7.004, 10);
        let t = m.map(2.1, 7.104, 10);
        assert!((t - 7.104).abs() < 1e-9);
        // The board restarts: its time goes back; the map starts again.
        let t = m.map(0.5, 9.0, 10);
        assert!((t - 9.0).abs() < 1e-9);
    }
}
