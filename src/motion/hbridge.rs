//! A sign-magnitude H-bridge pair (e.g. two Cytron MD10C channels) in embedded-hal 1.0 terms:
//! a PWM channel and a direction pin per motor and one shared enable pin. Any board whose HAL
//! implements [`SetDutyCycle`] and [`OutputPin`] drives its motors with it; the board only
//! hands over the configured channels and pins.
//!
//! Duty `d ∈ [-1, 1]`: `|d|` sets the compare value, the sign the DIR pin. A motor mounted
//! mirrored has its DIR level inverted ([`HBridge::new`]'s `invert_left`). `Brake` drives both
//! PWM outputs low with the bridge enabled (low-side brake on sign-magnitude drivers); `Coast`
//! disables the bridge (outputs high-impedance). An IN1/IN2 bridge such as the DRV8871 needs
//! another driver (docs/hardware.md).
//!
//! A reversal passes through zero duty: the STM32's compare registers are preloaded (a new
//! duty takes effect at the next PWM period) while a DIR pin changes at once, so flipping DIR with
//! the new duty would drive up to one PWM period of the old magnitude in the new direction (50 µs
//! at 20 kHz: a current spike into a motor still turning the other way). A channel that is to
//! reverse while it drives gets zero duty in that control period, its DIR unchanged; the next
//! control period flips DIR and sets the new duty. A control period is at least two PWM periods
//! ([`reversal_holds_zero`]), so the zero runs for at least one whole PWM period in between: a
//! reversal costs one control period (0.1–1 ms).
//!
//! Pin and PWM errors are ignored: the STM32 HAL's are `Infallible`, and a driver that could
//! fail has no better action in a control period than to try again in the next one.

use embedded_hal::digital::{OutputPin, PinState};
use embedded_hal::pwm::SetDutyCycle;

use super::motor::{MotorDriver, StopMode, clamp_duty};

/// Whether a zero duty written in one control period at `control_hz` has run for a whole PWM
/// period at `pwm_hz` before the next control period flips DIR: the zero is latched at the next
/// PWM update (within one PWM period) and must then last one more, so a control period must be
/// at least two PWM periods. Each board asserts it for its PWM and the fastest control rate.
pub const fn reversal_holds_zero(pwm_hz: u32, control_hz: u32) -> bool {
    pwm_hz >= 2 * control_hz
}

/// Two motors' PWM channels and direction pins and the shared enable pin.
pub struct HBridge<PR, PL, DR, DL, EN> {
    right: PR,
    left: PL,
    dir_right: DR,
    dir_left: DL,
    enable: EN,
    invert_left: bool,
    /// What each channel (right, left) was last given: forward (wheel frame), and its compare.
    applied: [(bool, u16); 2],
}

impl<PR, PL, DR, DL, EN> HBridge<PR, PL, DR, DL, EN>
where
    PR: SetDutyCycle,
    PL: SetDutyCycle,
    DR: OutputPin,
    DL: OutputPin,
    EN: OutputPin,
{
    /// Takes the enabled PWM channels (bound to their pins) and the output pins; starts with
    /// zero duty and the bridge disabled (coasting): the enable pin goes high only when the
    /// controller first commands the motors (a brake or a duty), never during the boot.
    /// `invert_left`: the left motor is mounted mirrored, so its DIR level
    /// is inverted.
    pub fn new(
        right: PR,
        left: PL,
        dir_right: DR,
        dir_left: DL,
        enable: EN,
        invert_left: bool,
    ) -> Self {
        let mut bridge = HBridge {
            right,
            left,
            dir_right,
            dir_left,
            enable,
            invert_left,
            applied: [(true, 0); 2],
        };
        bridge.stop(StopMode::Coast);
        bridge
    }

    /// The PWM compare value of `duty` (its magnitude) on a channel whose full scale is `max`.
    fn compare(duty: f32, max: u16) -> u16 {
        let magnitude = if duty < 0.0 { -duty } else { duty };
        (magnitude * f32::from(max)) as u16
    }

    /// What a channel that was last given `applied` (forward, compare) gets for `duty` of full
    /// scale `max` this period: its direction and compare, or zero in its old direction while
    /// it reverses from a nonzero duty.
    fn next(applied: (bool, u16), duty: f32, max: u16) -> (bool, u16) {
        let forward = duty >= 0.0;
        if forward != applied.0 && applied.1 != 0 {
            (applied.0, 0)
        } else {
            (forward, Self::compare(duty, max))
        }
    }
}

impl<PR, PL, DR, DL, EN> MotorDriver for HBridge<PR, PL, DR, DL, EN>
where
    PR: SetDutyCycle,
    PL: SetDutyCycle,
    DR: OutputPin,
    DL: OutputPin,
    EN: OutputPin,
{
    fn set_duty(&mut self, right: f32, left: f32) {
        let (right, left) = (clamp_duty(right), clamp_duty(left));
        let (fr, cr) = Self::next(self.applied[0], right, self.right.max_duty_cycle());
        let (fl, cl) = Self::next(self.applied[1], left, self.left.max_duty_cycle());
        self.applied = [(fr, cr), (fl, cl)];
        let _ = self.dir_right.set_state(PinState::from(fr));
        let _ = self
            .dir_left
            .set_state(PinState::from(fl != self.invert_left));
        let _ = self.right.set_duty_cycle(cr);
        let _ = self.left.set_duty_cycle(cl);
        let _ = self.enable.set_high();
    }

    fn stop(&mut self, mode: StopMode) {
        self.applied[0].1 = 0;
        self.applied[1].1 = 0;
        let _ = self.right.set_duty_cycle(0);
        let _ = self.left.set_duty_cycle(0);
        let _ = match mode {
            StopMode::Brake => self.enable.set_high(),
            StopMode::Coast => self.enable.set_low(),
        };
    }
}

#[cfg(test)]
mod tests {
    use core::convert::Infallible;
    use std::cell::RefCell;
    use std::rc::Rc;

    use super::*;

    /// Every pin and channel write, in order.
    type Log = Rc<RefCell<Vec<(&'static str, u16)>>>;

    struct Pwm(&'static str, Log);
    struct Pin(&'static str, Log);

    impl embedded_hal::pwm::ErrorType for Pwm {
        type Error = Infallible;
    }
    impl SetDutyCycle for Pwm {
        fn max_duty_cycle(&self) -> u16 {
            8_400
        }
        fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
            self.1.borrow_mut().push((self.0, duty));
            Ok(())
        }
    }
    impl embedded_hal::digital::ErrorType for Pin {
        type Error = Infallible;
    }
    impl OutputPin for Pin {
        fn set_low(&mut self) -> Result<(), Infallible> {
            self.1.borrow_mut().push((self.0, 0));
            Ok(())
        }
        fn set_high(&mut self) -> Result<(), Infallible> {
            self.1.borrow_mut().push((self.0, 1));
            Ok(())
        }
    }

    fn bridge(log: &Log) -> HBridge<Pwm, Pwm, Pin, Pin, Pin> {
        HBridge::new(
            Pwm("pwm_r", log.clone()),
            Pwm("pwm_l", log.clone()),
            Pin("dir_r", log.clone()),
            Pin("dir_l", log.clone()),
            Pin("en", log.clone()),
            true,
        )
    }

    #[test]
    fn it_starts_with_the_bridge_disabled() {
        let log = Log::default();
        let _ = bridge(&log);
        assert_eq!(*log.borrow(), [("pwm_r", 0), ("pwm_l", 0), ("en", 0)]);
    }

    #[test]
    fn duty_sets_magnitude_and_direction_with_the_left_motor_mirrored() {
        let log = Log::default();
        let mut b = bridge(&log);
        log.borrow_mut().clear();
        b.set_duty(0.5, 0.25);
        // Right forward: DIR high; left forward: DIR low (mirrored); 50 % and 25 % of 8,400.
        assert_eq!(
            *log.borrow(),
            [
                ("dir_r", 1),
                ("dir_l", 0),
                ("pwm_r", 4_200),
                ("pwm_l", 2_100),
                ("en", 1)
            ]
        );
        // Backward, beyond full scale (clamped) and NaN (zero), from a stop (a reversal while
        // driving passes through zero duty first: `reversal_passes_through_zero_duty`).
        b.stop(StopMode::Brake);
        log.borrow_mut().clear();
        b.set_duty(-2.0, f32::NAN);
        assert_eq!(
            *log.borrow(),
            [
                ("dir_r", 0),
                ("dir_l", 0),
                ("pwm_r", 8_400),
                ("pwm_l", 0),
                ("en", 1)
            ]
        );
    }

    /// Each control period's writes, as (DIR level, compare) per channel after the period: a
    /// channel that reverses while driving gets zero duty with its DIR unchanged for one
    /// control period, then the new DIR and duty; from zero (or after a stop) it reverses at
    /// once; a channel that keeps its direction is never held.
    #[test]
    fn reversal_passes_through_zero_duty() {
        let log = Log::default();
        let mut b = bridge(&log);
        let period = |b: &mut HBridge<Pwm, Pwm, Pin, Pin, Pin>, r: f32, l: f32| {
            log.borrow_mut().clear();
            b.set_duty(r, l);
            let log = log.borrow();
            let last = |name| log.iter().rev().find(|(n, _)| *n == name).unwrap().1;
            (last("dir_r"), last("pwm_r"), last("dir_l"), last("pwm_l"))
        };
        // Right forward 50 %, left forward 25 % (its DIR mirrored: low).
        assert_eq!(period(&mut b, 0.5, 0.25), (1, 4_200, 0, 2_100));
        // Right reverses; left goes on: right held at zero, DIR still forward.
        assert_eq!(period(&mut b, -0.5, 0.3), (1, 0, 0, 2_520));
        // Next period: right's DIR flips with its duty.
        assert_eq!(period(&mut b, -0.5, 0.3), (0, 4_200, 0, 2_520));
        // Both reverse at once: both held, then both flip.
        assert_eq!(period(&mut b, 0.25, -0.5), (0, 0, 0, 0));
        assert_eq!(period(&mut b, 0.25, -0.5), (1, 2_100, 1, 4_200));
        // Through a zero duty the direction changes at once.
        assert_eq!(period(&mut b, 0.0, 0.0), (1, 0, 1, 0));
        assert_eq!(period(&mut b, -0.25, 0.5), (0, 2_100, 0, 4_200));
        // After a stop (both compares zero) too.
        b.stop(StopMode::Brake);
        assert_eq!(period(&mut b, 0.25, -0.5), (1, 2_100, 1, 4_200));
        // The boards' PWM against the fastest control rate.
        assert!(reversal_holds_zero(20_000, 10_000));
        assert!(!reversal_holds_zero(15_000, 10_000));
    }

    #[test]
    fn coast_disables_the_bridge_and_brake_keeps_it_enabled_at_zero_duty() {
        let log = Log::default();
        let mut b = bridge(&log);
        log.borrow_mut().clear();
        b.stop(StopMode::Coast);
        assert_eq!(*log.borrow(), [("pwm_r", 0), ("pwm_l", 0), ("en", 0)]);
        log.borrow_mut().clear();
        b.stop(StopMode::Brake);
        assert_eq!(*log.borrow(), [("pwm_r", 0), ("pwm_l", 0), ("en", 1)]);
    }
}
