//! Simulated storage flash: the board's parameter sectors 1–2 and run sectors 10–11 as a
//! [`RamFlash`] that outlives boots.
//!
//! [`SimParamFlash`] is the simulator's flash chip. Each simulated boot builds a fresh
//! [`ParamAndRunStore`] over it (as the firmware's `init` does) and loads the parameters; the contents
//! stay in the `SimParamFlash` between boots, and can be kept in an image file between runs of
//! the simulator (`--image`).
//!
//! Layout ([`SimFlash`]: 18 pages of 16 KiB, byte-programmable, STM32 write rule): pages 0–1 are
//! the parameter sectors 1–2 ([`SIM_PARAMS`]), pages 2–17 the run region (sectors 10–11,
//! [`SIM_RUNS`]). The run region's map pages by 16 KiB here, by 128 KiB on the board (the store
//! works the same with any page size; only the erase counts differ). An image file is the
//! parameter region then the run region, 288 KiB, as the emulator board's; a 256 KiB image of
//! older versions (sectors 10–11 only) is read as the run region, so its parameter record is
//! moved at the next boot as on a board.
//!
//! The `flash` subcommand ([`crate::commands::flash`]) shows it: `flash demo` boots an erased flash, saves a calibration,
//! reboots, runs many saves and reports wear, damages the flash and boots again; `flash show`,
//! `flash calibrate` and `flash reset` work on an image file.

use std::path::Path;

use odocal::storage::ram_flash::RamFlash;
use odocal::storage::{LoadOutcome, ParamAndRunStore, ParamSectors};

/// Size of one parameter sector (STM32F407 sectors 1 and 2), bytes, and the simulated flash's
/// page.
pub const SECTOR_BYTES: usize = 16 * 1024;

/// Pages of the simulated flash: 2 parameter sectors, then 256 KiB of run region.
pub const PAGES: usize = 2 + 256 * 1024 / SECTOR_BYTES;

/// The board's storage flash: parameter sectors and run region, byte-programmable, STM32 write
/// rule.
pub type SimFlash = RamFlash<PAGES, SECTOR_BYTES, 1>;

/// The parameter sectors inside [`SimFlash`] (pages 0 and 1).
pub const SIM_PARAMS: ParamSectors = ParamSectors::new(
    0..SECTOR_BYTES as u32,
    SECTOR_BYTES as u32..2 * SECTOR_BYTES as u32,
);

/// The run region inside [`SimFlash`] (the rest of it).
pub const SIM_RUNS: std::ops::Range<u32> = 2 * SECTOR_BYTES as u32..SimFlash::CAPACITY as u32;

/// Length of an image file of older versions (the run region alone, then shared).
const OLD_IMAGE_BYTES: usize = 256 * 1024;

/// The simulated flash chip; survives simulated reboots.
pub struct SimParamFlash {
    flash: Box<SimFlash>,
}

impl Default for SimParamFlash {
    fn default() -> Self {
        Self::erased()
    }
}

impl SimParamFlash {
    /// A factory-fresh (erased) flash.
    pub fn erased() -> Self {
        SimParamFlash {
            flash: Box::new(SimFlash::default()),
        }
    }

    /// Opens an image file; a missing file is an erased flash.
    pub fn open(path: &Path) -> std::io::Result<Self> {
        let mut sim = Self::erased();
        match std::fs::read(path) {
            Ok(bytes) if bytes.len() == OLD_IMAGE_BYTES => {
                let mut image = vec![0xFF; SimFlash::CAPACITY];
                image[SIM_RUNS.start as usize..].copy_from_slice(&bytes);
                sim.flash.restore_image(&image);
            }
            Ok(bytes) => sim.flash.restore_image(&bytes),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(e),
        }
        Ok(sim)
    }

    /// Writes the contents to an image file.
    pub fn write_image(&self, path: &Path) -> std::io::Result<()> {
        let mut image = vec![0u8; SimFlash::CAPACITY];
        self.flash.copy_image(&mut image);
        std::fs::write(path, image)
    }

    /// A store over the flash, as built by the firmware at boot.
    pub fn store(&mut self) -> ParamAndRunStore<&mut SimFlash> {
        // Whole pages of SimFlash, apart: a layout the store always accepts.
        match ParamAndRunStore::new(&mut *self.flash, SIM_PARAMS, SIM_RUNS) {
            Ok(store) => store,
            Err(e) => unreachable!("SIM_PARAMS and SIM_RUNS are valid for SimFlash: {e}"),
        }
    }

    /// A simulated boot: a fresh store loads the parameters (defaults + warning if unusable).
    pub fn boot(&mut self) -> LoadOutcome {
        self.store().load_blocking()
    }

    /// The flash itself (wear statistics, fault injection).
    pub fn chip(&mut self) -> &mut SimFlash {
        &mut self.flash
    }
}
