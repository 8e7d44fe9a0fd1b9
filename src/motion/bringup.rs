//! Bring-up check: does each encoder count the way its motor turns?
//!
//! Two parts, both driven by the controller at the control rate:
//!
//! - **Motor pulses** ([`PulseCheck`], wheels off the ground): per wheel, right first, a forward
//!   pulse at a low duty, a pause, a backward pulse, a pause; both encoders are read during each
//!   pulse. A healthy wheel counts forward for the forward pulse and backward for the backward
//!   one, and the other encoder stays still.
//! - **Hand push** ([`PushCheck`], wheels on the floor, motors off): the operator pushes the
//!   robot straight forward a few centimetres; both encoders must count forward. This tells an
//!   encoder that counts backward apart from a motor that turns backward, which the pulses alone
//!   cannot (either one makes the counts run against the duty).
//!
//! The verdicts ([`WheelVerdict`], [`PushVerdict`]) are pure functions of the recorded counts,
//! so the session can print them and propose the wiring settings.

use crate::motion::identify::{IdentifyFailure, IdentifyMode, IdentifyReport};
use crate::motion::wheel::Wheel;
use crate::util::num::ceil_i64;

/// Duty of a bring-up pulse: enough to overcome static friction of a free wheel, too little to
/// hurt anything.
pub const PULSE_DUTY: f32 = 0.25;
/// Length of a pulse and of the pause after it, ms (below the 300 ms stall time, so a silent
/// encoder is reported by the check, not latched as a stall).
pub const PULSE_MS: u32 = 250;
/// How long the hand-push check watches the encoders, ms.
pub const PUSH_MS: u32 = 5_000;
/// Distance the push check waits for on either wheel, m (it ends early when reached).
pub const PUSH_DISTANCE_M: f64 = 0.05;

/// Counts of both encoders during one pulse (forward positive, with the wiring in force).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct PulseCounts {
    /// The pulsed wheel's encoder, counts.
    pub own: i64,
    /// The other wheel's encoder, counts.
    pub other: i64,
}

/// The pulses of one wheel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct WheelPulses {
    /// During the forward pulse.
    pub forward: PulseCounts,
    /// During the backward pulse.
    pub backward: PulseCounts,
}

/// What the pulses of one wheel show.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum WheelVerdict {
    /// Counts follow the duty in both directions; the other encoder stays still.
    Ok,
    /// The own encoder counted against the duty in both directions: the motor or the encoder
    /// is reversed.
    Reversed,
    /// The own encoder did not move (no power, a disconnected motor or encoder, a blocked wheel).
    NoMotion,
    /// The other wheel's encoder moved more than the own one: motors or encoders swapped.
    CrossWired,
    /// Counts in the two directions disagree (a loose encoder, a slipping coupling).
    Inconsistent,
}

impl WheelPulses {
    /// The verdict, with `min_counts` the smallest count that is motion.
    pub fn verdict(&self, min_counts: i64) -> WheelVerdict {
        let (f, b) = (self.forward, self.backward);
        let moved = |c: i64| c.abs() >= min_counts;
        if f.other.abs() > f.own.abs().max(min_counts)
            || b.other.abs() > b.own.abs().max(min_counts)
        {
            return WheelVerdict::CrossWired;
        }
        match (moved(f.own), moved(b.own)) {
            (false, false) => WheelVerdict::NoMotion,
            (true, true) if f.own > 0 && b.own < 0 => WheelVerdict::Ok,
            (true, true) if f.own < 0 && b.own > 0 => WheelVerdict::Reversed,
            _ => WheelVerdict::Inconsistent,
        }
    }
}

/// Result of the motor pulses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct PulseReport {
    /// Right wheel.
    pub right: WheelPulses,
    /// Left wheel.
    pub left: WheelPulses,
}

impl PulseReport {
    /// The pulses of `wheel`.
    pub fn wheel(&self, wheel: Wheel) -> &WheelPulses {
        match wheel {
            Wheel::Right => &self.right,
            Wheel::Left => &self.left,
        }
    }
}

/// What the hand push shows for one encoder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum PushVerdict {
    /// Counted forward.
    Ok,
    /// Counted backward: the encoder is reversed.
    Reversed,
    /// Did not move.
    NoMotion,
}

/// Result of the hand push: counts of both encoders (forward positive, wiring in force).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct PushReport {
    /// Right encoder, counts.
    pub right: i64,
    /// Left encoder, counts.
    pub left: i64,
}

impl PushReport {
    /// The verdict for `wheel`'s encoder, with `min_counts` the smallest count that is motion.
    pub fn verdict(&self, wheel: Wheel, min_counts: i64) -> PushVerdict {
        let c = match wheel {
            Wheel::Right => self.right,
            Wheel::Left => self.left,
        };
        if c.abs() < min_counts {
            PushVerdict::NoMotion
        } else if c > 0 {
            PushVerdict::Ok
        } else {
            PushVerdict::Reversed
        }
    }
}

/// A finished check.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum CheckReport {
    /// The motor pulses.
    Pulses(PulseReport),
    /// The hand push.
    Push(PushReport),
    /// A motor identification with a plausible result.
    Identify(IdentifyReport),
    /// A motor identification stopped by an abnormal response (a fault is latched).
    IdentifyFailed(IdentifyFailure),
}

/// Which check to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum CheckKind {
    /// Motor pulses, wheels off the ground.
    Pulses,
    /// Hand push, motors off.
    Push,
    /// Motor identification ([`crate::motion::identify`]).
    Identify(IdentifyMode),
}

/// One of the pulse sequence's phases.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Forward,
    PauseAfterForward,
    Backward,
    PauseAfterBackward,
}

/// The motor-pulse sequence (see the module docs); stepped once per control period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PulseCheck {
    wheel: Wheel,
    phase: Phase,
    left_in_phase: u32,
    phase_periods: u32,
    report: PulseReport,
}

/// What the pulse sequence commands for one period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PulseStep {
    /// Open-loop duties (right, left), wheel frame (forward positive).
    Duty(f32, f32),
    /// Motors off (coast) for this period.
    Off,
    /// The sequence is complete.
    Done(PulseReport),
}

impl PulseCheck {
    /// A sequence at `rate_hz`.
    pub fn new(rate_hz: u32) -> Self {
        let phase_periods = (u64::from(PULSE_MS) * u64::from(rate_hz) / 1000).max(1) as u32;
        PulseCheck {
            wheel: Wheel::Right,
            phase: Phase::Forward,
            left_in_phase: phase_periods,
            phase_periods,
            report: PulseReport::default(),
        }
    }

    /// One period: `dr`, `dl` are the counts of the period that just ended (during which the
    /// previous step's command was applied).
    pub fn step(&mut self, dr: i64, dl: i64) -> PulseStep {
        let (own, other) = match self.wheel {
            Wheel::Right => (dr, dl),
            Wheel::Left => (dl, dr),
        };
        let pulses = match self.wheel {
            Wheel::Right => &mut self.report.right,
            Wheel::Left => &mut self.report.left,
        };
        // Counts during a pulse, and the coast-down right after it (the wheel still turns the
        // way the pulse drove it), belong to that pulse.
        let counts = match self.phase {
            Phase::Forward | Phase::PauseAfterForward => &mut pulses.forward,
            Phase::Backward | Phase::PauseAfterBackward => &mut pulses.backward,
        };
        // The first period of the forward phase carries nothing of this wheel's pulse yet.
        if !(self.phase == Phase::Forward && self.left_in_phase == self.phase_periods) {
            counts.own += own;
            counts.other += other;
        }
        if self.left_in_phase == 0 {
            self.left_in_phase = self.phase_periods;
            self.phase = match self.phase {
                Phase::Forward => Phase::PauseAfterForward,
                Phase::PauseAfterForward => Phase::Backward,
                Phase::Backward => Phase::PauseAfterBackward,
                Phase::PauseAfterBackward => match self.wheel {
                    Wheel::Right => {
                        self.wheel = Wheel::Left;
                        Phase::Forward
                    }
                    Wheel::Left => return PulseStep::Done(self.report),
                },
            };
        }
        self.left_in_phase -= 1;
        let duty = match self.phase {
            Phase::Forward => PULSE_DUTY,
            Phase::Backward => -PULSE_DUTY,
            Phase::PauseAfterForward | Phase::PauseAfterBackward => return PulseStep::Off,
        };
        match self.wheel {
            Wheel::Right => PulseStep::Duty(duty, 0.0),
            Wheel::Left => PulseStep::Duty(0.0, duty),
        }
    }
}

/// The hand-push watch (see the module docs); stepped once per control period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PushCheck {
    left_periods: u32,
    target_counts: (i64, i64),
    report: PushReport,
}

impl PushCheck {
    /// A watch at `rate_hz` that ends early once a wheel has moved `PUSH_DISTANCE_M`
    /// (`counts_per_m` per wheel).
    pub fn new(rate_hz: u32, counts_per_m: (f64, f64)) -> Self {
        let c = |k: f64| ceil_i64(PUSH_DISTANCE_M * k);
        PushCheck {
            left_periods: (u64::from(PUSH_MS) * u64::from(rate_hz) / 1000).max(1) as u32,
            target_counts: (c(counts_per_m.0), c(counts_per_m.1)),
            report: PushReport::default(),
        }
    }

    /// The counts of periods the board missed beyond the share the next [`Self::step`] is
    /// given: part of the push.
    pub fn catch_up(&mut self, dr: i64, dl: i64) {
        self.report.right += dr;
        self.report.left += dl;
    }

    /// One period with the counts `dr`, `dl`; the report once the watch is over.
    pub fn step(&mut self, dr: i64, dl: i64) -> Option<PushReport> {
        self.report.right += dr;
        self.report.left += dl;
        self.left_periods = self.left_periods.saturating_sub(1);
        let far = self.report.right.abs() >= self.target_counts.0
            || self.report.left.abs() >= self.target_counts.1;
        (far || self.left_periods == 0).then_some(self.report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A free wheel model: counts per period proportional to the duty applied in the previous
    /// period, `sign` the wiring (−1 = reversed), `cross` sends the counts to the other encoder.
    fn run(rate: u32, sign: [i64; 2], cross: bool) -> PulseReport {
        let mut check = PulseCheck::new(rate);
        let (mut dr, mut dl) = (0, 0);
        for _ in 0..10 * rate {
            match check.step(dr, dl) {
                PulseStep::Done(r) => return r,
                PulseStep::Off => (dr, dl) = (0, 0),
                PulseStep::Duty(r, l) => {
                    let (a, b) = ((r * 400.0) as i64 * sign[0], (l * 400.0) as i64 * sign[1]);
                    (dr, dl) = if cross { (b, a) } else { (a, b) };
                }
            }
        }
        panic!("the pulse sequence did not end");
    }

    #[test]
    fn healthy_wheels_pass_and_the_sequence_takes_two_seconds() {
        let r = run(1000, [1, 1], false);
        assert_eq!(r.right.verdict(10), WheelVerdict::Ok);
        assert_eq!(r.left.verdict(10), WheelVerdict::Ok);
        // 250 periods of 100 counts per pulse.
        assert_eq!(r.right.forward.own, 250 * 100);
        assert_eq!(r.left.backward.own, -250 * 100);
        assert_eq!(r.right.forward.other, 0);
    }

    #[test]
    fn a_reversed_wheel_and_cross_wiring_are_told_apart() {
        let r = run(1000, [1, -1], false);
        assert_eq!(r.right.verdict(10), WheelVerdict::Ok);
        assert_eq!(r.left.verdict(10), WheelVerdict::Reversed);
        let r = run(1000, [1, 1], true);
        assert_eq!(r.right.verdict(10), WheelVerdict::CrossWired);
        let r = run(10_000, [0, 0], false);
        assert_eq!(r.right.verdict(10), WheelVerdict::NoMotion);
    }

    #[test]
    fn push_ends_early_and_reports_a_reversed_encoder() {
        let mut p = PushCheck::new(1000, (2000.0, 2000.0));
        let mut out = None;
        for _ in 0..1000 {
            out = p.step(5, -5);
            if out.is_some() {
                break;
            }
        }
        let r = out.unwrap();
        assert_eq!(r.right, 100);
        assert_eq!(r.verdict(Wheel::Right, 10), PushVerdict::Ok);
        assert_eq!(r.verdict(Wheel::Left, 10), PushVerdict::Reversed);
        let mut idle = PushCheck::new(1000, (2000.0, 2000.0));
        let ended = (0..5000).filter_map(|_| idle.step(0, 0)).next().unwrap();
        assert_eq!(ended.verdict(Wheel::Left, 10), PushVerdict::NoMotion);
    }
}
