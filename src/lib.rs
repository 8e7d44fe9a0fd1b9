//! odocal: odometry and odometry calibration for two-wheel differential-drive robots.
//!
//! Everything in this crate except [`board`] is portable `no_std` logic that is compiled for the
//! STM32F4 target and for the host, where the tests and `host-sim` drive exactly the same code.
//!
//! Conventions used throughout:
//! - the robot frame starts at the origin heading +x, y to the left, angles CCW positive;
//! - tick totals are `i64`; positive ticks mean the wheel rolls forward;
//! - measured errors are `true − odometry`;
//! - `E_d = D_R / D_L`, `E_b = b_actual / b_nominal`.
#![cfg_attr(not(test), no_std)]
#![warn(missing_docs)]
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

#[macro_use]
pub mod fmt;

pub mod angle;
pub mod button;
pub mod calibration;
pub mod controller;
pub mod decimal;
pub mod encoder;
pub mod geometry;
pub mod motor;
pub mod num;
pub mod odometry;
pub mod profile;
pub mod protocol;
pub mod reference;
pub mod routine;
pub mod run;
pub mod session;
pub mod speed;
pub mod storage;

#[cfg(target_os = "none")]
pub mod board;
