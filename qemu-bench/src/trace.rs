//! A deterministic encoder trace: about 1 km of mixed driving sampled at 1 kHz.
//!
//! The trace is a sequence of segments (straight runs, arcs, turns in place, reversing and
//! stops) whose kind, wheel speeds and length come from a xorshift32 generator with a fixed
//! seed. Wheel speeds ramp towards each segment's targets with a bounded acceleration, so
//! per-period tick deltas vary smoothly like a real robot's. Every quantity is an integer
//! (speeds in Q16 ticks per period), so the host and the target produce identical totals.
//!
//! Units: ticks of the reference robot (200,000 counts per revolution of a 150 mm wheel, 2.36 µm
//! per tick); one step is one 1 kHz control period. 424 ticks per step is 1 m/s.

use odocal::kinematics::encoder::WheelTicks;

/// Number of control periods in the standard trace.
pub const STEPS: u32 = 2_500_000;

/// Fixed seed of the generator.
const SEED: u32 = 0x0D0C_A1B5;

/// Largest change of a wheel speed per step, Q16 ticks per step (0.25 tick/step²: 0.59 m/s²).
const ACCEL_Q16: i64 = 1 << 14;

/// Generator state of the trace (an iterator over cumulative tick totals).
#[derive(Clone, Debug)]
pub struct Trace {
    rng: u32,
    remaining: u32,
    segment_left: u32,
    speed_q16: [i64; 2],
    target_q16: [i64; 2],
    position_q16: [i64; 2],
}

impl Trace {
    /// The standard trace of [`STEPS`] periods.
    pub fn standard() -> Self {
        Trace::with_steps(STEPS)
    }

    /// The same driving, cut after `steps` periods.
    pub fn with_steps(steps: u32) -> Self {
        Trace {
            rng: SEED,
            remaining: steps,
            segment_left: 0,
            speed_q16: [0; 2],
            target_q16: [0; 2],
            position_q16: [0; 2],
        }
    }

    /// xorshift32 (Marsaglia), never 0 for a non-zero seed.
    fn next_u32(&mut self) -> u32 {
        let mut x = self.rng;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.rng = x;
        x
    }

    /// A uniform integer in `lo..=hi`.
    fn range(&mut self, lo: i64, hi: i64) -> i64 {
        lo + i64::from(self.next_u32()) % (hi - lo + 1)
    }

    /// Picks the next segment: target wheel speeds (ticks per step) and a length.
    fn new_segment(&mut self) {
        let (right, left) = match self.next_u32() % 8 {
            // Straight ahead, 0.24 .. 1.0 m/s.
            0..=2 => {
                let v = self.range(100, 424);
                (v, v)
            }
            // Arc: base speed plus a wheel-speed difference either way.
            3 | 4 => {
                let v = self.range(100, 380);
                let dv = self.range(-80, 80);
                (v + dv, v - dv)
            }
            // Turn in place, either direction.
            5 => {
                let w = self.range(-200, 200);
                (w, -w)
            }
            // Reverse.
            6 => {
                let v = self.range(50, 200);
                (-v, -v)
            }
            // Stop.
            _ => (0, 0),
        };
        self.target_q16 = [right << 16, left << 16];
        self.segment_left = self.range(200, 4000) as u32;
    }
}

impl Iterator for Trace {
    type Item = WheelTicks;

    /// Cumulative tick totals at the end of the next period.
    fn next(&mut self) -> Option<WheelTicks> {
        if self.remaining == 0 {
            return None;
        }
        self.remaining -= 1;
        if self.segment_left == 0 {
            self.new_segment();
        }
        self.segment_left -= 1;
        for wheel in 0..2 {
            let dv = (self.target_q16[wheel] - self.speed_q16[wheel]).clamp(-ACCEL_Q16, ACCEL_Q16);
            self.speed_q16[wheel] += dv;
            self.position_q16[wheel] += self.speed_q16[wheel];
        }
        Some(WheelTicks::new(
            self.position_q16[0] >> 16,
            self.position_q16[1] >> 16,
        ))
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;

    #[test]
    fn steps_are_bounded_and_the_trace_is_reproducible() {
        let mut prev = WheelTicks::default();
        let mut n = 0u32;
        for t in Trace::with_steps(200_000) {
            let d = t - prev;
            // Targets never exceed 424 + 80 ticks per step, and a Q16 floor adds at most 1.
            assert!(d.right.abs() <= 505 && d.left.abs() <= 505, "{d:?}");
            prev = t;
            n += 1;
        }
        assert_eq!(n, 200_000);
        assert_eq!(Trace::with_steps(200_000).last(), Some(prev));
    }
}
