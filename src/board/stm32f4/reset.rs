//! What every STM32F4 board does around a reset: the reset cause, the crash record kept across
//! a fault's reset, the fault handlers' guard, and the debug-halt freeze of the motor PWM timer
//! (TIM1 on every board) and the watchdog. The boards' `safety` modules re-export these next to
//! their motor pins' safe state.

use core::sync::atomic::{AtomicBool, Ordering};

use stm32f4xx_hal::pac;

use crate::session::crash::{CrashRecord, WORDS};

/// Stops TIM1 (always) and the independent watchdog (debug builds only) while the core is
/// halted by a debugger, and keeps the debug port clocked in sleep and stop (the idle task's
/// WFI would otherwise leave a probe unable to connect: probe-rs reports `SwdDpWait`).
pub fn freeze_when_halted(dbgmcu: &pac::DBGMCU) {
    dbgmcu
        .cr()
        .modify(|_, w| w.dbg_sleep().set_bit().dbg_stop().set_bit());
    dbgmcu.apb2_fz().modify(|_, w| w.dbg_tim1_stop().set_bit());
    if cfg!(debug_assertions) {
        dbgmcu.apb1_fz().modify(|_, w| w.dbg_iwdg_stop().set_bit());
    }
}

/// Why the MCU last reset.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum ResetCause {
    /// The independent watchdog expired (the control loop stalled).
    Watchdog,
    /// The window watchdog expired.
    WindowWatchdog,
    /// Low-power management reset.
    LowPower,
    /// Software reset (the panic and HardFault handlers, or a debugger).
    Software,
    /// The supply dropped below the brown-out level.
    BrownOut,
    /// Power-on.
    PowerOn,
    /// The reset pin (the reset button, or a debugger).
    Pin,
    /// No flag set (an emulator, or the flags were cleared).
    Unknown,
}

impl ResetCause {
    /// The cause as the `event reset:` line names it.
    pub fn as_str(self) -> &'static str {
        match self {
            ResetCause::Watchdog => "watchdog",
            ResetCause::WindowWatchdog => "window-watchdog",
            ResetCause::LowPower => "low-power",
            ResetCause::Software => "software",
            ResetCause::BrownOut => "brown-out",
            ResetCause::PowerOn => "power-on",
            ResetCause::Pin => "pin",
            ResetCause::Unknown => "unknown",
        }
    }
}

/// Reads the reset flags of RCC_CSR (most specific first: a power-on also sets the brown-out
/// and pin flags, a watchdog reset also the pin flag) and clears them for the next boot.
pub fn reset_cause(rcc: &pac::RCC) -> ResetCause {
    let csr = rcc.csr().read().bits();
    let flag = |bit: u32| csr & (1 << bit) != 0;
    let cause = if flag(29) {
        ResetCause::Watchdog
    } else if flag(30) {
        ResetCause::WindowWatchdog
    } else if flag(31) {
        ResetCause::LowPower
    } else if flag(28) {
        ResetCause::Software
    } else if flag(27) {
        ResetCause::PowerOn
    } else if flag(25) {
        ResetCause::BrownOut
    } else if flag(26) {
        ResetCause::Pin
    } else {
        ResetCause::Unknown
    };
    rcc.csr().modify(|_, w| w.rmvf().set_bit());
    cause
}

/// Set by the first fault handler that runs; see [`first_fault`].
static IN_FAULT: AtomicBool = AtomicBool::new(false);

/// Whether this is the first fault since reset: `false` inside a fault handler that faulted
/// (a panic while formatting the panic's log line, a HardFault in the panic handler), which
/// must go straight to the emergency stop and the reset without touching anything else.
pub fn first_fault() -> bool {
    !IN_FAULT.swap(true, Ordering::Relaxed)
}

/// The crash record's region: in `.uninit`, which the startup code neither zeroes nor loads,
/// so it survives the software reset that follows a fault (not a power cycle).
#[unsafe(link_section = ".uninit.odocal_crash")]
static mut CRASH: [u32; WORDS] = [0; WORDS];

/// Stores `record` for the next boot. Called only by the fault handlers, after
/// [`first_fault`].
pub fn record_crash(record: &CrashRecord) {
    let words = record.encode();
    // SAFETY: only the fault handler that won `first_fault` writes (nothing else runs after it,
    // and it never returns), and only `take_crash`, in `init` before interrupts, reads; a
    // volatile write of plain words to a static of the same size.
    unsafe { core::ptr::addr_of_mut!(CRASH).write_volatile(words) }
}

/// The record the last fault left, if any, invalidating it (a later reset for another reason
/// is not blamed on it).
pub fn take_crash() -> Option<CrashRecord> {
    // SAFETY: called once from `init`, before interrupts are enabled: no other access; the
    // region holds arbitrary bits after a power-on, which `decode` rejects (magic and checksum).
    let words = unsafe { core::ptr::addr_of!(CRASH).read_volatile() };
    let record = CrashRecord::decode(&words);
    // SAFETY: as above.
    unsafe { core::ptr::addr_of_mut!(CRASH).write_volatile([0; WORDS]) }
    record
}
