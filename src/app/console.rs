//! The console task (the board's lowest priority): received lines and button presses executed
//! on the session, then the session's periodic work (finished runs, events, the pose stream).
//! Each call locks the controller only for the robot calls it makes (the caller's `robot`).

use core::fmt::{self, Write};
use core::sync::atomic::Ordering;

use super::Handoff;
use crate::motion::button::Press;
use crate::protocol::reply::{ErrorCode, write_err};
use crate::protocol::rx::{InputReceiver, Received};
use crate::protocol::token::LinesDropped;
use crate::session::{Calibrator, Robot, Session, SettingsAndRuns};

/// Where the console task takes received lines and stop keys from.
pub trait LineSource {
    /// The next item, if any.
    fn take(&mut self) -> Option<Received>;
    /// Whether nothing waits.
    fn is_empty(&self) -> bool;
}

impl LineSource for InputReceiver<'_> {
    fn take(&mut self) -> Option<Received> {
        InputReceiver::take(self)
    }

    fn is_empty(&self) -> bool {
        InputReceiver::is_empty(self)
    }
}

/// Executes the next received line (or stop key) on the session, its deferred echo first, and
/// publishes the session's echo setting for the receive. Once every line kept has been
/// answered, lines lost to a full input queue are reported instead: one notice for a whole
/// paste, after its last reply.
///
/// # Errors
/// Only if `out` refuses the text.
pub fn take_line<C: Calibrator>(
    handoff: &Handoff,
    session: &mut Session<C>,
    lines: &mut impl LineSource,
    robot: &mut dyn Robot,
    storage: &mut dyn SettingsAndRuns,
    out: &mut dyn Write,
) -> fmt::Result {
    if lines.is_empty() {
        let lost = handoff.lines_dropped.swap(0, Ordering::Relaxed);
        if lost > 0 {
            return write_err(out, ErrorCode::Busy, &LinesDropped(lost));
        }
    }
    // Busy from before the line leaves the queue: a line starting after the take but before
    // the reply would otherwise see an empty queue and an idle console, and its live echo
    // would land in front of this line's deferred echo. `SeqCst` keeps the flag's store ahead
    // of the take (a `Relaxed` store may be moved past it).
    handoff.console_busy.store(true, Ordering::SeqCst);
    let result = match lines.take() {
        Some(received) => {
            let result = session.handle_input(&received, robot, storage, out);
            handoff.echo.store(session.echo(), Ordering::Relaxed);
            result
        }
        None => Ok(()),
    };
    handoff.console_busy.store(false, Ordering::SeqCst);
    result
}

/// A button press, handed on by the control period: a short one starts the next planned run
/// (or clears a fault), a long one stops.
///
/// # Errors
/// Only if `out` refuses the text.
pub fn press<C: Calibrator>(
    session: &mut Session<C>,
    press: Press,
    robot: &mut dyn Robot,
    out: &mut dyn Write,
) -> fmt::Result {
    match press {
        Press::Short => session.button_short(robot, out),
        Press::Long => session.button_long(robot, out),
    }
}

/// The session's periodic work at `now_us` (finished runs, events, the pose stream, which holds
/// while a line is being typed with live echo); a button press the session refused since the
/// last poll is handed to the control period, which blinks the fault LED for it.
///
/// # Errors
/// Only if `out` refuses the text.
pub fn poll<C: Calibrator>(
    handoff: &Handoff,
    session: &mut Session<C>,
    now_us: u64,
    robot: &mut dyn Robot,
    storage: &mut dyn SettingsAndRuns,
    out: &mut dyn Write,
) -> fmt::Result {
    session.set_typing(handoff.typing.load(Ordering::Relaxed));
    if session.take_press_refused() {
        handoff.press_refused.store(true, Ordering::Relaxed);
    }
    session.poll(now_us, robot, storage, out)
}
