//! Faults: stall detection and the latched fault that keeps the motors stopped until cleared.

use core::fmt;

use super::mode::ActiveCheck;
use super::{Controller, ControllerConfig};
use crate::motion::bringup::CheckReport;
use crate::motion::identify::{IdentifyFailure, IdentifyProblem};
use crate::motion::wheel::Wheel;

/// A latched fault; the motors are stopped until [`Controller::clear_fault`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum Fault {
    /// An encoder counter jumped further than the wheel can move in one period.
    EncoderGlitch {
        /// Which encoder.
        wheel: Wheel,
        /// The rejected delta, counts.
        delta: i64,
    },
    /// A wheel was commanded to move but counted no tick for the stall time.
    Stall {
        /// Which wheel.
        wheel: Wheel,
    },
    /// A wheel stayed further from its reference than the following-error bound for its time:
    /// it is not under control (a reversed motor or encoder, a slipping or overloaded wheel).
    FollowingError {
        /// Which wheel.
        wheel: Wheel,
        /// Reference − measured travel when the fault latched, mm.
        error_mm: i32,
        /// Largest |duty| commanded to that wheel since the motion started, percent.
        peak_duty_pct: u8,
    },
    /// The motor identification met an abnormal response.
    Identify(IdentifyFailure),
    /// Control periods were missed while the robot moved (more than [`OVERRUN_FAULT_MS`] of
    /// them in one gap): the profile and the speed loops ran late.
    ///
    /// [`OVERRUN_FAULT_MS`]: super::OVERRUN_FAULT_MS
    Overrun {
        /// Periods missed in that gap.
        missed: u32,
    },
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Fault::EncoderGlitch { wheel, delta } => {
                write!(f, "{wheel:?} encoder glitch ({delta} counts in one period)")
            }
            Fault::Stall { wheel } => write!(f, "{wheel:?} wheel stalled"),
            Fault::FollowingError {
                wheel,
                error_mm,
                peak_duty_pct,
            } => write!(
                f,
                "{wheel:?} wheel following error {} mm (peak duty {} %): check its motor and encoder polarity",
                // Widened: the replies print integers through the `i64` and `u32` formatters only.
                i64::from(*error_mm),
                u32::from(*peak_duty_pct)
            ),
            Fault::Identify(e) => write!(
                f,
                "{:?} motor identification: {}",
                e.wheel,
                e.problem.describe()
            ),
            Fault::Overrun { missed } => write!(
                f,
                "control overrun: {missed} control periods missed while moving"
            ),
        }
    }
}

/// Following-error bookkeeping of both wheels (right, left).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct FollowingState {
    /// Reference − measured counts since the motion started.
    error_ticks: (f32, f32),
    /// Largest |duty| since the motion started.
    peak_duty: (f32, f32),
    /// Consecutive periods above the bound.
    over: (u32, u32),
    /// The bound in counts of each wheel.
    limit_ticks: (f32, f32),
    /// Periods above the bound that latch the fault.
    periods: u32,
}

impl FollowingState {
    /// Bounds for `config`, nothing accumulated.
    pub(super) fn for_config(config: &ControllerConfig) -> Self {
        let f = &config.following;
        let g = &config.geometry;
        let max = f64::from(f.max_error_m);
        FollowingState {
            limit_ticks: (
                (max / g.meters_per_tick_right()) as f32,
                (max / g.meters_per_tick_left()) as f32,
            ),
            periods: super::periods_of_ms(f.time_ms, config.rate_hz),
            ..FollowingState::default()
        }
    }

    /// Forgets the accumulated error (a new motion starts).
    pub(super) fn reset(&mut self) {
        self.error_ticks = (0.0, 0.0);
        self.peak_duty = (0.0, 0.0);
        self.over = (0, 0);
    }
}

impl Controller {
    /// Latches a fault and ends any motion.
    pub(super) fn latch(&mut self, fault: Fault) {
        if self.fault.is_none() {
            error!("fault: stopping motors");
        }
        self.fault = Some(fault);
        // An identification stopped by another fault still ends with its report (a finished one
        // keeps its statistics for its own report).
        if let Some(ActiveCheck::Identify(i)) = &self.check
            && !i.is_finished()
        {
            let failure = match fault {
                Fault::Identify(e) => Some(e),
                Fault::Stall { wheel } => Some(IdentifyFailure {
                    wheel,
                    problem: IdentifyProblem::Stalled,
                }),
                Fault::EncoderGlitch { wheel, .. } => Some(IdentifyFailure {
                    wheel,
                    problem: IdentifyProblem::EncoderGlitch,
                }),
                Fault::FollowingError { .. } | Fault::Overrun { .. } => None,
            };
            self.check_report = failure.map(CheckReport::IdentifyFailed);
        }
        self.discard_driven_run();
        self.drive = None;
        self.end_running_check();
        self.last_duty = (0.0, 0.0);
    }

    /// Following-error check for one period: `err` is the reference − measured count of the
    /// period that just ended, `duty` the wheel-frame duty just computed, per wheel.
    pub(super) fn check_following(&mut self, err: (f32, f32), duty: (f32, f32)) {
        let f = &mut self.following;
        f.error_ticks.0 += err.0;
        f.error_ticks.1 += err.1;
        // Duties are never NaN (the speed loop maps NaN to 0): a plain comparison suffices.
        let peak = |p: &mut f32, d: f32| {
            let d = libm::fabsf(d);
            if d > *p {
                *p = d;
            }
        };
        peak(&mut f.peak_duty.0, duty.0);
        peak(&mut f.peak_duty.1, duty.1);
        let limit = f.limit_ticks;
        let count = |c: &mut u32, e: f32, lim: f32| {
            *c = if libm::fabsf(e) > lim {
                c.saturating_add(1)
            } else {
                0
            };
            *c
        };
        let r = count(&mut f.over.0, f.error_ticks.0, limit.0);
        let l = count(&mut f.over.1, f.error_ticks.1, limit.1);
        let periods = f.periods;
        let (wheel, error, peak, limit) = if r >= periods {
            (Wheel::Right, f.error_ticks.0, f.peak_duty.0, limit.0)
        } else if l >= periods {
            (Wheel::Left, f.error_ticks.1, f.peak_duty.1, limit.1)
        } else {
            return;
        };
        // The bound is `max_error_m` in counts: its ratio converts counts to millimetres.
        let mm_per_tick = 1000.0 * self.config.following.max_error_m / limit;
        self.latch(Fault::FollowingError {
            wheel,
            error_mm: (error * mm_per_tick) as i32,
            peak_duty_pct: (libm::fminf(peak, 1.0) * 100.0 + 0.5) as u8,
        });
    }

    /// A wheel driven with at least `min_duty` in the last period that counted no tick.
    pub(super) fn check_stall(&mut self, dr: i64, dl: i64) {
        let min = self.config.stall.min_duty;
        let count = |c: &mut u32, duty: f32, d: i64| {
            if libm::fabsf(duty) >= min && d == 0 {
                *c = c.saturating_add(1);
            } else {
                *c = 0;
            }
            *c
        };
        let r = count(&mut self.stall_count.0, self.last_duty.0, dr);
        let l = count(&mut self.stall_count.1, self.last_duty.1, dl);
        if r >= self.stall_periods {
            self.latch(Fault::Stall {
                wheel: Wheel::Right,
            });
        } else if l >= self.stall_periods {
            self.latch(Fault::Stall { wheel: Wheel::Left });
        }
    }

    /// Clears a latched fault (the motors stay stopped until the next start or drive).
    pub fn clear_fault(&mut self) {
        self.fault = None;
        self.stall_count = (0, 0);
    }
}
