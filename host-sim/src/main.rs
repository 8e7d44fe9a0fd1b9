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
enum Command {}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cli = Cli::parse();
    match cli.command {}
}
