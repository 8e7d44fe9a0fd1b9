//! Internal flash of the STM32F407VG for the parameter store (target only).
//!
//! Flash map (offsets from `0x0800_0000`, see `memory.x`): sectors 0–9 (768 KiB) hold the
//! program; sectors 10–11 (`PARAMS_START..PARAMS_END`, 2 × 128 KiB) are reserved for
//! `sequential-storage` and never touched by the linker. The constants below are checked at
//! compile time; `memory.x` checks its `PARAMS` region against the same addresses at link time.
//!
//! [`BoardFlash`] owns the HAL's [`LockedFlash`] and implements the async `embedded-storage` NOR
//! traits that `sequential-storage` needs. It unlocks the flash controller only for the duration
//! of one erase or write, and refuses any access outside the parameter sectors, so a logic error
//! can never erase the program. Erase and program busy-wait inside the HAL: a 128 KiB sector
//! erase stalls instruction fetches (and so every interrupt) for about 2 s, up to 4 s (datasheet
//! t_ERASE128KB at x8 parallelism, which the HAL uses), which is why the store only writes while
//! the motors are stopped.

use core::ops::Range;

use embedded_storage::nor_flash::{NorFlash as BlockingNorFlash, ReadNorFlash as BlockingRead};
use embedded_storage_async::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use stm32f4xx_hal::flash::{self as hal_flash, FlashExt, LockedFlash};
use stm32f4xx_hal::pac::FLASH;

use crate::storage::{FlashTooSmall, MapConfig, ParamStore};

/// Base address of the internal flash in the memory map.
pub const FLASH_BASE: u32 = 0x0800_0000;
/// Total internal flash of the STM32F407VG, bytes.
pub const FLASH_BYTES: u32 = 1024 * 1024;
/// Size of sectors 5–11, bytes (the erase unit of the parameter area).
pub const SECTOR_BYTES: u32 = 128 * 1024;
/// Flash reserved for the program (`FLASH` length in `memory.x`), bytes.
pub const PROGRAM_BYTES: u32 = 768 * 1024;
/// Start of the parameter area (sector 10), offset from [`FLASH_BASE`].
pub const PARAMS_START: u32 = 0x000C_0000;
/// End (exclusive) of the parameter area (end of sector 11), offset from [`FLASH_BASE`].
pub const PARAMS_END: u32 = 0x0010_0000;

const _: () = assert!(
    PARAMS_START.is_multiple_of(SECTOR_BYTES) && PARAMS_END.is_multiple_of(SECTOR_BYTES),
    "parameter area must be 128 KiB-sector aligned"
);
const _: () = assert!(
    PARAMS_START >= PROGRAM_BYTES,
    "parameter area overlaps the program"
);
const _: () = assert!(PARAMS_END <= FLASH_BYTES, "parameter area beyond flash");
const _: () = assert!(
    PARAMS_END - PARAMS_START >= 2 * SECTOR_BYTES,
    "sequential-storage needs at least two sectors"
);

/// The parameter area as the store's range (offsets understood by [`BoardFlash`]).
pub const PARAMS_RANGE: Range<u32> = PARAMS_START..PARAMS_END;

/// Address of the flash size register (RM0090 §39.2: "Flash size", 16 bits, KiB).
const FLASH_SIZE_REGISTER: *const u16 = 0x1FFF_7A22 as *const u16;

/// The part's flash size in KiB, as its flash size register reports it (1024 on an
/// STM32F407VG, 512 on an STM32F407VE).
#[inline(never)]
pub fn flash_size_kib() -> u16 {
    // SAFETY: a 16-bit read of a read-only system-memory register that every STM32F4 has.
    unsafe { core::ptr::read_volatile(FLASH_SIZE_REGISTER) }
}

/// The parameter store on sectors 10–11. The range is checked when the firmware is built
/// (`MapConfig::new` in a const block), so this cannot fail at run time. On a part whose flash
/// ends before sector 11 does (its flash size register says so), the store never touches the
/// flash: boot uses the defaults and says why, `save` answers with an error.
pub fn param_store(flash: FLASH) -> ParamStore<BoardFlash> {
    let config = const { MapConfig::<BoardFlash>::new(PARAMS_RANGE) };
    let part_kib = u32::from(flash_size_kib());
    let needed_kib = PARAMS_END / 1024;
    if part_kib < needed_kib {
        error!(
            "this part has {} KiB of flash, the storage map needs {} KiB: storage disabled",
            part_kib, needed_kib
        );
        return ParamStore::without_flash(
            BoardFlash::new(flash),
            config,
            FlashTooSmall {
                part_kib,
                needed_kib,
            },
        );
    }
    ParamStore::from_config(BoardFlash::new(flash), config)
}

/// Why a [`BoardFlash`] access failed.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum BoardFlashError {
    /// The access reaches outside the parameter sectors, or is misaligned for an erase.
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

/// The internal flash, restricted to the parameter sectors.
///
/// Offsets are relative to [`FLASH_BASE`] (as in the HAL), so the store's range is
/// [`PARAMS_RANGE`].
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

    /// Checks that `offset .. offset + len` lies inside the parameter sectors.
    fn check(offset: u32, len: usize) -> Result<(), BoardFlashError> {
        let end = u32::try_from(len)
            .ok()
            .and_then(|len| offset.checked_add(len));
        match end {
            Some(end) if offset >= PARAMS_START && end <= PARAMS_END => Ok(()),
            _ => Err(BoardFlashError::OutOfRange),
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
        PARAMS_END as usize
    }
}

impl NorFlash for BoardFlash {
    /// The HAL programs byte by byte (x8 parallelism), so any length and alignment works.
    const WRITE_SIZE: usize = 1;
    const ERASE_SIZE: usize = SECTOR_BYTES as usize;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if from > to || !from.is_multiple_of(SECTOR_BYTES) || !to.is_multiple_of(SECTOR_BYTES) {
            return Err(BoardFlashError::OutOfRange);
        }
        Self::check(from, (to - from) as usize)?;
        Self::clear_error_flags();
        let result = {
            let mut unlocked = self.flash.unlocked();
            BlockingNorFlash::erase(&mut unlocked, from, to).map_err(BoardFlashError::from)
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
