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
//! | `Board::tick.clear()` | acknowledges the control-period interrupt ([`CONTROL_INTERRUPT`], the board's timer) |
//! | `Board::tick.set_rate_hz()`, `rate_hz()` | the control rate: at boot from the stored `control_hz`, and when `set control_hz` changed it |
//! | [`CONTROL_FROM_MONOTONIC`] | whether the app pends the control interrupt from the monotonic (a board without the timer) |
//! | `BUTTON_INTERRUPT` | the button's EXTI interrupt (the app's `binds` names it per board) |
//! | `Board::button.edge()` | acknowledges a button edge and reads the level (an embedded-hal `InputPin`, [`crate::app::io::button_pressed`]) |
//! | `Board::leds` | heartbeat and fault LEDs ([`crate::app::io::Leds`] over two embedded-hal `OutputPin`s) |
//! | `Board::console_rx` / `console_tx`, `CONSOLE_INTERRUPT` | the serial console's USART: an `embedded-hal-nb` reader and an `embedded-io` writer ([`crate::app::io::read_console`], [`crate::app::io::write_console`]) plus the board's transmit-interrupt switch |
//! | `CONSOLE_RX_POLLED` | whether the console's receive half is read from a DMA ring the app drains every millisecond (the boards: bytes arrive during a flash erase's stall) rather than by its RX interrupt (the emulator) |
//! | `Board::watchdog`, `watchdog::set_timeout` | fed every control period, relaxed around flash writes |
//! | `Board::params` | the parameter store, loaded by the app before anything moves |
//! | `Board::reset_cause` | why the MCU last reset, reported at boot |
//! | `Board::clock`, `boot_note` | whether the external clock started (else the internal oscillator); the boot line names the clock |
//! | `safety` | motor pins safe from reset, emergency stop, panic and HardFault handlers |
//! | `WATCHDOG_MS`, `FLASH_WATCHDOG_MS` | timeouts |
//!
//! The motors are the portable H-bridge [`crate::motion::hbridge::HBridge`] over embedded-hal's
//! `SetDutyCycle` and `OutputPin`. A board is a folder here: its pin map, its clocks, its
//! control-period timer and interrupt acknowledgements, its flash map and its `memory.x`
//! (docs/hardware.md, "Adding your board"). What every STM32F4 part shares (watchdog, console
//! receive ring, flash driver, TIM1 H-bridge, reset cause) is in [`stm32f4`].
//!
//! The board is chosen by a cargo feature (exactly one): `board-f407` (the default, [`f407`]),
//! `board-nucleo-f446re` (`nucleo_f446re`), `board-blackpill-f411ce` (`blackpill_f411ce`). With
//! the feature `emulator`, `emulator` (QEMU's `netduinoplus2` with a simulated robot, for the
//! firmware-in-the-loop test) takes the place of the default board behind the same names; the
//! app is the same.

#[cfg(any(
    all(feature = "board-f407", feature = "board-nucleo-f446re"),
    all(feature = "board-f407", feature = "board-blackpill-f411ce"),
    all(feature = "board-nucleo-f446re", feature = "board-blackpill-f411ce"),
))]
compile_error!("more than one board feature: build with --no-default-features --features board-…");

pub mod adapters;
pub mod crystal;
pub mod stm32f4;

#[cfg(feature = "board-blackpill-f411ce")]
pub mod blackpill_f411ce;
#[cfg(feature = "emulator")]
pub mod emulator;
#[cfg(feature = "board-f407")]
pub mod f407;
#[cfg(feature = "board-nucleo-f446re")]
pub mod nucleo_f446re;

/// The board the firmware is built for (the emulator's storage and pins follow the F407's).
#[cfg(feature = "board-blackpill-f411ce")]
use blackpill_f411ce as active;
#[cfg(feature = "board-f407")]
use f407 as active;
#[cfg(feature = "board-nucleo-f446re")]
use nucleo_f446re as active;

pub use active::flash as flash_map;
pub use active::{
    BUTTON_INTERRUPT, CLOCK_TEXTS, CONTROL_INTERRUPT, CONTROL_TIMER, ClockSource, ResetCause,
    safety,
};
pub use stm32f4::clock::clock_lost;

#[cfg(not(feature = "emulator"))]
pub use active::{
    Board, BoardFlash, BoardMotors, ButtonInput, CONSOLE_INTERRUPT, CONSOLE_RX_POLLED,
    CONTROL_FROM_MONOTONIC, ConsoleRx, ConsoleTx, ControlTick, Encoders, FLASH_WATCHDOG_MS, Leds,
    WATCHDOG_MS, boot_note, init, watchdog,
};

#[cfg(feature = "emulator")]
pub use emulator::{
    Board, BoardFlash, BoardMotors, ButtonInput, CONSOLE_INTERRUPT, CONSOLE_RX_POLLED,
    CONTROL_FROM_MONOTONIC, ConsoleRx, ConsoleTx, ControlTick, Encoders, FLASH_WATCHDOG_MS, Leds,
    WATCHDOG_MS, boot_note, init, watchdog,
};
