//! The control period (the board's highest priority, 1–10 kHz): stop requests, one controller
//! step, the motors, a long press's abort, and the period's bookkeeping (retiming after
//! `set control_hz`, the heartbeat).

use core::sync::atomic::Ordering;

use super::Handoff;
use crate::motion::button::Press;
use crate::motion::controller::{Controller, StepOutput};
use crate::motion::motor::MotorDriver;

/// One control period: a stop key received since the last period (Ctrl-C, Esc) aborts any
/// motion first; the controller steps on the raw encoder counts and its command goes to
/// `motors`; a long button press aborts now, not one period later (the controller steps again
/// and that command goes out too). Returns the period's first step output (its fault is the
/// one the fault LED shows). The caller hands `press` on to the console task, which acts on it.
pub fn period<M: MotorDriver>(
    handoff: &Handoff,
    controller: &mut Controller,
    raw_right: u32,
    raw_left: u32,
    press: Option<Press>,
    motors: &mut M,
) -> StepOutput {
    if handoff.stop_request.swap(false, Ordering::Relaxed) {
        controller.abort();
    }
    let out = controller.step(raw_right, raw_left);
    out.command.apply(motors);
    if press == Some(Press::Long) {
        controller.abort();
        controller.step(raw_right, raw_left).command.apply(motors);
    }
    out
}

/// What the board does after a period besides the control itself: it follows the controller's
/// rate (`set control_hz` retimes the controller while idle; the board's period source follows
/// from the next period on), blinks the heartbeat at 1 Hz at any rate, and blinks the fault LED
/// at 4 Hz for 1 s when the session refused a button press (the console says why).
#[derive(Clone, Copy, Debug)]
pub struct Pacing {
    rate_hz: u32,
    heartbeat_periods: u32,
    /// Periods since a refused press, while its blink lasts.
    refusal_periods: Option<u32>,
}

/// What [`Pacing::after_period`] asks of the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PacingNews {
    /// The control rate changed to this, Hz: retime the period source.
    pub retime_hz: Option<u32>,
    /// Toggle the heartbeat LED now.
    pub toggle_heartbeat: bool,
    /// The fault LED is lit for a refused button press now (blinking at 4 Hz for 1 s); the
    /// board lights it for this or a latched fault.
    pub refusal_lit: bool,
}

impl Pacing {
    /// Pacing for a period source started at `rate_hz`, published to `handoff`.
    pub fn new(handoff: &Handoff, rate_hz: u32) -> Self {
        handoff.set_control_rate_hz(rate_hz);
        Pacing {
            rate_hz,
            heartbeat_periods: 0,
            refusal_periods: None,
        }
    }

    /// The rate the period source runs at, Hz.
    pub fn rate_hz(&self) -> u32 {
        self.rate_hz
    }

    /// Bookkeeping after a period in which the controller ran at `controller_rate_hz`.
    pub fn after_period(&mut self, handoff: &Handoff, controller_rate_hz: u32) -> PacingNews {
        let mut retime_hz = None;
        if controller_rate_hz != self.rate_hz {
            self.rate_hz = controller_rate_hz;
            handoff.set_control_rate_hz(controller_rate_hz);
            self.heartbeat_periods = 0;
            retime_hz = Some(controller_rate_hz);
        }
        self.heartbeat_periods += 1;
        let toggle_heartbeat = self.heartbeat_periods >= self.rate_hz / 2;
        if toggle_heartbeat {
            self.heartbeat_periods = 0;
        }
        if handoff.press_refused.swap(false, Ordering::Relaxed) {
            self.refusal_periods = Some(0);
        }
        // Lit in every other eighth of a second: 4 Hz, for one second of periods.
        let refusal_lit = match self.refusal_periods {
            Some(n) if n < self.rate_hz => {
                self.refusal_periods = Some(n + 1);
                (u64::from(n) * 8 / u64::from(self.rate_hz.max(1))) % 2 == 0
            }
            _ => {
                self.refusal_periods = None;
                false
            }
        };
        PacingNews {
            retime_hz,
            toggle_heartbeat,
            refusal_lit,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refused_press_blinks_the_fault_led_at_4_hz_for_one_second() {
        let handoff = Handoff::new();
        let mut pacing = Pacing::new(&handoff, 1000);
        assert!(!pacing.after_period(&handoff, 1000).refusal_lit);
        handoff.press_refused.store(true, Ordering::Relaxed);
        let lit: std::vec::Vec<bool> = (0..1200)
            .map(|_| pacing.after_period(&handoff, 1000).refusal_lit)
            .collect();
        // 125 ms on, 125 ms off, four times; then dark.
        for (i, on) in lit.iter().enumerate() {
            assert_eq!(*on, i < 1000 && (i / 125) % 2 == 0, "period {i}");
        }
        // The flag was taken: no second blink.
        assert!(!handoff.press_refused.load(Ordering::Relaxed));
    }
}
