//! Board support for the STM32F407 (target only): pin map and HAL adapters.
//!
//! Pin map (STM32F4-Discovery class board, 8 MHz HSE, 168 MHz core):
//!
//! | function                  | peripheral      | pins                 |
//! |---------------------------|-----------------|----------------------|
//! | right encoder A/B         | TIM2 (32-bit)   | PA15 / PB3 (AF1)     |
//! | left encoder A/B          | TIM3 (16-bit)   | PB4 / PB5 (AF2)      |
//! | right motor PWM           | TIM1 CH1 20 kHz | PE9 (AF1)            |
//! | left motor PWM            | TIM1 CH2 20 kHz | PE11 (AF1)           |
//! | right / left motor DIR    | GPIO            | PE7 / PE8            |
//! | H-bridge enable (low = coast) | GPIO        | PE13                 |
//! | control tick 1 kHz        | TIM7            | —                    |
//! | serial 115200 8N1         | USART2          | PA2 TX / PA3 RX (ST-LINK VCP) |
//! | user button               | EXTI0           | PA0 (active high)    |
//! | heartbeat / fault LEDs    | GPIO            | PD12 green / PD14 red |
//! | parameters                | flash sectors 10–11 | 0x080C_0000..0x0810_0000 |
//!
//! Everything `unsafe` in the firmware lives here and carries a `// SAFETY:` note.

pub mod flash;
pub mod motors;
pub mod watchdog;

/// Core clock, Hz.
pub const SYSCLK_HZ: u32 = 168_000_000;
/// External crystal, Hz.
pub const HSE_HZ: u32 = 8_000_000;
/// Motor PWM frequency, Hz (above hearing, within the H-bridge's switching limit).
pub const PWM_HZ: u32 = 20_000;
/// Control and odometry rate, Hz.
pub const CONTROL_HZ: u32 = 1_000;
/// Independent watchdog timeout, ms: the control task feeds it every period.
pub const WATCHDOG_MS: u32 = 50;
/// Watchdog timeout while the parameter flash is written, ms. The HAL erases with x8
/// parallelism: a 128 KiB sector takes up to 4 s (STM32F407 datasheet, t_ERASE128KB) and stalls
/// the CPU. The timeout is computed for a 32 kHz LSI, which may run as fast as 47 kHz, so 10 s
/// gives at least 6.8 s.
pub const FLASH_WATCHDOG_MS: u32 = 10_000;
