//! host-sim: runs the odocal library against a simulated robot.
//!
//! Every subcommand drives the library's own state machines; nothing here re-implements
//! firmware logic. The simulated hardware (wheels, motors, encoders, flash, serial line) lives in
//! this crate.

use clap::{Parser, Subcommand};

/// Simulated odocal robot.
#[derive(Parser, Debug)]
#[command(name = "host-sim", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Print the odometry constants derived from a geometry.
    Geometry {
        /// Wheel diameter, metres.
        #[arg(long, default_value_t = 0.150)]
        diameter: f64,
        /// Wheelbase, metres.
        #[arg(long, default_value_t = 0.385)]
        wheelbase: f64,
        /// Encoder counts per wheel revolution.
        #[arg(long, default_value_t = odocal::geometry::DEFAULT_COUNTS_PER_REV)]
        counts_per_rev: u32,
    },
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cli = Cli::parse();
    match cli.command {
        Command::Geometry {
            diameter,
            wheelbase,
            counts_per_rev,
        } => print_geometry(diameter, wheelbase, counts_per_rev),
    }
}

/// Prints the per-tick constants of a geometry, or why it is invalid.
fn print_geometry(
    diameter: f64,
    wheelbase: f64,
    counts_per_rev: u32,
) -> Result<(), Box<dyn std::error::Error>> {
    use odocal::encoder::{CounterWidth, max_step_for};
    let g = odocal::geometry::Geometry::symmetric(diameter, wheelbase, counts_per_rev);
    g.validate().map_err(|e| format!("invalid geometry: {e}"))?;
    println!(
        "travel per tick      {:.6} um",
        g.meters_per_tick_right() * 1e6
    );
    println!(
        "heading per tick     {:.6e} rad",
        2.0 * g.meters_per_tick_right() / g.wheelbase_m
    );
    println!(
        "glitch limit @1 kHz  {} counts/period (16-bit timer, 2 m/s)",
        max_step_for(CounterWidth::Bits16, counts_per_rev, diameter, 2.0, 1e-3)
    );
    Ok(())
}
