//! The safe state of the motor outputs, from reset to panic: the PWM pins PA8 (TIM1_CH1),
//! PA9 (TIM1_CH2) and the bridge enable PA1 driven low with pull-downs (the register work is
//! the family's [`crate::board::stm32f4::safe_state`]). The reset cause, crash record and
//! debug-halt freeze are the family's ([`crate::board::stm32f4::reset`]).

pub use crate::board::stm32f4::reset::{
    ResetCause, first_fault, freeze_when_halted, record_crash, reset_cause, take_crash,
};

crate::board::stm32f4::safe_state::motor_safety!(GPIOA, gpioa, 0, [8, 9, 1]);
