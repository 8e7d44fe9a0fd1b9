//! The internal flash of an STM32F4 as the parameter and run store (target only): the driver
//! every board shares. The map (which sectors hold what) is the board's own `flash` module,
//! [`crate::board::flash_map`]: its parameter region (two small sectors used A/B), its run region
//! (two or more 128 KiB sectors), and the sectors that may be erased. The map is checked here at
//! compile time; the board's `memory.x` checks the same addresses at link time.
//!
//! [`BoardFlash`] owns the HAL's [`LockedFlash`] and implements the async `embedded-storage` NOR
//! traits. It unlocks the flash controller only for the duration of one erase or write, and
//! refuses any access outside the two regions and any erase that is not whole sectors of them
//! (the map's `SECTORS`), so a logic error can never erase the program. Erase and program
//! busy-wait inside the HAL: an erase stalls instruction fetches (and so every interrupt), which
//! is why the store only writes while the motors are stopped.

use core::ops::Range;

use embedded_storage::nor_flash::{NorFlash as BlockingNorFlash, ReadNorFlash as BlockingRead};
use embedded_storage_async::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use stm32f4xx_hal::flash::{self as hal_flash, FlashExt, LockedFlash, UnlockedFlash};
use stm32f4xx_hal::pac::FLASH;

use crate::board::flash_map::{
    FLASH_BYTES, PARAM_A, PARAM_B, PARAM_SECTORS, PROGRAM_END, RUNS_END, RUNS_RANGE, RUNS_START,
    SECTOR_BYTES, SECTORS, SMALL_SECTOR_BYTES, TEXT_START,
};
use crate::storage::{FlashTooSmall, MapConfig, PARAM_DATA_MAX, ParamAndRunStore};

/// Base address of the internal flash in the memory map.
pub const FLASH_BASE: u32 = 0x0800_0000;

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
// Every erasable sector lies in one of the two regions, and the regions are whole sectors.
const _: () = {
    let mut i = 0;
    let mut covered = 0;
    while i < SECTORS.len() {
        let s = &SECTORS[i].1;
        assert!(
            (s.start >= PARAM_A.start && s.end <= PARAM_B.end)
                || (s.start >= RUNS_START && s.end <= RUNS_END),
            "an erasable sector outside the two regions"
        );
        covered += s.end - s.start;
        i += 1;
    }
    assert!(
        covered == (PARAM_B.end - PARAM_A.start) + (RUNS_END - RUNS_START),
        "the erasable sectors do not cover the two regions"
    );
};

/// Address of the flash size register (RM0090 §39.2: "Flash size", 16 bits, KiB).
const FLASH_SIZE_REGISTER: *const u16 = 0x1FFF_7A22 as *const u16;

/// The part's flash size in KiB, as its flash size register reports it (1024 on a
/// 1 MiB part, 512 on a 512 KiB one).
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

/// The parameter and run store on the board's parameter and run sectors. The layout is checked when the
/// firmware is built (`MapConfig::new` in a const block, the assertions above), so this cannot
/// fail at run time. On a part whose flash ends before the run region does (its flash size register
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
