//! The session traits implemented for the library's own types.
//!
//! - [`Robot`] for [`LockedController`], which wraps anything that can lend the controller for
//!   one call ([`ControllerLock`]: on the target every RTIC `Mutex<T = Controller>`, see
//!   `board::adapters`; in host-sim and the tests `&mut Controller`), so the serial task holds
//!   the controller's lock for one short operation at a time and never during a calibration
//!   solve;
//! - [`SettingsAndRuns`] for [`ParamAndRunStore`] (blocking; with the motors stopped);
//! - [`Calibrator`] for [`LibraryCalibrator`], which runs [`crate::calibration`].

use core::fmt::{self, Write};

use embedded_storage_async::nor_flash::MultiwriteNorFlash;
use heapless::Vec;

use super::MAX_RUNS;
use super::Settings;
use super::traits::{
    Calibrator, Culprit, Health, Numbered, Reading, Rejection, Robot, RobotError, RunResidual,
    SettingsAndRuns, Solution, SolveError,
};
use crate::calibration::ExactOptions;
use crate::calibration::fit_check::{
    DEFAULT_HEADING_SD_DEG, EndResidual, FitCheck, MeasuringNoise,
};
use crate::calibration::track::{self, TrackAdviceInput};
use crate::calibration::{self, Calibration, CalibrationError, Method, RunObservation};
use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::{ArcModel, PoseF64};
use crate::motion::bringup::{CheckKind, CheckReport};
use crate::motion::controller::{
    Controller, DriveError, Fault, MotorsRunning, MotorsStopped, SetError, StartError, Status,
};
use crate::motion::convention::Convention;
use crate::motion::profile::MotionLimits;
use crate::motion::run::{PathKind, RunRecord};
use crate::motion::speed::SpeedTuning;
use crate::motion::wiring::Wiring;
use crate::protocol::EOL;
use crate::protocol::refusal::write_run_numbers;
use crate::protocol::token::ADVICE;

use crate::storage::{ParamAndRunStore, RunsLoaded, StoreError, StoredRun};
use crate::util::decimal::Decimal;

/// Short name of a fault as the protocol shows it.
pub fn fault_name(f: &Fault) -> &'static str {
    match f {
        Fault::EncoderGlitch { .. } => "encoder-glitch",
        Fault::Stall { .. } => "stall",
        Fault::FollowingError { .. } => "following-error",
        Fault::Identify(_) => "identify",
        Fault::Overrun { .. } => "overrun",
    }
}

/// The latched fault of `c` as a [`RobotError`].
fn fault_error(c: &Controller) -> RobotError {
    RobotError::Fault(c.fault().as_ref().map_or("fault", fault_name))
}

/// A refused start of a run or a check as a [`RobotError`]; `not_accepted` says which one the
/// controller did not accept.
fn start_error(e: StartError, c: &Controller, not_accepted: Rejection) -> RobotError {
    match e {
        StartError::Busy => RobotError::Busy,
        StartError::Faulted => fault_error(c),
        StartError::NotReady => RobotError::Rejected(Rejection::NotReady),
        StartError::Path(_) => RobotError::Rejected(not_accepted),
    }
}

/// A refused settings change as a [`RobotError`].
fn set_error(e: SetError) -> RobotError {
    match e {
        SetError::Busy => RobotError::Busy,
        SetError::Geometry(_) => RobotError::Rejected(Rejection::Geometry),
        SetError::Limits(e) => RobotError::Rejected(Rejection::Limits(e)),
        SetError::Tuning(_) => RobotError::Rejected(Rejection::Tuning),
        SetError::Rate => RobotError::Rejected(Rejection::Rate),
    }
}

/// Lends the controller for the duration of one closure call (e.g. an RTIC resource lock).
pub trait ControllerLock {
    /// Runs `f` with exclusive access to the controller.
    fn with_controller<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> R;
}

/// The controller itself, for a caller that owns it (host-sim, the tests): nothing to lock.
impl ControllerLock for &mut Controller {
    fn with_controller<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> R {
        f(self)
    }
}

/// The [`Robot`]: the controller behind a [`ControllerLock`], locked for each call separately.
#[derive(Debug)]
pub struct LockedController<L>(pub L);

// Each method out of line: the session calls most of them from several places, and an
// inlined lock (interrupt-priority raise and restore) at every call site costs flash.
impl<L: ControllerLock> Robot for LockedController<L> {
    #[inline(never)]
    fn start(&mut self, path: PathKind) -> Result<(), RobotError> {
        self.0.with_controller(|c| {
            c.start(path)
                .map_err(|e| start_error(e, c, Rejection::Path))
        })
    }
    #[inline(never)]
    fn abort(&mut self) {
        self.0.with_controller(Controller::abort);
    }
    #[inline(never)]
    fn drive(&mut self, v_mps: f32, w_radps: f32) -> Result<(), RobotError> {
        self.0.with_controller(|c| {
            c.drive(v_mps, w_radps).map_err(|e| match e {
                DriveError::Busy => RobotError::Busy,
                DriveError::Faulted => fault_error(c),
                DriveError::NotReady => RobotError::Rejected(Rejection::NotReady),
                DriveError::NotFinite => RobotError::Rejected(Rejection::NotFinite),
            })
        })
    }
    #[inline(never)]
    fn take_finished_run(&mut self) -> Option<RunRecord> {
        self.0.with_controller(Controller::take_finished_run)
    }
    #[inline(never)]
    fn set_geometry(&mut self, geometry: Geometry) -> Result<(), RobotError> {
        self.0
            .with_controller(|c| c.set_geometry(geometry).map_err(set_error))
    }
    #[inline(never)]
    fn set_limits(&mut self, limits: &MotionLimits) -> Result<(), RobotError> {
        self.0
            .with_controller(|c| c.set_limits(*limits).map_err(set_error))
    }
    #[inline(never)]
    fn status(&mut self) -> Status {
        self.0.with_controller(|c| c.status())
    }
    #[inline(never)]
    fn health(&mut self) -> Health {
        self.0.with_controller(|c| Health {
            missed_periods: c.missed_periods(),
            pose_lost: c.pose_lost(),
        })
    }
    #[inline(never)]
    fn pose(&mut self) -> PoseF64 {
        self.0.with_controller(|c| c.pose().to_f64())
    }
    #[inline(never)]
    fn totals(&mut self) -> WheelTicks {
        self.0.with_controller(|c| c.totals())
    }
    #[inline(never)]
    fn clear_fault(&mut self) {
        self.0.with_controller(Controller::clear_fault);
    }
    #[inline(never)]
    fn reset_odometry(&mut self) -> Result<(), RobotError> {
        self.0.with_controller(|c| match c.status() {
            Status::Idle | Status::Faulted(_) => {
                c.reset_odometry();
                Ok(())
            }
            _ => Err(RobotError::Busy),
        })
    }
    #[inline(never)]
    fn motors_stopped(&mut self) -> Result<MotorsStopped, MotorsRunning> {
        self.0.with_controller(|c| c.motors_stopped())
    }
    #[inline(never)]
    fn set_wiring(&mut self, wiring: Wiring) -> Result<(), RobotError> {
        self.0
            .with_controller(|c| c.set_wiring(wiring).map_err(set_error))
    }
    #[inline(never)]
    fn start_check(&mut self, kind: CheckKind) -> Result<(), RobotError> {
        self.0.with_controller(|c| {
            c.start_check(kind)
                .map_err(|e| start_error(e, c, Rejection::Check))
        })
    }
    /// A finished motor identification's fit (soft-float `f64` on the board, tens of thousands
    /// of instructions) runs between two locks, on a copy of its statistics on this task's
    /// stack, so the control task is never held up by it.
    #[inline(never)]
    fn take_check_report(&mut self) -> Option<CheckReport> {
        let (report, finished) = self
            .0
            .with_controller(|c| match c.finished_identification() {
                Some(identify) => (None, Some(*identify)),
                // Nothing to fit: a report (or none) as it is.
                None => (c.take_check_report(), None),
            });
        match finished {
            None => report,
            Some(identify) => {
                let fit = identify.fit();
                self.0.with_controller(|c| c.conclude_identification(fit))
            }
        }
    }
    #[inline(never)]
    fn set_tuning(&mut self, tuning: &SpeedTuning) -> Result<(), RobotError> {
        self.0
            .with_controller(|c| c.set_tuning(*tuning).map_err(set_error))
    }
    #[inline(never)]
    fn set_rate(&mut self, rate_hz: u32) -> Result<(), RobotError> {
        self.0
            .with_controller(|c| c.set_rate(rate_hz).map_err(set_error))
    }
}

impl<F: MultiwriteNorFlash> SettingsAndRuns for ParamAndRunStore<F> {
    fn usable(&self) -> Result<(), StoreError> {
        ParamAndRunStore::usable(self)
    }

    fn save(&mut self, settings: &Settings, stopped: MotorsStopped) -> Result<(), StoreError> {
        self.save_blocking(settings, stopped)
    }

    fn save_runs(
        &mut self,
        runs: &[RunRecord],
        ids: &mut [Option<StoredRun>],
        stopped: MotorsStopped,
    ) -> Result<(), StoreError> {
        self.save_runs_blocking(runs, ids, stopped)
    }

    fn load_runs(
        &mut self,
        runs: &mut Vec<RunRecord, MAX_RUNS>,
        ids: &mut Vec<Option<StoredRun>, MAX_RUNS>,
    ) -> RunsLoaded {
        self.load_runs_blocking(runs, ids)
    }
}

/// Method names in [`Method::ALL`] order (`Method::as_str` is not `const`; a test checks them).
const METHOD_NAMES: [&str; 6] = [
    "umbmark-x",
    "umbmark-y",
    "lee-x",
    "lee-y",
    "jung-chung",
    "exact",
];

/// [`Calibrator`] running [`crate::calibration`], with the assumptions of its track advice.
///
/// The exact fit takes seconds on the board (soft-float `f64`), and `calibrate` needs it for
/// the table and for the advice, `apply exact` once more: it is solved once and its solution
/// kept (about 0.7 KiB, not the solver's whole report) until the runs change
/// ([`Calibrator::runs_changed`]) or another nominal geometry is asked for.
#[derive(Clone, Debug, PartialEq)]
pub struct LibraryCalibrator {
    /// 1σ of one measured end coordinate (tape measure on the floor), metres.
    pub measurement_sigma_m: f64,
    /// 1σ of a measured end heading, radians.
    pub measurement_sigma_rad: f64,
    /// Largest square side that fits the floor, metres.
    pub max_side_m: f64,
    /// The exact fit of the current runs and the nominal geometry it was solved for.
    exact: Option<(Geometry, Result<KeptExact, SolveError>)>,
    /// Exact fits computed so far.
    exact_solves: u32,
    /// How every measured run is read.
    convention: Convention,
}

/// What is kept of an exact fit: the solution as `calibrate` shows it (its residuals say which
/// runs the robust fit flagged, which the track advice leaves out).
#[derive(Clone, Debug, PartialEq)]
struct KeptExact {
    solution: Solution,
}

impl LibraryCalibrator {
    /// A calibrator with these track-advice assumptions.
    pub fn new(measurement_sigma_m: f64, measurement_sigma_rad: f64, max_side_m: f64) -> Self {
        LibraryCalibrator {
            measurement_sigma_m,
            measurement_sigma_rad,
            max_side_m,
            exact: None,
            exact_solves: 0,
            convention: Convention::Standard,
        }
    }

    /// How many times the exact fit has been computed (each takes seconds on the board).
    pub fn exact_solves(&self) -> u32 {
        self.exact_solves
    }

    /// The exact fit of `runs` for `nominal`: the kept one, or solved now and kept. Out of
    /// line: `solve`, `advice` and `fit_check` each inlined their own copy.
    #[inline(never)]
    fn exact_fit(
        &mut self,
        runs: &[RunRecord],
        nominal: &Geometry,
    ) -> Result<&KeptExact, SolveError> {
        let kept = match self.exact.take() {
            Some((n, kept)) if n == *nominal => kept,
            _ => {
                self.exact_solves = self.exact_solves.saturating_add(1);
                let obs = observations(runs, self.convention);
                calibration::calibrate(&obs, nominal, Method::Exact)
                    .map(|c| KeptExact {
                        solution: solution(&c, runs),
                    })
                    .map_err(solve_error)
            }
        };
        match &self.exact.insert((*nominal, kept)).1 {
            Ok(k) => Ok(k),
            Err(e) => Err(*e),
        }
    }
}

/// A calibration as `calibrate` shows it, with every measured run's residual numbered as
/// `runs` numbers it.
fn solution(c: &Calibration, runs: &[RunRecord]) -> Solution {
    // Store numbers of the runs that became observations, in order.
    let numbers: Vec<usize, MAX_RUNS> = runs
        .iter()
        .enumerate()
        .filter(|(_, r)| r.measured.is_some())
        .map(|(i, _)| i + 1)
        .take(MAX_RUNS)
        .collect();
    let residuals = c
        .fit
        .iter()
        .flat_map(|f| f.runs().iter())
        .filter_map(|f| {
            Some(RunResidual {
                run: *numbers.get(f.index)?,
                dx_m: f.residual_x_m,
                dy_m: f.residual_y_m,
                dtheta_rad: f.residual_theta_rad,
                weight: f.weight,
                outlier: f.outlier,
            })
        })
        .take(MAX_RUNS)
        .collect();
    Solution {
        e_d: c.e_d,
        e_b: c.e_b,
        e_s: c.e_s,
        geometry: c.geometry,
        e_max_m: c.quality.e_max_after_m,
        sd_e_d: c.quality.sigma_e_d,
        sd_e_b: c.quality.sigma_e_b,
        residuals,
    }
}

/// 1σ of a measured end position the procedure asks for (and the advice assumes by default),
/// metres.
pub const MEASURED_POSITION_SIGMA_M: f64 = MeasuringNoise::DEFAULT.position_m;
/// 1σ of a measured end heading the procedure asks for (and the advice assumes by default),
/// degrees.
pub const MEASURED_HEADING_SIGMA_DEG: f64 = DEFAULT_HEADING_SD_DEG;

impl Default for LibraryCalibrator {
    /// [`MEASURED_POSITION_SIGMA_M`] and [`MEASURED_HEADING_SIGMA_DEG`] measurement error,
    /// squares up to 4 m.
    fn default() -> Self {
        LibraryCalibrator::new(
            MEASURED_POSITION_SIGMA_M,
            MEASURED_HEADING_SIGMA_DEG.to_radians(),
            4.0,
        )
    }
}

/// The measured runs as observations, each measurement re-read under `convention`.
fn observations(runs: &[RunRecord], convention: Convention) -> Vec<RunObservation<'_>, MAX_RUNS> {
    kept_observations(runs, &[], convention)
}

/// The measured runs but those at the 1-based store positions `left_out`, as observations,
/// each measurement re-read under `convention`.
#[inline(never)]
fn kept_observations<'a>(
    runs: &'a [RunRecord],
    left_out: &[usize],
    convention: Convention,
) -> Vec<RunObservation<'a>, MAX_RUNS> {
    let mut kept = Vec::new();
    for (i, r) in runs.iter().enumerate() {
        if let Some(mut o) = RunObservation::from_record(r)
            && !left_out.contains(&(i + 1))
        {
            o.measured = convention.reread(o.measured);
            let _ = kept.push(o);
        }
    }
    kept
}

/// Missing runs are the session's own refusal (`NotEnoughRuns`); every other calibration error
/// stays typed up to the reply.
fn solve_error(e: CalibrationError) -> SolveError {
    use CalibrationError as E;
    match e {
        E::NoRuns | E::NoSquareRuns | E::NoCwRun | E::NoCcwRun => SolveError::NotEnoughRuns,
        e => SolveError::Failed(e),
    }
}

impl Calibrator for LibraryCalibrator {
    fn methods(&self) -> &[&'static str] {
        &METHOD_NAMES
    }

    fn runs_changed(&mut self) {
        self.exact = None;
    }

    fn set_reading(&mut self, reading: Reading) {
        if reading.convention != self.convention {
            self.convention = reading.convention;
            self.exact = None;
        }
        self.measurement_sigma_m = reading.noise.position_m;
        self.measurement_sigma_rad = reading.noise.heading_rad;
    }

    fn fit_check(&mut self, runs: &[RunRecord], nominal: &Geometry) -> Option<FitCheck> {
        let flagged: Vec<usize, MAX_RUNS> = self
            .exact_fit(runs, nominal)
            .ok()?
            .solution
            .flagged()
            .collect();
        let obs = kept_observations(runs, &flagged, self.convention);
        let noise = MeasuringNoise {
            position_m: self.measurement_sigma_m,
            heading_rad: self.measurement_sigma_rad,
        };
        // Headings weighted against positions as the χ² weights them (at the longest path's
        // noise): the least-squares fit is then the χ²'s minimum.
        let longest = obs
            .iter()
            .map(RunObservation::characteristic_length_m)
            .fold(0.0, f64::max);
        let (sp, sh) = noise.end_sigma(longest);
        let options = ExactOptions {
            heading_length_m: Some(sp / sh),
            ..ExactOptions::plain()
        };
        let c = calibration::calibrate_with(&obs, nominal, Method::Exact, &options).ok()?;
        let fit = c.fit?;
        let residuals = fit.runs().iter().filter_map(|r| {
            Some(EndResidual {
                path: obs.get(r.index)?.path,
                dx_m: r.residual_x_m,
                dy_m: r.residual_y_m,
                dtheta_rad: r.residual_theta_rad,
            })
        });
        FitCheck::of(residuals, fit.parameters, &noise)
    }

    fn prediction_error(
        &mut self,
        runs: &[RunRecord],
        nominal: &Geometry,
        method: &str,
    ) -> Option<f64> {
        let method = Method::parse(method)?;
        let obs = observations(runs, self.convention);
        let mut sum = 0.0;
        for k in 0..obs.len() {
            // Pushed one by one: a collected `Vec` of observations is moved through a copy.
            let mut rest: Vec<RunObservation<'_>, MAX_RUNS> = Vec::new();
            for (i, o) in obs.iter().enumerate() {
                if i != k {
                    let _ = rest.push(*o);
                }
            }
            let left_out = obs.get(k)?;
            // Each fold of the exact method by its plain least-squares fit: the robust fit's
            // reweighting rounds would multiply the seconds `calibrate` takes on the board.
            let options = ExactOptions::plain();
            let c = calibration::calibrate_with(&rest, nominal, method, &options).ok()?;
            let end =
                ArcModel::from_geometry(&c.geometry).integrate(PoseF64::default(), left_out.knots);
            let (dx, dy) = (
                left_out.measured.x_m - end.x_m,
                left_out.measured.y_m - end.y_m,
            );
            sum += dx * dx + dy * dy;
        }
        (!obs.is_empty()).then(|| libm::sqrt(sum / obs.len() as f64))
    }

    fn solve(
        &mut self,
        runs: &[RunRecord],
        nominal: &Geometry,
        method: &str,
    ) -> Result<Solution, SolveError> {
        let method = Method::parse(method).ok_or(SolveError::UnknownMethod)?;
        if method == Method::Exact {
            return self.exact_fit(runs, nominal).map(|k| k.solution.clone());
        }
        let obs = observations(runs, self.convention);
        let c = calibration::calibrate(&obs, nominal, method).map_err(solve_error)?;
        Ok(solution(&c, runs))
    }

    fn culprit(&mut self, runs: &[RunRecord], nominal: &Geometry) -> Culprit {
        let obs = observations(runs, self.convention);
        let positions: Vec<usize, MAX_RUNS> = runs
            .iter()
            .enumerate()
            .filter(|(_, r)| RunObservation::from_record(r).is_some())
            .map(|(i, _)| i + 1)
            .collect();
        // Each run left out in turn: the robust fit of the others flags none.
        let (mut agreeing, mut found) = (0u8, None);
        for k in 0..obs.len() {
            let mut rest: Vec<RunObservation<'_>, MAX_RUNS> = Vec::new();
            for (i, o) in obs.iter().enumerate() {
                if i != k {
                    let _ = rest.push(*o);
                }
            }
            if let Ok(c) = calibration::calibrate(&rest, nominal, Method::Exact)
                && c.fit.is_some_and(|f| f.outliers == 0)
            {
                agreeing += 1;
                found = positions.get(k).copied();
            }
        }
        match (agreeing, found) {
            (1, Some(run)) => Culprit::Run(run),
            _ => Culprit::CannotTell,
        }
    }

    fn advice(
        &mut self,
        numbered: Numbered<'_>,
        nominal: &Geometry,
        only: Option<&str>,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let runs = numbered.runs;
        let obs = observations(runs, self.convention);
        // The side and driving geometry of the last measured square.
        let Some((side, belief)) = obs.iter().rev().find_map(|o| match o.path {
            PathKind::Square { side_m, .. } => Some((side_m, o.geometry)),
            _ => None,
        }) else {
            return Ok(());
        };
        // The runs the robust fit flagged (1-based store positions) are left out of the
        // scatter, the runs per direction and the estimate: the advice is the one the other
        // runs alone give.
        let fit = self.exact_fit(runs, nominal).ok().map(|k| {
            let flagged: Vec<usize, MAX_RUNS> = k.solution.flagged().collect();
            (k.solution.geometry, flagged)
        });
        let flagged = fit.as_ref().map(|(_, f)| f.clone()).unwrap_or_default();
        let kept = kept_observations(runs, &flagged, self.convention);
        let estimate = match fit {
            None => belief,
            Some((geometry, f)) if f.is_empty() => geometry,
            // The exact fit of the runs kept (one more solve, only with runs flagged; naming
            // the culprit solved once per run).
            Some((geometry, _)) => calibration::calibrate(&kept, nominal, Method::Exact)
                .map_or(geometry, |c| c.geometry),
        };
        let (scatter, runs_per_direction) = track::observed(&kept);
        let input = TrackAdviceInput {
            belief,
            estimate,
            measurement_sigma_m: self.measurement_sigma_m,
            measurement_sigma_rad: self.measurement_sigma_rad,
            observed_scatter: scatter.map(|s| (s, side)),
            runs_per_direction,
            max_side_m: self.max_side_m,
        };
        for method in Method::ALL {
            if only.is_some_and(|m| Method::parse(m) != Some(method)) {
                continue;
            }
            let now = track::evaluate(&input, method, side);
            let best = track::advise(&input, method);
            write!(out, "  {ADVICE}{:<12}", method.as_str())?;
            match now {
                Some(a) => write!(
                    out,
                    " L={} m: expected error {} %",
                    Decimal::fixed(side, 3),
                    Decimal::fixed(a.expected_error * 100.0, 4)
                )?,
                None => write!(out, " L={} m: not usable", Decimal::fixed(side, 3))?,
            }
            match best {
                Some(b) => write!(
                    out,
                    "; best L={} m (<= {} m): {} %",
                    Decimal::fixed(b.side_m, 3),
                    Decimal::fixed(self.max_side_m, 1),
                    Decimal::fixed(b.expected_error * 100.0, 4)
                )?,
                None => write!(out, "; no usable side")?,
            }
            write_left_out(out, numbered, &flagged)?;
            out.write_str(EOL)?;
        }
        Ok(())
    }
}

/// The end of an advice line computed without the runs the robust fit flagged (1-based store
/// `positions`), by their numbers: ` (run 3 flagged, left out)`, ` (runs 3 5 flagged, left
/// out)`; nothing without one.
fn write_left_out(out: &mut dyn Write, numbered: Numbered<'_>, positions: &[usize]) -> fmt::Result {
    if positions.is_empty() {
        return Ok(());
    }
    let numbers: Vec<usize, MAX_RUNS> = positions.iter().map(|&p| numbered.number(p)).collect();
    out.write_str(" (")?;
    write_run_numbers(out, &numbers)?;
    out.write_str(" flagged, left out)")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_names_match_the_calibration_module() {
        let names: [&str; 6] = Method::ALL.map(Method::as_str);
        assert_eq!(names, METHOD_NAMES);
    }

    #[test]
    fn settings_round_trip_through_the_record() {
        use crate::storage::record::{AppliedCalibration, ParamRecord};
        let mut s = Settings::default();
        s.motion.max_speed_mps = 0.45;
        s.square_side_m = 1.7;
        s.runs_per_direction = 4;
        s.control_hz = 8_000;
        s.active = s.nominal.with_factors(0.995, 1.01, 1.0);
        let mut method = heapless::String::new();
        method.push_str("exact").unwrap();
        s.calibration = Some(AppliedCalibration {
            method,
            e_d: 0.995,
            e_b: 1.01,
            e_s: 1.0,
            runs_used: 10,
            e_max_m: 0.0012,
        });
        assert_eq!(s.validate(), Ok(()));
        let mut buf = [0u8; ParamRecord::ENCODED_LEN];
        s.encode(&mut buf).unwrap();
        assert_eq!(ParamRecord::decode(&buf).unwrap(), s);
        assert_eq!(Settings::default(), ParamRecord::DEFAULT);
    }
}
