//! The commands that turn measured runs into calibration factors: `calibrate [method]` (solve
//! and compare the methods, change nothing) and `apply <method>` (make one method's factors the
//! active geometry, not saved); and `apply online <E_d> <E_b> <E_s>`, which makes factors
//! computed elsewhere active the same way.
//!
//! Owns the rule that both need a measured square in each direction and [`write_calibration`],
//! the `calibrate` reply, which the console's offline `recalibrate` prints from its kept runs
//! too (re-exported as `session::write_calibration`).

use core::fmt::{self, Write};

use heapless::Vec;

use super::AppliedCalibration;
use super::fit_check;
use super::traits::{
    Calibrator, Culprit, Numbered, Reading, Robot, RobotError, RunResidual, Solution,
};
use super::{MAX_RUNS, Progress, Session, progress_of, report, robot_err, storable, storage_err};
use crate::kinematics::geometry::Geometry;
use crate::motion::convention::Convention;
use crate::protocol::command::ONLINE;
use crate::protocol::number::f32_as_written;
use crate::protocol::outcome::{Ack, ParamOutcome, write_ack, write_param_outcome};
use crate::protocol::refusal::{Refusal, write_refusal};
use crate::protocol::reply::write_ok;
use crate::storage::record::METHOD_NAME_MAX;
use crate::util::text::keyword_eq;

impl<C: Calibrator> Session<C> {
    /// Why `calibrate`/`apply` cannot run yet, if so.
    fn refuse_calibration(&self, out: &mut dyn Write) -> Option<fmt::Result> {
        refuse_calibration(&self.progress(), out)
    }

    /// `calibrate [method]`: every method's result (or only `method`'s), refused while
    /// anything moves.
    pub(super) fn calibrate(
        &mut self,
        method: Option<&str>,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        // The exact solve takes seconds on the target; the console must stay responsive (`stop`)
        // while anything moves.
        if robot.status().is_busy() {
            return robot_err(out, RobotError::Busy, robot);
        }
        if let Some(m) = method
            && !self.calibrator.methods().iter().any(|k| keyword_eq(k, m))
        {
            return self.unknown_method(out);
        }
        let nominal = self.settings.nominal;
        let runs = Numbered {
            runs: &self.runs,
            numbers: &self.numbers,
        };
        let reading = self.reading();
        write_calibration(&mut self.calibrator, runs, &nominal, method, &reading, out)
    }

    /// How the session reads its runs now.
    pub(super) fn reading(&self) -> Reading {
        Reading {
            convention: self.settings.convention,
            noise: self.settings.measuring_noise(),
        }
    }

    /// `convention [name]`: re-reads every measured run under `name` from now on (kept with
    /// the settings: `save` stores it), or says which is in force.
    pub(super) fn convention(
        &mut self,
        name: Option<Convention>,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let changed = name.is_some_and(|c| c != self.settings.convention);
        if let Some(c) = name {
            self.settings.convention = c;
        }
        if changed {
            self.unsaved = true;
            let reading = self.reading();
            self.calibrator.set_reading(reading);
        }
        let ack = Ack::Convention {
            name: self.settings.convention,
            changed: name.is_some(),
        };
        write_ack(out, ack)
    }

    /// `err 7: unknown method; one of <m1>|<m2>|…`.
    fn unknown_method(&self, out: &mut dyn Write) -> fmt::Result {
        let methods = self.calibrator.methods();
        write_refusal(out, &Refusal::UnknownMethod { methods })
    }

    /// `apply <method>`: solves with `method` and makes its geometry active (the rule of `save`:
    /// what cannot be stored is not applied either).
    pub(super) fn apply(
        &mut self,
        method: &str,
        confirmed: bool,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        if robot.status().is_busy() {
            return robot_err(out, RobotError::Busy, robot);
        }
        let Some(name) = self
            .calibrator
            .methods()
            .iter()
            .copied()
            .find(|k| keyword_eq(k, method))
        else {
            return self.unknown_method(out);
        };
        if let Some(refused) = self.refuse_calibration(out) {
            return refused;
        }
        let nominal = self.settings.nominal;
        // A flagged run (one the robust fit finds disagreeing with the others) skews every
        // result computed with it: applying one then takes an explicit `yes`.
        let runs = Numbered {
            runs: &self.runs,
            numbers: &self.numbers,
        };
        self.calibrator.set_reading(self.reading());
        let flagged = flagged_runs(&mut self.calibrator, runs, &nominal);
        if !flagged.is_empty() && !confirmed {
            let refusal = Refusal::Flagged {
                runs: &flagged,
                method: name,
            };
            return write_refusal(out, &refusal);
        }
        // Runs that fit no geometry within the noise (a measuring mistake on every run?) make
        // every result wrong alike: applying one takes `yes` too.
        let check = self.calibrator.fit_check(&self.runs, &nominal);
        if let Some(c) = check.filter(|c| c.poor() && !confirmed) {
            let refusal = Refusal::PoorFit {
                probability: c.probability,
                method: name,
            };
            return write_refusal(out, &refusal);
        }
        let sol = match self.calibrator.solve(&self.runs, &nominal, name) {
            Ok(s) => s,
            Err(e) => return write_refusal(out, &Refusal::MethodFailed { why: &e }),
        };
        let p = self.progress();
        let runs_used = (p.cw_measured + p.ccw_measured).min(usize::from(u16::MAX)) as u16;
        self.make_active(name, &sol, runs_used, robot, out)
    }

    /// `apply online <E_d> <E_b> <E_s>`: factors computed elsewhere (the PC bridge's online
    /// estimate) made active on the nominal geometry under the method name [`ONLINE`], with no
    /// runs of this session behind them (`runs=0`, no `E_max`). Each factor is taken as the
    /// decimal it was written as ([`f32_as_written`]); the stored record's rule refuses what it
    /// cannot hold (`err 17`), as for `apply`.
    pub(super) fn apply_factors(
        &mut self,
        (e_d, e_b, e_s): (f32, f32, f32),
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        if robot.status().is_busy() {
            return robot_err(out, RobotError::Busy, robot);
        }
        let (e_d, e_b, e_s) = (
            f32_as_written(e_d),
            f32_as_written(e_b),
            f32_as_written(e_s),
        );
        let sol = Solution {
            e_d,
            e_b,
            e_s,
            geometry: self.settings.nominal.with_factors(e_d, e_b, e_s),
            e_max_m: None,
            sd_e_d: None,
            sd_e_b: None,
            residuals: Vec::new(),
        };
        self.make_active(ONLINE, &sol, 0, robot, out)
    }

    /// Makes `sol`, method `name` from `runs_used` runs, the active calibration: the rule of
    /// `save` first (what cannot be stored is not applied either), then the robot (odometry
    /// keeps its pose and integrates on with the new geometry), then the `ok applied` reply.
    fn make_active(
        &mut self,
        name: &str,
        sol: &Solution,
        runs_used: u16,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        // The longest whole-character prefix that fits (method names are short ASCII), copied
        // as one `str`: pushing `char`s would link the UTF-8 encoder for this one use.
        let mut end = name.len().min(METHOD_NAME_MAX);
        while !name.is_char_boundary(end) {
            end -= 1;
        }
        let mut method_name = heapless::String::new();
        let _ = method_name.push_str(name.get(..end).unwrap_or(""));
        let mut candidate = self.settings.clone();
        candidate.active = sol.geometry;
        candidate.calibration = Some(AppliedCalibration {
            method: method_name,
            e_d: sol.e_d,
            e_b: sol.e_b,
            e_s: sol.e_s,
            runs_used,
            e_max_m: sol.e_max_m.unwrap_or(0.0),
        });
        if let Err(e) = storable(&candidate) {
            return storage_err(out, e);
        }
        if let Err(e) = robot.set_geometry(sol.geometry) {
            return robot_err(out, e, robot);
        }
        self.settings = candidate;
        self.unsaved = true;
        self.dropped = None;
        let outcome = ParamOutcome::Applied {
            method: name,
            factors: (sol.e_d, sol.e_b, sol.e_s),
        };
        write_param_outcome(out, &outcome)
    }
}

/// The `calibrate` reply for `runs` (the header, one row per method or only `method`, the first
/// result's per-run residuals, the advice and the final line): what the board prints, and what a
/// host prints when it recalibrates the runs it kept (the console's offline `recalibrate`).
/// The caller has checked `method` against the calibrator's names.
///
/// # Errors
/// Only if `out` refuses the text.
pub fn write_calibration<C: Calibrator>(
    calibrator: &mut C,
    numbered: Numbered<'_>,
    nominal: &Geometry,
    method: Option<&str>,
    reading: &Reading,
    out: &mut dyn Write,
) -> fmt::Result {
    let runs = numbered.runs;
    let p = progress_of(runs);
    if let Some(refused) = refuse_calibration(&p, out) {
        return refused;
    }
    calibrator.set_reading(*reading);
    let flagged = flagged_runs(calibrator, numbered, nominal);
    let methods: Vec<&'static str, 16> = calibrator
        .methods()
        .iter()
        .filter(|name| method.is_none_or(|m| keyword_eq(m, name)))
        .take(16)
        .copied()
        .collect();
    // Each method's leave-one-out error, and the lowest (marked when more than one is listed).
    let loo: Vec<Option<f64>, 16> = methods
        .iter()
        .map(|name| calibrator.prediction_error(runs, nominal, name))
        .collect();
    let lowest = match methods.len() {
        1 => None,
        _ => (0..loo.len())
            .filter_map(|i| Some((i, (*loo.get(i)?)?)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i),
    };
    report::write_solution_header(out)?;
    let mut solved = 0usize;
    // The first result with per-run residuals (the exact fit) is listed after the table, with
    // its fit check.
    let mut residuals: Option<(&'static str, Vec<RunResidual, MAX_RUNS>)> = None;
    for (i, &name) in methods.iter().enumerate() {
        let result = calibrator.solve(runs, nominal, name);
        if let Ok(s) = &result {
            solved += 1;
            if residuals.is_none() && !s.residuals.is_empty() {
                let mut r = s.residuals.clone();
                for run in r.iter_mut() {
                    run.run = numbered.number(run.run);
                }
                residuals = Some((name, r));
            }
        }
        let loo_i = (loo.get(i).copied().flatten(), lowest == Some(i));
        report::write_solution_row(out, name, &result, loo_i, &flagged)?;
    }
    if let Some((name, r)) = &residuals {
        // Which run to look at: the one whose removal makes the others agree.
        let culprit = match r.iter().any(|r| r.outlier) {
            true => match calibrator.culprit(runs, nominal) {
                Culprit::Run(position) => Some(numbered.number(position)),
                Culprit::CannotTell => None,
            },
            false => None,
        };
        report::write_residuals(out, name, r, culprit)?;
    }
    if residuals.is_some()
        && let Some(check) = calibrator.fit_check(runs, nominal)
    {
        // A poor fit: the consistent measuring mistake that explains it, if one does.
        let mistake = match check.poor() {
            true => fit_check::name_mistake(calibrator, runs, nominal, *reading),
            false => None,
        };
        fit_check::write_fit(out, &check, mistake)?;
    }
    if solved == 0 {
        // Advice from a failed fit would be meaningless.
        return write_refusal(out, &Refusal::NoMethodSucceeded);
    }
    calibrator.advice(numbered, nominal, method, out)?;
    write_ok(
        out,
        format_args!(
            "{solved} solved from {} measured runs (cw {}, ccw {}); apply <method> to use one",
            p.cw_measured + p.ccw_measured,
            p.cw_measured,
            p.ccw_measured,
        ),
    )
}

/// The runs the robust fit flags as disagreeing with the others, by run number: from the last
/// method that reports per-run residuals (the board's only one is `exact`, whose residuals the
/// `calibrate` table lists).
pub fn flagged_runs<C: Calibrator>(
    calibrator: &mut C,
    numbered: Numbered<'_>,
    nominal: &Geometry,
) -> Vec<usize, MAX_RUNS> {
    let runs = numbered.runs;
    // The fit with residuals is the last method (exact, whose solution the calibrator keeps);
    // asking it first spares solving every closed form again on each `apply`.
    let methods: Vec<&'static str, 16> = calibrator.methods().iter().take(16).copied().collect();
    for &name in methods.iter().rev() {
        if let Ok(s) = calibrator.solve(runs, nominal, name)
            && !s.residuals.is_empty()
        {
            return s.flagged().map(|p| numbered.number(p)).collect();
        }
    }
    Vec::new()
}

/// The `err 13` reply when `calibrate`/`apply` cannot run yet (no measured square in a
/// direction), if so.
fn refuse_calibration(p: &Progress, out: &mut dyn Write) -> Option<fmt::Result> {
    if p.cw_measured == 0 || p.ccw_measured == 0 {
        let refusal = Refusal::NotEnoughRuns {
            cw: p.cw_measured,
            ccw: p.ccw_measured,
        };
        return Some(write_refusal(out, &refusal));
    }
    None
}
