//! The `bringup` command: runs the controller's wiring check and turns its counts into a verdict
//! per wheel and the `set` commands that fix a reversed motor or encoder.
//!
//! `bringup push` (motors off, the operator pushes the robot forward by hand) tells whether each
//! encoder counts forward; `bringup` / `bringup motors` (wheels off the ground) pulses each motor
//! and tells whether its encoder follows. A reversed count in the pulses alone can be the motor
//! or the encoder; with a push result from this boot, the session says which.

use core::fmt::{self, Write};

use crate::protocol::refusal::write_refusal;
use crate::protocol::reply::write_ok;

use super::traits::{Calibrator, Robot};
use super::{Session, robot_err};
use crate::motion::bringup::{
    CheckKind, CheckReport, PULSE_DUTY, PUSH_DISTANCE_M, PUSH_MS, PulseReport, PushReport,
    PushVerdict, WheelVerdict,
};
use crate::motion::controller::Wheel;
use crate::motion::wheel::MIN_MOTION_M;
use crate::protocol::ParamName;
use crate::protocol::token::{EventTag, WIRING_OK};
use crate::util::num::ceil_i64;

fn wheel_name(w: Wheel) -> &'static str {
    match w {
        Wheel::Right => "right",
        Wheel::Left => "left",
    }
}

fn sign_param(w: Wheel, motor: bool) -> ParamName {
    match (w, motor) {
        (Wheel::Right, true) => ParamName::MotorRightSign,
        (Wheel::Left, true) => ParamName::MotorLeftSign,
        (Wheel::Right, false) => ParamName::EncoderRightSign,
        (Wheel::Left, false) => ParamName::EncoderLeftSign,
    }
}

impl<C: Calibrator> Session<C> {
    /// Starts a bring-up check and says what the operator must do.
    pub(super) fn bringup(
        &mut self,
        kind: CheckKind,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        // Every check moves the robot (lifted, pushed or driven): not from an unmeasured end.
        if let Some(refusal) = self.unmeasured_end() {
            return write_refusal(out, &refusal);
        }
        if let Err(e) = robot.start_check(kind) {
            return robot_err(out, e, robot);
        }
        match kind {
            CheckKind::Identify(mode) => self.write_identify_started(mode, out),
            CheckKind::Pulses => write_ok(
                out,
                format_args!(
                    "bringup motors: wheels must be off the ground; pulsing right then left at {} \
                     % duty, 2 s",
                    (PULSE_DUTY * 100.0) as u32
                ),
            ),
            CheckKind::Push => write_ok(
                out,
                format_args!(
                    "bringup push: motors off; push the robot straight forward by hand about {} \
                     cm within {} s",
                    (PUSH_DISTANCE_M * 100.0) as u32,
                    PUSH_MS / 1000
                ),
            ),
        }
    }

    /// The smallest count that is wheel motion (1 mm) for `wheel` with the active geometry.
    fn min_counts(&self, wheel: Wheel) -> i64 {
        let g = &self.settings.active;
        let m_per_tick = match wheel {
            Wheel::Right => g.meters_per_tick_right(),
            Wheel::Left => g.meters_per_tick_left(),
        };
        ceil_i64(MIN_MOTION_M / m_per_tick)
    }

    /// Announces a finished bring-up check with `event bringup …` lines.
    pub(super) fn collect_check(
        &mut self,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        match robot.take_check_report() {
            None => Ok(()),
            Some(CheckReport::Push(p)) => {
                self.last_push = Some(p);
                self.report_push(&p, out)
            }
            Some(CheckReport::Pulses(p)) => self.report_pulses(&p, out),
            Some(CheckReport::Identify(r)) => self.report_identify(&r, robot, out),
            Some(CheckReport::IdentifyFailed(f)) => self.report_identify_failure(&f, out),
        }
    }

    fn propose(&self, wheel: Wheel, motor: bool, out: &mut dyn Write) -> fmt::Result {
        let name = sign_param(wheel, motor);
        // A sign parameter is 1 or -1: propose the other one.
        let flipped = if self.settings.value(name) < 0.0 {
            "1"
        } else {
            "-1"
        };
        EventTag::BringupPropose.write(out)?;
        write!(out, "set {} {flipped}\r\n", name.as_str())
    }

    fn report_push(&self, p: &PushReport, out: &mut dyn Write) -> fmt::Result {
        let mut found = Findings::default();
        for (wheel, counts) in [(Wheel::Right, p.right), (Wheel::Left, p.left)] {
            let verdict = p.verdict(wheel, self.min_counts(wheel));
            let text = match verdict {
                PushVerdict::Ok => "counts forward: ok",
                PushVerdict::Reversed => "counts backward: encoder reversed",
                PushVerdict::NoMotion => "did not move: check the encoder wiring (or push further)",
            };
            write!(
                out,
                "event bringup push: {} encoder {counts:+} counts, {text}\r\n",
                wheel_name(wheel)
            )?;
            match verdict {
                PushVerdict::Ok => {}
                PushVerdict::Reversed => {
                    self.propose(wheel, false, out)?;
                    found.proposed += 1;
                }
                PushVerdict::NoMotion => found.unfixed += 1,
            }
        }
        found.write_done(CheckKind::Push, out)
    }

    fn report_pulses(&self, p: &PulseReport, out: &mut dyn Write) -> fmt::Result {
        let mut found = Findings::default();
        for wheel in [Wheel::Right, Wheel::Left] {
            let min = self.min_counts(wheel);
            let pulses = p.wheel(wheel);
            let verdict = pulses.verdict(min);
            write!(
                out,
                "event bringup motors: {} forward {:+} back {:+} (other wheel {:+}/{:+}): ",
                wheel_name(wheel),
                pulses.forward.own,
                pulses.backward.own,
                pulses.forward.other,
                pulses.backward.other
            )?;
            let encoder_reversed = self
                .last_push
                .map(|push| push.verdict(wheel, min) == PushVerdict::Reversed);
            match verdict {
                WheelVerdict::Ok | WheelVerdict::Reversed => {
                    let counts_reversed = verdict == WheelVerdict::Reversed;
                    match encoder_reversed {
                        Some(enc) => {
                            let motor = counts_reversed != enc;
                            match (enc, motor) {
                                (false, false) => write!(out, "ok\r\n")?,
                                (true, false) => write!(out, "encoder reversed (push check)\r\n")?,
                                (false, true) => write!(out, "motor reversed\r\n")?,
                                (true, true) => write!(out, "motor and encoder reversed\r\n")?,
                            }
                            if enc {
                                self.propose(wheel, false, out)?;
                                found.proposed += 1;
                            }
                            if motor {
                                self.propose(wheel, true, out)?;
                                found.proposed += 1;
                            }
                        }
                        None if counts_reversed => {
                            write!(
                                out,
                                "counts run against the duty: motor or encoder reversed; run `bringup push` to tell which\r\n"
                            )?;
                            found.unfixed += 1;
                        }
                        None => write!(out, "ok\r\n")?,
                    }
                }
                WheelVerdict::NoMotion => write!(
                    out,
                    "no motion: check motor power and wiring, the encoder, and that the wheel is free\r\n"
                )?,
                WheelVerdict::CrossWired => write!(
                    out,
                    "the other wheel's encoder moved: motors or encoders are swapped between the sides\r\n"
                )?,
                WheelVerdict::Inconsistent => write!(
                    out,
                    "counts disagree between directions: check the encoder mounting and coupling\r\n"
                )?,
            }
            if matches!(
                verdict,
                WheelVerdict::NoMotion | WheelVerdict::CrossWired | WheelVerdict::Inconsistent
            ) {
                found.unfixed += 1;
            }
        }
        found.write_done(CheckKind::Pulses, out)
    }
}

/// What a check found: findings with a proposed `set` each, and findings no setting fixes.
#[derive(Clone, Copy, Debug, Default)]
struct Findings {
    proposed: u32,
    unfixed: u32,
}

impl Findings {
    /// `event bringup done: …`: says `wiring ok` only when the check covered the wiring (the
    /// push checks the encoders alone), and announces proposals only when some were made.
    fn write_done(self, kind: CheckKind, out: &mut dyn Write) -> fmt::Result {
        let (p, u) = (self.proposed, self.unfixed);
        EventTag::BringupDone.write(out)?;
        if p + u == 0 {
            return match kind {
                CheckKind::Push => write!(
                    out,
                    "encoders count forward (the push checks the encoders only; bringup motors \
                     checks the motors)\r\n"
                ),
                _ => write!(out, "{WIRING_OK}\r\n"),
            };
        }
        let finding = |n: u32| if n == 1 { "finding" } else { "findings" };
        let proposal = |n: u32| if n == 1 { "proposal" } else { "proposals" };
        match (p, u) {
            (0, u) => write!(
                out,
                "{u} {}, no setting fixes {}: see above, then check again\r\n",
                finding(u),
                if u == 1 { "it" } else { "them" }
            ),
            (p, 0) => write!(
                out,
                "{p} {}; apply the {} with set, then save and check again\r\n",
                finding(p),
                proposal(p)
            ),
            (p, u) => write!(
                out,
                "{} findings; apply the {} with set, see above for the other {}, then save and \
                 check again\r\n",
                p + u,
                proposal(p),
                u
            ),
        }
    }
}
