//! Workloads shared by the QEMU benchmark (thumbv7em-none-eabihf) and its host reference run.
//!
//! Both sides build the same inputs from the same integer-only generators in this crate, run the
//! same `odocal` code on them and print the results with the same formatting, so `run.sh` can
//! compare the two outputs line by line: any difference is a difference between the host's and
//! the target's execution of the library, not between two copies of the inputs.
#![no_std]
#![warn(missing_docs)]

pub mod console;
pub mod control;
pub mod report;
pub mod squares;
pub mod trace;

use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::odometry::{Integration, Odometry, OdometryState, Pose};

/// The geometry the benchmark integrates with: the paper's robot with a calibration applied
/// (`E_d = 0.9953`, `E_b = 1.0127`), so that no per-tick constant is a round number.
pub fn geometry() -> Geometry {
    Geometry::PAPER_NOMINAL.with_factors(0.995_3, 1.012_7, 1.0)
}

/// The odometry under test and a state reset at zero ticks, pose at the origin.
///
/// # Errors
/// The geometry's error if [`geometry`] were invalid (it is not; a host test checks it).
pub fn odometry(
    integration: Integration,
) -> Result<(Odometry, OdometryState), odocal::kinematics::geometry::GeometryError> {
    let odo = Odometry::new(&geometry(), integration)?;
    let mut state = OdometryState::default();
    odo.reset(&mut state, Default::default(), Pose::default());
    Ok((odo, state))
}

#[cfg(test)]
mod tests {
    #[test]
    fn bench_geometry_is_valid() {
        assert!(super::odometry(odocal::kinematics::odometry::Integration::ExactArc).is_ok());
    }
}
