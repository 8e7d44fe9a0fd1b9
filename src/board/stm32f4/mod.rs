//! What every STM32F4 board of odocal shares, whatever its pin map: the parts are the same
//! peripherals at the same addresses on the STM32F407, STM32F446 and STM32F411 (reference
//! manuals RM0090, RM0390, RM0383), so a board folder uses them as they are.
//!
//! | module | what |
//! |---|---|
//! | [`clock`] | the external clock with the bounded wait and the fall-back to the HSI |
//! | [`console_rx`] | USART2's receive half by DMA1 stream 5 channel 4 into a ring (the same request mapping on the three parts) |
//! | [`flash`] | the parameter and run store's flash driver, over the board's flash map |
//! | [`motors`] | two H-bridge channels on TIM1 channels 1 and 2, with the board's DIR and enable pins |
//! | [`reset`] | reset cause, crash record, fault guard, debug-halt freeze |
//! | [`safe_state`] | the motor pins' safe state and emergency stop for PWM and enable pins on one port |
//! | [`timers`] | the encoders (TIM2, TIM3), the control-period tick, the encoder input filter and pull-ups |
//! | [`watchdog`] | the independent watchdog's timeout changes |

pub mod clock;
pub mod console_rx;
pub mod flash;
pub mod motors;
pub mod reset;
pub mod safe_state;
pub mod timers;
pub mod watchdog;
