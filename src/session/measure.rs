//! Plausibility of a measured end pose, before it is accepted.
//!
//! A run ends where its odometry says, give or take the robot's systematic and random error,
//! which for any robot worth calibrating is a few per cent of the path length: UMBmark's
//! reference robot is 0.15 m off after a 6 m square, the paper's worst case about 1.5 %. A
//! measured end pose is refused when it is farther from the odometry end than
//! [`POSITION_FRACTION`] of the path length (at least [`POSITION_FLOOR_M`]), or when its heading
//! differs from the odometry heading by more than [`HEADING_LIMIT_DEG`]. The refusal says which
//! unit would have made it plausible (millimetres, centimetres typed for metres), since that is
//! the usual cause.

use core::f64::consts::PI;
use core::fmt::{self, Write};

use crate::motion::run::{PathKind, RunRecord};
use crate::util::decimal::Decimal;

/// Largest accepted distance between measured and odometry end, as a fraction of the path
/// length (25 %: ten times the error of a badly calibrated robot, far below what a unit error
/// gives).
pub const POSITION_FRACTION: f64 = 0.25;
/// A typical end error of an uncalibrated robot, as a fraction of the path length (for the
/// unit hint only).
const TYPICAL_FRACTION: f64 = 0.015;
/// Smallest position bound, metres (short paths).
pub const POSITION_FLOOR_M: f64 = 0.05;
/// Largest accepted heading difference between measured and odometry end, degrees.
pub const HEADING_LIMIT_DEG: f64 = 45.0;

/// Length of the path a run drove, metres.
pub fn path_length_m(path: &PathKind) -> f64 {
    match *path {
        PathKind::Square { side_m, .. } => 4.0 * side_m,
        PathKind::Line { length_m } => length_m,
        PathKind::Circle { radius_m, .. } => 2.0 * PI * radius_m,
    }
}

/// The position bound for a run, metres.
pub fn position_bound_m(path: &PathKind) -> f64 {
    (POSITION_FRACTION * path_length_m(path)).max(POSITION_FLOOR_M)
}

/// Angle in degrees wrapped into (-180, 180].
fn wrap_deg(d: f64) -> f64 {
    let mut d = crate::util::trig::fmod(d, 360.0);
    if d > 180.0 {
        d -= 360.0;
    } else if d <= -180.0 {
        d += 360.0;
    }
    d
}

/// Why a measurement was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Implausible {
    /// The measured end is `distance_m` from the odometry end, more than `bound_m`.
    Position {
        /// Distance measured − odometry, metres.
        distance_m: f64,
        /// The bound, metres.
        bound_m: f64,
        /// The measurement divided by this (1000 or 100) would be plausible.
        unit_hint: Option<u32>,
    },
    /// The measured heading differs from the odometry heading by `diff_deg`.
    Heading {
        /// Wrapped difference, degrees.
        diff_deg: f64,
    },
}

fn distance(run: &RunRecord, x_m: f64, y_m: f64) -> f64 {
    libm::hypot(x_m - run.odometry_end.x_m, y_m - run.odometry_end.y_m)
}

/// Checks a measurement `(x_m, y_m, theta_deg)` of `run` against its odometry end.
///
/// # Errors
/// [`Implausible`] with what is wrong.
pub fn check(
    run: &RunRecord,
    x_m: f64,
    y_m: f64,
    theta_deg: Option<f64>,
) -> Result<(), Implausible> {
    let bound_m = position_bound_m(&run.path);
    let distance_m = distance(run, x_m, y_m);
    if distance_m > bound_m {
        // Both units can make it plausible (a millimetre value over 100 is a centimetre value
        // over 10): the likelier one leaves an error nearest a typical one.
        let typical_m = TYPICAL_FRACTION * path_length_m(&run.path);
        let mut unit_hint = None;
        let mut best = f64::INFINITY;
        for k in [100u32, 1000] {
            let d = distance(run, x_m / f64::from(k), y_m / f64::from(k));
            let miss = libm::fabs(libm::log(d.max(1e-9) / typical_m));
            if d <= bound_m && miss < best {
                best = miss;
                unit_hint = Some(k);
            }
        }
        return Err(Implausible::Position {
            distance_m,
            bound_m,
            unit_hint,
        });
    }
    if let Some(t) = theta_deg {
        let diff_deg = wrap_deg(t - run.odometry_end.theta_rad.to_degrees());
        if diff_deg.abs() > HEADING_LIMIT_DEG {
            return Err(Implausible::Heading { diff_deg });
        }
    }
    Ok(())
}

impl fmt::Display for Implausible {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Implausible::Position {
                distance_m,
                bound_m,
                unit_hint,
            } => {
                write!(
                    f,
                    "measured end {} m from the odometry end, more than {} m ({} % of the path)",
                    Decimal::fixed(distance_m, 3),
                    Decimal::fixed(bound_m, 3),
                    Decimal::fixed(POSITION_FRACTION * 100.0, 0),
                )?;
                match unit_hint {
                    Some(1000) => f.write_str("; looks like millimetres: the unit is metres"),
                    Some(_) => f.write_str("; looks like centimetres: the unit is metres"),
                    None => f.write_str("; x forward, y left, in metres"),
                }
            }
            Implausible::Heading { diff_deg } => write!(
                f,
                "measured heading {} deg from the odometry heading, more than {} (degrees, CCW \
                 positive)",
                Decimal::signed(diff_deg, 1),
                Decimal::fixed(HEADING_LIMIT_DEG, 0),
            ),
        }
    }
}

/// Writes ` x=… y=…[ theta_deg=…]` of a stored measurement.
pub(super) fn write_measurement(
    out: &mut dyn Write,
    m: &crate::motion::run::Measurement,
) -> fmt::Result {
    write!(
        out,
        "x={} y={}",
        Decimal::signed(m.x_m, 6),
        Decimal::signed(m.y_m, 6)
    )?;
    if let Some(t) = m.theta_rad {
        write!(out, " theta_deg={}", Decimal::signed(t.to_degrees(), 4))?;
    }
    Ok(())
}
