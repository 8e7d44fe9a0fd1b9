//! The emulator board: the same RTIC app on QEMU's `netduinoplus2` (STM32F405), with a simulated
//! robot in place of the motors and encoders (cargo feature `emulator`; the shipped firmware
//! never contains it).
//!
//! What QEMU models is used as on the board: SysTick (the monotonic), NVIC, USART2 (the console,
//! the second `-serial`), SYSCFG/EXTI. What it does not model is replaced here, behind the same
//! names as [`super::f407`]:
//!
//! | item | on the F407 | here |
//! |---|---|---|
//! | clocks | HSE 8 MHz → PLL 168 MHz | HSI (QEMU has no RCC; its SysTick counts at 168 MHz whatever RCC says, so the monotonic is started at 168 MHz) |
//! | `Encoders` | TIM2/TIM3 in encoder mode | the [`plant`]'s counters (the library's robot model, [`crate::plant`]); each read first advances the plant by one control period with the last motor command |
//! | `BoardMotors` | TIM1 PWM + direction pins | stores the command for the plant |
//! | `ControlTick` | TIM7 update at the control rate (1–10 kHz) | QEMU has no TIM6/TIM7: the control interrupt is pended from the SysTick monotonic (`CONTROL_FROM_MONOTONIC`, the app's `pace_control` task), one period per 1 ms tick whatever the rate; `set_rate_hz` retimes the plant instead |
//! | `BoardFlash` | sectors 1–2 (parameters) and 10–11 (runs) | a 288 KiB host file through semihosting ([`flash`]) |
//! | button, LEDs, watchdog | GPIO, EXTI0, IWDG | the same HAL drivers; QEMU logs their register writes as unimplemented (`-d unimp`) and never resets on a missing feed |
//!
//! The plant runs inside the control interrupt, so it costs emulated CPU time there; the
//! emulator does not reproduce the board's timing (QEMU counts instructions, not cycles).
//!
//! Control rate: the controller and the plant both count control periods (the plant advances
//! `1 / rate` of robot time per read), so a run is the same at any rate. The monotonic's 1 ms
//! tick paces one period per millisecond of emulated time, so above 1 kHz the emulated robot
//! moves in slow motion (at 10 kHz a tenth of real speed): only what is timed by the
//! monotonic (button debounce, the pose stream's rate, console polling) sees the difference.

pub mod flash;
pub mod plant;
pub mod semihosting;

use crate::board::stm32f4::reset::ResetCause;
use core::sync::atomic::{AtomicU8, AtomicU32, Ordering};

use stm32f4xx_hal::gpio::{Edge, Pull};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::Config;
use stm32f4xx_hal::serial::{self, Serial};
use stm32f4xx_hal::watchdog::IndependentWatchdog;

pub use super::f407::{FLASH_WATCHDOG_MS, WATCHDOG_MS};
use super::stm32f4::clock::ClockSource;
pub use super::stm32f4::watchdog;
pub use flash::BoardFlash;
use plant::Plant;

use crate::motion::controller::{DEFAULT_RATE_HZ, MotorCommand};
use crate::motion::motor::{MotorDriver, StopMode};
use crate::storage::ParamAndRunStore;

/// SysTick's clock in QEMU's STM32F405 model, Hz (fixed, independent of RCC).
pub const SYSCLK_HZ: u32 = 168_000_000;

/// The last motor command, from [`BoardMotors`] (control task) to [`Encoders`] (same task).
static COMMAND_KIND: AtomicU8 = AtomicU8::new(KIND_BRAKE);
static DUTY_RIGHT: AtomicU32 = AtomicU32::new(0);
static DUTY_LEFT: AtomicU32 = AtomicU32::new(0);
const KIND_DUTY: u8 = 0;
const KIND_BRAKE: u8 = 1;
const KIND_COAST: u8 = 2;

/// The control rate, from [`ControlTick`] (control task) to [`Encoders`] (same task), Hz.
static RATE_HZ: AtomicU32 = AtomicU32::new(DEFAULT_RATE_HZ);

fn held_command() -> MotorCommand {
    match COMMAND_KIND.load(Ordering::Relaxed) {
        KIND_DUTY => MotorCommand::Duty {
            right: f32::from_bits(DUTY_RIGHT.load(Ordering::Relaxed)),
            left: f32::from_bits(DUTY_LEFT.load(Ordering::Relaxed)),
        },
        KIND_COAST => MotorCommand::Stop(StopMode::Coast),
        _ => MotorCommand::Stop(StopMode::Brake),
    }
}

/// The plant's encoder counters.
pub struct Encoders {
    plant: Plant,
    started: bool,
}

impl Encoders {
    /// Advances the plant by one control period with the command held since the last read
    /// (none before the first read), then returns its counters (right, left).
    pub fn read(&mut self) -> (u32, u32) {
        self.plant.set_rate_hz(RATE_HZ.load(Ordering::Relaxed));
        if self.started {
            self.plant.advance(held_command());
        }
        self.started = true;
        self.plant.raw()
    }
}

/// The plant's motors.
pub struct BoardMotors(());

impl MotorDriver for BoardMotors {
    fn set_duty(&mut self, right: f32, left: f32) {
        DUTY_RIGHT.store(right.to_bits(), Ordering::Relaxed);
        DUTY_LEFT.store(left.to_bits(), Ordering::Relaxed);
        COMMAND_KIND.store(KIND_DUTY, Ordering::Relaxed);
    }

    fn stop(&mut self, mode: StopMode) {
        let kind = match mode {
            StopMode::Brake => KIND_BRAKE,
            StopMode::Coast => KIND_COAST,
        };
        COMMAND_KIND.store(kind, Ordering::Relaxed);
    }
}

/// The control-period interrupt: pended in software, nothing to acknowledge.
pub struct ControlTick(());

impl ControlTick {
    /// Acknowledges the period's interrupt (nothing to do: it was pended in software).
    pub fn clear(&mut self) {}

    /// The control rate, Hz.
    pub fn rate_hz(&self) -> u32 {
        RATE_HZ.load(Ordering::Relaxed)
    }

    /// Whether the control periods come: always (the app pends them from the monotonic).
    pub fn counts(&mut self, _sysclk_hz: u32) -> bool {
        true
    }

    /// Sets the control rate: the plant advances `1 / rate_hz` of robot time per period from
    /// the next encoder read on (the app keeps pacing one period per monotonic tick).
    pub fn set_rate_hz(&mut self, rate_hz: u32) {
        RATE_HZ.store(rate_hz, Ordering::Relaxed);
    }
}

// The button (QEMU drives no GPIO input), the LEDs (register writes only in QEMU) and the
// console USART are the F407 board's own; the console receives by interrupt (QEMU's STM32F405
// models no DMA controller).
pub use crate::board::f407::{ButtonInput, CONSOLE_INTERRUPT, ConsoleTx, Leds};

/// The console port's receive half (USART2 RX interrupt).
pub type ConsoleRx = stm32f4xx_hal::serial::Rx<stm32f4xx_hal::pac::USART2>;
/// The RX interrupt serves the console's receive half: nothing to poll.
pub const CONSOLE_RX_POLLED: bool = false;
/// QEMU has no TIM7: the app pends the control interrupt from the monotonic.
pub const CONTROL_FROM_MONOTONIC: bool = true;

/// What the boot line ends with: what QEMU does not model, so nobody takes the emulated board's
/// numbers for a robot's.
pub fn boot_note(_clock: ClockSource) -> super::stm32f4::clock::ClockNote {
    super::stm32f4::clock::ClockNote {
        text: "emulated: QEMU has no motors, encoders, PWM or TIM7 (a simulated robot drives)",
        unknown_crystal_hz: None,
    }
}

/// Everything the board gives the application (see [`crate::board`]).
pub struct Board {
    /// Core clock the monotonic timer runs at, Hz.
    pub sysclk_hz: u32,
    /// Wheel encoders (the plant's).
    pub encoders: Encoders,
    /// Motor outputs (the plant's), braked.
    pub motors: BoardMotors,
    /// Control-period interrupt (pended by the app from the monotonic).
    pub tick: ControlTick,
    /// User button.
    pub button: ButtonInput,
    /// Status LEDs.
    pub leds: Leds,
    /// Console receive half, RX interrupt enabled.
    pub console_rx: ConsoleRx,
    /// Console transmit half.
    pub console_tx: ConsoleTx,
    /// Independent watchdog, not started yet.
    pub watchdog: IndependentWatchdog,
    /// The parameter and run store on the emulated sectors 1–2 and 10–11 (not loaded yet).
    pub params: ParamAndRunStore<BoardFlash>,
    /// Why the MCU last reset (QEMU models no reset flags: `Unknown`).
    pub reset_cause: ResetCause,
    /// The clock source: QEMU models no oscillators, so there is no crystal to miss and
    /// nothing to fall back from.
    pub clock: ClockSource,
}

/// Brings up the emulated board.
pub fn init(dp: pac::Peripherals) -> Board {
    let reset_cause = crate::board::stm32f4::reset::reset_cause(&dp.RCC);
    let mut rcc = dp.RCC.freeze(Config::hsi());
    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiod = dp.GPIOD.split(&mut rcc);

    let mut exti = dp.EXTI;
    let mut syscfg = dp.SYSCFG.constrain(&mut rcc);
    let mut button_pin = gpioa.pa0.into_input().internal_resistor(Pull::Down);
    button_pin.make_interrupt_source(&mut syscfg);
    button_pin.trigger_on_edge(&mut exti, Edge::RisingFalling);
    button_pin.enable_interrupt(&mut exti);

    let watchdog = IndependentWatchdog::new(dp.IWDG);

    let usart = Serial::new(
        dp.USART2,
        (gpioa.pa2, gpioa.pa3),
        serial::Config::default().baudrate(115_200.bps()),
        &mut rcc,
    );
    let (console_tx, mut console_rx) = match usart {
        Ok(s) => s.split(),
        Err(_) => defmt::panic!("USART2 configuration rejected"),
    };
    console_rx.listen();

    Board {
        sysclk_hz: SYSCLK_HZ,
        encoders: Encoders {
            plant: Plant::new(DEFAULT_RATE_HZ),
            started: false,
        },
        motors: BoardMotors(()),
        tick: ControlTick(()),
        button: ButtonInput::new(button_pin),
        leds: Leds::new(
            gpiod.pd12.into_push_pull_output(),
            gpiod.pd14.into_push_pull_output(),
        ),
        console_rx,
        console_tx,
        watchdog,
        params: flash::param_store(),
        reset_cause,
        clock: ClockSource::External(0),
    }
}
