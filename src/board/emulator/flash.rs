//! The emulator's storage flash: the board's parameter sectors 1–2 and run sectors 10–11, kept
//! in the host file [`IMAGE`] (288 KiB: the 32 KiB parameter region, then the 256 KiB run
//! region; created erased by the test harness) through semihosting.
//!
//! It behaves as NOR flash, like the board's: erases of whole sectors that set every byte to
//! 0xFF, and writes that can only clear bits (a write ANDs into what is there). Offsets, sectors
//! and the store's layout are the board's ([`PARAM_SECTORS`], [`RUNS_RANGE`]), so the store is
//! configured exactly as on the board. QEMU's own flash model is ROM (writes are dropped), hence
//! the file.

use embedded_storage_async::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

use super::semihosting::HostFile;
use crate::board::f407::flash::{
    PARAM_A, PARAM_B, PARAM_SECTORS, RUNS_END, RUNS_RANGE, RUNS_START, SECTOR_BYTES, in_regions,
    whole_sectors,
};
use crate::storage::{MapConfig, ParamAndRunStore};

/// The flash image on the host, relative to the emulator's working directory.
pub const IMAGE: &core::ffi::CStr = c"odocal-params.img";

/// Size of the parameter region in [`IMAGE`] (it comes first), bytes.
const PARAM_BYTES: u32 = PARAM_B.end - PARAM_A.start;
/// Size of [`IMAGE`], bytes.
pub const IMAGE_BYTES: u32 = PARAM_BYTES + (RUNS_END - RUNS_START);

/// Bytes moved per semihosting call.
const CHUNK: usize = 256;

/// Why an access failed.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum EmulatorFlashError {
    /// Outside the two regions, or an erase of other than whole sectors.
    OutOfRange,
    /// The image file is missing, too small, or a host read/write failed.
    Host,
}

impl NorFlashError for EmulatorFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            EmulatorFlashError::OutOfRange => NorFlashErrorKind::OutOfBounds,
            EmulatorFlashError::Host => NorFlashErrorKind::Other,
        }
    }
}

/// The parameter and run sectors, backed by [`IMAGE`].
pub struct BoardFlash {
    file: Option<HostFile>,
}

impl BoardFlash {
    /// Opens the image; without it (or if it is not [`IMAGE_BYTES`] long) every access fails
    /// and the store falls back to the defaults, as with unreadable flash.
    pub fn open() -> Self {
        let file = HostFile::open(IMAGE).filter(|f| f.size() == Some(IMAGE_BYTES));
        if file.is_none() {
            warn!("emulator flash image missing or not 288 KiB: storage unavailable");
        }
        BoardFlash { file }
    }

    /// The image and the position of `offset` in it, if `offset .. offset + len` lies inside
    /// one region.
    fn file(&self, offset: u32, len: usize) -> Result<(&HostFile, u32), EmulatorFlashError> {
        if !in_regions(offset, len) {
            return Err(EmulatorFlashError::OutOfRange);
        }
        let at = if offset >= RUNS_START {
            PARAM_BYTES + (offset - RUNS_START)
        } else {
            offset - PARAM_A.start
        };
        self.file
            .as_ref()
            .map(|f| (f, at))
            .ok_or(EmulatorFlashError::Host)
    }
}

/// The parameter and run store on the emulated sectors (the board's layout and configuration).
pub fn param_store() -> ParamAndRunStore<BoardFlash> {
    ParamAndRunStore::from_config(
        BoardFlash::open(),
        PARAM_SECTORS,
        const { MapConfig::<BoardFlash>::new(RUNS_RANGE) },
    )
}

impl ErrorType for BoardFlash {
    type Error = EmulatorFlashError;
}

impl ReadNorFlash for BoardFlash {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let (file, at) = self.file(offset, bytes.len())?;
        if file.read_at(at, bytes) {
            Ok(())
        } else {
            Err(EmulatorFlashError::Host)
        }
    }

    fn capacity(&self) -> usize {
        RUNS_END as usize
    }
}

impl NorFlash for BoardFlash {
    const WRITE_SIZE: usize = 1;
    const ERASE_SIZE: usize = SECTOR_BYTES as usize;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if whole_sectors(from, to).is_none() {
            return Err(EmulatorFlashError::OutOfRange);
        }
        let (file, mut at) = self.file(from, (to - from) as usize)?;
        let erased = [0xFF_u8; CHUNK];
        let end = at + (to - from);
        while at < end {
            if !file.write_at(at, &erased) {
                return Err(EmulatorFlashError::Host);
            }
            at += CHUNK as u32;
        }
        Ok(())
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let (file, at) = self.file(offset, bytes.len())?;
        // NOR programming only clears bits: AND the new bytes into what is stored.
        let mut buf = [0u8; CHUNK];
        for (i, part) in bytes.chunks(CHUNK).enumerate() {
            let pos = at + (i * CHUNK) as u32;
            let old = &mut buf[..part.len()];
            if !file.read_at(pos, old) {
                return Err(EmulatorFlashError::Host);
            }
            for (o, n) in old.iter_mut().zip(part) {
                *o &= *n;
            }
            if !file.write_at(pos, old) {
                return Err(EmulatorFlashError::Host);
            }
        }
        Ok(())
    }
}

/// Bits only go 1 → 0 on a write, as on the STM32F4's flash.
impl MultiwriteNorFlash for BoardFlash {}
