//! The NUCLEO-F446RE board (STM32F446RE, 180 MHz, 512 KiB flash): pin map, clocks and HAL
//! adapters. The parts every STM32F4 board shares are in [`crate::board::stm32f4`].
//!
//! Pin map (docs/hardware.md; Arduino header names in brackets). What the board itself wires is
//! left alone: the ST-LINK's virtual COM port (USART2, PA2/PA3) is the console, LD2 (PA5) the
//! heartbeat, B1 (PC13) the button; PH0 is the ST-LINK's 8 MHz clock, PC14/PC15 the 32 kHz
//! crystal, PA13/PA14 the SWD and PB3 the SWO line, none of them used.
//!
//! The ROM bootloader (BOOT0, strapped low on the NUCLEO but exposed on CN7-7) takes USART1's PA9
//! (the left PWM) and PA10 (the bridge enable) as inputs without a pull, and a host that selects
//! USART1 drives PA10 (AN2606 Rev 70, table 93). TIM1 CH1/CH2 have no other pins on this package,
//! so the hardware rule holds the bridge off: **a 4.7 kΩ pull-down from PA10 to ground** (it
//! would hold 0.45 V even against a 30 kΩ pull-up, 3.3 V × 4.7 / (4.7 + 30), under a driver's
//! 0.8 V logic low; 10 kΩ would give 0.83 V), and USART1 flashing only with the motor supply off
//! (docs/hardware.md, "The ROM bootloader's pins").
//!
//! | function                  | peripheral      | pins                 |
//! |---------------------------|-----------------|----------------------|
//! | right encoder A/B         | TIM2 (32-bit)   | PA0 [A0] / PA1 [A1] (AF1) |
//! | left encoder A/B          | TIM3 (16-bit)   | PB4 [D5] / PB5 [D4] (AF2) |
//! | right motor PWM           | TIM1 CH1 20 kHz | PA8 [D7] (AF1)       |
//! | left motor PWM            | TIM1 CH2 20 kHz | PA9 [D8] (AF1)       |
//! | right / left motor DIR    | GPIO            | PB12 / PB13 (morpho CN10) |
//! | H-bridge enable (low = coast) | GPIO        | PA10 [D2], 4.7 kΩ pull-down on the board |
//! | control tick 1–10 kHz     | TIM7            | —                    |
//! | serial 115200 8N1         | USART2          | PA2 TX / PA3 RX (ST-LINK virtual COM port, the USB cable) |
//! | user button               | EXTI15_10       | PC13 (B1, active low) |
//! | heartbeat / fault LEDs    | GPIO            | PA5 (LD2, green) / PB0 [A3] (external, active high) |
//! | parameters                | flash sectors 1–2 | 0x0800_4000..0x0800_C000 |
//! | stored runs               | flash sectors 6–7 | 0x0804_0000..0x0808_0000 |

pub mod flash;
pub mod safety;

use stm32f4xx_hal::gpio::{Output, PA5, PA10, PB0, PB12, PB13, Pull};
use stm32f4xx_hal::pac::{self, TIM7};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::qei::Qei;
use stm32f4xx_hal::watchdog::IndependentWatchdog;

pub use super::stm32f4::clock::{ClockSource, ClockTexts};
pub use super::stm32f4::console_rx::ConsoleRx;
use super::stm32f4::motors::Tim1Motors;
pub use super::stm32f4::timers::Encoders;
use super::stm32f4::timers::{filter_encoder_inputs, pull_up, rates_exact};
pub use super::stm32f4::watchdog;
use super::stm32f4::{ClockTree, button_edges, start_clocks, start_console, start_tick};
pub use flash::BoardFlash;
pub use safety::ResetCause;

/// Core clock, Hz (the part's maximum, with the regulator's over-drive the HAL switches on).
pub const SYSCLK_HZ: u32 = 180_000_000;
/// APB1 clock (USART2; the bus maximum), Hz: core / 4.
pub const PCLK1_HZ: u32 = 45_000_000;
/// APB2 clock (the bus maximum), Hz: core / 2.
pub const PCLK2_HZ: u32 = 90_000_000;
/// Clock of the APB1 timers (TIM2, TIM3, TIM7), Hz: twice PCLK1 (the APB1 prescaler is not 1).
pub const TIMCLK1_HZ: u32 = 2 * PCLK1_HZ;
/// Clock of the APB2 timers (TIM1), Hz: twice PCLK2.
pub const TIMCLK2_HZ: u32 = 2 * PCLK2_HZ;
/// The clock tree `init` sets and checks.
const CLOCK_TREE: ClockTree = ClockTree {
    crystals: CRYSTALS,
    hse_bypass: true,
    scale1: false,
    sysclk: SYSCLK_HZ,
    pclk1: PCLK1_HZ,
    pclk2: PCLK2_HZ,
    timclk1: TIMCLK1_HZ,
    timclk2: TIMCLK2_HZ,
};
/// The external clock: the ST-LINK's 8 MHz MCO output on PH0, in bypass mode (the board as
/// shipped has no crystal at X3), Hz ([`crate::board::crystal`]).
pub const CRYSTALS: &[u32] = crate::board::crystal::NUCLEO_F446RE_CRYSTALS;
/// Motor PWM frequency, Hz.
pub const PWM_HZ: u32 = 20_000;
/// Independent watchdog timeout, ms: the control task feeds it every period.
pub const WATCHDOG_MS: u32 = 50;
/// Watchdog timeout while the flash is written, ms: a 128 KiB sector's erase takes up to 4 s
/// (docs/storage.md) and stalls the CPU; computed for a 32 kHz LSI that may run at 47 kHz.
pub const FLASH_WATCHDOG_MS: u32 = 10_000;

const _: () = assert!(
    rates_exact(TIMCLK1_HZ),
    "a control rate does not divide TIM7's clock"
);
const _: () = assert!(TIMCLK2_HZ.is_multiple_of(PWM_HZ) && TIMCLK2_HZ / PWM_HZ <= 1 << 16);
const _: () = assert!(
    crate::motion::hbridge::reversal_holds_zero(PWM_HZ, crate::motion::controller::MAX_RATE_HZ),
    "a reversal's zero duty does not last a PWM period at the fastest control rate"
);

/// The interrupt the control task is bound to: TIM7's update (`binds = TIM7` in `src/main.rs`).
pub const CONTROL_INTERRUPT: pac::Interrupt = pac::Interrupt::TIM7;

/// The control-period timer's name, as the boot line names it when it does not count.
pub const CONTROL_TIMER: &str = "TIM7";
/// The button's EXTI interrupt (PC13: EXTI15_10; `binds = EXTI15_10` in `src/main.rs`).
pub const BUTTON_INTERRUPT: pac::Interrupt = pac::Interrupt::EXTI15_10;
/// Whether the app pends [`CONTROL_INTERRUPT`] from the monotonic: no, TIM7 raises it.
pub const CONTROL_FROM_MONOTONIC: bool = false;

/// The clocks as the boot line and the fault event name them.
pub const CLOCK_TEXTS: ClockTexts = ClockTexts {
    external: &["clock: ST-LINK MCO 8 MHz (HSE bypass), 180 MHz"],
    internal: "clock: internal oscillator (HSI 16 MHz), 180 MHz, no ST-LINK MCO at power-up",
    fault: "no external clock: the ST-LINK's 8 MHz MCO (HSE bypass) did not start, running on \
            the internal oscillator (HSI, 180 MHz through the PLL; timing and baud rate within a \
            few %)",
};

/// What the boot line ends with: which clock runs.
pub fn boot_note(clock: ClockSource) -> super::stm32f4::clock::ClockNote {
    clock.describe(&CLOCK_TEXTS)
}

/// The motors: TIM1 channels 1 and 2 (PA8, PA9), DIR on PB12/PB13, bridge enable on PA10.
pub type BoardMotors = Tim1Motors<PB12<Output>, PB13<Output>, PA10<Output>>;

/// The control-period interrupt source: TIM7's update at the control rate (90 MHz timer clock).
pub type ControlTick = super::stm32f4::timers::ControlTick<TIM7>;

/// The user button B1 on PC13 (EXTI15_10, both edges; pressed = low, the board's pull-up).
pub type ButtonInput = super::stm32f4::ButtonInput<'C', 13, false>;

/// Heartbeat (LD2, green, PA5) and fault (external, PB0) LEDs.
pub type Leds = crate::app::io::Leds<PA5<Output>, PB0<Output>>;

pub use super::stm32f4::{CONSOLE_INTERRUPT, CONSOLE_RX_POLLED, ConsoleTx};

/// Everything the board gives the application (see [`crate::board`]).
pub type Board = super::stm32f4::Board<BoardMotors, ControlTick, ButtonInput, Leds>;

/// Brings up clocks and every peripheral the application uses.
pub fn init(dp: pac::Peripherals) -> Board {
    // Before anything else (the motor pins are safe since `__pre_init`): the reset cause, and
    // TIM1 frozen while a debugger halts the core.
    let reset_cause = safety::reset_cause(&dp.RCC);
    safety::freeze_when_halted(&dp.DBGMCU);
    // The ST-LINK's clock if it runs; otherwise the HSI with the PLL set for the same clocks.
    let (mut rcc, clock) = start_clocks(dp.RCC, &CLOCK_TREE, &CLOCK_TEXTS);
    let clocks = rcc.clocks;
    let params = flash::param_store(dp.FLASH);

    // Port A without the HAL's port reset: the motor pins stay in their safe state.
    let gpioa = safety::motor_port_without_reset(dp.GPIOA);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpioc = dp.GPIOC.split(&mut rcc);

    // Encoders: PB4 comes out of reset as a JTAG pin.
    let right = Qei::new(dp.TIM2, (gpioa.pa0, gpioa.pa1), &mut rcc);
    let left = Qei::new(dp.TIM3, (gpiob.pb4.into_input(), gpiob.pb5), &mut rcc);

    // Motors: TIM1 CH1/CH2 PWM, zero duty, the bridge disabled until the first command.
    let (pwm, (ch1, ch2, ..)) = dp.TIM1.pwm_hz(PWM_HZ.Hz(), &mut rcc);
    let motors = BoardMotors::new(
        pwm,
        ch1.with(gpioa.pa8),
        ch2.with(gpioa.pa9),
        gpiob.pb12.into_push_pull_output(),
        gpiob.pb13.into_push_pull_output(),
        gpioa.pa10.into_push_pull_output(),
    );

    // User button B1: both edges, pressed = low.
    let mut button_pin = gpioc.pc13.into_input().internal_resistor(Pull::Up);
    button_edges(&mut button_pin, dp.SYSCFG, dp.EXTI, &mut rcc);

    // At the default rate until the app has loaded the stored one.
    let tick = start_tick(dp.TIM7.counter_hz(&mut rcc));

    // Started by the app once the parameters are loaded.
    let watchdog = IndependentWatchdog::new(dp.IWDG);

    // Serial console: USART2 on PA2/PA3 (the ST-LINK's virtual COM port), RX by DMA.
    let (console_tx, console_rx) = start_console(
        dp.USART2,
        (gpioa.pa2, gpioa.pa3),
        dp.DMA1,
        &mut rcc,
        clocks.sysclk().raw(),
    );
    // SAFETY: the ports' clocks are on (port A's since `__pre_init`, port B's by its
    // split above); `init` owns them and nothing else runs.
    unsafe {
        pull_up(pac::GPIOA::ptr(), &[0, 1, 3]);
        pull_up(pac::GPIOB::ptr().cast(), &[4, 5]);
    }
    filter_encoder_inputs();

    Board {
        sysclk_hz: clocks.sysclk().raw(),
        encoders: Encoders { right, left },
        motors,
        tick,
        button: ButtonInput::new(button_pin),
        leds: Leds::new(
            gpioa.pa5.into_push_pull_output(),
            gpiob.pb0.into_push_pull_output(),
        ),
        console_rx,
        console_tx,
        watchdog,
        params,
        reset_cause,
        clock,
    }
}
