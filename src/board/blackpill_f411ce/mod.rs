//! The WeAct Black Pill F411CE board (STM32F411CE, 100 MHz, 512 KiB flash, 25 or 8 MHz crystal):
//! pin map, clocks and HAL adapters. The parts every STM32F4 board shares are in
//! [`crate::board::stm32f4`].
//!
//! Pin map (docs/hardware.md). What the board itself wires is left alone: the KEY (PA0) is the
//! button, the LED (PC13) the heartbeat; PH0/PH1 carry the crystal (measured at boot: 25 or
//! 8 MHz), PC14/PC15 the 32 kHz one, PA11/PA12 the USB-C connector, PA13/PA14 the SWD header,
//! PB2 BOOT1; PA5–PA7 (the optional SPI flash footprint) stay free and its chip select PA4 is
//! held high (on V2.0 boards the flash's MISO is PB4, the left encoder's A). The part has no
//! TIM6/TIM7: the control tick is TIM11.
//!
//! The ROM bootloader (BOOT0, how a Black Pill is flashed over USB DFU) takes USART1's PA9 (the
//! left PWM) and PA10 as inputs without a pull, and drives PA9 once a host selects USART1
//! (AN2606 Rev 70, table 83): TIM1 CH1/CH2 have no other pins on this package, so the bridge
//! enable is on PA1, which no bootloader interface touches, and the board needs a 4.7 kΩ
//! pull-down from PA1 to ground (and one on PA10, so the floating USART1 RX does not keep DFU
//! from starting; docs/hardware.md, "The ROM bootloader's pins"): the bridge stays disabled
//! whatever the PWM pins do before our code runs.
//!
//! | function                  | peripheral      | pins                 |
//! |---------------------------|-----------------|----------------------|
//! | right encoder A/B         | TIM2 (32-bit)   | PA15 / PB3 (AF1)     |
//! | left encoder A/B          | TIM3 (16-bit)   | PB4 / PB5 (AF2)      |
//! | right motor PWM           | TIM1 CH1 20 kHz | PA8 (AF1)            |
//! | left motor PWM            | TIM1 CH2 20 kHz | PA9 (AF1)            |
//! | right / left motor DIR    | GPIO            | PB12 / PB13          |
//! | H-bridge enable (low = coast) | GPIO        | PA1 (4.7 kΩ pull-down on the board) |
//! | SPI flash CS (V2.0), held high | GPIO          | PA4                  |
//! | control tick 1–10 kHz     | TIM11           | — (interrupt TIM1_TRG_COM_TIM11) |
//! | serial 115200 8N1         | USART2          | PA2 TX / PA3 RX (USB-UART adapter) |
//! | user button               | EXTI0           | PA0 (KEY, active low) |
//! | heartbeat / fault LEDs    | GPIO            | PC13 (on-board, active low) / PB0 (external, active high) |
//! | parameters                | flash sectors 1–2 | 0x0800_4000..0x0800_C000 |
//! | stored runs               | flash sectors 6–7 | 0x0804_0000..0x0808_0000 |

pub mod flash;
pub mod safety;

use stm32f4xx_hal::gpio::{Output, PA1, PB0, PB12, PB13, PC13, PinState, Pull};
use stm32f4xx_hal::pac::{self, TIM11};
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

/// Core clock, Hz (the part's maximum).
pub const SYSCLK_HZ: u32 = 100_000_000;
/// APB1 clock (USART2; the bus maximum), Hz: core / 2.
pub const PCLK1_HZ: u32 = 50_000_000;
/// APB2 clock, Hz: the core clock (the bus runs at up to 100 MHz).
pub const PCLK2_HZ: u32 = 100_000_000;
/// Clock of the APB1 timers (TIM2, TIM3), Hz: twice PCLK1 (the APB1 prescaler is not 1).
pub const TIMCLK1_HZ: u32 = 2 * PCLK1_HZ;
/// Clock of the APB2 timers (TIM1, TIM11), Hz: PCLK2 (the APB2 prescaler is 1).
pub const TIMCLK2_HZ: u32 = PCLK2_HZ;
/// The clock tree `init` sets and checks.
const CLOCK_TREE: ClockTree = ClockTree {
    crystals: CRYSTALS,
    hse_bypass: false,
    scale1: true,
    sysclk: SYSCLK_HZ,
    pclk1: PCLK1_HZ,
    pclk2: PCLK2_HZ,
    timclk1: TIMCLK1_HZ,
    timclk2: TIMCLK2_HZ,
};
/// The external clock: the board's crystal on PH0/PH1, 25 MHz or (some batches) 8 MHz, Hz
/// ([`crate::board::crystal`]: measured at boot).
pub const CRYSTALS: &[u32] = crate::board::crystal::BLACKPILL_F411CE_CRYSTALS;
/// Motor PWM frequency, Hz.
pub const PWM_HZ: u32 = 20_000;
/// Independent watchdog timeout, ms: the control task feeds it every period.
pub const WATCHDOG_MS: u32 = 50;
/// Watchdog timeout while the flash is written, ms: a 128 KiB sector's erase takes up to 4 s
/// (docs/storage.md) and stalls the CPU; computed for a 32 kHz LSI that may run at 47 kHz.
pub const FLASH_WATCHDOG_MS: u32 = 10_000;

const _: () = assert!(
    rates_exact(TIMCLK2_HZ),
    "a control rate does not divide TIM11's clock"
);
const _: () = assert!(TIMCLK2_HZ.is_multiple_of(PWM_HZ) && TIMCLK2_HZ / PWM_HZ <= 1 << 16);
const _: () = assert!(
    crate::motion::hbridge::reversal_holds_zero(PWM_HZ, crate::motion::controller::MAX_RATE_HZ),
    "a reversal's zero duty does not last a PWM period at the fastest control rate"
);

/// The interrupt the control task is bound to: TIM11's update, which shares its vector with
/// TIM1's trigger and commutation interrupts (never enabled: TIM1 only makes the PWM)
/// (`binds = TIM1_TRG_COM_TIM11` in `src/main.rs`).
pub const CONTROL_INTERRUPT: pac::Interrupt = pac::Interrupt::TIM1_TRG_COM_TIM11;

/// The control-period timer's name, as the boot line names it when it does not count.
pub const CONTROL_TIMER: &str = "TIM11";
/// The button's EXTI interrupt (PA0: EXTI0; `binds = EXTI0` in `src/main.rs`).
pub const BUTTON_INTERRUPT: pac::Interrupt = pac::Interrupt::EXTI0;
/// Whether the app pends [`CONTROL_INTERRUPT`] from the monotonic: no, TIM11 raises it.
pub const CONTROL_FROM_MONOTONIC: bool = false;

/// The clocks as the boot line and the fault event name them.
pub const CLOCK_TEXTS: ClockTexts = ClockTexts {
    external: &[
        "clock: 25 MHz crystal (HSE), 100 MHz",
        "clock: 8 MHz crystal (HSE), 100 MHz",
    ],
    internal: "clock: internal oscillator (HSI 16 MHz), 100 MHz",
    fault: "no crystal: HSE did not start, running on the internal oscillator (HSI, 100 MHz \
            through the PLL; timing and baud rate within a few %)",
};

/// What the boot line ends with: which clock runs.
pub fn boot_note(clock: ClockSource) -> super::stm32f4::clock::ClockNote {
    clock.describe(&CLOCK_TEXTS)
}

/// The motors: TIM1 channels 1 and 2 (PA8, PA9), DIR on PB12/PB13, bridge enable on PA1.
pub type BoardMotors = Tim1Motors<PB12<Output>, PB13<Output>, PA1<Output>>;

/// The control-period interrupt source: TIM11's update at the control rate (100 MHz timer
/// clock).
pub type ControlTick = super::stm32f4::timers::ControlTick<TIM11>;

/// The KEY on PA0 (EXTI0, both edges; pressed = low, the internal pull-up).
pub type ButtonInput = super::stm32f4::ButtonInput<'A', 0, false>;

/// Heartbeat (on-board, PC13, active low: it blinks all the same) and fault (external, PB0) LEDs.
pub type Leds = crate::app::io::Leds<PC13<Output>, PB0<Output>>;

pub use super::stm32f4::{CONSOLE_INTERRUPT, CONSOLE_RX_POLLED, ConsoleTx};

/// Everything the board gives the application (see [`crate::board`]).
pub type Board = super::stm32f4::Board<BoardMotors, ControlTick, ButtonInput, Leds>;

/// Brings up clocks and every peripheral the application uses.
pub fn init(dp: pac::Peripherals) -> Board {
    // Before anything else (the motor pins are safe since `__pre_init`): the reset cause, and
    // TIM1 frozen while a debugger halts the core.
    let reset_cause = safety::reset_cause(&dp.RCC);
    safety::freeze_when_halted(&dp.DBGMCU);
    // The crystal if it starts; otherwise the HSI with the PLL set for the same clocks.
    let (mut rcc, clock) = start_clocks(dp.RCC, &CLOCK_TREE, &CLOCK_TEXTS);
    let clocks = rcc.clocks;
    let params = flash::param_store(dp.FLASH);

    // Port A without the HAL's port reset: the motor pins stay in their safe state.
    let gpioa = safety::motor_port_without_reset(dp.GPIOA);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpioc = dp.GPIOC.split(&mut rcc);

    // Encoders: PA15/PB3/PB4 come out of reset as JTAG pins.
    let right = Qei::new(
        dp.TIM2,
        (gpioa.pa15.into_input(), gpiob.pb3.into_input()),
        &mut rcc,
    );
    let left = Qei::new(dp.TIM3, (gpiob.pb4.into_input(), gpiob.pb5), &mut rcc);

    // Motors: TIM1 CH1/CH2 PWM, zero duty, the bridge disabled until the first command.
    let (pwm, (ch1, ch2, ..)) = dp.TIM1.pwm_hz(PWM_HZ.Hz(), &mut rcc);
    let motors = BoardMotors::new(
        pwm,
        ch1.with(gpioa.pa8),
        ch2.with(gpioa.pa9),
        gpiob.pb12.into_push_pull_output(),
        gpiob.pb13.into_push_pull_output(),
        gpioa.pa1.into_push_pull_output(),
    );
    // V2.0 boards' optional SPI flash: its chip select (PA4) high, so the flash never drives
    // its MISO, PB4, the left encoder's A input (V2.1 and later route it elsewhere).
    let _ = gpioa.pa4.into_push_pull_output_in_state(PinState::High);

    // The KEY: both edges, pressed = low (it connects PA0 to ground).
    let mut button_pin = gpioa.pa0.into_input().internal_resistor(Pull::Up);
    button_edges(&mut button_pin, dp.SYSCFG, dp.EXTI, &mut rcc);

    // At the default rate until the app has loaded the stored one.
    let tick = start_tick(dp.TIM11.counter_hz(&mut rcc));

    // Started by the app once the parameters are loaded.
    let watchdog = IndependentWatchdog::new(dp.IWDG);

    // Serial console: USART2 on PA2/PA3 (a USB-UART adapter), RX by DMA.
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
        pull_up(pac::GPIOA::ptr(), &[3, 15]);
        pull_up(pac::GPIOB::ptr().cast(), &[3, 4, 5]);
    }
    filter_encoder_inputs();

    Board {
        sysclk_hz: clocks.sysclk().raw(),
        encoders: Encoders { right, left },
        motors,
        tick,
        button: ButtonInput::new(button_pin),
        leds: Leds::new(
            gpioc.pc13.into_push_pull_output(),
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
