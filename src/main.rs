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
    use odocal::board::motors::BoardMotors;
    use odocal::board::{CONTROL_HZ, HSE_HZ, PWM_HZ, SYSCLK_HZ, WATCHDOG_MS};
    use odocal::encoder::{
        CounterWidth, Encoder, EncoderConfig, Polarity, WheelTicks, max_step_for,
    };
    use odocal::geometry::Geometry;
    use odocal::motor::{MotorDriver, StopMode};
    use odocal::odometry::{Integration, Odometry, OdometryState, Pose};
    use rtic_monotonics::systick::prelude::*;
    use stm32f4xx_hal::gpio::{Output, PD12, PD14};
    use stm32f4xx_hal::pac::{TIM2, TIM3, TIM7};
    use stm32f4xx_hal::prelude::*;
    use stm32f4xx_hal::qei::Qei;
    use stm32f4xx_hal::rcc::Config;
    use stm32f4xx_hal::timer::{CounterHz, Event, Flag};
    use stm32f4xx_hal::watchdog::IndependentWatchdog;

    use super::Mono;

    #[shared]
    struct Shared {
        pose: Pose,
        fault: bool,
    }

    #[local]
    struct Local {
        qei_right: Qei<TIM2>,
        qei_left: Qei<TIM3>,
        tick: CounterHz<TIM7>,
        enc_right: Encoder,
        enc_left: Encoder,
        odometry: Odometry,
        odo_state: OdometryState,
        motors: BoardMotors,
        watchdog: IndependentWatchdog,
        heartbeat: PD12<Output>,
        fault_led: PD14<Output>,
    }

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        let mut rcc = cx.device.RCC.freeze(
            Config::hse(HSE_HZ.Hz())
                .sysclk(SYSCLK_HZ.Hz())
                .pclk1(42.MHz()),
        );
        Mono::start(cx.core.SYST, SYSCLK_HZ);

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

        let geometry = Geometry::default();
        let period_s = 1.0 / f64::from(CONTROL_HZ);
        let enc_cfg = |width, polarity, d| EncoderConfig {
            width,
            polarity,
            max_step: max_step_for(width, geometry.counts_per_rev, d, 2.0, period_s),
        };
        let enc_right = Encoder::new(
            enc_cfg(
                CounterWidth::Bits32,
                Polarity::Normal,
                geometry.diameter_right_m,
            ),
            qei_right.count(),
        );
        let enc_left = Encoder::new(
            enc_cfg(
                CounterWidth::Bits16,
                Polarity::Inverted,
                geometry.diameter_left_m,
            ),
            u32::from(qei_left.count()),
        );
        let odometry = match Odometry::new(&geometry, Integration::ExactArc) {
            Ok(o) => o,
            Err(e) => {
                defmt::error!("default geometry rejected: {}", e);
                panic!("invalid built-in geometry")
            }
        };
        let mut odo_state = OdometryState::default();
        odometry.reset(&mut odo_state, WheelTicks::default(), Pose::default());

        // Motors: TIM1 CH1/CH2 PWM.
        let (pwm, (ch1, ch2, ..)) = cx.device.TIM1.pwm_hz(PWM_HZ.Hz(), &mut rcc);
        let motors = BoardMotors::new(
            pwm,
            ch1.with(gpioe.pe9),
            ch2.with(gpioe.pe11),
            gpioe.pe7.into_push_pull_output(),
            gpioe.pe8.into_push_pull_output(),
            gpioe.pe13.into_push_pull_output(),
        );

        let mut tick = cx.device.TIM7.counter_hz(&mut rcc);
        if tick.start(CONTROL_HZ.Hz()).is_err() {
            defmt::error!("control timer did not start");
        }
        tick.listen(Event::Update);

        let mut watchdog = IndependentWatchdog::new(cx.device.IWDG);
        watchdog.start(WATCHDOG_MS.millis());

        let _ = gpioa.pa0; // user button, wired in the button task
        let heartbeat = gpiod.pd12.into_push_pull_output();
        let fault_led = gpiod.pd14.into_push_pull_output();

        report::spawn().ok();
        defmt::info!("odocal up: control at {} Hz", CONTROL_HZ);

        (
            Shared {
                pose: Pose::default(),
                fault: false,
            },
            Local {
                qei_right,
                qei_left,
                tick,
                enc_right,
                enc_left,
                odometry,
                odo_state,
                motors,
                watchdog,
                heartbeat,
                fault_led,
            },
        )
    }

    /// Control period: encoders → odometry → motors.
    #[task(binds = TIM7, priority = 3,
           local = [qei_right, qei_left, tick, enc_right, enc_left, odometry, odo_state, motors, watchdog],
           shared = [pose, fault])]
    fn control(mut cx: control::Context) {
        cx.local.tick.clear_flags(Flag::Update);
        cx.local.watchdog.feed();
        let right = cx.local.enc_right.update(cx.local.qei_right.count());
        let left = cx
            .local
            .enc_left
            .update(u32::from(cx.local.qei_left.count()));
        if right.is_err() || left.is_err() {
            cx.local.motors.stop(StopMode::Brake);
            cx.shared.fault.lock(|f| *f = true);
        }
        let totals = WheelTicks::new(cx.local.enc_right.total(), cx.local.enc_left.total());
        let pose = cx.local.odometry.update(cx.local.odo_state, totals);
        cx.shared.pose.lock(|p| *p = pose);
    }

    /// Heartbeat LED and a 2 Hz pose log.
    #[task(priority = 1, local = [heartbeat, fault_led], shared = [pose, fault])]
    async fn report(mut cx: report::Context) {
        loop {
            Mono::delay(500.millis()).await;
            cx.local.heartbeat.toggle();
            let fault = cx.shared.fault.lock(|f| *f);
            cx.local.fault_led.set_state(fault.into());
            let pose = cx.shared.pose.lock(|p| *p);
            defmt::info!(
                "pose x={} y={} heading={}",
                pose.x.to_num::<f32>(),
                pose.y.to_num::<f32>(),
                pose.heading.to_radians() as f32
            );
        }
    }
}
