//! Two H-bridge channels driven by TIM1 PWM (20 kHz) plus a direction pin each and a shared
//! enable pin (sign-magnitude drive, e.g. a Cytron MD10C; an IN1/IN2 bridge such as the DRV8871
//! needs other wiring, see docs/hardware.md).
//!
//! Duty `d ∈ [-1, 1]`: `|d|` sets the compare value, the sign the DIR pin. The left motor is
//! mounted mirrored, so its DIR level is inverted in software. `Brake` drives both PWM outputs
//! low with the bridge enabled (low-side brake on sign-magnitude drivers); `Coast` disables the
//! bridge (outputs high-impedance).

use stm32f4xx_hal::gpio::{Output, PE7, PE8, PE13};
use stm32f4xx_hal::pac::TIM1;
use stm32f4xx_hal::timer::{C1, C2, PwmChannel, PwmHzManager};

use crate::motion::motor::{MotorDriver, StopMode, clamp_duty};

/// Whether the left motor's DIR level is inverted (mirrored mounting).
const LEFT_INVERTED: bool = true;

/// The board's motor outputs.
pub struct BoardMotors {
    _timer: PwmHzManager<TIM1>,
    right: PwmChannel<TIM1, C1>,
    left: PwmChannel<TIM1, C2>,
    dir_right: PE7<Output>,
    dir_left: PE8<Output>,
    enable: PE13<Output>,
    max_duty: u16,
}

impl BoardMotors {
    /// Takes the configured PWM timer, channels (already bound to their pins) and GPIOs; starts
    /// with both motors braked.
    pub fn new(
        timer: PwmHzManager<TIM1>,
        mut right: PwmChannel<TIM1, C1>,
        mut left: PwmChannel<TIM1, C2>,
        dir_right: PE7<Output>,
        dir_left: PE8<Output>,
        enable: PE13<Output>,
    ) -> Self {
        let max_duty = right.get_max_duty();
        right.set_duty(0);
        left.set_duty(0);
        right.enable();
        left.enable();
        let mut motors = BoardMotors {
            _timer: timer,
            right,
            left,
            dir_right,
            dir_left,
            enable,
            max_duty,
        };
        motors.stop(StopMode::Brake);
        motors
    }

    fn compare(&self, duty: f32) -> u16 {
        let magnitude = if duty < 0.0 { -duty } else { duty };
        (magnitude * f32::from(self.max_duty)) as u16
    }
}

impl MotorDriver for BoardMotors {
    fn set_duty(&mut self, right: f32, left: f32) {
        let (right, left) = (clamp_duty(right), clamp_duty(left));
        self.dir_right.set_state((right >= 0.0).into());
        self.dir_left
            .set_state(((left >= 0.0) != LEFT_INVERTED).into());
        let (cr, cl) = (self.compare(right), self.compare(left));
        self.right.set_duty(cr);
        self.left.set_duty(cl);
        self.enable.set_high();
    }

    fn stop(&mut self, mode: StopMode) {
        self.right.set_duty(0);
        self.left.set_duty(0);
        match mode {
            StopMode::Brake => self.enable.set_high(),
            StopMode::Coast => self.enable.set_low(),
        }
    }
}
