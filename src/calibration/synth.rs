//! Ideal kinematic runs: wheel pulse counts commanded from a belief geometry, driven by a
//! (different) true geometry with no dynamics, slip or noise.
//!
//! This is the simulation of the paper's §3 and the model the track-size advice evaluates the
//! closed-form methods on. Legs are `round(L / travel_per_tick)` pulses per wheel; an in-place
//! turn of `φ` is `round(±φ·(b/2) / travel_per_tick)` pulses (right wheel `+`, left `−` for a
//! CCW turn), all from the belief. The true end pose is the exact-arc integration of the same
//! pulses with the true geometry ([`crate::kinematics::reference::ArcModel`]).

use core::f64::consts::FRAC_PI_2;

use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::{ArcModel, PoseF64};
use crate::motion::run::{Direction, Measurement};

/// Knots of a square run: the start plus the end of each of 8 segments.
pub const SQUARE_KNOTS: usize = 9;

fn ticks(distance_m: f64, m_per_tick: f64) -> i64 {
    libm::round(distance_m / m_per_tick) as i64
}

/// Pulse counts of a straight leg of `length_m`, commanded from `belief`.
pub fn leg_ticks(belief: &Geometry, length_m: f64) -> WheelTicks {
    WheelTicks::new(
        ticks(length_m, belief.meters_per_tick_right()),
        ticks(length_m, belief.meters_per_tick_left()),
    )
}

/// Pulse counts of an in-place turn by `angle_rad` (CCW positive), commanded from `belief`.
pub fn turn_ticks(belief: &Geometry, angle_rad: f64) -> WheelTicks {
    let arc = angle_rad * 0.5 * belief.wheelbase_m;
    WheelTicks::new(
        ticks(arc, belief.meters_per_tick_right()),
        ticks(-arc, belief.meters_per_tick_left()),
    )
}

/// The 8 segment increments (leg, turn, leg, turn, …) of a square of side `side_m`.
pub fn square_segments(belief: &Geometry, direction: Direction, side_m: f64) -> [WheelTicks; 8] {
    let leg = leg_ticks(belief, side_m);
    let turn = turn_ticks(belief, direction.turn_sign() * FRAC_PI_2);
    [leg, turn, leg, turn, leg, turn, leg, turn]
}

/// Cumulative knots of a square (first knot `(0, 0)`).
pub fn square_knots(
    belief: &Geometry,
    direction: Direction,
    side_m: f64,
) -> [WheelTicks; SQUARE_KNOTS] {
    let mut k = [WheelTicks::default(); SQUARE_KNOTS];
    for (i, s) in square_segments(belief, direction, side_m)
        .iter()
        .enumerate()
    {
        k[i + 1] = WheelTicks::new(k[i].right + s.right, k[i].left + s.left);
    }
    k
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
