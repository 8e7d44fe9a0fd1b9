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
    /// The clock tree with each of the board's documented external clocks (in the order of its
    /// `crystals`), e.g. `clock: 8 MHz crystal (HSE), 168 MHz`.
    pub external: &'static [&'static str],
    /// The clock tree on the internal oscillator.
    pub internal: &'static str,
    /// The fault event's text when the external clock did not start.
    pub fault: &'static str,
}

/// Where the core clock comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ClockSource {
    /// The board's documented external clock number `.0` (HSE) through the PLL: its accuracy.
    External(u8),
    /// The external clock did not start: the internal 16 MHz RC oscillator (HSI) through the
    /// PLL, the same core clock, but only as accurate as the HSI (±1 % at 25 °C, a few % over
    /// temperature).
    Internal,
    /// The external clock started at a frequency that is none of the board's (Hz, at the HSI's
    /// nominal frequency; 0: TIM11 saw no edge): switched off, the core on the HSI as for
    /// [`ClockSource::Internal`].
    Unknown(u32),
}

impl ClockSource {
    /// The fault text of the boot event when the external clock did not start or is unknown,
    /// `None` with a documented one.
    pub fn fault(self, texts: &ClockTexts) -> Option<&'static str> {
        match self {
            ClockSource::External(_) => None,
            ClockSource::Internal => Some(texts.fault),
            ClockSource::Unknown(_) => Some(UNKNOWN_FAULT),
        }
    }

    /// Which clock runs, as the boot line names it.
    pub fn describe(self, texts: &ClockTexts) -> ClockNote {
        let (text, unknown_crystal_hz) = match self {
            ClockSource::External(i) => (
                texts.external.get(usize::from(i)).copied().unwrap_or(""),
                None,
            ),
            ClockSource::Internal => (texts.internal, None),
            ClockSource::Unknown(hz) => (texts.internal, Some(hz)),
        };
        ClockNote {
            text,
            unknown_crystal_hz,
        }
    }
}

pub use crate::board::crystal::ClockNote;

/// The fault event's text when the external clock is none of the board's frequencies.
pub const UNKNOWN_FAULT: &str =
    "unknown crystal (the boot line says what it measured): running on the internal oscillator";

/// The HSE ready flag (RCC_CR.HSERDY). Out of line and unmangled, so the emulator's boot assist
/// can answer it (QEMU does not model the RCC).
#[unsafe(no_mangle)]
#[inline(never)]
pub extern "C" fn odocal_hse_ready() -> bool {
    // SAFETY: a read of RCC_CR, which has no read side effects.
    unsafe { (*pac::RCC::ptr()).cr().read().hserdy().bit_is_set() }
}

/// Polls of TIM11's capture flag for one capture before the measurement gives up: a capture
/// comes every 62 µs with a 4 MHz crystal (the slowest the parts take), about 1,000 cycles at
/// the reset clock; a poll is at least 4 cycles, so 10,000 polls are at least 2.5 ms.
const CAPTURE_POLLS: u32 = 10_000;

/// The external clock measured against the internal oscillator before the PLL: HSI ticks in
/// [`crate::board::crystal::HSE_PERIODS`] periods of the running HSE, counted by TIM11's input
/// capture of HSE_RTC (RCC_CFGR.RTCPRE = 31, TIM11_OR.TI1_RMP = HSE_RTC: RM0090's "TIM11 option
/// register", the same in RM0383 and RM0390); 0 if a capture did not come. TIM11 runs on the
/// reset clock (the HSI, APB2 undivided) and is left stopped and disabled. Out of line and
/// unmangled, so the emulator's boot assist can answer it (QEMU models neither RCC nor TIM11).
#[unsafe(no_mangle)]
#[inline(never)]
pub extern "C" fn odocal_hse_count() -> u32 {
    use crate::board::crystal::{CAPTURES, EDGES_PER_CAPTURE, RTC_DIVIDER};
    // SAFETY: called once from `start_clocks`, which owns the RCC, before the HAL sets the
    // clocks; TIM11 is not in use yet (the HAL enables and resets it again when a board uses
    // it).
    let (rcc, tim) = unsafe { (&*pac::RCC::ptr(), &*pac::TIM11::ptr()) };
    rcc.cfgr()
        .modify(|_, w| unsafe { w.rtcpre().bits(RTC_DIVIDER as u8) });
    rcc.apb2enr().modify(|_, w| w.tim11en().set_bit());
    let _ = rcc.apb2enr().read().bits();
    // SAFETY (the raw writes): TI1_RMP = 0b10 (HSE_RTC); CCMR1 CC1S = 01 (IC1 on TI1), IC1PSC =
    // 11 (every 8th edge); CCER CC1E; the counter free-running over 16 bits.
    const _: () = assert!(EDGES_PER_CAPTURE == 8);
    tim.or().write(|w| unsafe { w.bits(0b10) });
    tim.ccmr1_input()
        .write(|w| unsafe { w.bits(0b01 | (0b11 << 2)) });
    tim.ccer().write(|w| unsafe { w.bits(1) });
    tim.arr().write(|w| unsafe { w.bits(0xFFFF) });
    tim.cr1().write(|w| unsafe { w.bits(1) });
    let mut first = 0u32;
    let mut count = 0u32;
    'captures: for capture in 0..=CAPTURES {
        for _ in 0..CAPTURE_POLLS {
            if tim.sr().read().bits() & 0b10 != 0 {
                // Reading CCR1 clears CC1IF.
                let at = tim.ccr1().read().bits();
                if capture == 0 {
                    first = at;
                } else {
                    count = at.wrapping_sub(first) & 0xFFFF;
                }
                continue 'captures;
            }
        }
        count = 0;
        break;
    }
    tim.cr1().write(|w| unsafe { w.bits(0) });
    tim.ccer().write(|w| unsafe { w.bits(0) });
    tim.or().write(|w| unsafe { w.bits(0) });
    rcc.apb2enr().modify(|_, w| w.tim11en().clear_bit());
    count
}

/// Polls of PWR_CSR.VOSRDY after the PLL has started (the regulator moves to the selected scale
/// once the PLL runs): at least 60 ms at the core clock.
const VOS_POLLS: u32 = 200_000;

/// PWR_CR.VOS = 0b11: voltage scale 1, needed above 84 MHz on the STM32F411 (it resets to scale
/// 2; RM0383, PWR_CR: written while the PLL is off, applied when it starts). The STM32F407 and
/// STM32F446 reset to scale 1 and need nothing (the F446's over-drive above 168 MHz is the
/// HAL's).
pub fn select_scale1(rcc: &pac::RCC) {
    rcc.apb1enr().modify(|_, w| w.pwren().set_bit());
    let _ = rcc.apb1enr().read().bits();
    // SAFETY: PWR_CR's VOS field (bits 15:14) only; nothing else writes PWR during boot.
    unsafe {
        (*pac::PWR::ptr())
            .cr()
            .modify(|r, w| w.bits(r.bits() | (0b11 << 14)))
    };
}

/// PWR_CSR.VOSRDY: the regulator is at the selected scale. Out of line and unmangled, so the
/// emulator's boot assist can answer it (QEMU does not model PWR).
#[unsafe(no_mangle)]
#[inline(never)]
pub extern "C" fn odocal_vos_ready() -> bool {
    // SAFETY: a read of PWR_CSR, which has no read side effects.
    unsafe { (*pac::PWR::ptr()).csr().read().bits() & (1 << 14) != 0 }
}

/// Waits at most [`VOS_POLLS`] polls for [`odocal_vos_ready`]; whether it came.
pub fn scale1_ready() -> bool {
    (0..VOS_POLLS).any(|_| odocal_vos_ready())
}

/// The clock security system on (RCC_CR.CSSON): if the external clock stops, the hardware
/// switches the core to the HSI and raises the NMI ([`clock_lost`]).
pub fn watch_external() {
    // SAFETY: RCC_CR's CSSON bit only, after the HAL's clock set-up.
    unsafe { (*pac::RCC::ptr()).cr().modify(|_, w| w.csson().set_bit()) };
}

/// The NMI of the clock security system: the external clock stopped and the core now runs on the
/// bare HSI (16 MHz, PLL off), so every rate is wrong. Called by the firmware's NMI handler after
/// `odocal_emergency_stop`: clears the flag (RCC_CIR.CSSC, else the NMI comes again), logs and
/// resets; the next boot finds no external clock and says so on its boot line.
pub fn clock_lost() -> ! {
    // SAFETY: a write-1-to-clear of RCC_CIR.CSSC; nothing runs after this handler.
    unsafe { (*pac::RCC::ptr()).cir().write(|w| w.cssc().set_bit()) };
    defmt::error!("external clock lost (clock security system): motors stopped, resetting");
    cortex_m::peripheral::SCB::sys_reset()
}

/// Starts the HSE (in bypass mode for a clock input, `bypass`) and waits at most [`HSE_POLLS`]
/// polls for it: whether it started. Without it the oscillator is switched off again.
pub fn start_external(rcc: &pac::RCC, bypass: bool) -> bool {
    if bypass {
        // HSEBYP can be written only while the HSE is off.
        rcc.cr().modify(|_, w| w.hsebyp().set_bit());
    }
    rcc.cr().modify(|_, w| w.hseon().set_bit());
    if (0..HSE_POLLS).any(|_| odocal_hse_ready()) {
        return true;
    }
    stop_external(rcc);
    false
}

/// The HSE (and its bypass) off again.
pub fn stop_external(rcc: &pac::RCC) {
    rcc.cr()
        .modify(|_, w| w.hseon().clear_bit().hsebyp().clear_bit());
}
