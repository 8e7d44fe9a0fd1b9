//! The online estimate: the library's exact fit (the board's `calibrate` and `host-sim replay`'s
//! `exact-path` fit) of the accepted windows within the forgetting horizon, each window a run
//! fitted along its whole path (the reference at every knot) and its smoothed end heading.
//!
//! - **Horizon**: the newest windows whose wheel travel adds up to `horizon_m` (at least
//!   [`MIN_WINDOWS`]); older ones are forgotten, so a worn tyre or a new load is followed
//!   within one horizon of driving.
//! - **Weights**: the reference's covariance sets its heading's weight against its positions:
//!   at every knot the fit compares both, the heading times `ℓ = σ_xy / σ_θ` (from the medians
//!   over the windows fitted), so that a heading row's noise is that of a position row; within
//!   the fit every window counts alike, and the robust fit's own weights take a window that
//!   disagrees with the rest down.
//! - **`E_s`**: fitted only when asked (`fit_scale`): a localization's scale is that of its map,
//!   which a lidar map built with this odometry inherits; motion capture's can be trusted.

use std::collections::VecDeque;

use odocal::calibration::exact::calibrate_exact;
use odocal::calibration::{Calibration, ExactOptions, RunObservation, ScaleFit};
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::{ArcModel, PoseF64};
use odocal::motion::run::{Measurement, PathKind};

use super::window::Window;

/// Fewest accepted windows an estimate is made from.
pub const MIN_WINDOWS: usize = 3;

/// The estimator's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EstimatorOptions {
    /// Wheel travel the estimate remembers, metres.
    pub horizon_m: f64,
    /// Fit the mean diameter `E_s` too.
    pub fit_scale: bool,
}

/// The estimate and its 1σ, relative to the board's nominal geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    pub e_d: f64,
    pub e_b: f64,
    pub e_s: f64,
    pub sd_e_d: f64,
    pub sd_e_b: f64,
    /// 0 when `E_s` is not fitted.
    pub sd_e_s: f64,
    /// Windows the estimate was fitted from, and their wheel travel (metres).
    pub windows: usize,
    pub travel_m: f64,
}

impl Estimate {
    /// How far factors `(e_d, e_b)` are from the estimate: the larger of the two distances in
    /// the estimate's 1σ.
    pub fn distance_sigma(&self, e_d: f64, e_b: f64) -> f64 {
        let d = (e_d - self.e_d).abs() / self.sd_e_d;
        let b = (e_b - self.e_b).abs() / self.sd_e_b;
        d.max(b)
    }
}

/// The online estimator (see the module's text).
#[derive(Debug)]
pub struct Estimator {
    nominal: Geometry,
    options: EstimatorOptions,
    windows: VecDeque<Window>,
    /// Windows accepted and rejected so far.
    pub used: usize,
    pub rejected: usize,
    estimate: Option<Estimate>,
}

impl Estimator {
    /// An estimator of the factors relative to `nominal`.
    pub fn new(nominal: Geometry, options: EstimatorOptions) -> Estimator {
        Estimator {
            nominal,
            options,
            windows: VecDeque::new(),
            used: 0,
            rejected: 0,
            estimate: None,
        }
    }

    /// The geometry of an estimate (the nominal one with its factors).
    pub fn geometry_of(&self, e: &Estimate) -> Geometry {
        self.nominal.with_factors(e.e_d, e.e_b, e.e_s)
    }

    /// The current estimate, once there is one.
    pub fn estimate(&self) -> Option<Estimate> {
        self.estimate
    }

    /// A closed window: a rejected one is counted; an accepted one joins the horizon and the
    /// estimate is fitted again. Returns the fit's error when it failed (the estimate stays).
    pub fn push(&mut self, w: Window) -> Result<(), String> {
        if w.rejected.is_some() {
            self.rejected += 1;
            return Ok(());
        }
        self.used += 1;
        self.windows.push_back(w);
        // The newest windows within the horizon.
        let mut travel = 0.0;
        let mut keep = 0;
        for w in self.windows.iter().rev() {
            if keep >= MIN_WINDOWS && travel + w.travel_m > self.options.horizon_m {
                break;
            }
            travel += w.travel_m;
            keep += 1;
        }
        let forget = self.windows.len() - keep;
        self.windows.drain(..forget);
        if self.windows.len() < MIN_WINDOWS {
            return Ok(());
        }
        match self.fit() {
            Ok(c) => {
                let q = &c.quality;
                self.estimate = Some(Estimate {
                    e_d: c.e_d,
                    e_b: c.e_b,
                    e_s: c.e_s,
                    sd_e_d: q.sigma_e_d.unwrap_or(f64::INFINITY),
                    sd_e_b: q.sigma_e_b.unwrap_or(f64::INFINITY),
                    sd_e_s: q.sigma_e_s.unwrap_or(0.0),
                    windows: self.windows.len(),
                    travel_m: travel,
                });
                Ok(())
            }
            Err(e) => Err(e),
        }
    }

    /// The exact fit of the windows in the horizon.
    fn fit(&self) -> Result<Calibration, String> {
        let median = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let sd_xy = median(self.windows.iter().map(|w| w.sd_xy_m).collect());
        let sd_th = median(self.windows.iter().map(|w| w.sd_theta_rad).collect());
        let heading_length_m = sd_xy / sd_th;
        let options = ExactOptions {
            scale: if self.options.fit_scale {
                ScaleFit::Always
            } else {
                ScaleFit::Never
            },
            heading_length_m: Some(heading_length_m),
            end_offset: false,
            resolution_m: 1e-6,
            resolution_rad: 1e-6,
            ..ExactOptions::default()
        };
        let runs: Vec<RunObservation<'_>> = self.windows.iter().map(observation).collect();
        calibrate_exact(&runs, &self.nominal, &options).map_err(|e| format!("{e:?}"))
    }
}

/// A window as a run of the exact fit: driven as a line of its travel (its heading's length
/// scale is set by the options), measured along its whole path.
fn observation(w: &Window) -> RunObservation<'_> {
    RunObservation {
        path: PathKind::Line {
            length_m: w.travel_m,
        },
        geometry: w.geometry,
        knots: &w.knots,
        odometry_end: ArcModel::from_geometry(&w.geometry).integrate(PoseF64::default(), &w.knots),
        measured: Measurement {
            x_m: w.end.x_m,
            y_m: w.end.y_m,
            theta_rad: Some(w.end.theta_rad),
        },
        truth_path: &w.truth,
    }
}
