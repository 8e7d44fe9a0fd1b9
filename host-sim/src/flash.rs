//! Simulated parameter flash: the board's sectors 10–11 as a [`RamFlash`] that outlives boots.
//!
//! [`SimParamFlash`] is the simulator's flash chip. Each simulated boot builds a fresh
//! [`ParamStore`] over it (as the firmware's `init` does) and loads the parameters; the contents
//! stay in the `SimParamFlash` between boots, and can be kept in an image file between runs of
//! the simulator (`--image`).
//!
//! The `flash` subcommand shows it: `flash demo` boots an erased flash, saves a calibration,
//! reboots, runs many saves and reports wear, damages the flash and boots again; `flash show`,
//! `flash calibrate` and `flash reset` work on an image file.

use std::path::{Path, PathBuf};

use clap::{Args, Subcommand};
use odocal::geometry::Geometry;
use odocal::storage::ram_flash::RamFlash;
use odocal::storage::{
    Calibration, LoadOutcome, MethodName, MotionSettings, ParamRecord, ParamStore,
};

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

/// Arguments of the `flash` subcommand.
#[derive(Args, Debug)]
pub struct FlashArgs {
    #[command(subcommand)]
    action: FlashAction,
}

#[derive(Subcommand, Debug)]
enum FlashAction {
    /// Boot, save, reboot, wear and damage an in-memory flash; print what each boot loads.
    Demo {
        /// Consecutive saves for the wear report.
        #[arg(long, default_value_t = 2_000)]
        saves: u32,
    },
    /// Boot from an image file and print the parameters it loads.
    Show {
        /// Flash image file (missing = erased flash).
        #[arg(long)]
        image: PathBuf,
    },
    /// Boot from an image, store a calibration of the nominal geometry, write the image back.
    Calibrate {
        /// Flash image file (missing = erased flash; created).
        #[arg(long)]
        image: PathBuf,
        /// Diameter ratio E_d = D_R / D_L.
        #[arg(long)]
        e_d: f64,
        /// Wheelbase factor E_b = b / b_nominal.
        #[arg(long)]
        e_b: f64,
        /// Mean-diameter scale E_s.
        #[arg(long, default_value_t = 1.0)]
        e_s: f64,
        /// Method name to record (≤ 12 printable ASCII).
        #[arg(long, default_value = "manual")]
        method: String,
    },
    /// Store the default parameters in an image file.
    Reset {
        /// Flash image file (missing = erased flash; created).
        #[arg(long)]
        image: PathBuf,
    },
}

/// Runs the `flash` subcommand.
pub fn run(args: FlashArgs) -> Result<(), Box<dyn std::error::Error>> {
    match args.action {
        FlashAction::Demo { saves } => demo(saves),
        FlashAction::Show { image } => {
            let mut sim = SimParamFlash::open(&image)?;
            print_boot("boot", &sim.boot());
            Ok(())
        }
        FlashAction::Calibrate {
            image,
            e_d,
            e_b,
            e_s,
            method,
        } => {
            let mut sim = SimParamFlash::open(&image)?;
            let mut record = sim.boot().record;
            record.calibration = Calibration {
                e_d,
                e_b,
                e_s,
                geometry: record.nominal.with_factors(e_d, e_b, e_s),
                method: MethodName::new(&method).map_err(|e| format!("method: {e}"))?,
                runs: 0,
                predicted_e_max_m: 0.0,
            };
            sim.store().save_blocking(&record, true)?;
            sim.write_image(&image)?;
            print_boot("saved; next boot", &sim.boot());
            Ok(())
        }
        FlashAction::Reset { image } => {
            let mut sim = SimParamFlash::open(&image)?;
            sim.store().reset_to_defaults_blocking(true)?;
            sim.write_image(&image)?;
            print_boot("reset; next boot", &sim.boot());
            Ok(())
        }
    }
}

/// A calibration record for the demo, distinct for each `n`.
fn demo_record(n: u32) -> ParamRecord {
    let nominal = Geometry::PAPER_NOMINAL;
    let e_d = 0.995 + 1e-6 * f64::from(n % 1000);
    let e_b = 1.008;
    ParamRecord {
        nominal,
        calibration: Calibration {
            e_d,
            e_b,
            e_s: 1.0,
            geometry: nominal.with_factors(e_d, e_b, 1.0),
            method: MethodName::new("exact").unwrap_or(MethodName::NONE),
            runs: 10,
            predicted_e_max_m: 0.002,
        },
        motion: MotionSettings::DEFAULT,
    }
}

fn demo(saves: u32) -> Result<(), Box<dyn std::error::Error>> {
    let mut sim = SimParamFlash::erased();
    print_boot("boot 1 (erased flash)", &sim.boot());

    let record = demo_record(0);
    sim.store().save_blocking(&record, true)?;
    let out = sim.boot();
    print_boot("boot 2 (after save)", &out);
    if out.record != record {
        return Err("reboot did not load the saved record".into());
    }

    match sim.store().save_blocking(&record, false) {
        Err(e) => println!("save while the motors run: refused ({e})"),
        Ok(()) => return Err("a save while the motors run was accepted".into()),
    }

    {
        let mut store = sim.store();
        for n in 1..=saves {
            store.save_blocking(&demo_record(n), true)?;
        }
    }
    let out = sim.boot();
    println!(
        "{saves} more saves: erases per sector {:?}; boot 3 loads save #{saves}: {}",
        sim.chip().erase_counts(),
        out.record == demo_record(saves) && out.warning.is_none()
    );

    // Damage: overwrite the whole area with a pseudo-random pattern.
    let mut x: u32 = 0x1234_5678;
    for i in 0..SimFlash::CAPACITY {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        sim.chip().corrupt_byte(i, x as u8);
    }
    print_boot("boot 4 (flash overwritten with noise)", &sim.boot());
    sim.store().save_blocking(&record, true)?;
    print_boot("boot 5 (after a save over the noise)", &sim.boot());
    Ok(())
}

fn print_boot(label: &str, out: &LoadOutcome) {
    let g = out.record.active_geometry();
    let c = &out.record.calibration;
    match &out.warning {
        Some(w) => println!("{label}: WARNING {w}; using defaults"),
        None => println!("{label}: stored parameters loaded"),
    }
    println!(
        "  method {} (E_d {:.9}, E_b {:.9}, E_s {:.9}), D_R {:.9} m, D_L {:.9} m, b {:.9} m, {} counts/rev",
        c.method,
        c.e_d,
        c.e_b,
        c.e_s,
        g.diameter_right_m,
        g.diameter_left_m,
        g.wheelbase_m,
        g.counts_per_rev
    );
}
