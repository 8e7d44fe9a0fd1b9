//! The safe state of the motor outputs, from reset to panic: the PWM pins PE9 (TIM1_CH1), PE11
//! (TIM1_CH2) and the bridge enable PE13 driven low with pull-downs (the register work is the
//! family's [`crate::board::stm32f4::safe_state`]). The reset cause, crash record and
//! debug-halt freeze are the family's ([`crate::board::stm32f4::reset`]).
//!
//! - `__pre_init`: the pins safe before the startup code initialises RAM (cortex-m-rt calls it
//!   first), so before clocks, before `init` and before the first flash access (a parameter
//!   load may erase a sector for seconds). Out of reset the pins are floating inputs, which
//!   some bridges read as "enabled".
//! - `odocal_emergency_stop`: from any context (panic, HardFault), whatever state the drivers are
//!   in: the pins driven low as plain GPIO outputs, and TIM1's main output off with its
//!   automatic re-enable cleared (BDTR.MOE and BDTR.AOE: the HAL's PWM sets AOE, which would set
//!   MOE again at the next update, 50 µs later, RM0090 §17.4.18) and both compare values zero.
//!   The firmware's panic and HardFault handlers (in `src/main.rs`, so that other target
//!   binaries of the library keep their own) call it, log, and reset the MCU, so a fault never
//!   leaves the last duty on the motors until the watchdog fires, and a panic before the
//!   watchdog runs does not hang for ever.
//! - `freeze_when_halted`: TIM1's counter (and, in debug builds, the watchdog) stop while a
//!   debugger halts the core, so the PWM does not run on at the last duty. Which level the
//!   frozen PWM pins then hold is not established for this board (docs/hardware.md): keep the
//!   motor supply off while the core is halted. The core's sleep and stop modes keep the debug
//!   port clocked (DBGMCU_CR.DBG_SLEEP, DBG_STOP), so a probe can attach while the idle loop
//!   sleeps in WFI.
//! - `reset_cause`: why the MCU last reset, from RCC_CSR (flags cleared after reading).
//! - `first_fault`, `record_crash`, `take_crash`: the fault handlers' guard against a fault
//!   inside a fault handler, and the [`crate::session::crash::CrashRecord`] kept across the
//!   reset in RAM that the startup code leaves alone.

pub use crate::board::stm32f4::reset::{
    ResetCause, first_fault, freeze_when_halted, record_crash, reset_cause, take_crash,
};

crate::board::stm32f4::safe_state::motor_safety!(GPIOE, gpioe, 4, [9, 11, 13]);
