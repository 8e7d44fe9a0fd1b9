//! Flash map of the STM32F407VG (1 MiB) for the parameter and run store (target only); the
//! driver is the family's ([`crate::board::stm32f4::flash`]).
//!
//! Flash map (offsets from `0x0800_0000`, see this folder's `memory.x` and `docs/storage.md`):
//!
//! | sectors | offsets | use |
//! |---|---|---|
//! | 0 | `0x0_0000..0x0_4000` | vector table (the rest of the sector unused) |
//! | 1–2 | `0x0_4000..0x0_C000` ([`PARAM_SECTORS`]) | parameter region: two 16 KiB sectors used A/B |
//! | 3–9 | `0x0_C000..0xC_0000` | program (`.text` starts here: `_stext` in `memory.x`) |
//! | 10–11 | `0xC_0000..0x10_0000` ([`RUNS_RANGE`]) | run region: `sequential-storage` map, 2 × 128 KiB |
//!
//! The parameters sit on small sectors so that an erase of theirs stalls the CPU for a small
//! sector's erase time (16 KiB: 400 ms typical, 800 ms at most at the HAL's x8 parallelism,
//! datasheet DS8626 t_ERASE16KB) rather than a large one's (128 KiB: 2 s typical, 4 s at most;
//! `docs/storage.md`), and apart from the runs so that nothing done to the runs touches them.
//! The constants are checked at compile time (`crate::board::stm32f4::flash`); `memory.x`
//! checks the same addresses at link time.

use core::ops::Range;

pub use crate::board::stm32f4::flash::{BoardFlash, in_regions, param_store, whole_sectors};
pub use crate::board::stm32f4::param_sectors::{
    PARAM_A, PARAM_B, PARAM_SECTORS, SECTOR_BYTES, SMALL_SECTOR_BYTES, TEXT_START,
};

/// Total internal flash of the STM32F407VG, bytes.
pub const FLASH_BYTES: u32 = 1024 * 1024;
/// End of the program region (start of sector 10), offset from the flash base.
pub const PROGRAM_END: u32 = 0x000C_0000;
/// Start of the run region (sector 10), offset from the flash base.
pub const RUNS_START: u32 = 0x000C_0000;
/// End (exclusive) of the run region (end of sector 11), offset from the flash base.
pub const RUNS_END: u32 = 0x0010_0000;
/// The run region as the store's range (offsets understood by [`BoardFlash`]).
pub const RUNS_RANGE: Range<u32> = RUNS_START..RUNS_END;

/// The sectors [`BoardFlash`] may erase: (sector number, offsets).
pub const SECTORS: [(u8, Range<u32>); 4] = [
    (1, PARAM_A),
    (2, PARAM_B),
    (10, RUNS_START..RUNS_START + SECTOR_BYTES),
    (11, RUNS_START + SECTOR_BYTES..RUNS_END),
];
