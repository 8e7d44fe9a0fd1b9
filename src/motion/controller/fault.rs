//! Faults: stall detection and the latched fault that keeps the motors stopped until cleared.

use core::fmt;

use super::Controller;

/// A wheel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Wheel {
    /// The right wheel.
    Right,
    /// The left wheel.
    Left,
}

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
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Fault::EncoderGlitch { wheel, delta } => {
                write!(f, "{wheel:?} encoder glitch ({delta} counts in one period)")
            }
            Fault::Stall { wheel } => write!(f, "{wheel:?} wheel stalled"),
        }
    }
}

impl Controller {
    /// Latches a fault and ends any motion.
    pub(super) fn latch(&mut self, fault: Fault) {
        if self.fault.is_none() {
            error!("fault: stopping motors");
        }
        self.fault = Some(fault);
        self.run = None;
        self.drive = None;
        self.last_duty = (0.0, 0.0);
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
