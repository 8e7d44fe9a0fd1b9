//! odocal: odometry and odometry calibration for two-wheel differential-drive robots.
//!
//! Everything in this crate except `board` (the hardware layer, compiled for the target only) is
//! portable `no_std` logic that is compiled for the STM32F4 target and for the host, where the
//! tests and `host-sim` drive exactly the same code.
//!
//! # Layers
//!
//! The folders follow the data flow, from the wheels up. A module may use its own layer and the
//! layers below it, never one above (checked by `tests/layering.rs`):
//!
//! | layer | modules | role |
//! |---|---|---|
//! | 0 | [`fmt`], [`util`] | logging shim, number/text helpers |
//! | 1 | [`kinematics`] | encoder ticks → pose: angle, encoder, geometry, odometry, `f64` reference |
//! | 2 | [`motion`] | the control task's spine: motor, speed loops, profiles, routines, run records, button, controller |
//! | 3 | [`calibration`], [`storage`] | E_b, E_d, E_s from runs; the parameter record in flash (independent of each other) |
//! | 3 | `plant` (feature `plant`) | the simulated robot that host-sim, the emulator board and qemu-bench run (never in the shipped firmware) |
//! | 4 | [`protocol`] | serial lines → commands, replies |
//! | 5 | [`session`] | commands and button presses → controller, run store, calibration, storage |
//! | 6 | [`app`] | the app core: what each interrupt and task of the board does, as portable functions (host-sim calls them too) |
//! | 7 | `board` (target only) | the peripherals the RTIC app (`src/main.rs`) binds to the app core |
//!
//! Data flow: encoders give wrap-safe tick totals (kinematics); odometry turns them into a pose;
//! the controller (motion) steps the routine, profile and speed loops and records each run's tick
//! knots; the session takes serial lines and button presses, stores runs and measurements, hands
//! them to the calibration engine and saves the chosen factors through storage, which the board
//! loads at boot.
//!
//! Conventions used throughout:
//! - the robot frame starts at the origin heading +x, y to the left, angles CCW positive;
//! - tick totals are `i64`; positive ticks mean the wheel rolls forward;
//! - measured errors are `true − odometry`;
//! - `E_d = D_R / D_L`, `E_b = b_actual / b_nominal`.
#![cfg_attr(not(test), no_std)]
#![warn(missing_docs)]
// `unsafe` lives only in `board` (the hardware layer); every portable layer is safe Rust.
#![deny(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

#[macro_use]
pub mod fmt;

pub mod util;

pub mod kinematics;

pub mod motion;

pub mod calibration;
pub mod storage;

#[cfg(feature = "plant")]
pub mod plant;

pub mod protocol;

pub mod session;

pub mod app;

#[cfg(target_os = "none")]
#[allow(unsafe_code)]
pub mod board;

/// On the host, the board layer's one portable part: which crystal a board has, decided from a
/// measured count (`board::crystal`, tested by tests/crystal.rs).
#[cfg(not(target_os = "none"))]
pub mod board {
    pub mod crystal;
}
