//! Kinematic geometry of the robot: wheel diameters, wheelbase, encoder resolution.
//!
//! [`Geometry`] is the user-facing, stored form (metres, `f64`). It is validated once by
//! [`Geometry::validate`]; the odometry then builds its fixed-point runtime constants from it
//! (see [`crate::kinematics::odometry::Odometry::new`]), so the 1 kHz loop never re-checks anything.
//!
//! Calibration factors follow the paper's definitions: `E_d = D_R / D_L` and
//! `E_b = b_actual / b_nominal`. A correction keeps the mean diameter `D_a = (D_R + D_L) / 2`
//! ([`Geometry::with_factors`]); a separate distance scale `E_s` scales `D_a`.

use core::f64::consts::PI;
use core::fmt;

use crate::util::decimal::Plain;

/// Default encoder resolution: counts per wheel revolution seen by the timer.
pub const DEFAULT_COUNTS_PER_REV: u32 = 200_000;

/// Kinematic parameters of a differential-drive robot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Geometry {
    /// Right wheel diameter `D_R` in metres.
    pub diameter_right_m: f64,
    /// Left wheel diameter `D_L` in metres.
    pub diameter_left_m: f64,
    /// Wheelbase `b` (distance between the wheel contact points) in metres.
    pub wheelbase_m: f64,
    /// Encoder counts per wheel revolution (`Re` in the paper), both wheels.
    pub counts_per_rev: u32,
}

/// Why a [`Geometry`] was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum GeometryError {
    /// A wheel diameter is not finite or outside 1 mm ..= 2 m.
    Diameter,
    /// The wheelbase is not finite or outside 1 cm ..= 5 m.
    Wheelbase,
    /// The encoder resolution is outside 1 ..= 100,000,000 counts per revolution.
    CountsPerRev,
}

impl fmt::Display for GeometryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (what, (lo, hi), unit) = match self {
            GeometryError::Diameter => ("wheel diameter", Geometry::DIAMETER_RANGE_M, " m"),
            GeometryError::Wheelbase => ("wheelbase", Geometry::WHEELBASE_RANGE_M, " m"),
            GeometryError::CountsPerRev => {
                let (lo, hi) = Geometry::COUNTS_PER_REV_RANGE;
                return write!(f, "counts per revolution must be within {lo}..{hi}");
            }
        };
        write!(
            f,
            "{what} must be within {}..{}{unit}",
            Plain(lo),
            Plain(hi)
        )
    }
}

impl Geometry {
    /// Nominal geometry of the paper's robot: D = 150 mm, b = 385 mm, 200,000 counts/rev.
    pub const PAPER_NOMINAL: Geometry = Geometry {
        diameter_right_m: 0.150,
        diameter_left_m: 0.150,
        wheelbase_m: 0.385,
        counts_per_rev: DEFAULT_COUNTS_PER_REV,
    };

    /// A geometry with equal wheels.
    pub const fn symmetric(diameter_m: f64, wheelbase_m: f64, counts_per_rev: u32) -> Self {
        Geometry {
            diameter_right_m: diameter_m,
            diameter_left_m: diameter_m,
            wheelbase_m,
            counts_per_rev,
        }
    }

    /// The wheel diameters `set` accepts and a geometry may have, metres.
    pub const DIAMETER_RANGE_M: (f64, f64) = (0.001, 2.0);
    /// The wheelbases `set` accepts and a geometry may have, metres.
    pub const WHEELBASE_RANGE_M: (f64, f64) = (0.01, 5.0);
    /// The encoder counts per wheel revolution `set` accepts and a geometry may have.
    pub const COUNTS_PER_REV_RANGE: (u32, u32) = (1, 100_000_000);

    /// Checks that every value is finite and within its range.
    ///
    /// # Errors
    /// The first offending field, as a [`GeometryError`].
    pub fn validate(&self) -> Result<(), GeometryError> {
        let ok = |v: f64, (lo, hi): (f64, f64)| v.is_finite() && (lo..=hi).contains(&v);
        if !ok(self.diameter_right_m, Self::DIAMETER_RANGE_M)
            || !ok(self.diameter_left_m, Self::DIAMETER_RANGE_M)
        {
            return Err(GeometryError::Diameter);
        }
        if !ok(self.wheelbase_m, Self::WHEELBASE_RANGE_M) {
            return Err(GeometryError::Wheelbase);
        }
        let (lo, hi) = Self::COUNTS_PER_REV_RANGE;
        if !(lo..=hi).contains(&self.counts_per_rev) {
            return Err(GeometryError::CountsPerRev);
        }
        Ok(())
    }

    /// Right wheel travel per encoder count, metres (`π D_R / Re`, paper eq. 4).
    pub fn meters_per_tick_right(&self) -> f64 {
        PI * self.diameter_right_m / f64::from(self.counts_per_rev)
    }

    /// Left wheel travel per encoder count, metres (`π D_L / Re`, paper eq. 4).
    pub fn meters_per_tick_left(&self) -> f64 {
        PI * self.diameter_left_m / f64::from(self.counts_per_rev)
    }

    /// Mean wheel diameter `D_a = (D_R + D_L) / 2`, metres.
    pub fn mean_diameter_m(&self) -> f64 {
        0.5 * (self.diameter_right_m + self.diameter_left_m)
    }

    /// Diameter ratio `D_R / D_L` of this geometry.
    pub fn diameter_ratio(&self) -> f64 {
        self.diameter_right_m / self.diameter_left_m
    }

    /// The geometry with diameter ratio `e_d = D_R / D_L`, mean diameter `e_s · D_a` and
    /// wheelbase `e_b · b`, where `D_a` and `b` are this geometry's.
    ///
    /// `D_R = 2 D_a' / (1 + 1/E_d)`, `D_L = 2 D_a' / (1 + E_d)` with `D_a' = E_s · D_a`.
    pub fn with_factors(&self, e_d: f64, e_b: f64, e_s: f64) -> Geometry {
        let mean = e_s * self.mean_diameter_m();
        Geometry {
            diameter_right_m: 2.0 * mean / (1.0 + 1.0 / e_d),
            diameter_left_m: 2.0 * mean / (1.0 + e_d),
            wheelbase_m: e_b * self.wheelbase_m,
            counts_per_rev: self.counts_per_rev,
        }
    }

    /// Composes a correction measured while driving with `self` onto it: the diameter ratio is
    /// multiplied by `e_d`, the wheelbase by `e_b` and the mean diameter by `e_s`.
    ///
    /// This is how an iterative calibration (paper Fig. 10) refines an earlier one: the geometry
    /// [`Geometry::with_factors`] gives for the diameter ratio `D_R / D_L · e_d`.
    pub fn corrected(&self, e_d: f64, e_b: f64, e_s: f64) -> Geometry {
        self.with_factors(self.diameter_ratio() * e_d, e_b, e_s)
    }
}

impl Default for Geometry {
    fn default() -> Self {
        Geometry::PAPER_NOMINAL
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factors_keep_the_mean_diameter() {
        let g = Geometry::PAPER_NOMINAL.with_factors(0.995, 1.010, 1.0);
        assert!((g.mean_diameter_m() - 0.150).abs() < 1e-15);
        assert!((g.diameter_ratio() - 0.995).abs() < 1e-15);
        assert!((g.wheelbase_m - 0.385 * 1.010).abs() < 1e-15);
    }

    #[test]
    fn corrections_compose() {
        let once = Geometry::PAPER_NOMINAL.corrected(0.998, 1.004, 1.0);
        let twice = once.corrected(0.997, 1.006, 1.0);
        assert!((twice.diameter_ratio() - 0.998 * 0.997).abs() < 1e-14);
        assert!((twice.wheelbase_m - 0.385 * 1.004 * 1.006).abs() < 1e-14);
        assert!((twice.mean_diameter_m() - 0.150).abs() < 1e-15);
    }

    #[test]
    fn rejects_absurd_values() {
        let mut g = Geometry::PAPER_NOMINAL;
        g.diameter_left_m = f64::NAN;
        assert_eq!(g.validate(), Err(GeometryError::Diameter));
        let mut g = Geometry::PAPER_NOMINAL;
        g.wheelbase_m = -1.0;
        assert_eq!(g.validate(), Err(GeometryError::Wheelbase));
        let mut g = Geometry::PAPER_NOMINAL;
        g.counts_per_rev = 0;
        assert_eq!(g.validate(), Err(GeometryError::CountsPerRev));
        assert_eq!(Geometry::PAPER_NOMINAL.validate(), Ok(()));
    }
}
