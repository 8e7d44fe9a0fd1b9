//! Motion: what the control task steps. Owns the motor trait, speed loops, profiles, the paths
//! and the ticks they command, routines, run records, wiring corrections, the bring-up check,
//! the motor identification, the button and the [`controller`]. May use [`crate::kinematics`]
//! and [`crate::util`].

pub mod bringup;
pub mod button;
pub mod controller;
pub mod convention;
pub mod hbridge;
pub mod identify;
pub mod motor;
pub mod path;
pub mod profile;
pub mod routine;
pub mod run;
pub mod speed;
pub mod wheel;
pub mod wiring;
