//! The CLI's subcommands, one module each. Each takes its clap arguments and drives the
//! simulator ([`crate::sim`]) and the odocal library.

pub mod advice;
pub mod bench;
pub mod bringup;
pub mod closedloop;
pub mod drive;
pub mod flash;
pub mod geometry;
pub mod montecarlo;
pub mod motors;
pub mod paper;
pub mod rectangle;
pub mod replay;
pub mod serial;
pub mod session;
pub mod square;
pub mod sweep;
