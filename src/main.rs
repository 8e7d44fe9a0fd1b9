//! odocal firmware entry point (RTIC 2, STM32F407).
//!
//! Wiring only: tasks own peripherals, call one library function each and publish the result.
//! Priorities: control (TIM7, 1–10 kHz: the stored `control_hz`) 3 > serial/button 2 >
//! background 1.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("the odocal firmware runs on the STM32F407; on the host, use `cargo sim`");
}

#[cfg(target_os = "none")]
use defmt_rtt as _;

/// A panic stops the motors (H-bridge disabled, TIM1 main output off), logs where, and resets
/// the MCU: nothing keeps driving the wheels, and nothing waits for the watchdog.
#[cfg(target_os = "none")]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    odocal::board::safety::odocal_emergency_stop();
    if let Some(loc) = info.location() {
        defmt::error!("panic at {}:{}", loc.file(), loc.line());
    }
    cortex_m::peripheral::SCB::sys_reset()
}

/// A HardFault does the same as a panic.
#[cfg(target_os = "none")]
#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    odocal::board::safety::odocal_emergency_stop();
    defmt::error!("hard fault at pc {=u32:#x}", frame.pc());
    cortex_m::peripheral::SCB::sys_reset()
}

#[cfg(target_os = "none")]
rtic_monotonics::systick_monotonic!(Mono, 1000);

/// Received lines dropped because the console's input queue was full (reported as an error).
#[cfg(target_os = "none")]
static LINES_DROPPED: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(0);

/// The control rate the control task runs at, Hz (published for `pace_control`).
#[cfg(target_os = "none")]
static CONTROL_RATE_HZ: core::sync::atomic::AtomicU32 =
    core::sync::atomic::AtomicU32::new(odocal::motion::controller::DEFAULT_RATE_HZ);

/// Set by the USART2 interrupt on Ctrl-C or Esc; the control task aborts any motion in its next
/// period, before the console task parses any queued line.
#[cfg(target_os = "none")]
static STOP_REQUEST: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);

/// Set by the console task while it executes a line: a line that starts meanwhile is echoed
/// with its reply, not into it.
#[cfg(target_os = "none")]
static CONSOLE_BUSY: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);

/// Whether the USART2 interrupt echoes received characters (the session's `echo on|off`,
/// published by the console task).
#[cfg(target_os = "none")]
static ECHO: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(true);

/// Set by the USART2 interrupt while a line is being typed and echoed as it is typed: the
/// console task holds the pose stream meanwhile, so its lines do not cut into the echo.
#[cfg(target_os = "none")]
static TYPING: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);

/// Most receive-register reads per USART2 interrupt (the rest re-enters the interrupt).
#[cfg(target_os = "none")]
const RX_READS_PER_IRQ: usize = 32;

/// Free transmit-queue space needed before the console takes the next line: the longest reply
/// (`calibrate`, `help`, `runs`: about 1.6 KiB) plus margin.
#[cfg(target_os = "none")]
const REPLY_ROOM: usize = 1_800;

#[cfg(target_os = "none")]
#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true, dispatchers = [SPI1, SPI2])]
mod app {
    use heapless::spsc::{Consumer, Producer, Queue};
    use odocal::board::watchdog::{set_timeout, wait_for_update, write_timeout};
    use odocal::board::{
        BoardFlash, BoardMotors, ButtonInput, CONSOLE_INTERRUPT, CONTROL_FROM_MONOTONIC,
        CONTROL_INTERRUPT, ConsoleRx, ConsoleTx, ControlTick, Encoders, FLASH_WATCHDOG_MS, Leds,
        WATCHDOG_MS,
    };
    use odocal::kinematics::geometry::Geometry;
    use odocal::motion::button::{Button, ButtonConfig, Press};
    use odocal::motion::controller::{Controller, ControllerConfig, DEFAULT_RATE_HZ};
    use odocal::motion::run::{MAX_RUNS, RunRecord};
    use odocal::protocol::LineAssembler;
    use odocal::protocol::reply::{ByteSink, ErrorCode, write_err};
    use odocal::protocol::rx::{
        self, INPUT_QUEUE_BYTES, InputQueue, InputReceiver, InputSender, RxRead,
    };
    use odocal::session::library::{LibraryCalibrator, Locked};
    use odocal::session::{
        ParamStorage, Session, Settings, StorageError, write_boot_event, write_fault_event,
    };
    use odocal::storage::{ParamStore, RunsLoaded, StoredRun};
    use rtic_monotonics::systick::prelude::*;
    use stm32f4xx_hal::prelude::*;
    use stm32f4xx_hal::serial::{TxISR, TxListen};
    use stm32f4xx_hal::watchdog::IndependentWatchdog;

    use super::{
        CONSOLE_BUSY, CONTROL_RATE_HZ, ECHO, LINES_DROPPED, Mono, REPLY_ROOM, RX_READS_PER_IRQ,
        STOP_REQUEST, TYPING,
    };
    use core::sync::atomic::Ordering;

    #[shared]
    struct Shared {
        watchdog: IndependentWatchdog,
        controller: Controller,
        button: Button,
    }

    #[local]
    struct Local {
        encoders: Encoders,
        tick: ControlTick,
        motors: BoardMotors,
        button_pin: ButtonInput,
        leds: Leds,
        params_store: ParamStore<BoardFlash>,
        session: Session<LibraryCalibrator>,
        usart_rx: ConsoleRx,
        usart_tx: ConsoleTx,
        assembler: LineAssembler,
        echo_out: heapless::Deque<u8, 64>,
        line_in: InputSender<'static>,
        line_out: InputReceiver<'static>,
        tx_in: Producer<'static, u8>,
        tx_out: Consumer<'static, u8>,
        press_in: Producer<'static, Press>,
        press_out: Consumer<'static, Press>,
    }

    /// Milliseconds since boot (wrapping), from the SysTick monotonic.
    fn now_ms() -> u32 {
        Mono::now().ticks()
    }

    /// A controller for the stored settings (at the stored rate), or for the built-in defaults
    /// when they are refused.
    fn make_controller(settings: &Settings) -> Controller {
        match Controller::new(settings.controller_config()) {
            Ok(c) => c,
            Err(e) => {
                defmt::warn!(
                    "stored parameters refused by the controller ({}), using defaults",
                    e
                );
                // The built-in defaults are validated by the library's tests
                // (`tests/controller.rs`), so this cannot fail at run time.
                match Controller::new(ControllerConfig::new(Geometry::default(), DEFAULT_RATE_HZ)) {
                    Ok(c) => c,
                    Err(_) => defmt::panic!("built-in controller defaults rejected"),
                }
            }
        }
    }

    /// Parameter storage with the watchdog relaxed while the flash is written: a sector erase
    /// stalls every instruction fetch (the control task included) for up to 2 s, so the
    /// timeout is lengthened for the operation and restored right after. Saves are refused
    /// unless the motors are stopped, so nothing moves while the control task is stalled.
    struct RelaxedWatchdog<'a, W: rtic::Mutex<T = IndependentWatchdog>> {
        store: &'a mut ParamStore<BoardFlash>,
        watchdog: W,
    }

    impl<W: rtic::Mutex<T = IndependentWatchdog>> RelaxedWatchdog<'_, W> {
        fn relaxed<R>(
            &mut self,
            motors_stopped: bool,
            f: impl FnOnce(&mut ParamStore<BoardFlash>) -> R,
        ) -> R {
            if !motors_stopped {
                // The store refuses without touching the flash: nothing to relax.
                return f(self.store);
            }
            // The waits for the low-power register domain stay outside the lock, so the
            // control task is never held up by them. The reload comes after the update has
            // crossed over: an earlier one would load the old 50 ms reload value, counted at the
            // new divider (about 1.1-1.6 s, shorter than an erase).
            wait_for_update();
            self.watchdog.lock(|w| write_timeout(w, FLASH_WATCHDOG_MS));
            wait_for_update();
            self.watchdog.lock(|w| w.feed());
            let result = f(self.store);
            self.watchdog.lock(|w| write_timeout(w, WATCHDOG_MS));
            wait_for_update();
            self.watchdog.lock(|w| w.feed());
            result
        }
    }

    impl<W: rtic::Mutex<T = IndependentWatchdog>> ParamStorage for RelaxedWatchdog<'_, W> {
        fn save(&mut self, settings: &Settings, motors_stopped: bool) -> Result<(), StorageError> {
            self.relaxed(motors_stopped, |s| {
                ParamStorage::save(s, settings, motors_stopped)
            })
        }

        fn reset(&mut self, motors_stopped: bool) -> Result<(), StorageError> {
            self.relaxed(motors_stopped, |s| ParamStorage::reset(s, motors_stopped))
        }

        fn save_runs(
            &mut self,
            runs: &[RunRecord],
            ids: &mut [Option<StoredRun>],
            motors_stopped: bool,
        ) -> Result<(), StorageError> {
            self.relaxed(motors_stopped, |s| {
                ParamStorage::save_runs(s, runs, ids, motors_stopped)
            })
        }

        fn load_runs(
            &mut self,
            runs: &mut heapless::Vec<RunRecord, MAX_RUNS>,
            ids: &mut heapless::Vec<Option<StoredRun>, MAX_RUNS>,
        ) -> RunsLoaded {
            // Only at boot, motors stopped: a repair may erase a sector.
            self.relaxed(true, |s| ParamStorage::load_runs(s, runs, ids))
        }
    }

    #[init(local = [
        lines: InputQueue<INPUT_QUEUE_BYTES> = InputQueue::new(),
        tx_bytes: Queue<u8, 2048> = Queue::new(),
        presses: Queue<Press, 4> = Queue::new(),
    ])]
    fn init(cx: init::Context) -> (Shared, Local) {
        let board = odocal::board::init(cx.device);
        Mono::start(cx.core.SYST, board.sysclk_hz);

        // Parameters first: loading may repair an interrupted save (motors are off here).
        let mut params_store = board.params;
        let loaded = params_store.load_blocking();
        let params = loaded.record;
        let settings = Settings::from(&params);
        let controller = make_controller(&settings);
        // The control period from the stored rate on (the board started it at the default).
        let rate_hz = controller.config().rate_hz;
        let mut tick = board.tick;
        tick.set_rate_hz(rate_hz);
        CONTROL_RATE_HZ.store(rate_hz, Ordering::Relaxed);
        let session = Session::new(settings, LibraryCalibrator::default());
        let mut watchdog = board.watchdog;
        set_timeout(&mut watchdog, WATCHDOG_MS);

        let (line_in, line_out) = cx.local.lines.split();
        let (mut tx_in, tx_out) = cx.local.tx_bytes.split();
        // The boot event is the first line on the console (sent once the USART2 task runs).
        let reset_cause = board.reset_cause;
        {
            let mut sink = ByteSink::new(|b| tx_in.enqueue(b).is_ok());
            let _ = write_boot_event(
                &mut sink,
                loaded.warning.as_ref(),
                Some(reset_cause.as_str()),
            );
            if let Some(fault) = board.clock.fault() {
                let _ = write_fault_event(&mut sink, fault);
            }
        }
        defmt::info!("reset cause: {}, clock: {}", reset_cause, board.clock);
        let (press_in, press_out) = cx.local.presses.split();

        report::spawn().ok();
        console::spawn().ok();
        pace_control::spawn().ok();
        defmt::info!(
            "odocal up: control at {} Hz, calibration '{}'",
            rate_hz,
            params.calibration.method.as_str()
        );

        (
            Shared {
                watchdog,
                controller,
                button: Button::new(ButtonConfig::DEFAULT),
            },
            Local {
                encoders: board.encoders,
                tick,
                motors: board.motors,
                button_pin: board.button,
                leds: board.leds,
                params_store,
                session,
                usart_rx: board.console_rx,
                usart_tx: board.console_tx,
                assembler: LineAssembler::new(),
                echo_out: heapless::Deque::new(),
                line_in,
                line_out,
                tx_in,
                tx_out,
                press_in,
                press_out,
            },
        )
    }

    /// Sleeps until the next interrupt (no work runs at priority 0). Saves power on the board,
    /// and lets an emulator skip idle time.
    #[idle]
    fn idle(_cx: idle::Context) -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// Control period: encoders → odometry → routine → speed loops → motors; button actions.
    #[task(binds = TIM7, priority = 3,
           local = [encoders, tick, motors, press_in, leds, heartbeat_periods: u32 = 0],
           shared = [controller, button, watchdog])]
    fn control(cx: control::Context) {
        cx.local.tick.clear();
        let mut watchdog = cx.shared.watchdog;
        watchdog.lock(|w| w.feed());
        let (raw_right, raw_left) = cx.local.encoders.read();
        let press = {
            let mut button = cx.shared.button;
            button.lock(|b| b.poll(now_ms()))
        };
        let mut controller = cx.shared.controller;
        let (fault, rate_hz) = controller.lock(|c| {
            if STOP_REQUEST.swap(false, Ordering::Relaxed) {
                // Ctrl-C or Esc on the console: stop in this period.
                c.abort();
            }
            let out = c.step(raw_right, raw_left);
            out.command.apply(cx.local.motors);
            if let Some(p) = press {
                if p == Press::Long {
                    // The abort takes effect now, not one period later.
                    c.abort();
                    c.step(raw_right, raw_left).command.apply(cx.local.motors);
                }
                // The session (console task) acts on the press: next planned run, clear, stop.
                let _ = cx.local.press_in.enqueue(p);
            }
            (out.fault.is_some(), c.config().rate_hz)
        });
        // `set control_hz` retimed the controller (only while idle): the period source follows
        // from the next period on.
        if rate_hz != cx.local.tick.rate_hz() {
            cx.local.tick.set_rate_hz(rate_hz);
            CONTROL_RATE_HZ.store(rate_hz, Ordering::Relaxed);
            *cx.local.heartbeat_periods = 0;
        }
        // The LEDs live here, at the control task's priority, so the heartbeat keeps blinking
        // while the console task runs a long calibration solve.
        *cx.local.heartbeat_periods += 1;
        if *cx.local.heartbeat_periods >= rate_hz / 2 {
            *cx.local.heartbeat_periods = 0;
            cx.local.leds.toggle_heartbeat();
        }
        cx.local.leds.set_fault(fault);
    }

    /// On a board without a control-period timer (the emulator), pends the control interrupt
    /// from the monotonic: every period at 1 kHz, one period per 1 ms tick at higher rates
    /// (the emulator's plant counts periods, not wall time). On the F407, TIM7 raises it and
    /// this task ends at once.
    #[task(priority = 3)]
    async fn pace_control(_cx: pace_control::Context) {
        if !CONTROL_FROM_MONOTONIC {
            return;
        }
        let mut next = Mono::now();
        loop {
            let rate_hz = CONTROL_RATE_HZ.load(Ordering::Relaxed).max(1);
            next += (1_000 / rate_hz).max(1).millis();
            Mono::delay_until(next).await;
            rtic::pend(CONTROL_INTERRUPT);
        }
    }

    /// Button edges, time-stamped for the debouncer.
    #[task(binds = EXTI0, priority = 2, local = [button_pin], shared = [button])]
    fn button_edge(mut cx: button_edge::Context) {
        let pressed = cx.local.button_pin.edge();
        cx.shared.button.lock(|b| b.edge(now_ms(), pressed));
    }

    /// A 2 Hz pose log.
    #[task(priority = 1, shared = [controller])]
    async fn report(mut cx: report::Context) {
        loop {
            Mono::delay(500.millis()).await;
            let (pose, fault) = cx.shared.controller.lock(|c| (c.pose(), c.fault()));
            defmt::info!(
                "pose x={} y={} heading={} fault={}",
                pose.x.to_num::<f32>(),
                pose.y.to_num::<f32>(),
                pose.heading.to_radians() as f32,
                fault
            );
        }
    }

    /// USART2: received bytes → line assembly → line queue (a stop key also tells the control
    /// task at once), echo; echo and transmit queue → TX register.
    #[task(binds = USART2, priority = 2,
           local = [usart_rx, usart_tx, assembler, echo_out, line_in, tx_out])]
    fn usart2(cx: usart2::Context) {
        let rx_port = cx.local.usart_rx;
        let line_in = cx.local.line_in;
        let echo_out = cx.local.echo_out;
        let echo = ECHO.load(Ordering::Relaxed);
        let usart_tx = cx.local.usart_tx;
        let tx_out = cx.local.tx_out;
        // A line is echoed as it is typed only while nothing else is on its way out or
        // waiting; otherwise the console echoes it right before its reply.
        let idle = echo
            && echo_out.is_empty()
            && !tx_out.ready()
            && line_in.is_empty()
            && !CONSOLE_BUSY.load(Ordering::Relaxed);
        // Each read checks SR and, on an overrun, framing, noise or parity error, reads DR,
        // which clears the flag (an ORE with RXNE clear would otherwise re-enter this
        // interrupt for ever); the error poisons the line being received.
        rx::drain(
            || match rx_port.read() {
                Ok(byte) => RxRead::Byte(byte),
                Err(stm32f4xx_hal::nb::Error::WouldBlock) => RxRead::Empty,
                Err(stm32f4xx_hal::nb::Error::Other(_)) => RxRead::Error,
            },
            cx.local.assembler,
            RX_READS_PER_IRQ,
            idle,
            |event, echoed| {
                if rx::is_stop(&event) {
                    STOP_REQUEST.store(true, Ordering::Relaxed);
                }
                // A full queue drops the line; the console reports how many were lost. A stop
                // key has already reached the control task.
                if !line_in.send(&event, echoed) {
                    LINES_DROPPED.fetch_add(1, Ordering::Relaxed);
                }
            },
            |bytes| {
                for &b in bytes {
                    let _ = echo_out.push_back(b);
                }
            },
        );
        TYPING.store(cx.local.assembler.typing(), Ordering::Relaxed);
        while usart_tx.is_tx_empty() {
            let Some(byte) = echo_out.pop_front().or_else(|| tx_out.dequeue()) else {
                break;
            };
            let _ = usart_tx.write(byte);
        }
        if !echo_out.is_empty() || tx_out.ready() {
            usart_tx.listen();
        } else {
            usart_tx.unlisten();
        }
    }

    /// The serial console: executes received lines and button presses on the session, and
    /// writes events and the pose stream. Locks the controller for one call at a time.
    #[task(priority = 1, shared = [controller, watchdog],
           local = [session, params_store, line_out, tx_in, press_out])]
    async fn console(mut cx: console::Context) {
        {
            // First, before any command: the session's runs and measurements as they were
            // before the reset, announced right after the boot line. Here rather than in
            // `init`, so the session is restored in place (no copy of it on the stack); the
            // watchdog is relaxed while the load may repair the flash (nothing moves yet).
            let tx_in = &mut *cx.local.tx_in;
            let mut out = ByteSink::new(|b| tx_in.enqueue(b).is_ok());
            let _ = cx.local.session.restore_runs(
                &mut RelaxedWatchdog {
                    store: &mut *cx.local.params_store,
                    watchdog: &mut cx.shared.watchdog,
                },
                &mut out,
            );
        }
        loop {
            Mono::delay(1.millis()).await;
            let session = &mut *cx.local.session;
            let store = &mut RelaxedWatchdog {
                store: &mut *cx.local.params_store,
                watchdog: &mut cx.shared.watchdog,
            };
            let tx_in = &mut *cx.local.tx_in;
            let mut robot = Locked(&mut cx.shared.controller);
            let mut dropped = 0;
            // One line per pass, and only while the transmit queue has room for the longest
            // reply, so a burst of commands never cuts a reply short.
            if tx_in.capacity() - tx_in.len() >= REPLY_ROOM {
                // Lines lost to a full queue are reported once the lines kept have been
                // answered: one notice for a whole paste, after its last reply.
                let lost = if cx.local.line_out.is_empty() {
                    LINES_DROPPED.swap(0, Ordering::Relaxed)
                } else {
                    0
                };
                let mut out = ByteSink::new(|b| tx_in.enqueue(b).is_ok());
                if lost > 0 {
                    let _ = write_err(
                        &mut out,
                        ErrorCode::Busy,
                        &format_args!("{lost} line(s) dropped: input queue full"),
                    );
                } else if let Some(received) = cx.local.line_out.take() {
                    CONSOLE_BUSY.store(true, Ordering::Relaxed);
                    let _ = session.handle_input(&received, &mut robot, store, &mut out);
                    ECHO.store(session.echo(), Ordering::Relaxed);
                    CONSOLE_BUSY.store(false, Ordering::Relaxed);
                }
                dropped += out.dropped;
            }
            let mut out = ByteSink::new(|b| tx_in.enqueue(b).is_ok());
            while let Some(press) = cx.local.press_out.dequeue() {
                let _ = match press {
                    Press::Short => session.button_short(&mut robot, &mut out),
                    Press::Long => session.button_long(&mut robot, &mut out),
                };
            }
            let now_us = u64::from(Mono::now().ticks()) * 1_000;
            session.set_typing(TYPING.load(Ordering::Relaxed));
            let _ = session.poll(now_us, &mut robot, store, &mut out);
            dropped += out.dropped;
            if dropped > 0 {
                defmt::warn!("serial transmit queue full: {} bytes dropped", dropped);
            }
            rtic::pend(CONSOLE_INTERRUPT);
        }
    }
}
