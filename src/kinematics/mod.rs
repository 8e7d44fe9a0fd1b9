//! Kinematics: wheel ticks to pose. Owns the encoder extension, the robot geometry, the binary
//! angle and fixed-point odometry, and the `f64` exact-arc reference. May use only [`crate::util`].

pub mod angle;
pub mod encoder;
pub mod geometry;
pub mod odometry;
pub mod reference;
