//! The control period (the board's highest priority, 1–10 kHz): stop requests, one controller
//! step, the motors, a long press's abort, and the period's bookkeeping (retiming after
//! `set control_hz`, the heartbeat).

use core::sync::atomic::{AtomicBool, Ordering};

use super::Handoff;
use crate::motion::button::Press;
use crate::motion::controller::{Controller, StepOutput};
use crate::motion::motor::MotorDriver;

/// One control period: the periods missed before it (`missed`, from [`MissedPeriods`]) are
/// told to the controller; a stop key received since the last period (Ctrl-C, Esc) aborts any
/// motion; the controller steps on the raw encoder counts and its command goes to
/// `motors`; a long button press aborts now, not one period later (the controller steps again
/// and that command goes out too). Returns the period's first step output (its fault is the
/// one the fault LED shows). The caller hands `press` on to the console task, which acts on it.
pub fn period<M: MotorDriver>(
    handoff: &Handoff,
    controller: &mut Controller,
    missed: u32,
    raw_right: u32,
    raw_left: u32,
    press: Option<Press>,
    motors: &mut M,
) -> StepOutput {
    controller.note_missed_periods(missed);
    if take_flag(&handoff.stop_request) {
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

/// Takes a flag another context sets: whether it was set, clearing it. Nearly every period finds
/// it clear, and a plain load says so; only a set flag is swapped (an atomic read-modify-write
/// is a locked instruction on the host, which waits for every pending store, and a load/store
/// exclusive loop on the board). The same outcome as a swap alone: the other contexts only ever
/// set the flag, so a flag set after the load is taken by the next period's.
#[inline(always)]
fn take_flag(flag: &AtomicBool) -> bool {
    flag.load(Ordering::Relaxed) && flag.swap(false, Ordering::Relaxed)
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
pub struct PacingActions {
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
    pub fn after_period(&mut self, handoff: &Handoff, controller_rate_hz: u32) -> PacingActions {
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
        if take_flag(&handoff.press_refused) {
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
        PacingActions {
            retime_hz,
            toggle_heartbeat,
            refusal_lit,
        }
    }
}

/// Counts the control periods the board missed, from a free-running cycle counter read at the
/// start of each period (the Cortex-M's DWT.CYCCNT at the core clock). The period's timer
/// updates on a fixed schedule; its interrupt starts some time after the update. An interrupt
/// held up by less than a period (something at a higher priority or in a critical section ran
/// long) still serves the update that is pending: nothing was missed. Only when a whole period
/// went by on top (a flash erase stalls every fetch, or a hold of more than a period) did an
/// update come and go without a control step. The controller is told
/// ([`Controller::note_missed_periods`]) and latches an `overrun` fault if it was moving.
///
/// The schedule is anchored at the earliest interrupt start seen for it: a start is never
/// before its update, so an interrupt that arrives less than a period after the last
/// anchored update is on time and moves the anchor back to itself.
#[derive(Clone, Copy, Debug, Default)]
pub struct MissedPeriods {
    /// The cycle at which the last period's update is taken to have come.
    last_update: Option<u32>,
    core_hz: u32,
    cycles_per_period: u32,
}

impl MissedPeriods {
    /// A counter of `core_hz` cycles per second for periods at `rate_hz`.
    pub fn new(core_hz: u32, rate_hz: u32) -> Self {
        let mut m = MissedPeriods {
            core_hz,
            ..MissedPeriods::default()
        };
        m.set_rate(rate_hz);
        m
    }

    /// The period changed (`set control_hz`): the next period starts the count afresh.
    pub fn set_rate(&mut self, rate_hz: u32) {
        self.cycles_per_period = self.core_hz / rate_hz.max(1);
        self.last_update = None;
    }

    /// The period that starts at cycle `now`: how many periods were missed since the last one
    /// (0 when its update was only pending). A counter that does not run (an emulator without
    /// the DWT) misses nothing. The counter wraps (every 25.6 s at 168 MHz): a gap longer than
    /// that is counted modulo it.
    pub fn observe(&mut self, now: u32) -> u32 {
        let period = self.cycles_per_period;
        let Some(last) = self.last_update else {
            self.last_update = Some(now);
            return 0;
        };
        let since = now.wrapping_sub(last);
        if period == 0 || since < period {
            // Earlier than the anchored schedule allows: the anchor was a late start.
            self.last_update = Some(now);
            return 0;
        }
        // The updates since the last one served: the last of them is this period's.
        let updates = since / period;
        self.last_update = Some(last.wrapping_add(updates.wrapping_mul(period)));
        updates - 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn periods_on_time_miss_nothing_and_a_stall_counts_the_whole_periods_it_took() {
        // 168 MHz, 1 kHz: 168,000 cycles a period.
        let mut m = MissedPeriods::new(168_000_000, 1_000);
        let mut t = 4_000_000_000u32;
        assert_eq!(m.observe(t), 0);
        // Jitter of up to half a period either way is on time, across the counter's wrap.
        for jitter in [0i64, 80_000, -80_000, 83_999] {
            t = t.wrapping_add((168_000 + jitter) as u32);
            assert_eq!(m.observe(t), 0, "jitter {jitter}");
        }
        // A 2 s erase stall: 1,999 periods never ran.
        t = t.wrapping_add(2 * 168_000_000);
        assert_eq!(m.observe(t), 1_999);
        // That start was 83,999 cycles after its update; the next update's interrupt starts 1.5
        // periods late (2.5 periods after that update): the update after it came and went.
        t = t.wrapping_add(420_000 - 83_999);
        assert_eq!(m.observe(t), 1);
        // At 10 kHz (16,800 cycles) after a retime, the first period only starts the count.
        m.set_rate(10_000);
        assert_eq!(m.observe(t.wrapping_add(999_999)), 0);
        assert_eq!(m.observe(t.wrapping_add(999_999 + 3 * 16_800)), 2);
    }

    /// A control interrupt held up by less than a period (a console lock, a higher-priority
    /// interrupt) serves the update that was pending: no period is missed, and the next one,
    /// back on the timer's schedule a fraction of a period later, is on time too. Held up by
    /// more than a period, the update after it came and went: one missed.
    #[test]
    fn late_interrupt_is_not_a_missed_period() {
        // The F411 at 100 MHz, 10 kHz: 10,000 cycles a period; the longest console lock
        // (13,055 instructions) can hold a period up by more than one.
        let p = 10_000u32;
        let mut m = MissedPeriods::new(100_000_000, 10_000);
        let mut update = 7u32;
        assert_eq!(m.observe(update), 0);
        for late in [0, 9_000, 0, 9_999, 2_000, 0] {
            update += p;
            assert_eq!(m.observe(update + late), 0, "{late} cycles late");
        }
        // Held up by 1.3 periods: the update after the pending one was missed.
        update += p;
        assert_eq!(m.observe(update + 13_055), 1);
        // The next start is 0.7 periods later, on the schedule again.
        update += 2 * p;
        assert_eq!(m.observe(update), 0);
    }

    #[test]
    fn a_counter_that_does_not_run_misses_nothing() {
        let mut m = MissedPeriods::new(168_000_000, 1_000);
        for _ in 0..3 {
            assert_eq!(m.observe(0), 0);
        }
    }

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
