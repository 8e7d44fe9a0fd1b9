//! The operator's inputs outside the command line: the button's short and long presses and the
//! stop keys (Ctrl-C, Esc) that the board's receive interrupt passes on.
//!
//! Each writes its outcome as an `event …` line, since no command line asked for it; a short
//! press clears a latched fault or starts the next planned run as `next` does.

use core::fmt::{self, Write};

use super::Session;
use super::traits::{Calibrator, Robot};
use crate::protocol::StopKey;
use crate::protocol::outcome::{Ack, Outcome, write_ack, write_outcome};
use crate::protocol::token::EventTag;

impl<C: Calibrator> Session<C> {
    /// The button's short press: clears a latched fault, otherwise starts the next planned run
    /// (refused with the usual error while the robot moves). The outcome is written as an
    /// `event button: …` line.
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    pub fn button_short(&mut self, robot: &mut dyn Robot, out: &mut dyn Write) -> fmt::Result {
        self.collect_finished(robot, out)?;
        EventTag::Button.write(out)?;
        if robot.status().fault().is_some() {
            robot.clear_fault();
            return write_ack(out, Ack::FaultCleared { name: None });
        }
        // A refusal is said on the console and shown on the LEDs.
        let started = self.start_next(robot, out)?;
        self.press_refused |= !started;
        Ok(())
    }

    /// Whether a short press was refused since the last call (for the board's LEDs).
    pub fn take_press_refused(&mut self) -> bool {
        core::mem::take(&mut self.press_refused)
    }

    /// The button's long press: stops any motion.
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    pub fn button_long(&mut self, robot: &mut dyn Robot, out: &mut dyn Write) -> fmt::Result {
        robot.abort();
        self.collect_finished(robot, out)?;
        EventTag::Button.write(out)?;
        write_outcome(out, &Outcome::Stopped { aborted: None })
    }

    /// Ctrl-C or Esc: stops any motion (the board's receive interrupt has already told the
    /// control task; this is idempotent). Writes `event stopped (Ctrl-C)` always, `event stopped
    /// (Esc)` only if something was still moving (arrow keys send Esc too), then the aborted
    /// run's event if it was not announced yet.
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    pub fn interrupt(
        &mut self,
        key: StopKey,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let moving = robot.status().is_busy() || self.active.is_some();
        robot.abort();
        if moving || key == StopKey::CtrlC {
            let name = match key {
                StopKey::CtrlC => "Ctrl-C",
                StopKey::Escape => "Esc",
            };
            EventTag::Stopped.write(out)?;
            write!(out, "({name})\r\n")?;
        }
        self.collect_finished(robot, out)
    }
}
