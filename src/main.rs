//! odocal firmware entry point (RTIC 2, STM32F407).
//!
//! Wiring only: tasks own peripherals, call one library function each and publish the result.
//! Priorities: control (TIM7, 1 kHz) 3 > serial/button 2 > background 1.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("the odocal firmware runs on the STM32F407; on the host, use `cargo sim`");
}

#[cfg(target_os = "none")]
use defmt_rtt as _;
#[cfg(target_os = "none")]
use panic_probe as _;

#[cfg(target_os = "none")]
rtic_monotonics::systick_monotonic!(Mono, 1000);

#[cfg(target_os = "none")]
#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true, dispatchers = [SPI1, SPI2])]
mod app {
    use odocal::board::flash::{BoardFlash, param_store};
    use odocal::board::motors::BoardMotors;
    use odocal::board::{CONTROL_HZ, HSE_HZ, PWM_HZ, SYSCLK_HZ, WATCHDOG_MS};
    use odocal::button::{Button, ButtonConfig, Press};
    use odocal::controller::{Controller, ControllerConfig};
    use odocal::geometry::Geometry;
    use odocal::routine::RunPlan;
    use odocal::run::Direction;
    use odocal::storage::ParamStore;
    use rtic_monotonics::systick::prelude::*;
    use stm32f4xx_hal::gpio::{Edge, Input, Output, PA0, PD12, PD14, Pull};
    use stm32f4xx_hal::pac::{TIM2, TIM3, TIM7};
    use stm32f4xx_hal::prelude::*;
    use stm32f4xx_hal::qei::Qei;
    use stm32f4xx_hal::rcc::Config;
    use stm32f4xx_hal::timer::{CounterHz, Event, Flag};
    use stm32f4xx_hal::watchdog::IndependentWatchdog;

    use super::Mono;

    #[shared]
    struct Shared {
        controller: Controller,
        button: Button,
    }

    #[local]
    struct Local {
        qei_right: Qei<TIM2>,
        qei_left: Qei<TIM3>,
        tick: CounterHz<TIM7>,
        motors: BoardMotors,
        watchdog: IndependentWatchdog,
        plan: RunPlan,
        button_pin: PA0<Input>,
        heartbeat: PD12<Output>,
        fault_led: PD14<Output>,
        params_store: ParamStore<BoardFlash>,
    }

    /// Milliseconds since boot (wrapping), from the SysTick monotonic.
    fn now_ms() -> u32 {
        Mono::now().ticks()
    }

    /// A controller for `geometry`, or for the built-in default when the stored one is refused.
    fn make_controller(geometry: Geometry) -> Controller {
        match Controller::new(ControllerConfig::new(geometry, CONTROL_HZ)) {
            Ok(c) => c,
            Err(e) => {
                defmt::warn!("stored geometry refused ({}), using defaults", e);
                let mut config = ControllerConfig::new(Geometry::default(), CONTROL_HZ);
                config.geometry = Geometry::default();
                // The built-in defaults are validated by the library's tests.
                match Controller::new(config) {
                    Ok(c) => c,
                    Err(_) => defmt::panic!("built-in controller defaults rejected"),
                }
            }
        }
    }

    #[init]
    fn init(mut cx: init::Context) -> (Shared, Local) {
        let mut rcc = cx.device.RCC.freeze(
            Config::hse(HSE_HZ.Hz())
                .sysclk(SYSCLK_HZ.Hz())
                .pclk1(42.MHz()),
        );
        Mono::start(cx.core.SYST, SYSCLK_HZ);

        // Parameters first: loading may repair an interrupted save (motors are off here).
        let mut params_store = param_store(cx.device.FLASH);
        let params = params_store.load_blocking().record;
        let mut controller = make_controller(params.active_geometry());
        if let Err(e) = controller.set_limits(params.motion.limits()) {
            defmt::warn!("stored motion limits refused ({}), using defaults", e);
        }
        let plan = RunPlan::new(f64::from(params.motion.square_side_m), Direction::Cw);

        let gpioa = cx.device.GPIOA.split(&mut rcc);
        let gpiob = cx.device.GPIOB.split(&mut rcc);
        let gpiod = cx.device.GPIOD.split(&mut rcc);
        let gpioe = cx.device.GPIOE.split(&mut rcc);

        // Encoders: PA15/PB3/PB4 come out of reset as JTAG pins.
        let qei_right = Qei::new(
            cx.device.TIM2,
            (gpioa.pa15.into_input(), gpiob.pb3.into_input()),
            &mut rcc,
        );
        let qei_left = Qei::new(
            cx.device.TIM3,
            (gpiob.pb4.into_input(), gpiob.pb5),
            &mut rcc,
        );

        // Motors: TIM1 CH1/CH2 PWM, braked until the controller commands otherwise.
        let (pwm, (ch1, ch2, ..)) = cx.device.TIM1.pwm_hz(PWM_HZ.Hz(), &mut rcc);
        let motors = BoardMotors::new(
            pwm,
            ch1.with(gpioe.pe9),
            ch2.with(gpioe.pe11),
            gpioe.pe7.into_push_pull_output(),
            gpioe.pe8.into_push_pull_output(),
            gpioe.pe13.into_push_pull_output(),
        );

        // User button: both edges, pressed = high.
        let mut syscfg = cx.device.SYSCFG.constrain(&mut rcc);
        let mut button_pin = gpioa.pa0.into_input().internal_resistor(Pull::Down);
        button_pin.make_interrupt_source(&mut syscfg);
        button_pin.trigger_on_edge(&mut cx.device.EXTI, Edge::RisingFalling);
        button_pin.enable_interrupt(&mut cx.device.EXTI);

        let mut tick = cx.device.TIM7.counter_hz(&mut rcc);
        if tick.start(CONTROL_HZ.Hz()).is_err() {
            defmt::error!("control timer did not start");
        }
        tick.listen(Event::Update);

        let mut watchdog = IndependentWatchdog::new(cx.device.IWDG);
        watchdog.start(WATCHDOG_MS.millis());

        let heartbeat = gpiod.pd12.into_push_pull_output();
        let fault_led = gpiod.pd14.into_push_pull_output();

        report::spawn().ok();
        defmt::info!(
            "odocal up: control at {} Hz, calibration '{}'",
            CONTROL_HZ,
            params.calibration.method.as_str()
        );

        (
            Shared {
                controller,
                button: Button::new(ButtonConfig::DEFAULT),
            },
            Local {
                qei_right,
                qei_left,
                tick,
                motors,
                watchdog,
                plan,
                button_pin,
                heartbeat,
                fault_led,
                params_store,
            },
        )
    }

    /// Control period: encoders → odometry → routine → speed loops → motors; button actions.
    #[task(binds = TIM7, priority = 3,
           local = [qei_right, qei_left, tick, motors, watchdog, plan],
           shared = [controller, button])]
    fn control(cx: control::Context) {
        cx.local.tick.clear_flags(Flag::Update);
        cx.local.watchdog.feed();
        let raw_right = cx.local.qei_right.count();
        let raw_left = u32::from(cx.local.qei_left.count());
        let press = {
            let mut button = cx.shared.button;
            button.lock(|b| b.poll(now_ms()))
        };
        let mut controller = cx.shared.controller;
        controller.lock(|c| {
            let out = c.step(raw_right, raw_left);
            out.command.apply(cx.local.motors);
            if let Some(p) = press {
                let action = c.on_press(p, cx.local.plan);
                defmt::info!("button {}: {}", p, action);
                if p == Press::Long {
                    // The abort takes effect now, not one period later.
                    c.step(raw_right, raw_left).command.apply(cx.local.motors);
                }
            }
        });
    }

    /// Button edges, time-stamped for the debouncer.
    #[task(binds = EXTI0, priority = 2, local = [button_pin], shared = [button])]
    fn button_edge(mut cx: button_edge::Context) {
        cx.local.button_pin.clear_interrupt_pending_bit();
        let pressed = cx.local.button_pin.is_high();
        cx.shared.button.lock(|b| b.edge(now_ms(), pressed));
    }

    /// Heartbeat LED, fault LED and a 2 Hz pose log.
    #[task(priority = 1, local = [heartbeat, fault_led, params_store], shared = [controller])]
    async fn report(mut cx: report::Context) {
        loop {
            Mono::delay(500.millis()).await;
            cx.local.heartbeat.toggle();
            let (pose, fault) = cx.shared.controller.lock(|c| (c.pose(), c.fault()));
            cx.local.fault_led.set_state(fault.is_some().into());
            defmt::info!(
                "pose x={} y={} heading={} fault={}",
                pose.x.to_num::<f32>(),
                pose.y.to_num::<f32>(),
                pose.heading.to_radians() as f32,
                fault
            );
        }
    }
}
