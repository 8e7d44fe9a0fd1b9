//! Plausibility of a measured end pose, before it is accepted.
//!
//! A run ends where its odometry says, give or take what the robot's geometry may differ from
//! its nominal values. The bound is computed for the run's own path: the wheel ticks of that
//! path as commanded ([`commanded_knots`], the routine's own targets) are
//! integrated with the run's geometry changed by each corner of the tolerance box
//! (diameter ratio `E_d` ±[`DIAMETER_RATIO_TOLERANCE`], wheelbase ±[`WHEELBASE_TOLERANCE`], mean
//! diameter ±[`SCALE_TOLERANCE`]); the farthest of those eight ends from the odometry end, plus
//! the measuring precision ([`MEASURING_PRECISION_M`], [`MEASURING_PRECISION_DEG`]), bounds the
//! position and the heading. A measurement beyond either is kept only with `yes` (a unit or a
//! sign slip is the usual cause); units are never inferred (bare values are refused before).

use core::fmt;

use crate::calibration::wrap_angle;
use crate::kinematics::reference::{ArcModel, PoseF64};
use crate::motion::path::commanded_knots;
use crate::motion::run::RunRecord;
use crate::util::decimal::Decimal;
use crate::util::num::fmax;

/// Tolerance of the wheel diameter ratio `E_d = D_R / D_L` around the nominal one (1 %: two
/// wheels of the same make, measured to 0.5 % each).
pub const DIAMETER_RATIO_TOLERANCE: f64 = 0.01;
/// Tolerance of the wheelbase around its nominal value (3 %: the contact points of soft tyres
/// move by a few millimetres on a 0.2–0.4 m wheelbase).
pub const WHEELBASE_TOLERANCE: f64 = 0.03;
/// Tolerance of the mean wheel diameter around its nominal value (1 %).
pub const SCALE_TOLERANCE: f64 = 0.01;
/// Precision of a measured end position, metres (a tape or a floor mark: 10 mm).
pub const MEASURING_PRECISION_M: f64 = 0.01;
/// Precision of a measured end heading, degrees (a straight edge on a floor line: about 1°).
pub const MEASURING_PRECISION_DEG: f64 = 1.0;

/// How far a measured end may lie from a run's odometry end.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bound {
    /// Largest distance from the odometry end, metres.
    pub position_m: f64,
    /// Largest heading difference from the odometry heading, degrees.
    pub heading_deg: f64,
}

/// The bound of `run`: its path's ticks integrated with every corner of the geometry tolerance
/// box, the farthest end (and heading) from the nominal one, plus the measuring precision.
pub fn bound(run: &RunRecord) -> Bound {
    let knots = commanded_knots(&run.path, &run.geometry);
    let nominal = ArcModel::from_geometry(&run.geometry).integrate(PoseF64::default(), &knots);
    let mut position_m: f64 = 0.0;
    let mut heading_deg: f64 = 0.0;
    for corner in 0..8u8 {
        let sign = |bit: u8| if corner & bit == 0 { -1.0 } else { 1.0 };
        let g = run.geometry.with_factors(
            run.geometry.diameter_ratio() * (1.0 + sign(1) * DIAMETER_RATIO_TOLERANCE),
            1.0 + sign(2) * WHEELBASE_TOLERANCE,
            1.0 + sign(4) * SCALE_TOLERANCE,
        );
        let end = ArcModel::from_geometry(&g).integrate(PoseF64::default(), &knots);
        position_m = fmax(
            position_m,
            libm::hypot(end.x_m - nominal.x_m, end.y_m - nominal.y_m),
        );
        heading_deg = fmax(
            heading_deg,
            libm::fabs(wrap_angle(end.theta_rad - nominal.theta_rad)).to_degrees(),
        );
    }
    Bound {
        position_m: position_m + MEASURING_PRECISION_M,
        heading_deg: heading_deg + MEASURING_PRECISION_DEG,
    }
}

/// Why a measurement needs `yes`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Implausible {
    /// The measured end is `distance_m` from the odometry end, more than `bound_m`.
    Position {
        /// Distance measured − odometry, metres.
        distance_m: f64,
        /// The bound, metres.
        bound_m: f64,
    },
    /// The measured heading differs from the odometry heading by `diff_deg`, more than
    /// `bound_deg`.
    Heading {
        /// Wrapped difference, degrees.
        diff_deg: f64,
        /// The bound, degrees.
        bound_deg: f64,
    },
}

/// Checks a measurement of `run` (metres, degrees) against its odometry end and [`bound`].
///
/// # Errors
/// [`Implausible`] with what is beyond the bound.
pub fn check(
    run: &RunRecord,
    x_m: f64,
    y_m: f64,
    theta_deg: Option<f64>,
) -> Result<(), Implausible> {
    let b = bound(run);
    let odo = run.odometry_end;
    let distance_m = libm::hypot(x_m - odo.x_m, y_m - odo.y_m);
    if distance_m > b.position_m {
        return Err(Implausible::Position {
            distance_m,
            bound_m: b.position_m,
        });
    }
    if let Some(t) = theta_deg {
        let diff_deg = wrap_angle(t.to_radians() - odo.theta_rad).to_degrees();
        if diff_deg.abs() > b.heading_deg {
            return Err(Implausible::Heading {
                diff_deg,
                bound_deg: b.heading_deg,
            });
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
            } => write!(
                f,
                "measured end {} m from the odometry end, more than {} m",
                Decimal::fixed(distance_m, 3),
                Decimal::fixed(bound_m, 3),
            )?,
            Implausible::Heading {
                diff_deg,
                bound_deg,
            } => write!(
                f,
                "measured heading {} deg from the odometry heading, more than {} deg",
                Decimal::signed(diff_deg, 1),
                Decimal::fixed(bound_deg, 1),
            )?,
        }
        f.write_str(
            " (the nominal geometry's tolerance on this path, plus measuring): check the values, \
             their units and signs, or add yes to keep it",
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::kinematics::geometry::Geometry;
    use crate::motion::run::{Direction, PathKind};

    fn run_on(path: PathKind) -> RunRecord {
        let g = Geometry::PAPER_NOMINAL;
        let knots = commanded_knots(&path, &g);
        let end = ArcModel::from_geometry(&g).integrate(PoseF64::default(), &knots);
        RunRecord {
            path,
            geometry: g,
            knots: heapless::Vec::from_slice(&knots).unwrap(),
            odometry_end: end,
            measured: None,
        }
    }

    fn line_run(length_m: f64) -> RunRecord {
        run_on(PathKind::Line { length_m })
    }

    #[test]
    fn the_bound_follows_the_geometry_tolerance_on_the_path() {
        // A 1 m line: the scale tolerance moves the end by 1 % (10 mm) and E_d bends it by
        // about L²·ΔE_d/(4b); the bound grows faster than the path.
        let short = bound(&line_run(1.0));
        let long = bound(&line_run(4.0));
        assert!(
            short.position_m > 0.02 && short.position_m < 0.2,
            "{short:?}"
        );
        assert!(long.position_m > 4.0 * (short.position_m - MEASURING_PRECISION_M));
        assert!(short.heading_deg > MEASURING_PRECISION_DEG);
        // A square: the wheelbase tolerance turns each corner by up to 3 % of 90°.
        let square = |side_m| {
            bound(&run_on(PathKind::Square {
                direction: Direction::Cw,
                side_m,
            }))
        };
        let (one, two) = (square(1.0), square(2.0));
        std::println!("bound 1 m square {one:?}, 2 m square {two:?}");
        assert!(
            one.heading_deg > 4.0 * 90.0 * WHEELBASE_TOLERANCE,
            "{one:?}"
        );
        // A centimetre value read as metres (0.5355 m for 5.355 mm in x and y) is beyond it.
        assert!(one.position_m < 0.75, "{one:?}");
        let circle = bound(&run_on(PathKind::Circle {
            direction: Direction::Ccw,
            radius_m: 0.5,
        }));
        assert!(circle.position_m > MEASURING_PRECISION_M, "{circle:?}");
    }

    #[test]
    fn a_value_beyond_the_bound_is_implausible() {
        let run = line_run(1.0);
        assert_eq!(check(&run, 1.005, 0.002, Some(0.5)), Ok(()));
        // 1 m typed where 1 cm was meant, or a centimetre value read as metres.
        let e = check(&run, 0.01, 0.0, None).unwrap_err();
        assert!(matches!(e, Implausible::Position { .. }), "{e}");
        let e = check(&run, 1.0, 0.0, Some(0.5f64.to_degrees())).unwrap_err();
        assert!(matches!(e, Implausible::Heading { .. }), "{e}");
    }
}
