//! Flash map: the 512 KiB parts' ([`crate::board::stm32f4::map_512k`]: parameters in sectors
//! 1–2, runs in sectors 6–7), checked against this folder's `memory.x` at link time.

pub use crate::board::stm32f4::map_512k::*;
