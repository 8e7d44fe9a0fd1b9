//! Centres of gravity and scatter of the square runs' end errors, per direction.
//!
//! Errors are `true − odometry` in the start frame (metres, radians). Our frame (origin,
//! heading +x, y left, CCW positive, CW square at y ≤ 0) yields, to first order, exactly the
//! relations UMBmark's formulas assume: with α the under-rotation of every 90° turn and β the
//! heading change (CCW positive) along every leg,
//! `x_cw = −2L(β + α)`, `y_cw = −2L(β + α)`, `x_ccw = 2L(β − α)`, `y_ccw = −2L(β − α)`,
//! `θ_cw = 4(β + α)`, `θ_ccw = 4(β − α)`. So the centres of gravity are passed to the published
//! formulas unchanged; `tests/calibration_paper.rs` checks this numerically.
//!
//! Means and variances are accumulated with Welford's update, run by run, so nothing is stored.

use super::{CalibrationError, ClosedFormInputs, Method, RunObservation, square_direction};
use crate::kinematics::geometry::Geometry;
use crate::motion::run::Direction;
use crate::util::num::fmax;

/// Mean and sample variance of one coordinate, accumulated one value at a time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Welford {
    /// Number of values.
    pub n: u32,
    /// Mean.
    pub mean: f64,
    m2: f64,
}

impl Welford {
    /// Adds a value.
    pub fn push(&mut self, v: f64) {
        self.n += 1;
        let d = v - self.mean;
        self.mean += d / f64::from(self.n);
        self.m2 += d * (v - self.mean);
    }

    /// Sample variance (`n − 1` in the denominator); `None` with fewer than two values.
    pub fn variance(&self) -> Option<f64> {
        (self.n >= 2).then(|| self.m2 / f64::from(self.n - 1))
    }

    /// Sum of squared deviations from the mean.
    pub fn sum_sq(&self) -> f64 {
        self.m2
    }
}

/// End-error statistics of the square runs of one direction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DirectionStats {
    /// x error, metres.
    pub x: Welford,
    /// y error, metres.
    pub y: Welford,
    /// Heading error, radians (only runs with a measured heading).
    pub theta: Welford,
}

impl DirectionStats {
    /// Number of runs.
    pub fn n(&self) -> u32 {
        self.x.n
    }

    /// Distance of the centre of gravity from the origin, metres.
    pub fn cg_distance_m(&self) -> f64 {
        libm::hypot(self.x.mean, self.y.mean)
    }

    /// Whether every run of this direction had its heading measured.
    pub fn has_heading(&self) -> bool {
        self.theta.n == self.x.n && self.x.n > 0
    }
}

/// Statistics of all square runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SquareStats {
    /// Side length `L`, metres.
    pub side_m: f64,
    /// Geometry used while driving (that of the first square run).
    pub geometry: Geometry,
    /// Clockwise runs.
    pub cw: DirectionStats,
    /// Counter-clockwise runs.
    pub ccw: DirectionStats,
}

impl SquareStats {
    /// Accumulates the square runs of `runs` (other paths are skipped).
    ///
    /// With `strict`, every square must share the first one's side and geometry, as the
    /// closed-form methods need.
    ///
    /// # Errors
    /// [`CalibrationError::NoSquareRuns`], `NoCwRun`, `NoCcwRun`, and with `strict`
    /// `MixedSide` / `MixedGeometry`.
    pub fn from_runs(runs: &[RunObservation<'_>], strict: bool) -> Result<Self, CalibrationError> {
        let mut first: Option<(f64, Geometry)> = None;
        let mut cw = DirectionStats::default();
        let mut ccw = DirectionStats::default();
        for r in runs {
            let Some((direction, side)) = square_direction(&r.path) else {
                continue;
            };
            match first {
                None => first = Some((side, r.geometry)),
                Some((s0, g0)) if strict => {
                    if libm::fabs(side - s0) > 1e-9 * libm::fabs(s0) {
                        return Err(CalibrationError::MixedSide);
                    }
                    if r.geometry != g0 {
                        return Err(CalibrationError::MixedGeometry);
                    }
                }
                Some(_) => {}
            }
            let d = match direction {
                Direction::Cw => &mut cw,
                Direction::Ccw => &mut ccw,
            };
            let (ex, ey, et) = r.error();
            d.x.push(ex);
            d.y.push(ey);
            if let Some(t) = et {
                d.theta.push(t);
            }
        }
        let (side_m, geometry) = first.ok_or(CalibrationError::NoSquareRuns)?;
        if cw.n() == 0 {
            return Err(CalibrationError::NoCwRun);
        }
        if ccw.n() == 0 {
            return Err(CalibrationError::NoCcwRun);
        }
        Ok(SquareStats {
            side_m,
            geometry,
            cw,
            ccw,
        })
    }

    /// The inputs of a closed-form method: `(x_cw, y_cw, x_ccw, y_ccw)`, or for
    /// [`Method::JungChung`] `(θ_cw, 0, θ_ccw, 0)`.
    ///
    /// # Errors
    /// [`CalibrationError::NoHeading`] for Jung & Chung when a heading is missing.
    pub fn inputs(&self, method: Method) -> Result<ClosedFormInputs, CalibrationError> {
        if method == Method::JungChung {
            if !(self.cw.has_heading() && self.ccw.has_heading()) {
                return Err(CalibrationError::NoHeading);
            }
            return Ok([self.cw.theta.mean, 0.0, self.ccw.theta.mean, 0.0]);
        }
        Ok([
            self.cw.x.mean,
            self.cw.y.mean,
            self.ccw.x.mean,
            self.ccw.y.mean,
        ])
    }

    /// Variances of the mean of each input of [`SquareStats::inputs`] (sample variance / n);
    /// `None` unless both directions have at least two runs.
    pub fn input_variances(&self, method: Method) -> Option<ClosedFormInputs> {
        let vm = |w: &Welford| w.variance().map(|v| v / f64::from(w.n));
        if method == Method::JungChung {
            return Some([vm(&self.cw.theta)?, 0.0, vm(&self.ccw.theta)?, 0.0]);
        }
        Some([
            vm(&self.cw.x)?,
            vm(&self.cw.y)?,
            vm(&self.ccw.x)?,
            vm(&self.ccw.y)?,
        ])
    }

    /// UMBmark's `E_max,syst = max(|cg_cw|, |cg_ccw|)`, metres.
    pub fn e_max_m(&self) -> f64 {
        fmax(self.cw.cg_distance_m(), self.ccw.cg_distance_m())
    }

    /// Scatter of the runs around their direction's centre of gravity: root of the pooled
    /// sample variance of the distance, `sqrt(Σ|e − cg|² / (n − 2))` over both directions,
    /// metres; `None` with fewer than three runs.
    pub fn scatter_m(&self) -> Option<f64> {
        let n = self.cw.n() + self.ccw.n();
        if n < 3 {
            return None;
        }
        let ss =
            self.cw.x.sum_sq() + self.cw.y.sum_sq() + self.ccw.x.sum_sq() + self.ccw.y.sum_sq();
        Some(libm::sqrt(ss / f64::from(n - 2)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn welford_matches_two_pass() {
        let v = [1.0, 2.0, 4.0, 7.0];
        let mut w = Welford::default();
        v.iter().for_each(|&x| w.push(x));
        // mean 3.5, sample variance (6.25 + 2.25 + 0.25 + 12.25)/3 = 7.
        assert!((w.mean - 3.5).abs() < 1e-15);
        assert!((w.variance().unwrap() - 7.0).abs() < 1e-14);
        let mut one = Welford::default();
        one.push(1.0);
        assert_eq!(one.variance(), None);
    }
}
