//! The core clock's source, chosen at boot: the board's external clock (HSE: a crystal, or a
//! clock input in bypass mode) if it starts within a bounded wait, else the internal 16 MHz RC
//! oscillator (HSI); the PLL makes the same core and bus clocks from either, so timers, PWM and
//! baud rates stay as configured (a missing external clock must not hang the boot before the
//! watchdog runs). The texts that name the clocks are the board's ([`ClockTexts`]).

use stm32f4xx_hal::pac;

/// Polls of the HSE ready flag before the internal oscillator is used instead. Each poll is a
/// call of [`odocal_hse_ready`], a volatile register read, a test and a loop branch (12
/// instructions in the release build, about 20 cycles at the 16 MHz HSI the core runs on at
/// reset), so the wait is about 0.25 s, and at least 60 ms however the loop is compiled; a
/// crystal starts within 2 ms (datasheets: t_SU(HSE)), a clock input at once.
pub const HSE_POLLS: u32 = 200_000;

/// How a board names its clocks: at boot (the end of the boot line), and in the fault event when
/// the external clock did not start.
pub struct ClockTexts {
    /// The clock tree with the external clock, e.g. `clock: 8 MHz crystal (HSE), 168 MHz`.
    pub external: &'static str,
    /// The clock tree on the internal oscillator.
    pub internal: &'static str,
    /// The fault event's text when the external clock did not start.
    pub fault: &'static str,
}

/// Where the core clock comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ClockSource {
    /// The board's external clock (HSE) through the PLL: its accuracy.
    External,
    /// The external clock did not start: the internal 16 MHz RC oscillator (HSI) through the
    /// PLL, the same core clock, but only as accurate as the HSI (±1 % at 25 °C, a few % over
    /// temperature).
    Internal,
}

impl ClockSource {
    /// The fault text of the boot event when the external clock did not start, `None` with it.
    pub fn fault(self, texts: &ClockTexts) -> Option<&'static str> {
        match self {
            ClockSource::External => None,
            ClockSource::Internal => Some(texts.fault),
        }
    }

    /// Which clock runs, as the boot line names it.
    pub fn describe(self, texts: &ClockTexts) -> &'static str {
        match self {
            ClockSource::External => texts.external,
            ClockSource::Internal => texts.internal,
        }
    }
}

/// The HSE ready flag (RCC_CR.HSERDY). Out of line and unmangled, so the emulator's boot assist
/// can answer it (QEMU does not model the RCC).
#[unsafe(no_mangle)]
#[inline(never)]
pub extern "C" fn odocal_hse_ready() -> bool {
    // SAFETY: a read of RCC_CR, which has no read side effects.
    unsafe { (*pac::RCC::ptr()).cr().read().hserdy().bit_is_set() }
}

/// Starts the HSE (in bypass mode for a clock input, `bypass`) and waits at most [`HSE_POLLS`]
/// polls for it: the clock source to configure. Without it the oscillator is switched off again.
pub fn start_external(rcc: &pac::RCC, bypass: bool) -> ClockSource {
    if bypass {
        // HSEBYP can be written only while the HSE is off.
        rcc.cr().modify(|_, w| w.hsebyp().set_bit());
    }
    rcc.cr().modify(|_, w| w.hseon().set_bit());
    for _ in 0..HSE_POLLS {
        if odocal_hse_ready() {
            return ClockSource::External;
        }
    }
    rcc.cr()
        .modify(|_, w| w.hseon().clear_bit().hsebyp().clear_bit());
    ClockSource::Internal
}
