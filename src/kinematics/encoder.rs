//! Quadrature encoders: wrap-safe extension of hardware timer counts to `i64` tick totals.
//!
//! The timers run in encoder (QEI) mode and count up and down freely in 16 or 32 bits. Each
//! control period the raw count is read once; the difference to the previous read is taken in
//! the counter's own width (`wrapping_sub`, then sign-extended), so any wrap in either direction
//! is handled by construction as long as the wheel moves less than half the counter range per
//! period. A per-period delta larger than the robot can physically move (`max_step`) is a glitch
//! (noise on the encoder lines, a counter reset): it is reported as a fault and **not**
//! integrated; the reader re-synchronises on the new count so one glitch costs one fault.
//!
//! Polarity maps the counter direction to "wheel rolls forward = positive ticks".

use core::fmt;

/// Tick totals (or deltas) of the right and left wheels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct WheelTicks {
    /// Right wheel ticks, positive forward.
    pub right: i64,
    /// Left wheel ticks, positive forward.
    pub left: i64,
}

impl WheelTicks {
    /// A pair of tick values.
    pub const fn new(right: i64, left: i64) -> Self {
        WheelTicks { right, left }
    }
}

impl core::ops::Sub for WheelTicks {
    type Output = WheelTicks;

    /// Component-wise difference (wrapping).
    fn sub(self, other: WheelTicks) -> WheelTicks {
        WheelTicks::new(
            self.right.wrapping_sub(other.right),
            self.left.wrapping_sub(other.left),
        )
    }
}

/// Width of the hardware counter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum CounterWidth {
    /// 16-bit timer (TIM3, TIM4 on the STM32F4).
    Bits16,
    /// 32-bit timer (TIM2, TIM5 on the STM32F4).
    Bits32,
}

impl CounterWidth {
    /// Largest delta per period that can still be unwrapped unambiguously.
    pub const fn max_unambiguous_step(self) -> u32 {
        match self {
            CounterWidth::Bits16 => (1 << 15) - 1,
            CounterWidth::Bits32 => (1 << 31) - 1,
        }
    }

    /// Signed difference `now - prev` in this width.
    #[inline]
    pub fn delta(self, now: u32, prev: u32) -> i64 {
        match self {
            CounterWidth::Bits16 => i64::from((now as u16).wrapping_sub(prev as u16) as i16),
            CounterWidth::Bits32 => i64::from(now.wrapping_sub(prev) as i32),
        }
    }
}

/// Counting direction of an encoder relative to forward wheel motion.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Polarity {
    /// The counter counts up when the wheel rolls forward.
    Normal,
    /// The counter counts down when the wheel rolls forward (mirrored motor on the left side).
    Inverted,
}

impl Polarity {
    /// The opposite direction.
    pub const fn flipped(self) -> Polarity {
        match self {
            Polarity::Normal => Polarity::Inverted,
            Polarity::Inverted => Polarity::Normal,
        }
    }

    /// `self` flipped when `reversed`.
    pub const fn flipped_if(self, reversed: bool) -> Polarity {
        if reversed { self.flipped() } else { self }
    }
}

/// A glitch: the counter moved further in one period than the wheel can.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct EncoderGlitch {
    /// The rejected delta, counts.
    pub delta: i64,
    /// The largest accepted delta, counts.
    pub max_step: u32,
}

impl fmt::Display for EncoderGlitch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "encoder jumped {} counts in one period (max {})",
            self.delta, self.max_step
        )
    }
}

/// Encoder configuration (immutable while running).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct EncoderConfig {
    /// Width of the hardware counter.
    pub width: CounterWidth,
    /// Counting direction.
    pub polarity: Polarity,
    /// Largest physically possible |delta| per period, counts (see [`max_step_for`]).
    pub max_step: u32,
}

/// Largest plausible per-period delta for a wheel of `diameter_m` at `max_speed_mps`, with a
/// 50 % margin, clamped to what a counter of `width` can unwrap.
pub fn max_step_for(
    width: CounterWidth,
    counts_per_rev: u32,
    diameter_m: f64,
    max_speed_mps: f64,
    period_s: f64,
) -> u32 {
    let counts = 1.5 * max_speed_mps * period_s * f64::from(counts_per_rev)
        / (core::f64::consts::PI * diameter_m);
    let limit = width.max_unambiguous_step();
    if !(counts.is_finite()) || counts >= f64::from(limit) {
        limit
    } else if counts < 1.0 {
        1
    } else {
        libm::ceil(counts) as u32
    }
}

/// Wrap-safe reader of one encoder: turns raw counter values into an `i64` total.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Encoder {
    config: EncoderConfig,
    last_raw: u32,
    total: i64,
}

impl Encoder {
    /// A reader whose first raw value is `initial_raw`; the total starts at 0.
    pub const fn new(config: EncoderConfig, initial_raw: u32) -> Self {
        Encoder {
            config,
            last_raw: initial_raw,
            total: 0,
        }
    }

    /// Feeds the counter value read this period and returns the accepted delta (forward
    /// positive).
    ///
    /// # Errors
    /// [`EncoderGlitch`] when the delta exceeds `max_step`; the total is left unchanged and the
    /// reader re-synchronises on `raw`.
    #[inline]
    pub fn update(&mut self, raw: u32) -> Result<i64, EncoderGlitch> {
        let mut delta = self.config.width.delta(raw, self.last_raw);
        self.last_raw = raw;
        if delta.unsigned_abs() > u64::from(self.config.max_step) {
            return Err(EncoderGlitch {
                delta,
                max_step: self.config.max_step,
            });
        }
        if self.config.polarity == Polarity::Inverted {
            delta = -delta;
        }
        self.total = self.total.wrapping_add(delta);
        Ok(delta)
    }

    /// Tick total since construction (forward positive).
    pub fn total(&self) -> i64 {
        self.total
    }

    /// The configuration.
    pub fn config(&self) -> &EncoderConfig {
        &self.config
    }

    /// Changes the counting direction (a wiring correction); the total so far is kept and
    /// later deltas count with the new sign.
    pub fn set_polarity(&mut self, polarity: Polarity) {
        self.config.polarity = polarity;
    }

    /// Changes the glitch limit (after a geometry change); the count and total are kept.
    pub fn set_max_step(&mut self, max_step: u32) {
        self.config.max_step = max_step;
    }

    /// [`Encoder::update`] for a reading that spans `periods` control periods (the ones a stall
    /// held back arrive at once): the glitch limit is `periods` times the per-period one, up to
    /// what the counter's width tells apart, for this reading only.
    ///
    /// # Errors
    /// As [`Encoder::update`], against the widened limit.
    pub fn update_over(&mut self, raw: u32, periods: u32) -> Result<i64, EncoderGlitch> {
        let per_period = self.config.max_step;
        self.config.max_step = per_period
            .saturating_mul(periods.max(1))
            .min(self.config.width.max_unambiguous_step());
        let result = self.update(raw);
        self.config.max_step = per_period;
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(width: CounterWidth, max_step: u32) -> EncoderConfig {
        EncoderConfig {
            width,
            polarity: Polarity::Normal,
            max_step,
        }
    }

    #[test]
    fn a_reading_over_several_periods_widens_the_glitch_limit_for_that_reading_only() {
        let mut e = Encoder::new(cfg(CounterWidth::Bits16, 100), 0);
        // Three periods' worth: 300 counts pass, and the limit is back to 100 after.
        assert_eq!(e.update_over(250, 3), Ok(250));
        assert_eq!(e.config().max_step, 100);
        assert!(e.update(400).is_err());
        // However many periods, never beyond what 16 bits tell apart.
        let mut e = Encoder::new(cfg(CounterWidth::Bits16, 100), 0);
        assert_eq!(e.update_over(32_767, 1_000), Ok(32_767));
        let mut e = Encoder::new(cfg(CounterWidth::Bits16, 100), 0);
        assert!(e.update_over(32_768, 1_000).is_err());
    }

    /// Drives a simulated counter of the given width across `boundary` in both directions and
    /// checks that the total equals the true motion.
    fn cross(width: CounterWidth, boundary: u64, step: i64) {
        let modulus: u64 = match width {
            CounterWidth::Bits16 => 1 << 16,
            CounterWidth::Bits32 => 1 << 32,
        };
        for dir in [1i64, -1] {
            // Start a few steps before (or after) the boundary.
            let start = (boundary as i128 - i128::from(dir * step * 5)).rem_euclid(modulus as i128);
            let mut raw = start as u64;
            let mut enc = Encoder::new(cfg(width, 1000), raw as u32);
            let mut truth = 0i64;
            for _ in 0..10 {
                let d = dir * step;
                raw = ((raw as i128 + i128::from(d)).rem_euclid(modulus as i128)) as u64;
                truth += d;
                assert_eq!(enc.update(raw as u32), Ok(d));
            }
            assert_eq!(
                enc.total(),
                truth,
                "width {width:?} boundary {boundary:#x} dir {dir}"
            );
        }
    }

    #[test]
    fn wraps_at_every_16_bit_boundary() {
        for boundary in [0u64, 0x7FFF, 0x8000, 0xFFFF] {
            for step in [1, 7, 999] {
                cross(CounterWidth::Bits16, boundary, step);
            }
        }
    }

    #[test]
    fn wraps_at_every_32_bit_boundary() {
        for boundary in [0u64, 0x7FFF_FFFF, 0x8000_0000, 0xFFFF_FFFF, 0xFFFF] {
            for step in [1, 7, 999] {
                cross(CounterWidth::Bits32, boundary, step);
            }
        }
    }

    #[test]
    fn largest_unambiguous_step_in_16_bits() {
        let max = CounterWidth::Bits16.max_unambiguous_step();
        let mut enc = Encoder::new(cfg(CounterWidth::Bits16, max), 0xFFF0);
        let raw = (0xFFF0u32 + max) & 0xFFFF;
        assert_eq!(enc.update(raw), Ok(i64::from(max)));
        assert_eq!(enc.update(0xFFF0), Ok(-i64::from(max)));
        assert_eq!(enc.total(), 0);
    }

    #[test]
    fn glitch_is_reported_and_not_integrated() {
        let mut enc = Encoder::new(cfg(CounterWidth::Bits16, 500), 100);
        assert_eq!(enc.update(300), Ok(200));
        assert_eq!(
            enc.update(5000),
            Err(EncoderGlitch {
                delta: 4700,
                max_step: 500
            })
        );
        assert_eq!(enc.total(), 200);
        // Re-synchronised: the next normal step counts again.
        assert_eq!(enc.update(5010), Ok(10));
        assert_eq!(enc.total(), 210);
        // A backwards jump is a glitch too.
        assert!(enc.update(4000).is_err());
        assert_eq!(enc.total(), 210);
    }

    #[test]
    fn inverted_polarity_counts_forward_positive() {
        let mut enc = Encoder::new(
            EncoderConfig {
                width: CounterWidth::Bits32,
                polarity: Polarity::Inverted,
                max_step: 100,
            },
            5,
        );
        assert_eq!(enc.update(0), Ok(5));
        assert_eq!(enc.update(u32::MAX - 14), Ok(15));
        assert_eq!(enc.total(), 20);
    }

    #[test]
    fn max_step_for_reference_robot() {
        // 2 m/s on a 150 mm wheel at 1 kHz: 849 counts per period, +50 % margin.
        let step = max_step_for(CounterWidth::Bits16, 200_000, 0.150, 2.0, 1e-3);
        assert_eq!(step, 1274);
        // Absurd speed is clamped to what 16 bits can unwrap.
        let step = max_step_for(CounterWidth::Bits16, 200_000, 0.150, 1e6, 1e-3);
        assert_eq!(step, CounterWidth::Bits16.max_unambiguous_step());
    }
}
