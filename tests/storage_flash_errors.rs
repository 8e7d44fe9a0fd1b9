//! Flash driver errors during a save. The STM32F4's flash controller latches its error flags
//! (FLASH_SR) until software clears them, and the HAL never does: after one failed write every
//! later erase and write fails too. The board's driver clears them before each operation; the
//! store never wipes anything on a driver error (and never the parameter region at all), so a
//! failing flash keeps the last good record.

mod storage_support;

use embedded_storage_async::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use odocal::storage::StoreError;
use odocal::storage::ram_flash::RamFlashError;
use storage_support::{BoardFlash, STOPPED, board_store, calibrated};

/// A flash with the STM32's sticky error flags: `fail_write` makes the next write fail and
/// latches the flag; while latched, every erase and write fails. `clears_flags` models a driver
/// that clears the flags before each operation (the board's `BoardFlash`).
struct StickyFlash {
    inner: BoardFlash,
    fail_write: bool,
    latched: bool,
    clears_flags: bool,
    erases: u32,
}

#[derive(Debug)]
enum StickyError {
    Flash(RamFlashError),
    Latched,
}

impl NorFlashError for StickyError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            StickyError::Flash(e) => e.kind(),
            StickyError::Latched => NorFlashErrorKind::Other,
        }
    }
}

impl StickyFlash {
    fn new() -> Box<Self> {
        Box::new(StickyFlash {
            inner: BoardFlash::default(),
            fail_write: false,
            latched: false,
            clears_flags: false,
            erases: 0,
        })
    }

    fn before_operation(&mut self) -> Result<(), StickyError> {
        if self.clears_flags {
            self.latched = false;
        }
        if self.latched {
            Err(StickyError::Latched)
        } else {
            Ok(())
        }
    }
}

impl ErrorType for StickyFlash {
    type Error = StickyError;
}

impl ReadNorFlash for StickyFlash {
    const READ_SIZE: usize = 1;
    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.inner
            .read(offset, bytes)
            .await
            .map_err(StickyError::Flash)
    }
    fn capacity(&self) -> usize {
        self.inner.capacity()
    }
}

impl NorFlash for StickyFlash {
    const WRITE_SIZE: usize = 1;
    const ERASE_SIZE: usize = storage_support::SECTOR;
    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.before_operation()?;
        self.erases += 1;
        self.inner.erase(from, to).await.map_err(StickyError::Flash)
    }
    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.before_operation()?;
        if self.fail_write {
            self.fail_write = false;
            self.latched = true;
            return Err(StickyError::Latched);
        }
        self.inner
            .write(offset, bytes)
            .await
            .map_err(StickyError::Flash)
    }
}

impl MultiwriteNorFlash for StickyFlash {}

#[test]
fn a_driver_error_keeps_the_last_record_and_erases_nothing() {
    let mut flash = StickyFlash::new();
    {
        let mut store = board_store(&mut *flash);
        store.save_blocking(&calibrated(1), STOPPED).unwrap();
    }
    let erases_before = flash.erases;
    flash.fail_write = true;
    let mut store = board_store(&mut *flash);
    let err = store.save_blocking(&calibrated(2), STOPPED).unwrap_err();
    assert!(matches!(err, StoreError::Flash(_)), "{err:?}");
    assert_eq!(store.wipes(), 0, "a driver error must not wipe anything");
    let out = store.load_blocking();
    assert_eq!(out.warning, None);
    assert_eq!(out.record, calibrated(1), "the last good record is kept");
    assert_eq!(flash.erases, erases_before, "nothing was erased");
    // With the flags latched and nobody clearing them, every later save fails as well.
    let mut store = board_store(&mut *flash);
    assert!(store.save_blocking(&calibrated(3), STOPPED).is_err());
    assert_eq!(store.load_blocking().record, calibrated(1));
}

#[test]
fn a_driver_that_clears_the_flags_saves_again_after_an_error() {
    let mut flash = StickyFlash::new();
    flash.clears_flags = true;
    {
        let mut store = board_store(&mut *flash);
        store.save_blocking(&calibrated(1), STOPPED).unwrap();
    }
    flash.fail_write = true;
    let mut store = board_store(&mut *flash);
    assert!(store.save_blocking(&calibrated(2), STOPPED).is_err());
    assert_eq!(store.load_blocking().record, calibrated(1));
    store.save_blocking(&calibrated(3), STOPPED).unwrap();
    let out = store.load_blocking();
    assert_eq!(out.warning, None);
    assert_eq!(out.record, calibrated(3));
    assert_eq!(store.wipes(), 0);
}
