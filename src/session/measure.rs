//! Plausibility of a measured end pose, before it is accepted.
//!
//! A run ends where its odometry says, give or take the robot's systematic and random error,
//! which for any robot worth calibrating is a few per cent of the path length: UMBmark's
//! reference robot is 0.15 m off after a 6 m square, the paper's worst case about 1.5 %. A
//! measured end pose is refused when it is farther from the odometry end than
//! [`POSITION_FRACTION`] of the path length (at least [`POSITION_FLOOR_M`]), or when its heading
//! differs from the odometry heading by more than [`HEADING_LIMIT_DEG`]. A unit is never guessed:
//! the refusal asks for the unit written out and names every unit that would make the bare
//! values plausible (millimetres and centimetres often both do), since a unit slip is the usual
//! cause; a value typed with its unit is read exactly.

use core::fmt;

use crate::motion::run::{PathKind, RunRecord};
use crate::protocol::command::MeasureUnits;
use crate::protocol::unit::{Angle, Length, LengthUnit};
use crate::util::decimal::{Decimal, Plain};
use crate::util::trig;

/// Largest accepted distance between measured and odometry end, as a fraction of the path
/// length (25 %: ten times the error of a badly calibrated robot, far below what a unit error
/// gives).
pub const POSITION_FRACTION: f64 = 0.25;
/// Smallest position bound, metres (short paths).
pub const POSITION_FLOOR_M: f64 = 0.05;
/// Largest accepted heading difference between measured and odometry end, degrees.
pub const HEADING_LIMIT_DEG: f64 = 45.0;

/// The position bound for a run, metres.
pub fn position_bound_m(path: &PathKind) -> f64 {
    (POSITION_FRACTION * path.length_m()).max(POSITION_FLOOR_M)
}

/// A measured end pose as typed: each value converted from its written unit, with the unit
/// (`None`: bare, metres or degrees).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeasuredPose {
    /// x in the run's start frame.
    pub x: Length,
    /// y in the run's start frame.
    pub y: Length,
    /// The heading, if measured.
    pub theta: Option<Angle>,
}

impl MeasuredPose {
    /// The pose of a parsed `measure` (values in metres and degrees, and the units written).
    pub fn new(x_m: f64, y_m: f64, theta_deg: Option<f64>, units: MeasureUnits) -> Self {
        MeasuredPose {
            x: Length {
                m: x_m,
                unit: units.x,
            },
            y: Length {
                m: y_m,
                unit: units.y,
            },
            theta: theta_deg.map(|deg| Angle {
                deg,
                unit: units.theta,
            }),
        }
    }
}

/// The units that would make a bare (unit-less) value plausible, for a refusal that asks for
/// the unit written out; never used to convert anything.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UnitHint {
    /// A bare value as typed, to show the unit written after it.
    pub example: f64,
    /// The units (each one on its own, for every bare value) that make the measurement
    /// plausible.
    pub units: UnitSet,
}

/// A small set of length units (the plausible readings of a bare value).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UnitSet {
    /// Millimetres.
    pub millimetres: bool,
    /// Centimetres.
    pub centimetres: bool,
}

impl UnitSet {
    /// The symbols in the set, smallest length unit first.
    pub fn symbols(&self) -> impl Iterator<Item = &'static str> {
        [
            (self.millimetres, LengthUnit::Millimetre.symbol()),
            (self.centimetres, LengthUnit::Centimetre.symbol()),
        ]
        .into_iter()
        .filter_map(|(on, s)| on.then_some(s))
    }

    fn is_empty(&self) -> bool {
        !(self.millimetres || self.centimetres)
    }
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
        /// The units that would make the bare values plausible (`None`: none would, or every
        /// value had its unit written).
        unit_hint: Option<UnitHint>,
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

fn heading_diff_deg(run: &RunRecord, theta_deg: f64) -> f64 {
    trig::wrap_deg(theta_deg - run.odometry_end.theta_rad.to_degrees())
}

/// Checks a measurement of `run` given as bare numbers (`x_m`, `y_m` in metres, `theta_deg` in
/// degrees) against its odometry end: as [`check_typed`] with no unit written.
///
/// # Errors
/// [`Implausible`] with what is wrong.
pub fn check(
    run: &RunRecord,
    x_m: f64,
    y_m: f64,
    theta_deg: Option<f64>,
) -> Result<(), Implausible> {
    let bare = |m| Length { m, unit: None };
    check_typed(
        run,
        bare(x_m),
        bare(y_m),
        theta_deg.map(|deg| Angle { deg, unit: None }),
    )
}

/// Checks a measurement of `run` as typed (values converted from their written units) against
/// its odometry end. A refused position names every unit that, written after each bare value,
/// would make it plausible (millimetres and centimetres can both fit: the reply never picks
/// one).
///
/// # Errors
/// [`Implausible`] with what is wrong.
pub fn check_typed(
    run: &RunRecord,
    x: Length,
    y: Length,
    theta: Option<Angle>,
) -> Result<(), Implausible> {
    let bound_m = position_bound_m(&run.path);
    let distance_m = distance(run, x.m, y.m);
    if distance_m > bound_m {
        let mut units = UnitSet::default();
        let example = [x, y].into_iter().find(|l| l.unit.is_none()).map(|l| l.m);
        if example.is_some() {
            for unit in [LengthUnit::Millimetre, LengthUnit::Centimetre] {
                let scale = |l: Length| match l.unit {
                    None => l.m * unit.metres(),
                    Some(_) => l.m,
                };
                if distance(run, scale(x), scale(y)) <= bound_m {
                    match unit {
                        LengthUnit::Millimetre => units.millimetres = true,
                        _ => units.centimetres = true,
                    }
                }
            }
        }
        let unit_hint = example
            .filter(|_| !units.is_empty())
            .map(|example| UnitHint { example, units });
        return Err(Implausible::Position {
            distance_m,
            bound_m,
            unit_hint,
        });
    }
    if let Some(t) = theta {
        // A bare heading is degrees; one that fits only as radians is not converted either
        // (the refusal says how radians are written).
        let diff_deg = heading_diff_deg(run, t.deg);
        if diff_deg.abs() > HEADING_LIMIT_DEG {
            return Err(Implausible::Heading { diff_deg });
        }
    }
    Ok(())
}

impl fmt::Display for UnitHint {
    /// `write the unit (-5.356mm or -5.356cm)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("write the unit (")?;
        for (i, symbol) in self.units.symbols().enumerate() {
            if i > 0 {
                f.write_str(" or ")?;
            }
            write!(f, "{}{symbol}", Plain(self.example))?;
        }
        f.write_str(")")
    }
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
                    Some(hint) => write!(f, ": {hint}"),
                    None => f.write_str("; x forward, y left, in metres"),
                }
            }
            Implausible::Heading { diff_deg } => write!(
                f,
                "measured heading {} deg from the odometry heading, more than {} (a bare heading \
                 is degrees, CCW positive; radians need the unit written: 0.04rad)",
                Decimal::signed(diff_deg, 1),
                Decimal::fixed(HEADING_LIMIT_DEG, 0),
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::encoder::WheelTicks;
    use crate::kinematics::geometry::Geometry;
    use crate::kinematics::reference::PoseF64;
    use crate::protocol::unit::AngleUnit;
    use std::string::ToString;

    fn line_run(length_m: f64) -> RunRecord {
        let mut knots = heapless::Vec::new();
        knots.push(WheelTicks::new(0, 0)).unwrap();
        RunRecord {
            path: PathKind::Line { length_m },
            geometry: Geometry::PAPER_NOMINAL,
            knots,
            odometry_end: PoseF64::new(length_m, 0.0, 0.0),
            measured: None,
        }
    }

    fn bare(m: f64) -> Length {
        Length { m, unit: None }
    }

    #[test]
    fn only_the_units_that_fit_are_named() {
        // A 0.3 m line (bound 0.075 m): 300 fits as millimetres, not as centimetres.
        let run = line_run(0.3);
        let e = check_typed(&run, bare(300.0), bare(0.0), None).unwrap_err();
        assert!(e.to_string().ends_with(": write the unit (300mm)"), "{e}");
        // Nothing fits: no unit is suggested.
        let e = check_typed(&run, bare(90.0), bare(90.0), None).unwrap_err();
        assert!(
            e.to_string().ends_with("; x forward, y left, in metres"),
            "{e}"
        );
        // A value written with its unit is never rescaled: only the bare one is.
        let mm = |m| Length {
            m,
            unit: Some(LengthUnit::Millimetre),
        };
        assert_eq!(check_typed(&run, mm(0.3), bare(0.0), None), Ok(()));
        let e = check_typed(&run, bare(300.0), mm(0.0003), None).unwrap_err();
        assert!(e.to_string().ends_with(": write the unit (300mm)"), "{e}");
    }

    #[test]
    fn a_bare_heading_is_degrees_and_never_converted() {
        let run = line_run(1.0);
        let deg = |deg, unit| Some(Angle { deg, unit });
        assert_eq!(
            check_typed(&run, bare(1.0), bare(0.0), deg(0.8, None)),
            Ok(())
        );
        // 50 would fit as radians only by accident; it is refused as degrees.
        let e = check_typed(&run, bare(1.0), bare(0.0), deg(50.0, None)).unwrap_err();
        assert!(matches!(e, Implausible::Heading { .. }), "{e}");
        assert!(
            e.to_string().contains("radians need the unit written"),
            "{e}"
        );
        let rad = deg(0.04f64.to_degrees(), Some(AngleUnit::Radian));
        assert_eq!(check_typed(&run, bare(1.0), bare(0.0), rad), Ok(()));
    }
}
