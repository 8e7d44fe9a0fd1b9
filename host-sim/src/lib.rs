//! host-sim library: the simulated robot and the scenarios that drive the odocal library with it.
//!
//! The binary (`main.rs`) is a thin CLI over these modules; closed-loop integration tests use
//! them directly.

pub mod advice;
pub mod bench;
pub mod closedloop;
pub mod drive;
pub mod flash;
pub mod montecarlo;
pub mod optiodom;
pub mod paper;
pub mod plot;
pub mod rectangle;
pub mod replay;
pub mod robot;
pub mod serial;
pub mod session;
pub mod square;
pub mod sweep;
