//! Board support (target only): the seam between the RTIC app and the hardware.
//!
//! Owns the peripherals; may use every portable layer. The only target-only module, and the only
//! place with `unsafe` (each block carries a `// SAFETY:` note).
//!
//! A board module provides, under the same names, everything the app (`src/main.rs`) touches:
//!
//! | item | what the app does with it |
//! |---|---|
//! | `init(pac::Peripherals) -> Board` | clocks and every peripheral, once, in `init` |
//! | `Board::encoders.read()` | raw right/left counter values each control period |
//! | `Board::motors` ([`crate::motion::motor::MotorDriver`]) | the controller's motor command |
//! | `Board::tick.clear()` | acknowledges the control-period interrupt (TIM7, [`CONTROL_INTERRUPT`]) |
//! | `Board::tick.set_rate_hz()`, `rate_hz()` | the control rate: at boot from the stored `control_hz`, and when `set control_hz` changed it |
//! | [`CONTROL_FROM_MONOTONIC`] | whether the app pends the control interrupt from the monotonic (a board without the timer) |
//! | `Board::button.edge()` | acknowledges a button edge and reads the level (an embedded-hal `InputPin`, [`crate::app::io::button_pressed`]) |
//! | `Board::leds` | heartbeat and fault LEDs ([`crate::app::io::Leds`] over two embedded-hal `OutputPin`s) |
//! | `Board::console_rx` / `console_tx`, `CONSOLE_INTERRUPT` | the serial console's USART: an `embedded-hal-nb` reader and an `embedded-io` writer ([`crate::app::io::read_console`], [`crate::app::io::write_console`]) plus the board's transmit-interrupt switch |
//! | `CONSOLE_RX_POLLED` | whether the console's receive half is read from a DMA ring the app drains every millisecond (the F407: bytes arrive during a flash erase's stall) rather than by its RX interrupt (the emulator) |
//! | `Board::watchdog`, `watchdog::set_timeout` | fed every control period, relaxed around flash writes |
//! | `Board::params` | the parameter store, loaded by the app before anything moves |
//! | `Board::reset_cause` | why the MCU last reset, reported at boot |
//! | `Board::clock` | whether the crystal started (else the internal oscillator), reported at boot |
//! | `safety` | motor pins safe from reset, emergency stop, panic and HardFault handlers |
//! | `WATCHDOG_MS`, `FLASH_WATCHDOG_MS` | timeouts |
//!
//! The motors are the portable H-bridge [`crate::motion::hbridge::HBridge`] over embedded-hal's
//! `SetDutyCycle` and `OutputPin`. A board other than the F407 is a new folder here: its pin map,
//! its clocks and its interrupt acknowledgements.
//!
//! [`f407`] is the STM32F407 board (pin map in its module docs). With the cargo feature
//! `emulator`, `emulator` (QEMU's `netduinoplus2` with a simulated robot, for the
//! firmware-in-the-loop test) takes its place behind the same names; the app is the same.

pub mod adapters;
pub mod f407;

#[cfg(feature = "emulator")]
pub mod emulator;

#[cfg(not(feature = "emulator"))]
pub use f407::{
    Board, BoardFlash, BoardMotors, ButtonInput, CONSOLE_INTERRUPT, CONSOLE_RX_POLLED, ConsoleRx,
    ConsoleTx, ControlTick, Encoders, FLASH_WATCHDOG_MS, Leds, ResetCause, WATCHDOG_MS, init,
    safety, watchdog,
};

#[cfg(feature = "emulator")]
pub use emulator::{
    Board, BoardFlash, BoardMotors, ButtonInput, CONSOLE_INTERRUPT, CONSOLE_RX_POLLED, ConsoleRx,
    ConsoleTx, ControlTick, Encoders, FLASH_WATCHDOG_MS, Leds, WATCHDOG_MS, init, watchdog,
};
// The safe-state code and the reset cause are the MCU's, the same on both boards.
pub use f407::ClockSource;
#[cfg(feature = "emulator")]
pub use f407::{ResetCause, safety};

/// The interrupt the control task is bound to (TIM7's vector on every board).
pub const CONTROL_INTERRUPT: stm32f4xx_hal::pac::Interrupt = stm32f4xx_hal::pac::Interrupt::TIM7;

/// Whether the app pends [`CONTROL_INTERRUPT`] from the monotonic (one period per 1 ms tick): false on the
/// F407 (TIM7 raises it), true on the emulator (QEMU has no TIM7).
pub const CONTROL_FROM_MONOTONIC: bool = cfg!(feature = "emulator");
