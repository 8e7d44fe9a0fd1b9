//! Two H-bridge channels driven by TIM1 PWM (20 kHz, channels 1 and 2) plus a direction pin each
//! and a shared enable pin (the pins are the board's) (sign-magnitude drive, e.g. a Cytron MD10C; an IN1/IN2 bridge such as the DRV8871
//! needs other wiring, see docs/hardware.md), through the portable
//! [`crate::motion::hbridge::HBridge`] (duty, direction, brake and coast are its rules; the
//! left motor is mounted mirrored, so its DIR level is inverted).

use embedded_hal::digital::OutputPin;
use stm32f4xx_hal::pac::TIM1;
use stm32f4xx_hal::timer::{C1, C2, PwmChannel, PwmHzManager};

use crate::motion::hbridge::HBridge;
use crate::motion::motor::{MotorDriver, StopMode};

/// Whether the left motor's DIR level is inverted (mirrored mounting).
const LEFT_INVERTED: bool = true;

/// TIM1 channels 1 and 2 with the board's DIR and enable pins.
type Bridge<DR, DL, EN> = HBridge<PwmChannel<TIM1, C1>, PwmChannel<TIM1, C2>, DR, DL, EN>;

/// The board's motor outputs: the portable sign-magnitude driver on TIM1's channels, with the
/// right and left DIR pins `DR`, `DL` and the bridge enable `EN`.
pub struct Tim1Motors<DR, DL, EN> {
    _timer: PwmHzManager<TIM1>,
    bridge: Bridge<DR, DL, EN>,
}

impl<DR: OutputPin, DL: OutputPin, EN: OutputPin> Tim1Motors<DR, DL, EN> {
    /// Takes the configured PWM timer, channels (already bound to their pins) and GPIOs; starts
    /// with zero duty and the bridge disabled until the controller's first command.
    pub fn new(
        timer: PwmHzManager<TIM1>,
        mut right: PwmChannel<TIM1, C1>,
        mut left: PwmChannel<TIM1, C2>,
        dir_right: DR,
        dir_left: DL,
        enable: EN,
    ) -> Self {
        right.set_duty(0);
        left.set_duty(0);
        right.enable();
        left.enable();
        Tim1Motors {
            _timer: timer,
            bridge: HBridge::new(right, left, dir_right, dir_left, enable, LEFT_INVERTED),
        }
    }
}

impl<DR: OutputPin, DL: OutputPin, EN: OutputPin> MotorDriver for Tim1Motors<DR, DL, EN> {
    fn set_duty(&mut self, right: f32, left: f32) {
        self.bridge.set_duty(right, left);
    }

    fn stop(&mut self, mode: StopMode) {
        self.bridge.stop(mode);
    }
}
