//! The `flash` subcommand: `flash demo` boots an erased simulated flash, saves a calibration,
//! reboots, runs many saves and reports wear, damages the flash and boots again; `flash show`,
//! `flash calibrate` and `flash reset` work on an image file.

use std::path::PathBuf;

use clap::{Args, Subcommand};
use odocal::kinematics::geometry::Geometry;
use odocal::motion::controller::{Controller, MotorsStopped};
use odocal::storage::{AppliedCalibration, LoadOutcome, MethodName, ParamRecord};

use crate::sim::flash::{SimFlash, SimParamFlash};

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
            MethodName::new(&method).map_err(|e| format!("method: {e}"))?;
            record.active = record.nominal.with_factors(e_d, e_b, e_s);
            record.calibration = Some(AppliedCalibration {
                method: method.as_str().try_into().map_err(|_| "method: too long")?,
                e_d,
                e_b,
                e_s,
                runs_used: 0,
                e_max_m: 0.0,
            });
            sim.store()
                .save_blocking(&record, MotorsStopped::without_controller())?;
            sim.write_image(&image)?;
            print_boot("saved; next boot", &sim.boot());
            Ok(())
        }
        FlashAction::Reset { image } => {
            let mut sim = SimParamFlash::open(&image)?;
            sim.store()
                .reset_to_defaults_blocking(MotorsStopped::without_controller())?;
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
        active: nominal.with_factors(e_d, e_b, 1.0),
        calibration: Some(AppliedCalibration {
            method: "exact".try_into().unwrap_or_default(),
            e_d,
            e_b,
            e_s: 1.0,
            runs_used: 10,
            e_max_m: 0.002,
        }),
        ..ParamRecord::DEFAULT
    }
}

fn demo(saves: u32) -> Result<(), Box<dyn std::error::Error>> {
    let mut sim = SimParamFlash::erased();
    print_boot("boot 1 (erased flash)", &sim.boot());

    let record = demo_record(0);
    sim.store()
        .save_blocking(&record, MotorsStopped::without_controller())?;
    let out = sim.boot();
    print_boot("boot 2 (after save)", &out);
    if out.record != record {
        return Err("reboot did not load the saved record".into());
    }

    // A save takes the controller's proof that the motors are stopped; a controller that has
    // not run a control period yet gives none.
    let controller = Controller::new(record.controller_config())
        .map_err(|e| format!("controller config: {e}"))?;
    match controller.motors_stopped() {
        Err(e) => println!("save while the motors run: refused ({e})"),
        Ok(_) => return Err("a controller that never ran confirmed the motors stopped".into()),
    }

    {
        let mut store = sim.store();
        for n in 1..=saves {
            store.save_blocking(&demo_record(n), MotorsStopped::without_controller())?;
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
    sim.store()
        .save_blocking(&record, MotorsStopped::without_controller())?;
    print_boot("boot 5 (after a save over the noise)", &sim.boot());
    Ok(())
}

fn print_boot(label: &str, out: &LoadOutcome) {
    let g = out.record.active;
    let none = AppliedCalibration {
        method: "none".try_into().unwrap_or_default(),
        e_d: 1.0,
        e_b: 1.0,
        e_s: 1.0,
        runs_used: 0,
        e_max_m: 0.0,
    };
    let c = out.record.calibration.as_ref().unwrap_or(&none);
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
