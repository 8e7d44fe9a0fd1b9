//! The experiments behind the subcommands, as library functions: each takes its parameters and
//! returns its results; the command modules ([`crate::commands`]) parse options and print.
//!
//! - [`paper`]: Lee, Jung & Chung 2011 §3 in the ideal kinematic mode (pulse counts from the
//!   belief, exact arcs with the truth); the true geometry from E_b, E_d.
//! - [`montecarlo`]: noisy paper-mode squares (slip, measurement noise, slipping starts) and
//!   the statistics of repeated calibrations; the seedable generator.
//! - [`sweep`]: that Monte Carlo over sides and noise levels against the track-size advice.
//! - [`square`]: closed-loop paths of the library's controller on the simulated robot; `E_max`
//!   and scatter of end errors.
//! - [`rectangle`]: the rectangle test of a robot's odometry.
//! - [`motors`]: motor identification on robots with other motors, and the squares with the
//!   identified tuning against the default one.
//! - [`closedloop`]: calibrations from closed-loop squares with slip and measurement noise.
//! - [`session`]: the full simulated calibration session through the board's serial path
//!   (the default `cargo sim`).

pub mod closedloop;
pub mod montecarlo;
pub mod motors;
pub mod paper;
pub mod rectangle;
pub mod session;
pub mod square;
pub mod sweep;
