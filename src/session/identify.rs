//! The `identify [lifted|floor]` command: runs the controller's motor identification
//! ([`crate::motion::identify`]) and, when the result is plausible, makes it the speed-loop
//! tuning at once (not saved: `save` keeps it), with the same rule as `set` and `save`.
//!
//! The command's reply says where the robot must be; the result arrives as `event identify …`
//! lines when the routine ends: one per motor (gains per direction, time constant, dead-band,
//! coasting deceleration, fit residual) and `event identify done …`, or
//! `event identify err 23: …` when the response was implausible (the motors are stopped, a
//! fault is latched and the tuning is unchanged).

use core::fmt::{self, Write};

use super::traits::{Calibrator, Robot};
use super::{Session, storable};
use crate::motion::identify::{
    IdentifyFailure, IdentifyMode, IdentifyReport, LEVEL_FRACTIONS, MAX_SPEED_MPS, MotorFit,
};
use crate::motion::speed::SpeedTuning;
use crate::protocol::reply::{ErrorCode, write_ok_with};
use crate::protocol::token::{self, EventTag};
use crate::util::decimal::Decimal;

fn mode_name(mode: IdentifyMode) -> &'static str {
    match mode {
        IdentifyMode::Lifted => "lifted",
        IdentifyMode::Floor => "floor",
    }
}

fn write_fit(out: &mut dyn Write, side: &str, fit: &MotorFit) -> fmt::Result {
    let p = &fit.params;
    let d = |v: f32, places| Decimal::fixed(f64::from(v), places);
    write!(
        out,
        "event identify {side}: gain_fwd={} gain_back={} m/s per duty, tau={} s, deadband={}, \
         coast {} m/s^2 from {} m/s, residual {} m/s\r\n",
        d(p.gain_forward_mps, 4),
        d(p.gain_backward_mps, 4),
        d(p.time_constant_s, 4),
        d(p.deadband, 4),
        d(fit.coast_decel_mps2, 3),
        d(fit.coast_from_mps, 3),
        d(fit.residual_mps, 5),
    )
}

impl<C: Calibrator> Session<C> {
    /// The reply to a started identification: where the robot must be, what it does.
    pub(super) fn write_identify_started(
        &self,
        mode: IdentifyMode,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let where_ = match mode {
            IdentifyMode::Lifted => "wheels must be off the ground; right then left",
            IdentifyMode::Floor => {
                "robot on the floor with 1 m free ahead and behind (it stays within 1 m, with lower \
                 steps if that needs them); both wheels"
            }
        };
        let cap = f64::from(self.settings.motion.max_speed_mps).min(MAX_SPEED_MPS);
        // Longer than a reply line buffer: written straight out.
        write_ok_with(out, &mut |out| {
            write!(
                out,
                "identify {}: {where_}; a slow probe, then steps to {}/{}/{} % of max_speed {} \
                 m/s forward and backward, about {} s",
                mode_name(mode),
                (LEVEL_FRACTIONS[0] * 100.0) as u32,
                (LEVEL_FRACTIONS[1] * 100.0) as u32,
                (LEVEL_FRACTIONS[2] * 100.0) as u32,
                Decimal::fixed(cap, 2),
                Decimal::fixed(f64::from(mode.duration_ms()) / 1000.0 + 3.0, 0),
            )
        })
    }

    /// Reports a finished identification and applies its tuning, with the bandwidth by
    /// [`SpeedTuning::bandwidth_for`].
    pub(super) fn report_identify(
        &mut self,
        r: &IdentifyReport,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        write_fit(out, "right", &r.right)?;
        write_fit(out, "left", &r.left)?;
        let mut candidate = self.settings.clone();
        candidate.tuning.right = r.right.params;
        candidate.tuning.left = r.left.params;
        candidate.tuning.bandwidth_radps = SpeedTuning::bandwidth_for(libm::fminf(
            r.right.params.time_constant_s,
            r.left.params.time_constant_s,
        ));
        let code = ErrorCode::IdentifyRefused.code();
        if let Err(e) = storable(&candidate) {
            EventTag::IdentifyErr.write(out)?;
            return write!(out, "{code}: result not applied: {e}; tuning unchanged\r\n");
        }
        if let Err(e) = robot.set_tuning(&candidate.tuning) {
            EventTag::IdentifyErr.write(out)?;
            return write!(out, "{code}: result not applied: {e}; tuning unchanged\r\n");
        }
        let bandwidth = candidate.tuning.bandwidth_radps;
        self.settings = candidate;
        EventTag::IdentifyDone.write(out)?;
        self.unsaved = true;
        write!(
            out,
            "({}): speed-loop tuning applied, bandwidth {} rad/s{}\r\n",
            mode_name(r.mode),
            Decimal::fixed(f64::from(bandwidth), 1),
            token::NOT_SAVED
        )
    }

    /// Reports an identification that an abnormal response stopped.
    pub(super) fn report_identify_failure(
        &self,
        f: &IdentifyFailure,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let side = match f.wheel {
            crate::motion::controller::Wheel::Right => "right",
            crate::motion::controller::Wheel::Left => "left",
        };
        EventTag::IdentifyErr.write(out)?;
        write!(
            out,
            "{}: {side} motor: {}; motors stopped, tuning unchanged, fault latched (clear)\r\n",
            ErrorCode::IdentifyRefused.code(),
            f.problem.describe()
        )
    }
}
