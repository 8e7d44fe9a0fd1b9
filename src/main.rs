//! odocal firmware entry point (RTIC 2, any board of `src/board/`).
//!
//! Wiring only: tasks own peripherals, call one library function each and publish the result.
//! Priorities: control (the board's control timer, 1–10 kHz: the stored `control_hz`) 3 >
//! serial/button 2 > background 1. The wiring is the same on every board; only the names of
//! the two board-specific interrupts RTIC binds to come from one line per board (the end of
//! this file).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("the odocal firmware runs on an STM32F4 board; on the host, use `cargo sim`");
}

#[cfg(target_os = "none")]
use defmt_rtt as _;

/// A panic stops the motors (H-bridge disabled, TIM1 main output off), keeps where it happened
/// for the next boot's `reset:` line, logs it, and resets the MCU: nothing keeps driving the
/// wheels, and nothing waits for the watchdog. A panic inside the handler goes straight to the
/// reset.
#[cfg(target_os = "none")]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    odocal::board::safety::odocal_emergency_stop();
    if odocal::board::safety::first_fault() {
        let (file, line) = info.location().map_or(("?", 0), |l| (l.file(), l.line()));
        odocal::board::safety::record_crash(&odocal::session::crash::CrashRecord::panic(
            file, line,
        ));
        defmt::error!("panic at {}:{}", file, line);
    }
    cortex_m::peripheral::SCB::sys_reset()
}

/// A HardFault does the same as a panic, keeping the faulting address.
#[cfg(target_os = "none")]
#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    odocal::board::safety::odocal_emergency_stop();
    if odocal::board::safety::first_fault() {
        odocal::board::safety::record_crash(&odocal::session::crash::CrashRecord::hard_fault(
            frame.pc(),
        ));
        defmt::error!("hard fault at pc {=u32:#x}", frame.pc());
    }
    cortex_m::peripheral::SCB::sys_reset()
}

/// The clock security system's NMI (the NUCLEO's external clock, the ST-LINK's MCO, stopped):
/// the motors stop first, then the board clears the flag, logs and resets.
#[cfg(target_os = "none")]
#[cortex_m_rt::exception]
unsafe fn NonMaskableInt() -> ! {
    odocal::board::safety::odocal_emergency_stop();
    odocal::board::clock_lost()
}

#[cfg(target_os = "none")]
rtic_monotonics::systick_monotonic!(Mono, 1000);

/// Most receive reads per USART2 interrupt: by RXNE the rest re-enters the interrupt; from the
/// board's DMA ring the next millisecond's pend reads it (32 bytes a millisecond, about three
/// times the line rate, so a backlog after an erase's stall drains).
#[cfg(target_os = "none")]
const RX_READS_PER_IRQ: usize = 32;

/// Free transmit-queue space needed before the console takes the next line: the longest reply
/// (`calibrate` of 12 runs: 3,017 B measured with a flagged run, about 3.3 KiB with a poor fit
/// and its mistake line too; `help`, `runs` below 2 KiB) plus margin.
#[cfg(target_os = "none")]
const REPLY_ROOM: usize = 3_400;

/// The RTIC app, for the board's control-timer and button interrupts (RTIC's `binds` takes an
/// interrupt's name, so the board's names are passed in: one line per board below). rustfmt
/// leaves a macro's body as written: the app below is formatted as if it stood alone.
#[cfg(target_os = "none")]
macro_rules! odocal_app {
    (control = $control:ident, button = $button:ident) => {
        // The names agree with the board's constants (the app pends and unmasks by those).
        const _: () = assert!(
            odocal::board::CONTROL_INTERRUPT as u16
                == stm32f4xx_hal::pac::Interrupt::$control as u16
                && odocal::board::BUTTON_INTERRUPT as u16
                    == stm32f4xx_hal::pac::Interrupt::$button as u16,
            "src/main.rs binds other interrupts than the board's"
        );

// RTIC's generated `unsafe fn`s call unsafe functions without an `unsafe` block; through this
// crate's macro their code takes this crate's edition (2024), where that is a warning.
#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true, dispatchers = [SPI1, SPI2])]
#[allow(unsafe_op_in_unsafe_fn)]
mod app {
    use heapless::spsc::{Consumer, Producer, Queue};
    use odocal::app::Handoff;
    use odocal::app::control::{MissedPeriods, Pacing};
    use odocal::board::adapters::{RelaxedWatchdog, read_console};
    use odocal::board::watchdog::set_timeout;
    use odocal::board::{
        BoardFlash, BoardMotors, ButtonInput, CONSOLE_INTERRUPT, CONSOLE_RX_POLLED,
        CONTROL_FROM_MONOTONIC, CONTROL_INTERRUPT, ConsoleRx, ConsoleTx, ControlTick, Encoders,
        Leds, WATCHDOG_MS,
    };
    use odocal::kinematics::odometry::metres_f32;
    use odocal::motion::button::{Button, ButtonConfig, Press};
    use odocal::motion::controller::Controller;
    use odocal::protocol::LineAssembler;
    use odocal::protocol::reply::ByteSink;
    use odocal::protocol::rx::{INPUT_QUEUE_BYTES, InputQueue, InputReceiver, InputSender};
    use odocal::session::library::{LibraryCalibrator, LockedController};
    use odocal::session::{Booted, ControlTimerStopped, Session, boot, write_fault_event};
    use odocal::storage::ParamAndRunStore;
    use rtic_monotonics::systick::prelude::*;
    use rtic_sync::channel::{Channel, Receiver, Sender};
    use stm32f4xx_hal::watchdog::IndependentWatchdog;

    use super::{Mono, REPLY_ROOM, RX_READS_PER_IRQ};

    /// A wake-up for the console task: a line or a button press is waiting.
    type Doorbell = Channel<(), 1>;

    #[shared]
    struct Shared {
        watchdog: IndependentWatchdog,
        controller: Controller,
        button: Button,
    }

    #[local]
    struct Local {
        // The one handoff, lent to each task that uses it (RTIC locals are per task).
        control_handoff: &'static Handoff,
        pace_handoff: &'static Handoff,
        serial_handoff: &'static Handoff,
        console_handoff: &'static Handoff,
        encoders: Encoders,
        tick: ControlTick,
        pacing: Pacing,
        missed: MissedPeriods,
        motors: BoardMotors,
        button_pin: ButtonInput,
        leds: Leds,
        params_store: ParamAndRunStore<BoardFlash>,
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
        ring_on_line: Sender<'static, (), 1>,
        ring_on_press: Sender<'static, (), 1>,
        doorbell: Receiver<'static, (), 1>,
    }

    /// Milliseconds since boot (wrapping), from the SysTick monotonic.
    fn now_ms() -> u32 {
        Mono::now().ticks()
    }

    #[init(local = [
        handoff: Handoff = Handoff::new(),
        lines: InputQueue<INPUT_QUEUE_BYTES> = InputQueue::new(),
        tx_bytes: Queue<u8, 4096> = Queue::new(),
        presses: Queue<Press, 4> = Queue::new(),
        wakes: Doorbell = Channel::new(),
    ])]
    fn init(cx: init::Context) -> (Shared, Local) {
        let board = odocal::board::init(cx.device);
        let mut core = cx.core;
        // The cycle counter the control task times its periods with (missed periods).
        core.DCB.enable_trace();
        core.DWT.enable_cycle_counter();
        Mono::start(core.SYST, board.sysclk_hz);
        let handoff: &'static Handoff = cx.local.handoff;

        // Parameters first: loading may repair an interrupted save (motors are off here).
        let mut params_store = board.params;
        let loaded = params_store.load_blocking();
        let (line_in, line_out) = cx.local.lines.split();
        let (mut tx_in, tx_out) = cx.local.tx_bytes.split();
        let (ring_on_line, doorbell) = cx.local.wakes.split();
        let ring_on_press = ring_on_line.clone();
        let reset_cause = board.reset_cause;
        let mut tick = board.tick;
        let mut tick_counts = true;
        // The boot event is the first line on the console (sent once the USART2 task runs).
        let mut sink = ByteSink::new(|b| tx_in.enqueue(b).is_ok());
        let booted = boot(
            &loaded,
            LibraryCalibrator::default(),
            odocal::board::safety::take_crash(),
            Some(reset_cause.as_str()),
            |controller, note| {
                // The control period from the stored rate on (the board started it at the
                // default); a timer that does not count runs no control loop: the note says so.
                tick.set_rate_hz(controller.config().rate_hz);
                tick_counts = tick.counts(board.sysclk_hz);
                write!(note, "{}", odocal::board::boot_note(board.clock))?;
                if !tick_counts {
                    write!(note, "; {}", ControlTimerStopped(odocal::board::CONTROL_TIMER))?;
                }
                Ok(())
            },
            &mut sink,
        );
        // The built-in defaults are validated by the library's tests (`tests/controller.rs`).
        let Ok(Booted { controller, session, controller_refused }) = booted else {
            defmt::panic!("built-in controller defaults rejected")
        };
        if let Some(fault) = board.clock.fault(&odocal::board::CLOCK_TEXTS) {
            let _ = write_fault_event(&mut sink, fault);
        }
        if let Some(e) = controller_refused {
            defmt::warn!("stored parameters refused by the controller ({}), using defaults", e);
        }
        let rate_hz = controller.config().rate_hz;
        let pacing = Pacing::new(handoff, rate_hz);
        let missed = MissedPeriods::new(board.sysclk_hz, rate_hz);
        let mut watchdog = board.watchdog;
        set_timeout(&mut watchdog, WATCHDOG_MS);
        let calibration = session.settings().calibration.as_ref();
        defmt::info!(
            "odocal up: reset cause {}, {}; control at {} Hz{}, calibration '{}'",
            reset_cause,
            odocal::board::boot_note(board.clock),
            rate_hz,
            if tick_counts { "" } else { " (control timer not counting: no control loop)" },
            calibration.map_or("none", |c| c.method.as_str())
        );
        let (press_in, press_out) = cx.local.presses.split();
        report::spawn().ok();
        console::spawn().ok();
        pace_control::spawn().ok();
        poll_console_rx::spawn().ok();

        (
            Shared {
                watchdog,
                controller,
                button: Button::new(ButtonConfig::DEFAULT),
            },
            Local {
                control_handoff: handoff,
                pace_handoff: handoff,
                serial_handoff: handoff,
                console_handoff: handoff,
                encoders: board.encoders,
                tick,
                pacing,
                missed,
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
                ring_on_line,
                ring_on_press,
                doorbell,
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

    /// Control period: encoders → odometry → routine → speed loops → motors; button presses
    /// handed to the console task; retiming and LEDs.
    #[task(binds = $control, priority = 3,
           local = [control_handoff, encoders, tick, pacing, missed, motors, press_in,
                    ring_on_press, leds],
           shared = [controller, button, watchdog])]
    fn control(cx: control::Context) {
        let missed = cx
            .local
            .missed
            .observe(cortex_m::peripheral::DWT::cycle_count());
        cx.local.tick.clear();
        let mut watchdog = cx.shared.watchdog;
        watchdog.lock(|w| w.feed());
        let (raw_right, raw_left) = cx.local.encoders.read();
        let press = {
            let mut button = cx.shared.button;
            button.lock(|b| b.poll(now_ms()))
        };
        let handoff = *cx.local.control_handoff;
        let motors = cx.local.motors;
        let mut controller = cx.shared.controller;
        let (fault, rate_hz) = controller.lock(|c| {
            let out = odocal::app::control::period(
                handoff, c, missed, raw_right, raw_left, press, motors,
            );
            (out.fault.is_some(), c.config().rate_hz)
        });
        if let Some(p) = press {
            // The session (console task) acts on the press: next planned run, clear, stop.
            if cx.local.press_in.enqueue(p).is_ok() {
                let _ = cx.local.ring_on_press.try_send(());
            }
        }
        let news = cx.local.pacing.after_period(handoff, rate_hz);
        if let Some(hz) = news.retime_hz {
            cx.local.tick.set_rate_hz(hz);
            cx.local.missed.set_rate(hz);
        }
        // The LEDs live here, at the control task's priority, so the heartbeat keeps blinking
        // while the console task runs a long calibration solve.
        if news.toggle_heartbeat {
            cx.local.leds.toggle_heartbeat();
        }
        cx.local.leds.set_fault(fault || news.refusal_lit);
    }

    /// On a board without a control-period timer (the emulator), pends the control interrupt
    /// from the monotonic: every period at 1 kHz, one period per 1 ms tick at higher rates
    /// (the emulator's plant counts periods, not wall time). On a board, its control timer raises
    /// it and this task ends at once.
    #[task(priority = 3, local = [pace_handoff])]
    async fn pace_control(cx: pace_control::Context) {
        if !CONTROL_FROM_MONOTONIC {
            return;
        }
        let mut next = Mono::now();
        loop {
            let rate_hz = cx.local.pace_handoff.control_rate_hz();
            next += (1_000 / rate_hz).max(1).millis();
            Mono::delay_until(next).await;
            rtic::pend(CONTROL_INTERRUPT);
        }
    }

    /// On a board whose console receives by DMA into a ring (every board), pends the console
    /// interrupt every millisecond so the serial receive drains the ring (and, after a flash
    /// erase's stall, what arrived during it); on a board with an RX interrupt it ends at once.
    #[task(priority = 3)]
    async fn poll_console_rx(_: poll_console_rx::Context) {
        if !CONSOLE_RX_POLLED {
            return;
        }
        loop {
            Mono::delay(1.millis()).await;
            rtic::pend(CONSOLE_INTERRUPT);
        }
    }

    /// Button edges, time-stamped for the debouncer.
    #[task(binds = $button, priority = 2, local = [button_pin], shared = [button])]
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
                metres_f32(pose.x),
                metres_f32(pose.y),
                pose.heading.to_radians() as f32,
                fault
            );
        }
    }

    /// USART2: received bytes → line assembly → line queue (a stop key also tells the control
    /// task), echo; echo and transmit queue → TX register. Rings the console task when a line
    /// waits.
    #[task(binds = USART2, priority = 2,
           local = [serial_handoff, usart_rx, usart_tx, assembler, echo_out, line_in, tx_out,
                    ring_on_line])]
    fn usart2(cx: usart2::Context) {
        let rx_port = cx.local.usart_rx;
        let echo_out = cx.local.echo_out;
        let tx_out = cx.local.tx_out;
        // A line is echoed as it is typed only while nothing else is on its way out or
        // waiting; otherwise the console echoes it right before its reply.
        let output_pending = !echo_out.is_empty() || tx_out.ready();
        odocal::app::serial::receive(
            cx.local.serial_handoff,
            cx.local.assembler,
            || read_console(rx_port),
            RX_READS_PER_IRQ,
            output_pending,
            cx.local.line_in,
            |bytes| {
                for &b in bytes {
                    let _ = echo_out.push_back(b);
                }
            },
        );
        if !cx.local.line_in.is_empty() {
            let _ = cx.local.ring_on_line.try_send(());
        }
        odocal::app::serial::transmit(cx.local.usart_tx, echo_out, tx_out);
    }

    /// The serial console: executes received lines and button presses on the session, and
    /// writes events and the pose stream. Awaits the doorbell (a line or a press waits) or its
    /// next 1 ms poll, whichever comes first. Locks the controller for one call at a time.
    #[task(priority = 1, shared = [controller, watchdog],
           local = [console_handoff, session, params_store, line_out, tx_in, press_out,
                    doorbell])]
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
        let handoff = *cx.local.console_handoff;
        let mut next_poll = Mono::now();
        loop {
            // One line per pass, and only while the transmit queue has room for the longest
            // reply, so a burst of commands never cuts a reply short.
            let room = |tx: &Producer<'static, u8>| tx.capacity() - tx.len() >= REPLY_ROOM;
            if cx.local.line_out.is_empty() || !room(cx.local.tx_in) {
                let _ = Mono::timeout_at(next_poll, cx.local.doorbell.recv()).await;
            }
            let now = Mono::now();
            if now >= next_poll {
                next_poll = now + 1.millis();
            }
            let session = &mut *cx.local.session;
            let store = &mut RelaxedWatchdog {
                store: &mut *cx.local.params_store,
                watchdog: &mut cx.shared.watchdog,
            };
            let tx_in = &mut *cx.local.tx_in;
            let mut robot = LockedController(&mut cx.shared.controller);
            let mut dropped = 0;
            if room(tx_in) {
                let mut out = ByteSink::new(|b| tx_in.enqueue(b).is_ok());
                let _ = odocal::app::console::take_line(
                    handoff,
                    session,
                    cx.local.line_out,
                    &mut robot,
                    store,
                    &mut out,
                );
                dropped += out.dropped;
            }
            let mut out = ByteSink::new(|b| tx_in.enqueue(b).is_ok());
            while let Some(press) = cx.local.press_out.dequeue() {
                let _ = odocal::app::console::press(session, press, &mut robot, &mut out);
            }
            let now_us = u64::from(Mono::now().ticks()) * 1_000;
            let _ =
                odocal::app::console::poll(handoff, session, now_us, &mut robot, store, &mut out);
            dropped += out.dropped;
            if dropped > 0 {
                defmt::warn!("serial transmit queue full: {} bytes dropped", dropped);
            }
            rtic::pend(CONSOLE_INTERRUPT);
        }
    }
}
    };
}

#[cfg(all(target_os = "none", feature = "board-f407"))]
odocal_app!(control = TIM7, button = EXTI0);
#[cfg(all(target_os = "none", feature = "board-nucleo-f446re"))]
odocal_app!(control = TIM7, button = EXTI15_10);
#[cfg(all(target_os = "none", feature = "board-blackpill-f411ce"))]
odocal_app!(control = TIM1_TRG_COM_TIM11, button = EXTI0);
