//! The safe state of the motor outputs, from reset to panic.
//!
//! - [`motors_off_at_reset`]: the first thing `init` does, before clocks and before the first
//!   flash access (a parameter load may erase a sector for seconds): the H-bridge enable (PE13)
//!   and both PWM pins (PE9, PE11) become push-pull outputs driven low, with pull-downs. Out of
//!   reset they are floating inputs, which some bridges read as "enabled".
//! - [`odocal_emergency_stop`]: from any context (panic, HardFault), whatever state the drivers are
//!   in: the bridge enable and both PWM pins driven low as plain GPIO outputs (the state of
//!   [`motors_off_at_reset`]), and TIM1's main output off with its automatic re-enable cleared
//!   (BDTR.MOE and BDTR.AOE: the HAL's PWM sets AOE, which would set MOE again at the next
//!   update, 50 µs later, RM0090 §17.4.18) and both compare values zero. The firmware's panic
//!   and HardFault handlers (in `src/main.rs`, so that other target binaries of the library keep
//!   their own) call it, log, and reset the MCU, so a fault never leaves the last duty on the
//!   motors until the watchdog fires, and a panic before the watchdog runs does not hang for
//!   ever.
//! - [`freeze_when_halted`]: TIM1's counter (and, in debug builds, the watchdog) stop while a
//!   debugger halts the core, so the PWM does not run on at the last duty. Which level the
//!   frozen PWM pins then hold is not established for this board (docs/hardware.md): keep the
//!   motor supply off while the core is halted.
//!   The core's sleep and stop modes keep the debug port clocked (DBGMCU_CR.DBG_SLEEP,
//!   DBG_STOP), so a probe can attach while the idle loop sleeps in WFI.
//! - [`reset_cause`]: why the MCU last reset, from RCC_CSR (flags cleared after reading).
//! - [`first_fault`], [`record_crash`], [`take_crash`]: the fault handlers' guard against a
//!   fault inside a fault handler, and the [`CrashRecord`] kept across the reset in RAM that the
//!   startup code leaves alone.

use core::sync::atomic::{AtomicBool, Ordering};

use stm32f4xx_hal::pac;

use crate::session::crash::{CrashRecord, WORDS};

/// PE9 (TIM1_CH1, right PWM), PE11 (TIM1_CH2, left PWM), PE13 (bridge enable).
const MOTOR_PINS: [u32; 3] = [9, 11, 13];

/// GPIOE register values for the motor pins: (BSRR word that drives them low, MODER/PUPDR mask
/// of their bit pairs, MODER bits making them outputs, PUPDR bits giving them pull-downs).
const fn motor_pin_fields() -> (u32, u32, u32, u32) {
    let (mut low, mut mask2, mut output, mut pull_down) = (0u32, 0u32, 0u32, 0u32);
    let mut i = 0;
    while i < MOTOR_PINS.len() {
        let pin = MOTOR_PINS[i];
        low |= 1 << (pin + 16);
        mask2 |= 0b11 << (2 * pin);
        output |= 0b01 << (2 * pin);
        pull_down |= 0b10 << (2 * pin);
        i += 1;
    }
    (low, mask2, output, pull_down)
}

/// Drives the motor pins to the safe state (see the module docs).
pub fn motors_off_at_reset(rcc: &pac::RCC, gpioe: &pac::GPIOE) {
    rcc.ahb1enr().modify(|_, w| w.gpioeen().set_bit());
    // Two peripheral-clock cycles must pass before GPIOE responds (RM0090 §6.3.10 errata note):
    // a read-back of the enable register provides them.
    let _ = rcc.ahb1enr().read().bits();
    drive_motor_pins_safe(gpioe);
}

/// Port E's pin tokens without the HAL's `GPIOE.split()`, which would reset the whole port
/// (RCC_AHB1RSTR.GPIOERST) and leave the motor pins floating, pull-downs cleared, until their
/// drivers take them. Here they keep the state [`motors_off_at_reset`] gave them (which also
/// enabled the port's clock); the HAL's mode changes then set each pin's mode, type and
/// alternate function and never touch PUPDR, so the pull-downs stay on. `fil/safe_boot_test.py`
/// lists every GPIOE write of the shipped image's boot and rejects a port reset.
pub fn port_e_without_reset(port: pac::GPIOE) -> stm32f4xx_hal::gpio::gpioe::Parts {
    const { assert!(core::mem::size_of::<stm32f4xx_hal::gpio::gpioe::Parts>() == 0) };
    // The port's only handle: no other pin tokens of port E can be made after this.
    let _ = port;
    // SAFETY: `Parts` is zero-sized (a zero-sized token per pin, checked above): no bytes are
    // made up. `port`, consumed here, was the only way to get port E's tokens, so these are
    // the only ones, as `split` would have returned them.
    unsafe { core::mem::zeroed() }
}

fn drive_motor_pins_safe(gpioe: &pac::gpioi::RegisterBlock) {
    let (low, mask2, output, pull_down) = motor_pin_fields();
    // SAFETY: GPIOE is owned by `init` at this point (nothing else runs); BSRR resets only the
    // three motor pins, and the MODER/PUPDR read-modify-writes change only their bit pairs.
    unsafe {
        gpioe.bsrr().write(|w| w.bits(low));
        gpioe
            .pupdr()
            .modify(|r, w| w.bits((r.bits() & !mask2) | pull_down));
        gpioe
            .moder()
            .modify(|r, w| w.bits((r.bits() & !mask2) | output));
    }
}

/// TIM1_BDTR.MOE: main output enable.
const BDTR_MOE: u32 = 1 << 15;
/// TIM1_BDTR.AOE: automatic output enable (MOE set again at the next update event).
const BDTR_AOE: u32 = 1 << 14;

/// Motors off from any context (see the module docs). Never inlined and with a fixed symbol
/// name, so the firmware-in-the-loop check can see the fault handlers call it first.
#[inline(never)]
#[unsafe(no_mangle)]
pub extern "C" fn odocal_emergency_stop() {
    let (low, mask2, output, _) = motor_pin_fields();
    // SAFETY: called from the panic and HardFault handlers, which never return: the drivers
    // that own these registers never run again, so their read-modify-writes cannot be undone
    // by an interrupted one. BSRR is a write-only set/reset register (the write drives only
    // the three motor pins low), MODER changes only their bit pairs (AF → output), the BDTR
    // write clears only MOE and AOE, and CCR1/CCR2 become 0. With GPIOE's or TIM1's clock
    // still off (a fault early in `init`) the writes are ignored and the pins are still in
    // their reset state (inputs, the bridge's own pull-downs).
    unsafe {
        let gpioe = &*pac::GPIOE::ptr();
        gpioe.bsrr().write(|w| w.bits(low));
        gpioe
            .moder()
            .modify(|r, w| w.bits((r.bits() & !mask2) | output));
        let tim1 = &*pac::TIM1::ptr();
        tim1.bdtr()
            .modify(|r, w| w.bits(r.bits() & !(BDTR_MOE | BDTR_AOE)));
        tim1.ccr1().write(|w| w.bits(0));
        tim1.ccr2().write(|w| w.bits(0));
    }
}

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
