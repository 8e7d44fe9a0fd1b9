//! What every STM32F4 board of odocal shares, whatever its pin map: the parts are the same
//! peripherals at the same addresses on the STM32F407, STM32F446 and STM32F411 (reference
//! manuals RM0090, RM0390, RM0383), so a board folder uses them as they are.
//!
//! | module | what |
//! |---|---|
//! | [`clock`] | the external clock with the bounded wait and the fall-back to the HSI |
//! | [`console_rx`] | USART2's receive half by DMA1 stream 5 channel 4 into a ring (the same request mapping on the three parts) |
//! | [`flash`] | the parameter and run store's flash driver, over the board's flash map |
//! | [`map_512k`] | the flash map of the 512 KiB parts (parameters in sectors 1–2, runs in 6–7) |
//! | [`motors`] | two H-bridge channels on TIM1 channels 1 and 2, with the board's DIR and enable pins |
//! | [`reset`] | reset cause, crash record, fault guard, debug-halt freeze |
//! | [`safe_state`] | the motor pins' safe state and emergency stop for PWM and enable pins on one port |
//! | [`timers`] | the encoders (TIM2, TIM3), the control-period tick, the encoder input filter and pull-ups |
//! | [`watchdog`] | the independent watchdog's timeout changes |

pub mod clock;
pub mod console_rx;
pub mod flash;
pub mod map_512k;
pub mod motors;
pub mod param_sectors;
pub mod reset;
pub mod safe_state;
pub mod timers;
pub mod watchdog;

use stm32f4xx_hal::gpio::{Edge, ExtiPin, PA2, PA3};
use stm32f4xx_hal::pac::{DMA1, EXTI, RCC, SYSCFG, USART2};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::{Config, Rcc};
use stm32f4xx_hal::serial::{self, Serial, Tx};
use stm32f4xx_hal::timer::{CounterHz, Event, Instance};
use stm32f4xx_hal::watchdog::IndependentWatchdog;

use crate::storage::ParamAndRunStore;

/// Everything a board gives the application (see [`crate::board`]), over the board's motors
/// `M`, control tick `T`, button `B` and LEDs `L`.
pub struct Board<M, T, B, L> {
    /// Core clock the monotonic timer runs at, Hz.
    pub sysclk_hz: u32,
    /// Wheel encoders.
    pub encoders: timers::Encoders,
    /// Motor outputs (zero duty, bridge disabled until the controller's first command).
    pub motors: M,
    /// Control-period interrupt, already running.
    pub tick: T,
    /// User button.
    pub button: B,
    /// Status LEDs.
    pub leds: L,
    /// Console receive half.
    pub console_rx: console_rx::ConsoleRx,
    /// Console transmit half.
    pub console_tx: Tx<USART2>,
    /// Independent watchdog, not started yet ([`watchdog::set_timeout`] starts it).
    pub watchdog: IndependentWatchdog,
    /// The parameter and run store on the board's flash map (not loaded yet).
    pub params: ParamAndRunStore<flash::BoardFlash>,
    /// Why the MCU last reset.
    pub reset_cause: reset::ResetCause,
    /// Where the core clock comes from (the internal oscillator if the external clock did not
    /// start).
    pub clock: clock::ClockSource,
}

/// A board's clock tree, Hz: its external clocks, what the HAL is asked for (core and the two
/// buses) and the timer clocks that follow from it (twice a bus clock whose prescaler is not 1).
pub struct ClockTree {
    /// The external clock's documented frequencies ([`crate::board::crystal`]).
    pub crystals: &'static [u32],
    /// Whether the external clock is a clock input (HSE bypass) rather than a crystal: another
    /// chip's output, which can stop, so the clock security system watches it.
    pub hse_bypass: bool,
    /// Whether the core clock needs the regulator's voltage scale 1 selected before the PLL
    /// starts (the STM32F411 resets to scale 2).
    pub scale1: bool,
    /// Core clock.
    pub sysclk: u32,
    /// APB1 clock (USART2, TIM2, TIM3, TIM7).
    pub pclk1: u32,
    /// APB2 clock (TIM1, TIM11).
    pub pclk2: u32,
    /// Clock of the APB1 timers.
    pub timclk1: u32,
    /// Clock of the APB2 timers.
    pub timclk2: u32,
}

/// Starts the clocks: the regulator's scale first where the tree needs it, then the external
/// clock (bounded wait, [`clock::start_external`]) measured against the HSI
/// ([`clock::odocal_hse_count`], [`crate::board::crystal::identify`]) and the PLL set for the
/// crystal found; without an external clock, or with one that is none of the board's, the HSI
/// with the PLL set for the same tree, logging the fault. Logs an error if the HAL's clocks
/// differ from `tree` (the timer periods, the PWM and the baud rate assume exactly those) or
/// the regulator did not reach its scale; turns on the clock security system for a clock input.
pub fn start_clocks(
    rcc: RCC,
    tree: &ClockTree,
    texts: &clock::ClockTexts,
) -> (Rcc, clock::ClockSource) {
    use crate::board::crystal::{Crystal, identify};
    if tree.scale1 {
        clock::select_scale1(&rcc);
    }
    let started = if clock::start_external(&rcc, tree.hse_bypass) {
        match identify(clock::odocal_hse_count(), tree.crystals) {
            Crystal::Documented { index, .. } => clock::ClockSource::External(index as u8),
            Crystal::Unknown { measured_hz } => {
                clock::stop_external(&rcc);
                clock::ClockSource::Unknown(measured_hz)
            }
        }
    } else {
        clock::ClockSource::Internal
    };
    let source = match started {
        clock::ClockSource::External(i) => {
            let hz = tree.crystals.get(usize::from(i)).copied().unwrap_or(0);
            let config = Config::hse(hz.Hz());
            if tree.hse_bypass {
                config.bypass_hse_oscillator()
            } else {
                config
            }
        }
        clock::ClockSource::Internal | clock::ClockSource::Unknown(_) => {
            if let Some(fault) = started.fault(texts) {
                error!("{}", fault);
            }
            Config::hsi()
        }
    };
    let rcc = rcc.freeze(
        source
            .sysclk(tree.sysclk.Hz())
            .pclk1(tree.pclk1.Hz())
            .pclk2(tree.pclk2.Hz()),
    );
    if tree.scale1 && !clock::scale1_ready() {
        error!("regulator not at voltage scale 1 (PWR_CSR.VOSRDY clear) with the PLL running");
    }
    if tree.hse_bypass && matches!(started, clock::ClockSource::External(_)) {
        clock::watch_external();
    }
    let clocks = &rcc.clocks;
    if clocks.sysclk().raw() != tree.sysclk
        || clocks.pclk1().raw() != tree.pclk1
        || clocks.pclk2().raw() != tree.pclk2
        || clocks.timclk1().raw() != tree.timclk1
        || clocks.timclk2().raw() != tree.timclk2
    {
        error!(
            "clocks differ from the board's: sysclk {} pclk1 {} pclk2 {} timers {} / {} Hz",
            clocks.sysclk().raw(),
            clocks.pclk1().raw(),
            clocks.pclk2().raw(),
            clocks.timclk1().raw(),
            clocks.timclk2().raw()
        );
    }
    (rcc, started)
}

/// The user button's pin as an interrupt source on both edges (its EXTI line through SYSCFG).
pub fn button_edges(pin: &mut impl ExtiPin, syscfg: SYSCFG, mut exti: EXTI, rcc: &mut Rcc) {
    let mut syscfg = syscfg.constrain(rcc);
    pin.make_interrupt_source(&mut syscfg);
    pin.trigger_on_edge(&mut exti, Edge::RisingFalling);
    pin.enable_interrupt(&mut exti);
}

/// The serial console: USART2 on PA2 (TX) / PA3 (RX) at 115,200 Bd, the receive half by DMA into
/// its ring ([`console_rx`], which bounds the bytes that can have arrived between two reads by
/// the core's cycle count at `sysclk_hz`).
pub fn start_console(
    usart: USART2,
    pins: (PA2, PA3),
    dma: DMA1,
    rcc: &mut Rcc,
    sysclk_hz: u32,
) -> (Tx<USART2>, console_rx::ConsoleRx) {
    let usart = Serial::new(
        usart,
        pins,
        serial::Config::default().baudrate(console_rx::CONSOLE_BAUD.bps()),
        rcc,
    );
    let (console_tx, console_rx) = match usart {
        Ok(s) => s.split(),
        Err(_) => defmt::panic!("USART2 configuration rejected"),
    };
    (
        console_tx,
        console_rx::ConsoleRx::start(console_rx, dma, rcc, sysclk_hz),
    )
}

/// The control tick on `timer`, started at the default rate (until the app has loaded the stored
/// one) with its update interrupt enabled.
pub fn start_tick<TIM: Instance>(mut timer: CounterHz<TIM>) -> timers::ControlTick<TIM> {
    let rate_hz = crate::motion::controller::DEFAULT_RATE_HZ;
    if timer.start(rate_hz.Hz()).is_err() {
        error!("control timer did not start");
    }
    timer.listen(Event::Update);
    timers::ControlTick { timer, rate_hz }
}

/// The user button on an EXTI line (both edges), pressed at the level `ACTIVE_HIGH` says.
pub struct ButtonInput<const P: char, const N: u8, const ACTIVE_HIGH: bool>(
    stm32f4xx_hal::gpio::Pin<P, N, stm32f4xx_hal::gpio::Input>,
);

impl<const P: char, const N: u8, const ACTIVE_HIGH: bool> ButtonInput<P, N, ACTIVE_HIGH> {
    /// The button on `pin`, already an interrupt source.
    pub fn new(pin: stm32f4xx_hal::gpio::Pin<P, N, stm32f4xx_hal::gpio::Input>) -> Self {
        ButtonInput(pin)
    }

    /// Acknowledges the edge interrupt and reads the level (true = pressed).
    pub fn edge(&mut self) -> bool {
        use stm32f4xx_hal::gpio::ExtiPin;
        self.0.clear_interrupt_pending_bit();
        crate::app::io::button_pressed(&mut self.0, ACTIVE_HIGH)
    }
}

/// The console's receive half is read from its DMA ring: the app pends the console interrupt
/// every millisecond to drain it.
pub const CONSOLE_RX_POLLED: bool = true;
/// The console port's transmit half (USART2 TXE interrupt).
pub type ConsoleTx = Tx<USART2>;
/// The interrupt that serves the console port; the console task pends it to start sending.
pub const CONSOLE_INTERRUPT: stm32f4xx_hal::pac::Interrupt = stm32f4xx_hal::pac::Interrupt::USART2;
