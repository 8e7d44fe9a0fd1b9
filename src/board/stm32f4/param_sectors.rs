//! The sector layout every STM32F4 part shares at the start of its flash (sectors 0–3 of 16 KiB,
//! 4 of 64 KiB, 128 KiB from 5 on) and the parameter region every board puts on it: sectors 1
//! and 2, used A/B, with the program from sector 3. A board's flash map adds its size and its
//! run region.

use core::ops::Range;

use crate::storage::ParamSectors;

/// Size of sectors 0–3, bytes (the parameter region's erase unit).
pub const SMALL_SECTOR_BYTES: u32 = 16 * 1024;
/// Size of the sectors from 5 on, bytes (the run region's erase unit, `BoardFlash::ERASE_SIZE`).
pub const SECTOR_BYTES: u32 = 128 * 1024;
/// Parameter sector A (sector 1), offsets from the flash base.
pub const PARAM_A: Range<u32> = 0x0000_4000..0x0000_8000;
/// Parameter sector B (sector 2), offsets from the flash base.
pub const PARAM_B: Range<u32> = 0x0000_8000..0x0000_C000;
/// The parameter region: sectors 1 and 2, used A/B.
pub const PARAM_SECTORS: ParamSectors = ParamSectors::new(PARAM_A, PARAM_B);
/// Start of the program's code (`_stext` in `memory.x`): sector 3.
pub const TEXT_START: u32 = PARAM_B.end;
