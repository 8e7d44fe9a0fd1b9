//! The STM32F407 board (STM32F4-Discovery class): pin map, clocks and HAL adapters.
//!
//! Pin map (STM32F4-Discovery class board, 8 MHz HSE, 168 MHz core):
//!
//! | function                  | peripheral      | pins                 |
//! |---------------------------|-----------------|----------------------|
//! | right encoder A/B         | TIM2 (32-bit)   | PA15 / PB3 (AF1)     |
//! | left encoder A/B          | TIM3 (16-bit)   | PB4 / PB5 (AF2)      |
//! | right motor PWM           | TIM1 CH1 20 kHz | PE9 (AF1)            |
//! | left motor PWM            | TIM1 CH2 20 kHz | PE11 (AF1)           |
//! | right / left motor DIR    | GPIO            | PE7 / PE8            |
//! | H-bridge enable (low = coast) | GPIO        | PE13                 |
//! | control tick 1–10 kHz     | TIM7            | —                    |
//! | serial 115200 8N1         | USART2          | PA2 TX / PA3 RX (USB-UART adapter) |
//! | user button               | EXTI0           | PA0 (active high)    |
//! | heartbeat / fault LEDs    | GPIO            | PD12 green / PD14 red |
//! | parameters                | flash sectors 1–2   | 0x0800_4000..0x0800_C000 |
//! | stored runs               | flash sectors 10–11 | 0x080C_0000..0x0810_0000 |
//!
//! Everything `unsafe` in the firmware lives here and carries a `// SAFETY:` note.

pub mod flash;
pub mod safety;

use stm32f4xx_hal::gpio::{Output, PD12, PD14, PE7, PE8, PE13, Pull};
use stm32f4xx_hal::pac::{self, TIM7};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::qei::Qei;
use stm32f4xx_hal::watchdog::IndependentWatchdog;

pub use super::stm32f4::clock::{ClockSource, ClockTexts};
pub use super::stm32f4::console_rx::ConsoleRx;
pub use super::stm32f4::timers::Encoders;
use super::stm32f4::timers::{filter_encoder_inputs, pull_up, rates_exact};
pub use super::stm32f4::{CONSOLE_INTERRUPT, CONSOLE_RX_POLLED, ConsoleTx};
use super::stm32f4::{ClockTree, button_edges, start_clocks, start_console, start_tick};
pub use super::stm32f4::{console_rx, watchdog};
pub use flash::BoardFlash;
pub use safety::ResetCause;

/// The motors: TIM1 channels 1 and 2 (PE9, PE11), DIR on PE7/PE8, bridge enable on PE13.
pub type BoardMotors = super::stm32f4::motors::Tim1Motors<PE7<Output>, PE8<Output>, PE13<Output>>;

/// The interrupt the control task is bound to: TIM7's update (`binds = TIM7` in `src/main.rs`).
pub const CONTROL_INTERRUPT: pac::Interrupt = pac::Interrupt::TIM7;

/// The control-period timer's name, as the boot line names it when it does not count.
pub const CONTROL_TIMER: &str = "TIM7";
/// The interrupt of the button's EXTI line (PA0: EXTI0; `binds = EXTI0` in `src/main.rs`).
pub const BUTTON_INTERRUPT: pac::Interrupt = pac::Interrupt::EXTI0;
/// Whether the app pends [`CONTROL_INTERRUPT`] from the monotonic: no, TIM7 raises it.
pub const CONTROL_FROM_MONOTONIC: bool = false;

/// Core clock, Hz.
pub const SYSCLK_HZ: u32 = 168_000_000;
/// APB1 clock (USART2; the bus maximum), Hz: core / 4.
pub const PCLK1_HZ: u32 = 42_000_000;
/// Clock of the APB1 timers (TIM2, TIM3, TIM7), Hz: twice PCLK1, because the APB1 prescaler is
/// not 1 (RM0090 §6.2, "timer clock frequencies").
pub const TIMCLK1_HZ: u32 = 2 * PCLK1_HZ;
/// APB2 clock (the 84 MHz bus maximum), Hz: core / 2.
pub const PCLK2_HZ: u32 = 84_000_000;
/// Clock of the APB2 timers (TIM1), Hz: twice PCLK2, for the same reason.
pub const TIMCLK2_HZ: u32 = 2 * PCLK2_HZ;
/// The clock tree `init` sets and checks.
const CLOCK_TREE: ClockTree = ClockTree {
    crystals: CRYSTALS,
    hse_bypass: false,
    scale1: false,
    sysclk: SYSCLK_HZ,
    pclk1: PCLK1_HZ,
    pclk2: PCLK2_HZ,
    timclk1: TIMCLK1_HZ,
    timclk2: TIMCLK2_HZ,
};

const _: () = assert!(
    rates_exact(TIMCLK1_HZ),
    "a control rate does not divide TIM7's clock"
);
// TIM1's PWM period (ARR + 1 = 8,400 timer ticks, the duty resolution) is exact.
const _: () = assert!(TIMCLK2_HZ.is_multiple_of(PWM_HZ) && TIMCLK2_HZ / PWM_HZ <= 1 << 16);
const _: () = assert!(
    crate::motion::hbridge::reversal_holds_zero(PWM_HZ, crate::motion::controller::MAX_RATE_HZ),
    "a reversal's zero duty does not last a PWM period at the fastest control rate"
);
/// The documented external crystal, Hz ([`crate::board::crystal`]): 8 MHz.
pub const CRYSTALS: &[u32] = crate::board::crystal::F407_CRYSTALS;
/// Motor PWM frequency, Hz (above hearing, within the H-bridge's switching limit).
pub const PWM_HZ: u32 = 20_000;
/// Independent watchdog timeout, ms: the control task feeds it every period.
pub const WATCHDOG_MS: u32 = 50;
/// Watchdog timeout while the parameter flash is written, ms. The HAL erases with x8
/// parallelism: a 128 KiB sector takes up to 4 s (STM32F407 datasheet, t_ERASE128KB) and stalls
/// the CPU. The timeout is computed for a 32 kHz LSI, which may run as fast as 47 kHz, so 10 s
/// gives at least 6.8 s.
pub const FLASH_WATCHDOG_MS: u32 = 10_000;

/// The clocks as the boot line and the fault event name them.
pub const CLOCK_TEXTS: ClockTexts = ClockTexts {
    external: &["clock: 8 MHz crystal (HSE), 168 MHz"],
    internal: "clock: internal oscillator (HSI 16 MHz), 168 MHz",
    fault: "no crystal: HSE did not start, running on the internal oscillator (HSI, 168 MHz \
            through the PLL; timing and baud rate within a few %)",
};

/// What the boot line ends with: which clock runs.
pub fn boot_note(clock: ClockSource) -> super::stm32f4::clock::ClockNote {
    clock.describe(&CLOCK_TEXTS)
}

/// The control-period interrupt source: TIM7's update at the control rate (84 MHz timer clock,
/// so every rate of [`crate::motion::controller::RATES_HZ`] divides exactly).
pub type ControlTick = super::stm32f4::timers::ControlTick<TIM7>;

/// The user button on PA0 (EXTI0, both edges, pressed = high).
pub type ButtonInput = super::stm32f4::ButtonInput<'A', 0, true>;

/// Heartbeat (green PD12) and fault (red PD14) LEDs.
pub type Leds = crate::app::io::Leds<PD12<Output>, PD14<Output>>;

/// Everything the board gives the application (see [`crate::board`]).
pub type Board = super::stm32f4::Board<BoardMotors, ControlTick, ButtonInput, Leds>;

/// Brings up clocks and every peripheral the application uses.
pub fn init(dp: pac::Peripherals) -> Board {
    // Before anything else (the motor pins are safe since `__pre_init`): the reset cause, and
    // TIM1 frozen while a debugger halts the core.
    let reset_cause = safety::reset_cause(&dp.RCC);
    safety::freeze_when_halted(&dp.DBGMCU);
    // The crystal, if it starts within the timeout; otherwise the internal oscillator, with
    // the PLL derived from it for the same 168 MHz core and 42/84 MHz buses, so timers, PWM
    // and baud rates stay as configured (a missing crystal must not hang the boot before the
    // watchdog runs).
    // The HAL picks the PLL factors and bus prescalers (8 or 16 MHz / M = 2 MHz, × 168, / 2;
    // APB1 / 4, APB2 / 2; 5 flash wait states for 168 MHz at 2.7–3.6 V, RM0090 Table 10).
    let (mut rcc, clock) = start_clocks(dp.RCC, &CLOCK_TREE, &CLOCK_TEXTS);
    let clocks = rcc.clocks;
    let params = flash::param_store(dp.FLASH);

    // Port E without the HAL's port reset: the motor pins stay in their safe state.
    let gpioe = safety::motor_port_without_reset(dp.GPIOE);
    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpiod = dp.GPIOD.split(&mut rcc);

    // Encoders: PA15/PB3/PB4 come out of reset as JTAG pins.
    let right = Qei::new(
        dp.TIM2,
        (gpioa.pa15.into_input(), gpiob.pb3.into_input()),
        &mut rcc,
    );
    let left = Qei::new(dp.TIM3, (gpiob.pb4.into_input(), gpiob.pb5), &mut rcc);

    // Motors: TIM1 CH1/CH2 PWM, zero duty, the bridge disabled until the controller's first
    // command (PE13 stays low through the boot: fil/safe_boot_test.py).
    let (pwm, (ch1, ch2, ..)) = dp.TIM1.pwm_hz(PWM_HZ.Hz(), &mut rcc);
    let motors = BoardMotors::new(
        pwm,
        ch1.with(gpioe.pe9),
        ch2.with(gpioe.pe11),
        gpioe.pe7.into_push_pull_output(),
        gpioe.pe8.into_push_pull_output(),
        gpioe.pe13.into_push_pull_output(),
    );

    // User button: both edges, pressed = high.
    let mut button_pin = gpioa.pa0.into_input().internal_resistor(Pull::Down);
    button_edges(&mut button_pin, dp.SYSCFG, dp.EXTI, &mut rcc);

    // At the default rate until the app has loaded the stored one.
    let tick = start_tick(dp.TIM7.counter_hz(&mut rcc));

    // Not started here: the app starts it once the parameters are loaded (a load may repair
    // an interrupted save, which erases a sector for seconds).
    let watchdog = IndependentWatchdog::new(dp.IWDG);

    // Serial console: USART2 on PA2/PA3 (a USB-UART adapter), RX by DMA into a ring.
    let (console_tx, console_rx) = start_console(
        dp.USART2,
        (gpioa.pa2, gpioa.pa3),
        dp.DMA1,
        &mut rcc,
        clocks.sysclk().raw(),
    );
    // Pull-ups on the four encoder pins (PA15 and PB4 keep their JTAG pull-ups out of reset,
    // PB3 and PB5 would float) and on the console's RX pin (PA3), so an unconnected input is
    // quiet, not noise.
    // SAFETY: the ports' clocks are on (their splits above); `init` owns them and nothing else
    // runs.
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
            gpiod.pd12.into_push_pull_output(),
            gpiod.pd14.into_push_pull_output(),
        ),
        console_rx,
        console_tx,
        watchdog,
        params,
        reset_cause,
        clock,
    }
}
