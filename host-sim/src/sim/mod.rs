//! The simulator: what replaces the hardware and the floor. The robot (true geometry, motors,
//! encoders, slip), the parameter flash, the serial board, real-robot logs and plots.

pub mod board;
pub mod flash;
pub mod optiodom;
#[allow(unsafe_code)] // SSE2 intrinsics (each block says why)
pub mod pair;
pub mod plot;
pub mod robot;
