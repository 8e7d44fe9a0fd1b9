//! Motor output: the interface between the wheel-speed controller and an H-bridge.
//!
//! Duty is a signed fraction of the supply: `+1.0` drives the wheel forward at full PWM, `-1.0`
//! backward, `0.0` off. Implementations clamp out-of-range values; the board implementation is
//! timer PWM at ≥ 20 kHz plus a direction pin per channel (see `board::motors`), host-sim's feeds
//! the simulated motors.

/// How to stop a motor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum StopMode {
    /// Short the motor windings: stops quickly, holds position weakly.
    Brake,
    /// Open the bridge: the wheel rolls out freely.
    Coast,
}

/// Two H-bridge channels, right and left wheel.
pub trait MotorDriver {
    /// Sets both duties in `[-1.0, 1.0]`, positive forward (values outside are clamped, NaN is 0).
    fn set_duty(&mut self, right: f32, left: f32);
    /// Stops both motors.
    fn stop(&mut self, mode: StopMode);
}

/// Clamps a duty to `[-1, 1]`, mapping NaN to 0.
#[inline]
pub fn clamp_duty(d: f32) -> f32 {
    if d.is_nan() {
        0.0
    } else {
        crate::util::num::clamp(d, -1.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clamps() {
        assert_eq!(clamp_duty(f32::NAN), 0.0);
        assert_eq!(clamp_duty(3.0), 1.0);
        assert_eq!(clamp_duty(-3.0), -1.0);
        assert_eq!(clamp_duty(0.25), 0.25);
    }
}
