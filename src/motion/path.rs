//! The paths the routine drives, as segments, and the wheel ticks each segment commands: the
//! one place that turns a path and a geometry into ticks. The routine drives to them, the
//! synthetic runs ([`crate::calibration::synth`]) and the measurement bound integrate them.
//!
//! A square is 4 legs of `L` and 4 in-place 90° turns (right turns for CW, left turns for CCW),
//! a line is one leg, a circle one arc of `2π r`. A segment's ticks are its length in each
//! wheel's ticks, rounded to whole ticks. Signs: positive ticks roll forward; CCW turns drive
//! the right wheel forward.

use core::f64::consts::PI;
use core::fmt;

use heapless::Vec;

use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::geometry::Geometry;
use crate::motion::run::{Direction, PathKind};

/// The most segments a path has (a square's 4 legs and 4 turns).
pub const MAX_SEGMENTS: usize = 8;

/// The commanded knots of a path: the start and every segment's end.
pub type CommandedKnots = Vec<WheelTicks, { MAX_SEGMENTS + 1 }>;

/// One segment of a path.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum SegmentKind {
    /// A straight leg forward.
    Straight {
        /// Length, metres.
        length_m: f64,
    },
    /// An in-place turn.
    Turn {
        /// Signed angle, radians (CCW positive).
        angle_rad: f64,
    },
    /// A circular arc forward.
    Arc {
        /// Path length of the robot's centre, metres.
        length_m: f64,
        /// Radius, metres.
        radius_m: f64,
        /// Turn direction.
        direction: Direction,
    },
}

/// The sides, lengths and radii a path may have, metres.
pub const PATH_SIZE_RANGE_M: (f64, f64) = (0.01, 100.0);

/// Why a path was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum PathError {
    /// A side, length or radius is not finite or outside [`PATH_SIZE_RANGE_M`].
    Size,
}

impl fmt::Display for PathError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Written out; `the_size_error_names_the_range` holds it to `PATH_SIZE_RANGE_M`.
        f.write_str(match self {
            PathError::Size => "path size must be within 0.01..100 m",
        })
    }
}

/// Checks a path's dimensions.
///
/// # Errors
/// [`PathError::Size`] for a non-finite or implausible size.
pub fn validate_path(path: &PathKind) -> Result<(), PathError> {
    let size = match *path {
        PathKind::Square { side_m, .. } => side_m,
        PathKind::Line { length_m } => length_m,
        PathKind::Circle { radius_m, .. } => radius_m,
    };
    if size.is_finite() && (PATH_SIZE_RANGE_M.0..=PATH_SIZE_RANGE_M.1).contains(&size) {
        Ok(())
    } else {
        Err(PathError::Size)
    }
}

/// Number of segments of a path.
pub fn segment_count(path: &PathKind) -> usize {
    match path {
        PathKind::Square { .. } => MAX_SEGMENTS,
        PathKind::Line { .. } | PathKind::Circle { .. } => 1,
    }
}

/// Segment `index` of a path (indices past the end repeat the last segment).
pub fn segment(path: &PathKind, index: usize) -> SegmentKind {
    match *path {
        PathKind::Square { direction, side_m } => {
            if index.is_multiple_of(2) {
                SegmentKind::Straight { length_m: side_m }
            } else {
                SegmentKind::Turn {
                    angle_rad: direction.turn_sign() * 0.5 * PI,
                }
            }
        }
        PathKind::Line { length_m } => SegmentKind::Straight { length_m },
        PathKind::Circle {
            direction,
            radius_m,
        } => SegmentKind::Arc {
            length_m: 2.0 * PI * radius_m,
            radius_m,
            direction,
        },
    }
}

/// Wheel ticks per unit of the segment's parameter (before rounding), right and left.
pub(crate) fn segment_scales(kind: &SegmentKind, g: &Geometry) -> (f64, f64, f64) {
    let kr = g.meters_per_tick_right();
    let kl = g.meters_per_tick_left();
    let half_b = 0.5 * g.wheelbase_m;
    match *kind {
        SegmentKind::Straight { length_m } => (length_m, 1.0 / kr, 1.0 / kl),
        SegmentKind::Turn { angle_rad } => {
            let s = if angle_rad < 0.0 { -1.0 } else { 1.0 };
            (libm::fabs(angle_rad), s * half_b / kr, -s * half_b / kl)
        }
        SegmentKind::Arc {
            length_m,
            radius_m,
            direction,
        } => {
            let s = direction.turn_sign();
            (
                length_m,
                (1.0 + s * half_b / radius_m) / kr,
                (1.0 - s * half_b / radius_m) / kl,
            )
        }
    }
}

/// The wheel ticks `kind` commands from `g`: the segment's end relative to its start, each
/// wheel's share of the segment's length in its own ticks, rounded to whole ticks.
pub fn segment_ticks(kind: &SegmentKind, g: &Geometry) -> WheelTicks {
    let (distance, per_right, per_left) = segment_scales(kind, g);
    WheelTicks::new(
        libm::round(distance * per_right) as i64,
        libm::round(distance * per_left) as i64,
    )
}

/// The cumulative wheel ticks `path` commands from `g`: `(0, 0)`, then every segment's end.
pub fn commanded_knots(path: &PathKind, g: &Geometry) -> CommandedKnots {
    let mut knots = CommandedKnots::new();
    let mut at = WheelTicks::default();
    let _ = knots.push(at);
    for index in 0..segment_count(path) {
        let step = segment_ticks(&segment(path, index), g);
        at = WheelTicks::new(at.right + step.right, at.left + step.left);
        // Never full: `segment_count` is at most `MAX_SEGMENTS`.
        let _ = knots.push(at);
    }
    knots
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::util::decimal::Plain;

    #[test]
    fn the_size_error_names_the_range() {
        let (lo, hi) = PATH_SIZE_RANGE_M;
        let text = format!("path size must be within {}..{} m", Plain(lo), Plain(hi));
        assert_eq!(PathError::Size.to_string(), text);
    }
}
