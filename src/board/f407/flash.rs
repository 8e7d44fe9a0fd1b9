//! Internal flash of the STM32F407VG for the parameter and run store (target only).
//!
//! Flash map (offsets from `0x0800_0000`, see `memory.x` and `docs/storage.md`):
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
//! The constants below are checked at compile time; `memory.x` checks the same addresses at
//! link time.
//!
//! [`BoardFlash`] owns the HAL's [`LockedFlash`] and implements the async `embedded-storage` NOR
//! traits. It unlocks the flash controller only for the duration of one erase or write, and
//! refuses any access outside the two regions and any erase that is not whole sectors of them
//! ([`SECTORS`]), so a logic error can never erase the program. Erase and program busy-wait
//! inside the HAL: an erase stalls instruction fetches (and so every interrupt), which is why
//! the store only writes while the motors are stopped.

use core::ops::Range;

use embedded_storage::nor_flash::{NorFlash as BlockingNorFlash, ReadNorFlash as BlockingRead};
use embedded_storage_async::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use stm32f4xx_hal::flash::{self as hal_flash, FlashExt, LockedFlash, UnlockedFlash};
use stm32f4xx_hal::pac::FLASH;

use crate::storage::{FlashTooSmall, MapConfig, PARAM_DATA_MAX, ParamAndRunStore, ParamSectors};

/// Base address of the internal flash in the memory map.
pub const FLASH_BASE: u32 = 0x0800_0000;
/// Total internal flash of the STM32F407VG, bytes.
pub const FLASH_BYTES: u32 = 1024 * 1024;
/// Size of sectors 0–3, bytes (the parameter region's erase unit).
pub const SMALL_SECTOR_BYTES: u32 = 16 * 1024;
/// Size of sectors 5–11, bytes (the run region's erase unit, `BoardFlash::ERASE_SIZE`).
pub const SECTOR_BYTES: u32 = 128 * 1024;
/// Parameter sector A (sector 1), offsets from [`FLASH_BASE`].
pub const PARAM_A: Range<u32> = 0x0000_4000..0x0000_8000;
/// Parameter sector B (sector 2), offsets from [`FLASH_BASE`].
pub const PARAM_B: Range<u32> = 0x0000_8000..0x0000_C000;
/// The parameter region: sectors 1 and 2, used A/B.
pub const PARAM_SECTORS: ParamSectors = ParamSectors::new(PARAM_A, PARAM_B);
/// Start of the program's code (`_stext` in `memory.x`): sector 3.
pub const TEXT_START: u32 = PARAM_B.end;
/// End of the program region (start of sector 10), offset from [`FLASH_BASE`].
pub const PROGRAM_END: u32 = 0x000C_0000;
/// Start of the run region (sector 10), offset from [`FLASH_BASE`].
pub const RUNS_START: u32 = 0x000C_0000;
/// End (exclusive) of the run region (end of sector 11), offset from [`FLASH_BASE`].
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

const _: () = assert!(
    PARAM_A.end - PARAM_A.start == SMALL_SECTOR_BYTES
        && PARAM_B.end - PARAM_B.start == SMALL_SECTOR_BYTES
        && PARAM_A.start == SMALL_SECTOR_BYTES
        && PARAM_B.start == PARAM_A.end,
    "parameter region must be sectors 1 and 2"
);
const _: () = assert!(
    PARAM_SECTORS.valid(1, PARAM_DATA_MAX),
    "parameter sectors too small for a record"
);
const _: () = assert!(
    RUNS_START.is_multiple_of(SECTOR_BYTES) && RUNS_END.is_multiple_of(SECTOR_BYTES),
    "run region must be 128 KiB-sector aligned"
);
const _: () = assert!(
    TEXT_START <= PROGRAM_END && PROGRAM_END <= RUNS_START,
    "run region overlaps the program"
);
const _: () = assert!(RUNS_END <= FLASH_BYTES, "run region beyond flash");
const _: () = assert!(
    RUNS_END - RUNS_START >= 2 * SECTOR_BYTES,
    "sequential-storage needs at least two sectors"
);

/// Address of the flash size register (RM0090 §39.2: "Flash size", 16 bits, KiB).
const FLASH_SIZE_REGISTER: *const u16 = 0x1FFF_7A22 as *const u16;

/// The part's flash size in KiB, as its flash size register reports it (1024 on an
/// STM32F407VG, 512 on an STM32F407VE).
#[inline(never)]
pub fn flash_size_kib() -> u16 {
    // SAFETY: a 16-bit read of a read-only system-memory register that every STM32F4 has.
    unsafe { core::ptr::read_volatile(FLASH_SIZE_REGISTER) }
}

/// Whether `offset .. offset + len` lies inside one of the two regions.
pub fn in_regions(offset: u32, len: usize) -> bool {
    let end = u32::try_from(len)
        .ok()
        .and_then(|len| offset.checked_add(len));
    match end {
        Some(end) => {
            (offset >= PARAM_A.start && end <= PARAM_B.end)
                || (offset >= RUNS_START && end <= RUNS_END)
        }
        None => false,
    }
}

/// The sectors that make up exactly `from..to` (in order), or `None` if the range is not
/// whole sectors of [`SECTORS`].
pub fn whole_sectors(
    from: u32,
    to: u32,
) -> Option<impl Iterator<Item = &'static (u8, Range<u32>)>> {
    let mut at = from;
    while at < to {
        let (_, s) = SECTORS.iter().find(|(_, s)| s.start == at)?;
        if s.end > to {
            return None;
        }
        at = s.end;
    }
    (from <= to).then(|| {
        SECTORS
            .iter()
            .filter(move |(_, s)| s.start >= from && s.end <= to)
    })
}

/// The parameter and run store on sectors 1–2 and 10–11. The layout is checked when the
/// firmware is built (`MapConfig::new` in a const block, the assertions above), so this cannot
/// fail at run time. On a part whose flash ends before sector 11 does (its flash size register
/// says so), the store never touches the flash: boot uses the defaults and says why, `save`
/// answers with an error.
pub fn param_store(flash: FLASH) -> ParamAndRunStore<BoardFlash> {
    let runs = const { MapConfig::<BoardFlash>::new(RUNS_RANGE) };
    let part_kib = u32::from(flash_size_kib());
    let needed_kib = RUNS_END / 1024;
    if part_kib < needed_kib {
        error!(
            "this part has {} KiB of flash, the storage map needs {} KiB: storage disabled",
            part_kib, needed_kib
        );
        return ParamAndRunStore::without_flash(
            BoardFlash::new(flash),
            PARAM_SECTORS,
            runs,
            FlashTooSmall {
                part_kib,
                needed_kib,
            },
        );
    }
    ParamAndRunStore::from_config(BoardFlash::new(flash), PARAM_SECTORS, runs)
}

/// Why a [`BoardFlash`] access failed.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum BoardFlashError {
    /// The access reaches outside the two regions, or an erase is not whole sectors of them.
    OutOfRange,
    /// The HAL reported a programming or erase error.
    Hal(HalError),
}

/// The HAL's flash error, mirrored so it can be logged with defmt.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum HalError {
    /// Programming sequence error (PGSERR).
    ProgrammingSequence,
    /// Programming parallelism error (PGPERR).
    ProgrammingParallelism,
    /// Programming alignment error (PGAERR).
    ProgrammingAlignment,
    /// Write protection error (WRPERR).
    WriteProtection,
    /// Operation error (OPERR).
    Operation,
}

impl From<hal_flash::Error> for BoardFlashError {
    fn from(e: hal_flash::Error) -> Self {
        BoardFlashError::Hal(match e {
            hal_flash::Error::ProgrammingSequence => HalError::ProgrammingSequence,
            hal_flash::Error::ProgrammingParallelism => HalError::ProgrammingParallelism,
            hal_flash::Error::ProgrammingAlignment => HalError::ProgrammingAlignment,
            hal_flash::Error::WriteProtection => HalError::WriteProtection,
            hal_flash::Error::Operation => HalError::Operation,
        })
    }
}

impl NorFlashError for BoardFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            BoardFlashError::OutOfRange => NorFlashErrorKind::OutOfBounds,
            BoardFlashError::Hal(HalError::ProgrammingAlignment) => NorFlashErrorKind::NotAligned,
            BoardFlashError::Hal(_) => NorFlashErrorKind::Other,
        }
    }
}

/// The internal flash, restricted to the parameter and run regions.
///
/// Offsets are relative to [`FLASH_BASE`] (as in the HAL). `ERASE_SIZE` is the run region's
/// 128 KiB sector, the page of its `sequential-storage` map; like the HAL's own flash driver,
/// `erase` also takes the smaller sectors (here only the parameter region's, whole).
pub struct BoardFlash {
    flash: LockedFlash,
}

impl BoardFlash {
    /// Takes the flash controller. The flash stays locked except during an erase or a write.
    pub fn new(flash: FLASH) -> Self {
        BoardFlash {
            flash: LockedFlash::new(flash),
        }
    }

    /// Clears the flash controller's sticky error flags (FLASH_SR: PGSERR, PGPERR, PGAERR,
    /// WRPERR, OPERR; written 1 to clear, RM0090 §3.9.6). The HAL checks them after each
    /// operation but never clears them, so one error would fail every later erase and write.
    fn clear_error_flags() {
        const ERRORS: u32 = (1 << 7) | (1 << 6) | (1 << 5) | (1 << 4) | (1 << 1);
        // SAFETY: a write-1-to-clear of status bits of FLASH_SR; it changes no other state and
        // no flash operation is in progress (the store runs one operation at a time).
        unsafe { (*FLASH::ptr()).sr().write(|w| w.bits(ERRORS)) };
    }

    /// Resets the instruction and data caches after an erase (RM0090 §3.5.2: a cache line may
    /// still hold the erased contents). Caches are disabled, reset, and enabled again.
    fn reset_caches() {
        const ICEN: u32 = 1 << 9;
        const DCEN: u32 = 1 << 10;
        const ICRST: u32 = 1 << 11;
        const DCRST: u32 = 1 << 12;
        // SAFETY: FLASH_ACR read-modify-writes of the cache enable and reset bits only; the
        // latency and prefetch bits are written back unchanged. Instruction fetch continues
        // (uncached) while the caches are off.
        unsafe {
            let acr = (*FLASH::ptr()).acr();
            let was = acr.read().bits();
            acr.write(|w| w.bits(was & !(ICEN | DCEN)));
            acr.write(|w| w.bits((was & !(ICEN | DCEN)) | ICRST | DCRST));
            acr.write(|w| w.bits(was & !(ICRST | DCRST)));
        }
    }

    /// Checks that `offset .. offset + len` lies inside the two regions.
    fn check(offset: u32, len: usize) -> Result<(), BoardFlashError> {
        if in_regions(offset, len) {
            Ok(())
        } else {
            Err(BoardFlashError::OutOfRange)
        }
    }
}

impl ErrorType for BoardFlash {
    type Error = BoardFlashError;
}

impl ReadNorFlash for BoardFlash {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        Self::check(offset, bytes.len())?;
        BlockingRead::read(&mut self.flash, offset, bytes).map_err(BoardFlashError::from)
    }

    fn capacity(&self) -> usize {
        RUNS_END as usize
    }
}

impl NorFlash for BoardFlash {
    /// The HAL programs byte by byte (x8 parallelism), so any length and alignment works.
    const WRITE_SIZE: usize = 1;
    const ERASE_SIZE: usize = SECTOR_BYTES as usize;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let sectors = whole_sectors(from, to).ok_or(BoardFlashError::OutOfRange)?;
        Self::clear_error_flags();
        let result = {
            let mut unlocked = self.flash.unlocked();
            sectors.into_iter().try_for_each(|(number, _)| {
                UnlockedFlash::erase(&mut unlocked, *number).map_err(BoardFlashError::from)
            })
            // `unlocked` drops here and locks the flash again.
        };
        Self::reset_caches();
        result
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        Self::check(offset, bytes.len())?;
        Self::clear_error_flags();
        let mut unlocked = self.flash.unlocked();
        BlockingNorFlash::write(&mut unlocked, offset, bytes).map_err(BoardFlashError::from)
    }
}

/// The STM32F4 flash has no ECC: a byte may be programmed again as long as bits only go 1 → 0
/// (the HAL declares the same for its `UnlockedFlash`).
impl MultiwriteNorFlash for BoardFlash {}
