//! Simulated parameter flash: the board's sectors 10–11 as a [`RamFlash`] that outlives boots.
//!
//! [`SimParamFlash`] is the simulator's flash chip. Each simulated boot builds a fresh
//! [`ParamStore`] over it (as the firmware's `init` does) and loads the parameters; the contents
//! stay in the `SimParamFlash` between boots, and can be kept in an image file between runs of
//! the simulator (`--image`).
//!
//! The `flash` subcommand ([`crate::commands::flash`]) shows it: `flash demo` boots an erased flash, saves a calibration,
//! reboots, runs many saves and reports wear, damages the flash and boots again; `flash show`,
//! `flash calibrate` and `flash reset` work on an image file.

use std::path::Path;

use odocal::storage::ram_flash::RamFlash;
use odocal::storage::{LoadOutcome, ParamStore};

/// Size of one parameter sector (STM32F407 sectors 10 and 11), bytes.
pub const SECTOR_BYTES: usize = 128 * 1024;

/// The board's parameter area: 2 × 128 KiB sectors, byte-programmable, STM32 write rule.
pub type SimFlash = RamFlash<2, SECTOR_BYTES, 1>;

/// The store's range inside [`SimFlash`] (the whole of it; offset 0 = sector 10).
pub const SIM_RANGE: std::ops::Range<u32> = 0..(2 * SECTOR_BYTES) as u32;

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
    pub fn store(&mut self) -> ParamStore<&mut SimFlash> {
        // SIM_RANGE is two whole sectors of SimFlash, which MapConfig always accepts.
        match ParamStore::new(&mut *self.flash, SIM_RANGE) {
            Ok(store) => store,
            Err(e) => unreachable!("SIM_RANGE is valid for SimFlash: {e}"),
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
