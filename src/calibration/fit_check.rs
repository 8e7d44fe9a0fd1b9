//! Goodness of fit: whether the measured runs agree with a fitted geometry within the noise a
//! measured end carries, as a χ² of the normalised end residuals against its degrees of freedom.
//!
//! A run's end scatters by the operator's measuring (`set measure_sd`, `set heading_sd`) and by
//! the robot's own run-to-run repeatability, which grows with the path: wheel slip at the turns
//! and starts adds a heading walk whose lateral effect grows with the distance driven after it.
//! The repeatability is [`ROBOT_POSITION_SCATTER_M`] × (L / 1 m)² and
//! [`ROBOT_HEADING_SCATTER_RAD`] × L / 1 m for a path of characteristic length `L`: the upper
//! envelope of the exact fit's residuals on the shared OptiOdom squares (motion capture, no
//! measuring error: 2.5 mm and 0.2–0.9° RMS at L = 0.75 m, 14–18 mm and 0.9–1.4° at 1.7 m;
//! docs/calibration.md, *Goodness of fit*). A consistent measuring mistake (y to the right, x
//! and y exchanged, radians for degrees) leaves residuals of tens of millimetres or several
//! degrees that no geometry removes; honest runs leave χ² near its degrees of freedom.

use crate::motion::run::PathKind;

/// The robot's run-to-run scatter of an end position, 1σ per coordinate, metres, for a path of
/// characteristic length 1 m (grown as the square of the length).
pub const ROBOT_POSITION_SCATTER_M: f64 = 5e-3;

/// The robot's run-to-run scatter of an end heading, 1σ, radians, for a path of characteristic
/// length 1 m (grown with the length): 0.8°.
pub const ROBOT_HEADING_SCATTER_RAD: f64 = 0.8 * core::f64::consts::PI / 180.0;

/// A fit whose χ² probability is below this is poor: the runs agree with no geometry within
/// the noise assumed (0.1 %: honest runs are refused once in a thousand sessions).
pub const POOR_FIT_PROBABILITY: f64 = 1e-3;

/// The noise a measured end carries, as the operator declares it (the board's settings hold it:
/// the stored record sits below this module).
pub use crate::motion::convention::{
    DEFAULT_HEADING_SD_DEG, HEADING_SD_RANGE_DEG, MEASURE_SD_RANGE_M, MeasuringNoise,
};

impl MeasuringNoise {
    /// 1σ of a run's measured end `(position, heading)` for a path of characteristic length
    /// `length_m`: the measuring and the robot's repeatability together.
    pub fn end_sigma(&self, length_m: f64) -> (f64, f64) {
        let l = length_m.abs();
        let robot_p = ROBOT_POSITION_SCATTER_M * l * l;
        let robot_h = ROBOT_HEADING_SCATTER_RAD * l;
        (
            libm::sqrt(self.position_m * self.position_m + robot_p * robot_p),
            libm::sqrt(self.heading_rad * self.heading_rad + robot_h * robot_h),
        )
    }
}

/// One measured run's end residual against a fit (measured − fitted).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EndResidual {
    /// What was driven (its characteristic length sets the robot's share of the noise).
    pub path: PathKind,
    /// x residual, metres.
    pub dx_m: f64,
    /// y residual, metres.
    pub dy_m: f64,
    /// Heading residual, radians, when the heading was measured.
    pub dtheta_rad: Option<f64>,
}

/// The χ² of a fit and what it says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitCheck {
    /// Sum of the squared normalised residuals.
    pub chi2: f64,
    /// Degrees of freedom: residual components less fitted parameters.
    pub dof: u32,
    /// Probability of a χ² at least this large from honest runs.
    pub probability: f64,
}

impl FitCheck {
    /// The χ² of `residuals` (each normalised by [`MeasuringNoise::end_sigma`]) against a fit of
    /// `parameters` numbers; `None` when the runs leave no degree of freedom (the fit passes
    /// through them whatever they are) or a residual is not finite.
    pub fn of(
        residuals: impl IntoIterator<Item = EndResidual>,
        parameters: u32,
        noise: &MeasuringNoise,
    ) -> Option<FitCheck> {
        let (mut chi2, mut components) = (0.0, 0u32);
        for r in residuals {
            let (sp, sh) = noise.end_sigma(r.path.characteristic_length_m());
            chi2 += (r.dx_m * r.dx_m + r.dy_m * r.dy_m) / (sp * sp);
            components += 2;
            if let Some(t) = r.dtheta_rad {
                chi2 += t * t / (sh * sh);
                components += 1;
            }
        }
        let dof = components.checked_sub(parameters).filter(|&d| d > 0)?;
        chi2.is_finite().then(|| FitCheck {
            chi2,
            dof,
            probability: chi2_survival(chi2, dof),
        })
    }

    /// The runs agree with no geometry within the noise assumed.
    pub fn poor(&self) -> bool {
        self.probability < POOR_FIT_PROBABILITY
    }
}

/// `P(X ≥ chi2)` for a χ² variable of `dof` degrees of freedom, in closed form: for even `dof`
/// the regularised upper incomplete gamma function `Q(dof/2, chi2/2)` as its finite Poisson
/// sum; for odd `dof` the geometric mean of its even neighbours' (within 12 % of the exact value
/// at the 0.1 % threshold for 3 degrees of freedom, 2 % from 15 on; for 1, the 2's: the board
/// does without `erfc`).
pub fn chi2_survival(chi2: f64, dof: u32) -> f64 {
    if chi2.is_nan() || chi2 <= 0.0 {
        return 1.0;
    }
    let h = 0.5 * chi2;
    // e^-h Σ_{i<m} hⁱ/i!
    let even = |m: u32| {
        let (mut sum, mut term) = (0.0, libm::exp(-h));
        for i in 0..m {
            sum += term;
            term *= h / f64::from(i + 1);
        }
        sum
    };
    let q = match dof {
        1 => even(1),
        d if d % 2 == 0 => even(d / 2),
        d => libm::sqrt(even(d / 2) * even(d / 2 + 1)),
    };
    q.clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::run::Direction;

    /// Known quantiles (e.g. scipy.stats.chi2.sf): the survival at the 95 % and 99.9 % points.
    #[test]
    fn survival_matches_tabulated_quantiles() {
        // Even degrees of freedom: exact.
        for (x, k, p) in [
            (5.991_464_547_107_983, 2, 0.05),
            (23.684_791_304_840_576, 14, 0.05),
            (36.123_273_680_398_14, 14, 0.001),
            (124.342_113_404_004_08, 100, 0.05),
        ] {
            let q = chi2_survival(x, k);
            assert!((q - p).abs() < 1e-6 * p, "k={k} x={x}: {q}");
        }
        // Odd: within the stated error of the exact survival.
        for (x, k, p, within) in [
            (16.266_236_196_238_13, 3, 0.001, 0.12),
            (37.697_298_218_353_83, 15, 0.001, 0.02),
            (7.814_727_903_251_178, 3, 0.05, 0.12),
        ] {
            let q = chi2_survival(x, k);
            assert!((q / p - 1.0).abs() < within, "k={k} x={x}: {q}");
        }
        assert!(
            chi2_survival(10.83, 1) > 1e-3,
            "1 degree: the 2's, never stricter"
        );
        assert_eq!(chi2_survival(0.0, 4), 1.0);
        assert!(chi2_survival(5000.0, 14) < 1e-300);
    }

    /// A fit whose residuals are exactly one σ per component has χ² = its component count.
    #[test]
    fn residuals_are_normalised_by_the_end_sigma() {
        let path = PathKind::Square {
            direction: Direction::Cw,
            side_m: 1.0,
        };
        let noise = MeasuringNoise::DEFAULT;
        let (sp, sh) = noise.end_sigma(1.0);
        assert!((sp - libm::sqrt(1e-6 + 25e-6)).abs() < 1e-15);
        let r = EndResidual {
            path,
            dx_m: sp,
            dy_m: -sp,
            dtheta_rad: Some(sh),
        };
        let c = FitCheck::of([r; 4], 4, &noise).unwrap();
        assert!((c.chi2 - 12.0).abs() < 1e-9);
        assert_eq!(c.dof, 8);
        assert!(!c.poor());
        assert_eq!(FitCheck::of([r; 1], 3, &noise), None);
    }
}
