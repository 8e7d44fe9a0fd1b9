//! Driving by hand and the odometry it moves: `drive <v> <w>` (a velocity command, limited to
//! the motion limits), `pose` (the odometry pose) and `odom reset` (the pose back to the
//! origin).
//!
//! Owns the reply that says when `drive` asked for more than the limits allow (the controller
//! clamps to the same limits).

use core::fmt::{self, Write};

use crate::protocol::outcome::{Ack, write_ack};
use crate::protocol::refusal::write_refusal;

use super::traits::{Calibrator, Robot};
use super::{Session, report, robot_err};
use crate::protocol::reply::write_ok_with;
use crate::util::num::clamp;

impl<C: Calibrator> Session<C> {
    /// `drive <v> <w>`: forward speed `v_mps` and turn rate `w_radps`.
    pub(super) fn drive(
        &mut self,
        v_mps: f32,
        w_radps: f32,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        // The robot stays at an unmeasured run's end until it is measured or dropped.
        if (v_mps != 0.0 || w_radps != 0.0)
            && let Some(refusal) = self.unmeasured_end()
        {
            return write_refusal(out, &refusal);
        }
        match robot.drive(v_mps, w_radps) {
            Ok(()) => {
                // The controller clamps to the same limits; say so rather than silently.
                let l = &self.settings.motion;
                let v = clamp(v_mps, -l.max_speed_mps, l.max_speed_mps);
                let w = clamp(w_radps, -l.max_turn_rate_radps, l.max_turn_rate_radps);
                let ack = if v == v_mps && w == w_radps {
                    Ack::Driving
                } else {
                    Ack::DriveLimited {
                        v_mps: v,
                        w_radps: w,
                    }
                };
                write_ack(out, ack)
            }
            Err(e) => robot_err(out, e, robot),
        }
    }

    /// `pose`: `ok x=… y=… theta_deg=…`.
    pub(super) fn pose(&self, robot: &mut dyn Robot, out: &mut dyn Write) -> fmt::Result {
        let p = robot.pose();
        write_ok_with(out, &mut |out| report::write_pose(out, &p))
    }

    /// `odom reset`: the odometry pose back to the origin.
    pub(super) fn odom_reset(&self, robot: &mut dyn Robot, out: &mut dyn Write) -> fmt::Result {
        match robot.reset_odometry() {
            Ok(()) => write_ack(out, Ack::OdometryReset),
            Err(e) => robot_err(out, e, robot),
        }
    }
}
