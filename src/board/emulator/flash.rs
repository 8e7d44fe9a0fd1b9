//! The emulator's parameter flash: sectors 10–11 of the board's map, kept in the host file
//! [`IMAGE`] (256 KiB, created erased by the test harness) through semihosting.
//!
//! It behaves as NOR flash, like the board's: 128 KiB erase sectors that set every byte to 0xFF,
//! and writes that can only clear bits (a write ANDs into what is there). Offsets and the store's
//! range are the board's ([`PARAMS_RANGE`]), so the parameter store is configured exactly as on
//! the board. QEMU's own flash model is ROM (writes are dropped), hence the file.

use embedded_storage_async::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

use super::semihosting::HostFile;
use crate::board::f407::flash::{PARAMS_END, PARAMS_RANGE, PARAMS_START, SECTOR_BYTES};
use crate::storage::{MapConfig, ParamStore};

/// The flash image on the host, relative to the emulator's working directory.
pub const IMAGE: &core::ffi::CStr = c"odocal-params.img";

/// Bytes moved per semihosting call.
const CHUNK: usize = 256;

/// Why an access failed.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum EmulatorFlashError {
    /// Outside the parameter sectors, or a misaligned erase.
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

/// The parameter sectors, backed by [`IMAGE`].
pub struct BoardFlash {
    file: Option<HostFile>,
}

impl BoardFlash {
    /// Opens the image; without it (or if it is shorter than the two sectors) every access fails
    /// and the store falls back to the defaults, as with unreadable flash.
    pub fn open() -> Self {
        let file = HostFile::open(IMAGE).filter(|f| f.size() == Some(PARAMS_END - PARAMS_START));
        if file.is_none() {
            warn!("emulator flash image missing or not 256 KiB: storage unavailable");
        }
        BoardFlash { file }
    }

    fn file(&self, offset: u32, len: usize) -> Result<(&HostFile, u32), EmulatorFlashError> {
        let end = u32::try_from(len)
            .ok()
            .and_then(|len| offset.checked_add(len));
        match end {
            Some(end) if offset >= PARAMS_START && end <= PARAMS_END => self
                .file
                .as_ref()
                .map(|f| (f, offset - PARAMS_START))
                .ok_or(EmulatorFlashError::Host),
            _ => Err(EmulatorFlashError::OutOfRange),
        }
    }
}

/// The parameter store on the emulated sectors (the board's range and configuration).
pub fn param_store() -> ParamStore<BoardFlash> {
    ParamStore::from_config(
        BoardFlash::open(),
        const { MapConfig::<BoardFlash>::new(PARAMS_RANGE) },
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
        PARAMS_END as usize
    }
}

impl NorFlash for BoardFlash {
    const WRITE_SIZE: usize = 1;
    const ERASE_SIZE: usize = SECTOR_BYTES as usize;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if from > to || !from.is_multiple_of(SECTOR_BYTES) || !to.is_multiple_of(SECTOR_BYTES) {
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
