//! Flash map of a 512 KiB STM32F4 part (the STM32F446RE of the NUCLEO-F446RE, the STM32F411CE
//! of the Black Pill F411CE: sectors 0–3 of 16 KiB, 4 of 64 KiB, 5–7 of 128 KiB) for the
//! parameter and run store; the driver is [`crate::board::stm32f4::flash`], which checks this map
//! at compile time (the board's `memory.x` checks the same addresses at link time).
//!
//! | sectors | offsets | use |
//! |---|---|---|
//! | 0 | `0x0_0000..0x0_4000` | vector table (the rest of the sector unused) |
//! | 1–2 | `0x0_4000..0x0_C000` ([`PARAM_SECTORS`]) | parameter region: two 16 KiB sectors used A/B |
//! | 3–5 | `0x0_C000..0x4_0000` | program (`.text` from sector 3; 16 + 64 + 128 = 208 KiB) |
//! | 6–7 | `0x4_0000..0x8_0000` ([`RUNS_RANGE`]) | run region: `sequential-storage` map, 2 × 128 KiB |
//!
//! The same split on every board: the parameters on small sectors (an erase stalls the CPU for a
//! 16 KiB sector's erase time, not a 128 KiB one's: docs/storage.md) and apart from the runs.

use core::ops::Range;

pub use crate::board::stm32f4::flash::{BoardFlash, param_store};
pub use crate::board::stm32f4::param_sectors::{
    PARAM_A, PARAM_B, PARAM_SECTORS, SECTOR_BYTES, SMALL_SECTOR_BYTES, TEXT_START,
};

/// Total internal flash, bytes.
pub const FLASH_BYTES: u32 = 512 * 1024;
/// End of the program region (start of sector 6), offset from the flash base.
pub const PROGRAM_END: u32 = 0x0004_0000;
/// Start of the run region (sector 6), offset from the flash base.
pub const RUNS_START: u32 = 0x0004_0000;
/// End (exclusive) of the run region (end of sector 7), offset from the flash base.
pub const RUNS_END: u32 = 0x0008_0000;
/// The run region as the store's range.
pub const RUNS_RANGE: Range<u32> = RUNS_START..RUNS_END;

/// The sectors [`BoardFlash`] may erase: (sector number, offsets).
pub const SECTORS: [(u8, Range<u32>); 4] = [
    (1, PARAM_A),
    (2, PARAM_B),
    (6, RUNS_START..RUNS_START + SECTOR_BYTES),
    (7, RUNS_START + SECTOR_BYTES..RUNS_END),
];
