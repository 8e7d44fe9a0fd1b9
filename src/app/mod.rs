//! The app core: what the board's interrupt handlers and tasks do, as portable code that the
//! host tests and host-sim drive too.
//!
//! The RTIC binary (`src/main.rs`) owns the peripherals and binds each interrupt or task to one
//! function here; host-sim's simulated board calls the same functions in the same order, so the
//! firmware's console and control glue is one path, tested on the host.
//!
//! | priority on the board | part | what it does |
//! |---|---|---|
//! | 3, control period (the board's timer) | [`control::period`], [`control::Pacing`] | stop requests, one controller step, the motors, a long press's abort; retiming, the heartbeat and the refused-press blink |
//! | 2, serial receive (USART2) | [`serial::receive`] | bytes → lines (echo, stop keys, lines lost to a full queue) |
//! | 2, serial transmit (USART2) | [`serial::transmit`] | the echo first, then the console's replies |
//! | 1, console task | [`console::take_line`], [`console::press`], [`console::poll`] | lines and presses on the session; events and the pose stream |
//!
//! [`io`] holds the board's LEDs, button and console port in embedded-hal terms; [`rx_ring`] the
//! reading side of a console receive ring that a DMA stream fills (the boards' console).
//!
//! The few facts the parts at different priorities tell each other live in one [`Handoff`],
//! lock-free (see its fields for who writes and who reads each).

pub mod console;
pub mod control;
pub mod io;
pub mod rx_ring;
pub mod serial;

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use crate::motion::controller::DEFAULT_RATE_HZ;

/// What the control period, the serial interrupt and the console task tell each other.
///
/// Every field has one writer (or one writer that sets and one reader that clears it by swap),
/// and each is a single word read or written whole, so no lock is needed: a reader sees either
/// the old or the new value, and every use below is correct with either. Orderings are
/// `Relaxed` because no field guards other memory (the lines themselves travel through the
/// single-producer single-consumer input queue, which orders its own accesses), except
/// `console_busy`, which must be set before the console takes a line from that queue
/// (`SeqCst`, see [`console::take_line`]).
#[derive(Debug)]
pub struct Handoff {
    /// Set by the serial receive on Ctrl-C or Esc; the control period takes it (swap) and
    /// aborts any motion, before the console task parses any queued line.
    stop_request: AtomicBool,
    /// Set by the console task while it executes a line: a line that starts meanwhile is echoed
    /// with its reply, not into it (read by the serial receive).
    console_busy: AtomicBool,
    /// The session's `echo on|off`, published by the console task after each line; the serial
    /// receive echoes characters while it is on.
    echo: AtomicBool,
    /// Set by the serial receive while a line is being typed and echoed as it is typed: the
    /// console task holds the pose stream meanwhile, so its lines do not cut into the echo.
    typing: AtomicBool,
    /// Lines the serial receive dropped because the input queue was full; the console task
    /// reports them (swap) once the lines kept have been answered.
    lines_dropped: AtomicU32,
    /// The rate the control period runs at, Hz, published by the control period for a board
    /// that paces it from a timer of its own.
    control_rate_hz: AtomicU32,
    /// Set by the console task when the session refused a button press (a finished run not
    /// measured, the plan complete, …); the control period takes it (swap) and blinks the
    /// fault LED ([`control::Pacing::after_period`]).
    press_refused: AtomicBool,
}

impl Handoff {
    /// Echo on, nothing requested, nothing dropped, the default control rate (`const`, for a
    /// static or an RTIC resource).
    pub const fn new() -> Self {
        Handoff {
            stop_request: AtomicBool::new(false),
            console_busy: AtomicBool::new(false),
            echo: AtomicBool::new(true),
            typing: AtomicBool::new(false),
            lines_dropped: AtomicU32::new(0),
            control_rate_hz: AtomicU32::new(DEFAULT_RATE_HZ),
            press_refused: AtomicBool::new(false),
        }
    }

    /// The control rate last published by the control period, Hz (at least 1).
    pub fn control_rate_hz(&self) -> u32 {
        self.control_rate_hz.load(Ordering::Relaxed).max(1)
    }

    /// Publishes the control rate (at boot, and whenever the controller is retimed).
    pub fn set_control_rate_hz(&self, rate_hz: u32) {
        self.control_rate_hz.store(rate_hz, Ordering::Relaxed);
    }

    /// Whether the serial receive echoes characters (the session's `echo`).
    pub fn echo(&self) -> bool {
        self.echo.load(Ordering::Relaxed)
    }
}

impl Default for Handoff {
    fn default() -> Self {
        Self::new()
    }
}
