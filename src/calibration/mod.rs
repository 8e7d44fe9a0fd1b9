//! Calibration engine: E_d, E_b (and the distance scale E_s) from measured runs.
//!
//! Owns the calibration methods, their quality figures and the track-size advice.
//! May use [`crate::motion::run`], [`crate::kinematics`] and [`crate::util`].
//!
//! Input: [`RunObservation`]s — the path that was driven, the geometry the robot believed in
//! while driving, the cumulative wheel-tick knots, the odometry end pose and the measured true
//! end pose, all in the run's start frame (origin, heading +x, y to the left, CCW positive;
//! metres and radians). Measured errors are `true − odometry`.
//!
//! Methods ([`Method`]):
//! - [`umbmark`]: Borenstein & Feng 1996, x- and y-based;
//! - [`lee`]: Lee, Jung & Chung 2011, eq. (11) and (12);
//! - [`jung_chung`]: Jung & Chung 2012, from the final heading errors;
//! - [`exact`]: a Levenberg–Marquardt fit of the kinematic parameters that re-integrates every
//!   run's ticks with exact arcs.
//!
//! The closed-form methods measure a correction *relative to the geometry used while driving*;
//! it is composed onto that geometry with [`Geometry::corrected`]. The exact method fits the
//! absolute parameters from the raw ticks. Either way the result is reported relative to the
//! nominal geometry: `E_d = D_R / D_L` (absolute ratio, so that `nominal.with_factors(E_d, E_b,
//! E_s)` is the corrected geometry), `E_b = b / b_nominal`, `E_s = D_a / D_a,nominal`.
//!
//! Nothing here allocates; the working set is a few 3×3 matrices and per-direction sums, so the
//! engine runs on the firmware as well as on host replay data with thousands of knots per run.

use core::fmt;

use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::PoseF64;
use crate::motion::run::{Direction, Measurement, PathKind, RunRecord};
use crate::util::decimal::Decimal;
use crate::util::trig;

pub mod covariance;
pub mod exact;
pub mod fit_check;
pub mod jung_chung;
pub mod lee;
pub mod quality;
pub mod stats;
pub mod synth;
pub mod track;
pub mod umbmark;

pub use exact::{ExactFit, ExactOptions, RunFit, ScaleFit};
pub use quality::Quality;
pub use stats::{DirectionStats, SquareStats};
pub use track::{TrackAdvice, TrackAdviceInput};

/// Plausible range of every calibration factor; a result outside is rejected. What may be
/// stored and applied is narrower (`storage::record::STORED_FACTOR_RANGE`, 0.8..1.25).
pub const FACTOR_RANGE: core::ops::RangeInclusive<f64> = 0.5..=2.0;

/// One measured run, borrowed from a firmware [`RunRecord`] or from host replay data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunObservation<'a> {
    /// What was driven.
    pub path: PathKind,
    /// The geometry used while driving (the robot's belief).
    pub geometry: Geometry,
    /// Cumulative ticks since the run start; the first knot is `(0, 0)`.
    pub knots: &'a [WheelTicks],
    /// Odometry's end pose in the start frame (belief).
    pub odometry_end: PoseF64,
    /// True end pose in the start frame.
    pub measured: Measurement,
    /// Ground truth along the path (e.g. a motion-capture log): the true pose in the start frame
    /// at every knot, as long as `knots`; empty when only the end pose was measured. The exact
    /// method then fits the whole path, not only its end (see [`exact`]); only with the
    /// host-only `mocap` feature (without it a non-empty path is an invalid measurement).
    pub truth_path: &'a [PoseF64],
}

impl<'a> RunObservation<'a> {
    /// Borrows a run record; `None` if its end pose was not measured.
    pub fn from_record(r: &'a RunRecord) -> Option<Self> {
        Some(RunObservation {
            path: r.path,
            geometry: r.geometry,
            knots: &r.knots,
            odometry_end: r.odometry_end,
            measured: r.measured?,
            truth_path: &[],
        })
    }

    /// End error `true − odometry` (x, y in metres; θ wrapped to (−π, π] when measured).
    pub fn error(&self) -> (f64, f64, Option<f64>) {
        (
            self.measured.x_m - self.odometry_end.x_m,
            self.measured.y_m - self.odometry_end.y_m,
            self.measured
                .theta_rad
                .map(|t| wrap_angle(t - self.odometry_end.theta_rad)),
        )
    }

    /// Characteristic length of the path ([`PathKind::characteristic_length_m`]); the exact
    /// method weights heading residuals by it.
    pub fn characteristic_length_m(&self) -> f64 {
        self.path.characteristic_length_m()
    }

    /// Checks that the measurement and odometry are finite, the error is not absurd (larger
    /// than the path length plus 1 m), and a ground-truth path has one finite pose per knot.
    fn check(&self, index: usize) -> Result<(), CalibrationError> {
        let m = &self.measured;
        let o = &self.odometry_end;
        let finite = m.x_m.is_finite()
            && m.y_m.is_finite()
            && m.theta_rad.is_none_or(f64::is_finite)
            && o.x_m.is_finite()
            && o.y_m.is_finite()
            && o.theta_rad.is_finite();
        let len = self.path.length_m();
        if !finite || !len.is_finite() || len <= 0.0 {
            return Err(CalibrationError::InvalidMeasurement { index });
        }
        let (ex, ey, _) = self.error();
        if libm::hypot(ex, ey) > len + 1.0 {
            return Err(CalibrationError::InvalidMeasurement { index });
        }
        let path_ok = self.truth_path.is_empty()
            || (cfg!(feature = "mocap")
                && self.truth_path.len() == self.knots.len()
                && self
                    .truth_path
                    .iter()
                    .all(|p| p.x_m.is_finite() && p.y_m.is_finite() && p.theta_rad.is_finite()));
        if !path_ok {
            return Err(CalibrationError::InvalidMeasurement { index });
        }
        Ok(())
    }
}

/// Wraps an angle to (−π, π].
pub fn wrap_angle(a: f64) -> f64 {
    libm::atan2(trig::sin(a), trig::cos(a))
}

/// A calibration method.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Method {
    /// UMBmark, x-based (Borenstein & Feng 1996).
    UmbmarkX,
    /// UMBmark, y-based.
    UmbmarkY,
    /// Lee, Jung & Chung 2011, eq. (11) (x-based).
    LeeX,
    /// Lee, Jung & Chung 2011, eq. (12) (y-based).
    LeeY,
    /// Jung & Chung 2012, from final heading errors (needs θ measured).
    JungChung,
    /// odocal's exact least-squares fit.
    Exact,
}

impl Method {
    /// Every method, in display order.
    pub const ALL: [Method; 6] = [
        Method::UmbmarkX,
        Method::UmbmarkY,
        Method::LeeX,
        Method::LeeY,
        Method::JungChung,
        Method::Exact,
    ];

    /// Lower-case name (`umbmark-x`, `umbmark-y`, `lee-x`, `lee-y`, `jung-chung`, `exact`).
    pub fn as_str(self) -> &'static str {
        match self {
            Method::UmbmarkX => "umbmark-x",
            Method::UmbmarkY => "umbmark-y",
            Method::LeeX => "lee-x",
            Method::LeeY => "lee-y",
            Method::JungChung => "jung-chung",
            Method::Exact => "exact",
        }
    }

    /// The method of a name as returned by [`Method::as_str`] (ASCII case-insensitive).
    pub fn parse(name: &str) -> Option<Method> {
        Method::ALL
            .into_iter()
            .find(|m| crate::util::text::keyword_eq(m.as_str(), name))
    }

    /// Whether this is one of the closed-form square-path formulas.
    pub fn is_closed_form(self) -> bool {
        !matches!(self, Method::Exact)
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A correction relative to some reference geometry: `E_d` multiplies the diameter ratio,
/// `E_b` the wheelbase, `E_s` the mean diameter.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Factors {
    /// Diameter-ratio factor.
    pub e_d: f64,
    /// Wheelbase factor.
    pub e_b: f64,
}

impl Factors {
    /// Checks both factors are finite and within [`FACTOR_RANGE`].
    ///
    /// # Errors
    /// [`CalibrationError::OutOfRange`] otherwise.
    pub fn check(self) -> Result<Self, CalibrationError> {
        if FACTOR_RANGE.contains(&self.e_d) && FACTOR_RANGE.contains(&self.e_b) {
            Ok(self)
        } else {
            Err(CalibrationError::OutOfRange)
        }
    }
}

/// The result of one calibration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Calibration {
    /// The method that produced it.
    pub method: Method,
    /// `E_d = D_R / D_L` of the corrected geometry.
    pub e_d: f64,
    /// `E_b = b / b_nominal`.
    pub e_b: f64,
    /// `E_s = D_a / D_a,nominal`.
    pub e_s: f64,
    /// The corrected absolute geometry (`D_R`, `D_L`, `b`).
    pub geometry: Geometry,
    /// Quality figures.
    pub quality: Quality,
    /// Solver iterations (0 for the closed-form methods).
    pub iterations: u32,
    /// The exact method's per-run residuals, weights and outlier flags (`None` for the
    /// closed-form methods).
    pub fit: Option<ExactFit>,
}

impl fmt::Display for Calibration {
    /// One line for the serial console: method, factors with 1σ, geometry in mm, E_max in mm.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let q = &self.quality;
        write!(f, "{} E_b={}", self.method, Decimal::fixed(self.e_b, 6))?;
        if let Some(s) = q.sigma_e_b {
            write!(f, "+-{}", Decimal::fixed(s, 6))?;
        }
        write!(f, " E_d={}", Decimal::fixed(self.e_d, 6))?;
        if let Some(s) = q.sigma_e_d {
            write!(f, "+-{}", Decimal::fixed(s, 6))?;
        }
        write!(
            f,
            " E_s={} D_R={}mm D_L={}mm b={}mm",
            Decimal::fixed(self.e_s, 6),
            Decimal::fixed(self.geometry.diameter_right_m * 1e3, 4),
            Decimal::fixed(self.geometry.diameter_left_m * 1e3, 4),
            Decimal::fixed(self.geometry.wheelbase_m * 1e3, 3)
        )?;
        if let (Some(b), Some(a)) = (q.e_max_before_m, q.e_max_after_m) {
            write!(
                f,
                " E_max={}->{}mm",
                Decimal::fixed(b * 1e3, 1),
                Decimal::fixed(a * 1e3, 1)
            )?;
        }
        Ok(())
    }
}

/// Why a calibration failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum CalibrationError {
    /// No measured run was given.
    NoRuns,
    /// The closed-form methods need square runs and none was given.
    NoSquareRuns,
    /// No clockwise square run was measured.
    NoCwRun,
    /// No counter-clockwise square run was measured.
    NoCcwRun,
    /// The method needs the final heading and a run has none.
    NoHeading,
    /// A run's measurement or odometry is NaN, infinite or absurdly far from the odometry.
    InvalidMeasurement {
        /// Index of the run in the input slice.
        index: usize,
    },
    /// The square runs do not all have the same side length.
    MixedSide,
    /// The closed-form methods need every run driven with the same geometry.
    MixedGeometry,
    /// A geometry (nominal, driving or the result) is not valid.
    InvalidGeometry,
    /// The formulas hit a singularity (e.g. α ≥ 90°, R = b/2), or the fit is not determined.
    Degenerate,
    /// The least-squares solver did not converge.
    NotConverged,
    /// A factor came out outside the plausible range 0.5..=2.
    OutOfRange,
}

impl fmt::Display for CalibrationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CalibrationError::NoRuns => f.write_str("no measured run"),
            CalibrationError::NoSquareRuns => f.write_str("no measured square run"),
            CalibrationError::NoCwRun => f.write_str("no measured cw run"),
            CalibrationError::NoCcwRun => f.write_str("no measured ccw run"),
            CalibrationError::NoHeading => f.write_str("method needs the measured heading"),
            CalibrationError::InvalidMeasurement { index } => {
                write!(f, "run {index}: invalid or absurd measurement")
            }
            CalibrationError::MixedSide => f.write_str("square runs differ in side length"),
            CalibrationError::MixedGeometry => {
                f.write_str("runs were driven with different geometries")
            }
            CalibrationError::InvalidGeometry => f.write_str("invalid geometry"),
            CalibrationError::Degenerate => {
                f.write_str("degenerate: the runs do not determine every factor")
            }
            CalibrationError::NotConverged => f.write_str("solver did not converge"),
            CalibrationError::OutOfRange => f.write_str("factor outside 0.5..2"),
        }
    }
}

/// Calibrates `runs` with `method`; the exact method uses [`ExactOptions::default`].
///
/// # Errors
/// See [`CalibrationError`]: bad measurements, missing directions, mixed side or geometry
/// (closed-form methods), degenerate formulas, solver failure, implausible results.
pub fn calibrate(
    runs: &[RunObservation<'_>],
    nominal: &Geometry,
    method: Method,
) -> Result<Calibration, CalibrationError> {
    calibrate_with(runs, nominal, method, &ExactOptions::default())
}

/// [`calibrate`] with explicit options for the exact method.
///
/// # Errors
/// As [`calibrate`].
pub fn calibrate_with(
    runs: &[RunObservation<'_>],
    nominal: &Geometry,
    method: Method,
    options: &ExactOptions,
) -> Result<Calibration, CalibrationError> {
    nominal
        .validate()
        .map_err(|_| CalibrationError::InvalidGeometry)?;
    if runs.is_empty() {
        return Err(CalibrationError::NoRuns);
    }
    for (i, r) in runs.iter().enumerate() {
        r.check(i)?;
        r.geometry
            .validate()
            .map_err(|_| CalibrationError::InvalidGeometry)?;
    }
    if method == Method::Exact {
        return exact::calibrate_exact(runs, nominal, options);
    }
    let stats = SquareStats::from_runs(runs, true)?;
    let drive = stats.geometry;
    let relative = closed_form(method, &stats.inputs(method)?, stats.side_m, &drive)?;
    let geometry = drive.corrected(relative.e_d, relative.e_b, 1.0);
    geometry
        .validate()
        .map_err(|_| CalibrationError::InvalidGeometry)?;
    let (e_d, e_b, e_s) = factors_of(&geometry, nominal);
    Factors { e_d, e_b }.check()?;
    let sigma = quality::closed_form_sigma(method, &stats, nominal);
    let quality = Quality::from_runs(runs, &geometry, Some(&stats), sigma, None);
    Ok(Calibration {
        method,
        e_d,
        e_b,
        e_s,
        geometry,
        quality,
        iterations: 0,
        fit: None,
    })
}

/// The four numbers a closed-form method reads: `(x_cw, y_cw, x_ccw, y_ccw)` centres of
/// gravity for the position-based methods, `(θ_cw, 0, θ_ccw, 0)` for Jung & Chung.
pub type ClosedFormInputs = [f64; 4];

/// Evaluates a closed-form method on its inputs; the result is relative to the geometry
/// `drive` used while driving (`b = drive.wheelbase_m`).
///
/// # Errors
/// [`CalibrationError::Degenerate`] at a singularity, [`CalibrationError::OutOfRange`] for an
/// implausible result; [`Method::Exact`] is not closed-form and gives `Degenerate`.
pub fn closed_form(
    method: Method,
    inputs: &ClosedFormInputs,
    side_m: f64,
    drive: &Geometry,
) -> Result<Factors, CalibrationError> {
    let b = drive.wheelbase_m;
    let [a, b2, c, d] = *inputs;
    match method {
        Method::UmbmarkX => umbmark::umbmark_x(a, c, side_m, b),
        Method::UmbmarkY => umbmark::umbmark_y(b2, d, side_m, b),
        Method::LeeX => lee::lee_x(a, c, side_m, b),
        Method::LeeY => lee::lee_y(b2, d, side_m, b),
        Method::JungChung => jung_chung::jung_chung(a, c, side_m, b),
        Method::Exact => Err(CalibrationError::Degenerate),
    }
}

/// `(E_d, E_b, E_s)` of `g` relative to `nominal` (E_d is the absolute ratio `D_R / D_L`).
pub fn factors_of(g: &Geometry, nominal: &Geometry) -> (f64, f64, f64) {
    (
        g.diameter_ratio(),
        g.wheelbase_m / nominal.wheelbase_m,
        g.mean_diameter_m() / nominal.mean_diameter_m(),
    )
}

/// The direction of a square run, `None` for other paths.
pub(crate) fn square_direction(p: &PathKind) -> Option<(Direction, f64)> {
    match *p {
        PathKind::Square { direction, side_m } => Some((direction, side_m)),
        _ => None,
    }
}
