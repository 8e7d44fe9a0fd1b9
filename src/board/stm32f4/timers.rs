//! The wheel encoders (TIM2, 32-bit, right; TIM3, 16-bit, left; the same timers on every board,
//! on the board's pins) and the control-period interrupt source (the board's timer), plus the
//! check that every control rate is an exact period of that timer.

use stm32f4xx_hal::pac::{TIM2, TIM3};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::qei::Qei;
use stm32f4xx_hal::timer::{CounterHz, Flag, Instance};

/// The two quadrature encoders: TIM2 (32-bit, right) and TIM3 (16-bit, left).
pub struct Encoders {
    /// Right wheel.
    pub right: Qei<TIM2>,
    /// Left wheel.
    pub left: Qei<TIM3>,
}

impl Encoders {
    /// The raw hardware counter values (right, left); the library extends them to tick totals.
    pub fn read(&mut self) -> (u32, u32) {
        (self.right.count(), u32::from(self.left.count()))
    }
}

/// The control-period interrupt source: the update of the board's timer `TIM` at the control
/// rate (its clock chosen so that every rate of [`crate::motion::controller::RATES_HZ`] divides
/// exactly, [`rates_exact`]).
pub struct ControlTick<TIM> {
    /// The timer, its update interrupt enabled.
    pub timer: CounterHz<TIM>,
    /// The rate it runs at, Hz.
    pub rate_hz: u32,
}

impl<TIM: Instance> ControlTick<TIM> {
    /// Acknowledges the period's interrupt.
    pub fn clear(&mut self) {
        self.timer.clear_flags(Flag::Update);
    }

    /// The rate the timer runs at, Hz.
    pub fn rate_hz(&self) -> u32 {
        self.rate_hz
    }

    /// Whether the timer counts: its update flag rises within two control periods of
    /// [`set_rate_hz`](Self::set_rate_hz) (polled, `sysclk_hz` cycles a second; called once in
    /// `init`, interrupts off, so the flag stays for the first period's interrupt). A timer
    /// that never rises (a part whose timer clock is off, or an emulator that does not model
    /// it, as QEMU's STM32F405 models neither TIM7 nor TIM11) means no control loop.
    pub fn counts(&mut self, sysclk_hz: u32) -> bool {
        use stm32f4xx_hal::ReadFlags as _;
        // Twenty polls a period for two periods; the delay counts core cycles on silicon.
        let poll_cycles = (sysclk_hz / self.rate_hz.max(1) / 20).max(1);
        for _ in 0..40 {
            if self.timer.flags().contains(Flag::Update) {
                return true;
            }
            cortex_m::asm::delay(poll_cycles);
        }
        self.timer.flags().contains(Flag::Update)
    }

    /// Retimes the timer to `rate_hz`: the counter restarts, so the next update comes one new
    /// period after the call (the update interrupt stays enabled).
    pub fn set_rate_hz(&mut self, rate_hz: u32) {
        if self.timer.start(rate_hz.Hz()).is_err() {
            error!("control timer refused {} Hz", rate_hz);
        } else {
            self.rate_hz = rate_hz;
        }
    }
}

/// Whether every control rate is an exact period of a timer clocked at `timclk_hz` with the
/// HAL's split of the period into a 16-bit prescaler and auto-reload (`CounterHz::start`:
/// prescaler (ticks - 1) / 2^16 + 1, then ARR = ticks / prescaler - 1).
pub const fn rates_exact(timclk_hz: u32) -> bool {
    let rates = crate::motion::controller::RATES_HZ;
    let mut i = 0;
    while i < rates.len() {
        if !timclk_hz.is_multiple_of(rates[i]) {
            return false;
        }
        let ticks = timclk_hz / rates[i];
        let psc = (ticks - 1) / (1 << 16);
        if !ticks.is_multiple_of(psc + 1) {
            return false;
        }
        i += 1;
    }
    true
}

/// Encoder input filter (TIMx_CCMR1 IC1F/IC2F = 0b0110: f_DTS/4, 6 samples): at an 84–100 MHz
/// timer clock an edge must be stable for 240–286 ns. The fastest edges (200,000 counts/rev,
/// 150 mm wheels at 2 m/s: 850,000 counts/s) come every 1.18 µs, so no real edge is lost; spikes
/// shorter than the filter are.
pub const ENCODER_FILTER: u32 = 0b0110;

/// Sets [`ENCODER_FILTER`] on both encoder timers' inputs. Called once in `init`, after the HAL
/// configured them.
pub fn filter_encoder_inputs() {
    let filter_mask = (0xF << 4) | (0xF << 12);
    let filter = (ENCODER_FILTER << 4) | (ENCODER_FILTER << 12);
    // SAFETY: read-modify-writes of the input-filter fields of TIM2/TIM3 CCMR1 after the HAL
    // configured the timers in `init` (nothing else runs yet); no other bits change.
    unsafe {
        (*TIM2::ptr())
            .ccmr1_input()
            .modify(|r, w| w.bits((r.bits() & !filter_mask) | filter));
        (*TIM3::ptr())
            .ccmr1_input()
            .modify(|r, w| w.bits((r.bits() & !filter_mask) | filter));
    }
}

/// Pull-ups on `pins` of a GPIO port (encoder inputs and the console's RX, so an unconnected
/// input is quiet, not noise).
///
/// # Safety
/// `port` is a GPIO port's register block whose clock is on; `init` owns it and nothing else
/// runs; only the pull fields of `pins` change.
pub unsafe fn pull_up(port: *const stm32f4xx_hal::pac::gpioa::RegisterBlock, pins: &[u32]) {
    let (mut mask, mut up) = (0u32, 0u32);
    for &p in pins {
        mask |= 0b11 << (2 * p);
        up |= 0b01 << (2 * p);
    }
    // SAFETY: the caller's promise above.
    unsafe {
        (*port)
            .pupdr()
            .modify(|r, w| w.bits((r.bits() & !mask) | up));
    }
}
