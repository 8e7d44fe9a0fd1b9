//! Ideal kinematic runs: wheel pulse counts commanded from a belief geometry, driven by a
//! (different) true geometry with no dynamics, slip or noise.
//!
//! This is the simulation of the paper's §3 and the model the track-size advice evaluates the
//! closed-form methods on. The pulses are the routine's own ([`crate::motion::path`]): a leg is
//! `L` in each wheel's pulses, an in-place turn of `φ` is `±φ·b/2` (right wheel `+`, left `−`
//! for a CCW turn), rounded, all from the belief. The true end pose is the exact-arc
//! integration of the same pulses with the true geometry
//! ([`crate::kinematics::reference::ArcModel`]).

use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::{ArcModel, PoseF64};
use crate::motion::path::{MAX_SEGMENTS, SegmentKind, commanded_knots, segment, segment_ticks};
use crate::motion::run::{Direction, Measurement, PathKind};

/// Knots of a square run: the start plus the end of each of its segments.
pub const SQUARE_KNOTS: usize = MAX_SEGMENTS + 1;

/// Pulse counts of a straight leg of `length_m`, commanded from `belief`.
pub fn leg_ticks(belief: &Geometry, length_m: f64) -> WheelTicks {
    segment_ticks(&SegmentKind::Straight { length_m }, belief)
}

/// Pulse counts of an in-place turn by `angle_rad` (CCW positive), commanded from `belief`.
pub fn turn_ticks(belief: &Geometry, angle_rad: f64) -> WheelTicks {
    segment_ticks(&SegmentKind::Turn { angle_rad }, belief)
}

/// The 8 segment increments (leg, turn, leg, turn, …) of a square of side `side_m`.
pub fn square_segments(
    belief: &Geometry,
    direction: Direction,
    side_m: f64,
) -> [WheelTicks; MAX_SEGMENTS] {
    let path = PathKind::Square { direction, side_m };
    core::array::from_fn(|i| segment_ticks(&segment(&path, i), belief))
}

/// Cumulative knots of a square (first knot `(0, 0)`).
pub fn square_knots(
    belief: &Geometry,
    direction: Direction,
    side_m: f64,
) -> [WheelTicks; SQUARE_KNOTS] {
    let knots = commanded_knots(&PathKind::Square { direction, side_m }, belief);
    core::array::from_fn(|i| knots.get(i).copied().unwrap_or_default())
}

/// Odometry end pose (belief) and true end pose (truth, θ included) of a knot record.
pub fn end_poses(
    belief: &Geometry,
    truth: &Geometry,
    knots: &[WheelTicks],
) -> (PoseF64, Measurement) {
    let odo = ArcModel::from_geometry(belief).integrate(PoseF64::default(), knots);
    let t = ArcModel::from_geometry(truth).integrate(PoseF64::default(), knots);
    (
        odo,
        Measurement {
            x_m: t.x_m,
            y_m: t.y_m,
            theta_rad: Some(t.theta_rad),
        },
    )
}
