//! Run records: what a calibration needs to know about one driven path.
//!
//! A run stores the wheel-tick *knots* of the path: cumulative tick counts of both wheels since
//! the start of the run, sampled at every segment boundary (leg/turn) and at evenly spaced
//! points inside each segment. Between two knots the wheel-speed ratio is nearly constant, so
//! re-integrating the knots as constant-curvature arcs (see [`crate::kinematics::reference`]) reproduces the
//! path for *any* candidate geometry. That is what makes odocal's exact calibration exact.

use heapless::Vec;

use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::PoseF64;

/// Capacity of the run store (both directions, all path kinds): the board keeps this many
/// [`RunRecord`]s in RAM, so the command parser bounds run numbers and plans by it.
pub const MAX_RUNS: usize = 12;

/// Maximum number of knots kept for one run: 8 segments × 12 knots + 4 spare.
///
/// A knot costs 16 bytes, so one record is about 1.7 KiB and a session of 12 runs about 20 KiB of
/// static RAM. Between knots the wheels turn at a nearly constant ratio (both follow one motion
/// profile), which is all the arc model needs; more knots add RAM, not accuracy.
pub const MAX_KNOTS: usize = 100;

/// Direction of travel around a closed path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Direction {
    /// Clockwise: right turns.
    Cw,
    /// Counter-clockwise: left turns.
    Ccw,
}

impl Direction {
    /// `+1.0` for CCW, `-1.0` for CW: the sign of the turns.
    pub fn turn_sign(self) -> f64 {
        match self {
            Direction::Cw => -1.0,
            Direction::Ccw => 1.0,
        }
    }

    /// The other direction.
    pub fn opposite(self) -> Self {
        match self {
            Direction::Cw => Direction::Ccw,
            Direction::Ccw => Direction::Cw,
        }
    }

    /// Lower-case name as used by the serial protocol (`cw`, `ccw`).
    pub fn as_str(self) -> &'static str {
        match self {
            Direction::Cw => "cw",
            Direction::Ccw => "ccw",
        }
    }
}

/// The kind of path a run drove.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum PathKind {
    /// UMBmark square: 4 legs of `side_m` and 4 in-place 90° turns.
    Square {
        /// Turn direction.
        direction: Direction,
        /// Side length `L`, metres.
        side_m: f64,
    },
    /// Straight line of `length_m` (distance-scale test).
    Line {
        /// Length, metres.
        length_m: f64,
    },
    /// Full circle of `radius_m` (bi-directional circular path test).
    Circle {
        /// Turn direction.
        direction: Direction,
        /// Radius, metres.
        radius_m: f64,
    },
}

impl PathKind {
    /// Length of the commanded path, metres (4L for a square, 2πr for a circle).
    pub fn length_m(&self) -> f64 {
        match *self {
            PathKind::Square { side_m, .. } => 4.0 * side_m,
            PathKind::Line { length_m } => length_m,
            PathKind::Circle { radius_m, .. } => 2.0 * core::f64::consts::PI * radius_m,
        }
    }

    /// Characteristic length of the path, metres: the side of a square, the length of a line,
    /// the radius of a circle.
    pub fn characteristic_length_m(&self) -> f64 {
        match *self {
            PathKind::Square { side_m, .. } => side_m,
            PathKind::Line { length_m } => length_m,
            PathKind::Circle { radius_m, .. } => radius_m,
        }
    }
}

/// A measured true end pose, in the start frame of the run.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Measurement {
    /// True x, metres.
    pub x_m: f64,
    /// True y, metres.
    pub y_m: f64,
    /// True heading, radians, when it was measured.
    pub theta_rad: Option<f64>,
}

/// Everything recorded about one driven run.
#[derive(Clone, Debug, PartialEq)]
pub struct RunRecord {
    /// What was driven.
    pub path: PathKind,
    /// The geometry the robot believed in while driving (targets and odometry used it).
    pub geometry: Geometry,
    /// Cumulative wheel ticks since the start of the run; the first knot is `(0, 0)`.
    pub knots: Vec<WheelTicks, MAX_KNOTS>,
    /// Odometry end pose in the start frame.
    pub odometry_end: PoseF64,
    /// The operator's measurement of the true end pose, once entered.
    pub measured: Option<Measurement>,
}
