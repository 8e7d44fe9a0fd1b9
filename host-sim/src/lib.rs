//! host-sim library: the simulated robot and the commands that drive the odocal library with it.
//!
//! - [`sim`]: the simulator itself — robot and plant, simulated flash, the serial board, the
//!   OptiOdom log reader and the plots; it only ever steps the library's own state machines.
//! - [`experiments`]: the experiments the subcommands run (paper, Monte Carlo, sweep, closed-loop
//!   paths, rectangle), as functions that return their results.
//! - [`commands`]: one module per subcommand of the CLI: options and printing; `main.rs` only
//!   parses and dispatches.
//!
//! Closed-loop integration tests use both directly.

pub mod commands;
pub mod experiments;
pub mod sim;
