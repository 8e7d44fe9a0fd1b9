//! The sweep (`host-sim sweep`, and the session's Fig. 5): Monte Carlo over square sides and noise levels, the check of the track-size
//! advice ([`odocal::calibration::track`]).
//!
//! For every noise level (1σ measurement error of a coordinate × 1σ relative wheel slip per
//! substep, a substep being a fixed length of travel: [`substeps_for`]) and every side `L`, `trials` calibrations are simulated in paper mode
//! ([`crate::experiments::montecarlo::noisy_square`]: pulse counts commanded from the belief, slip on the
//! ground travel, measurement noise on the true end position), `runs` squares per direction
//! each, and every position-based method is applied. The figure of merit per method and cell is
//! the one the advice minimises: the root mean square over trials of
//! `sqrt(ΔE_b² + ΔE_d²)` (relative errors against the truth).
//!
//! The advice is given what an operator would know: the measurement σ and the end-position
//! scatter observed in a pilot set of slip-only squares at 2 m. Its predicted error at each side
//! is written next to the measured one, and the best side by both is reported per method.
//!
//! Trials run in parallel (rayon); each trial has its own seed derived from `--seed`, the noise
//! level, the side and the trial number, so the result does not depend on the thread count.
//! Output: a table on stdout, `sweep.csv` and one SVG per noise level (parameter error against
//! side, per method, measured and predicted) in `--out`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use odocal::calibration::track::{TrackAdviceInput, advise, evaluate};
use odocal::calibration::{Method, SquareStats, calibrate};
use odocal::kinematics::geometry::Geometry;
use rayon::prelude::*;

use crate::experiments::montecarlo::{MonteCarloArgs, Rng, noisy_squares, observations};
use crate::experiments::paper::{Format, TruthModel, true_geometry};
use crate::sim::plot::{Figure, Series, Style, write_svg};

/// The methods a sweep evaluates: those that need only the measured end positions.
pub const SWEEP_METHODS: [Method; 5] = [
    Method::UmbmarkX,
    Method::UmbmarkY,
    Method::LeeX,
    Method::LeeY,
    Method::Exact,
];

/// Side at which the pilot scatter is observed, metres.
pub const PILOT_SIDE_M: f64 = 2.0;

/// Arguments of `host-sim sweep`.
#[derive(Args, Debug, Clone)]
pub struct SweepArgs {
    /// Square sides L, metres.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0.5,0.75,1,1.5,2,3,4,6,8"
    )]
    pub sides: Vec<f64>,
    /// 1σ of a measured coordinate, metres (one noise level per value × slip value).
    #[arg(long, value_delimiter = ',', default_value = "0.002,0.01")]
    pub meas_sigmas: Vec<f64>,
    /// 1σ of the relative slip of a wheel per substep.
    #[arg(long, value_delimiter = ',', default_value = "0.0005,0.003")]
    pub slips: Vec<f64>,
    /// Calibrations per (noise level, side).
    #[arg(long, default_value_t = 200)]
    pub trials: u32,
    /// Runs per direction in each calibration.
    #[arg(long, default_value_t = 5)]
    pub runs: u32,
    /// Substeps per segment of a [`PILOT_SIDE_M`] square (slip is drawn per substep); a side
    /// `L` gets `substeps · L / PILOT_SIDE_M` of them (at least one), so slip is drawn per fixed
    /// length of travel (0.1 m by default) and the end scatter grows as `L^1.5`, a random walk
    /// in distance as on a floor. A fixed count per segment would draw larger slips on longer
    /// legs and grow the scatter as `L²`, faster than any floor does.
    #[arg(long, default_value_t = 20)]
    pub substeps: u32,
    /// True E_b.
    #[arg(long, default_value_t = 1.010)]
    pub eb: f64,
    /// True E_d.
    #[arg(long, default_value_t = 0.995)]
    pub ed: f64,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory (CSV and SVG files).
    #[arg(long, default_value = "target/odocal-sim/sweep")]
    pub out: PathBuf,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

impl Default for SweepArgs {
    fn default() -> Self {
        SweepArgs {
            sides: vec![0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0],
            meas_sigmas: vec![0.002, 0.01],
            slips: vec![0.0005, 0.003],
            trials: 200,
            runs: 5,
            substeps: 20,
            eb: 1.010,
            ed: 0.995,
            seed: 1,
            out: PathBuf::from("target/odocal-sim/sweep"),
            quiet: true,
        }
    }
}

/// Statistics of one method in one cell.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MethodStats {
    /// Successful calibrations.
    pub n: u32,
    /// Failed calibrations.
    pub failed: u32,
    /// Mean relative error of `E_b`.
    pub e_b_mean: f64,
    /// Standard deviation of the relative error of `E_b`.
    pub e_b_std: f64,
    /// Mean relative error of `E_d`.
    pub e_d_mean: f64,
    /// Standard deviation of the relative error of `E_d`.
    pub e_d_std: f64,
    /// RMS over trials of `sqrt(ΔE_b² + ΔE_d²)`.
    pub rms_error: f64,
    /// The advice's expected error at this side (`None` where the method fails).
    pub predicted: Option<f64>,
}

/// One (noise level, side) cell.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    /// 1σ measurement error of a coordinate, metres.
    pub meas_sigma_m: f64,
    /// Relative slip σ per substep.
    pub slip: f64,
    /// Side, metres.
    pub side_m: f64,
    /// Per method, in [`SWEEP_METHODS`] order.
    pub methods: [MethodStats; 5],
}

/// Best side per method at one noise level, by the sweep and by the advice.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BestSide {
    /// 1σ measurement error of a coordinate, metres.
    pub meas_sigma_m: f64,
    /// Relative slip σ per substep.
    pub slip: f64,
    /// Pilot scatter at [`PILOT_SIDE_M`] given to the advice, metres.
    pub pilot_scatter_m: f64,
    /// Method.
    pub method: Method,
    /// Side with the smallest measured RMS error (and that error).
    pub sweep: Option<(f64, f64)>,
    /// Side the advice picks among the sweep's sides (and its predicted error).
    pub advice_on_grid: Option<(f64, f64)>,
    /// Side the advice picks among all its candidates up to the largest swept side.
    pub advice: Option<(f64, f64)>,
    /// Measured RMS error at the side the advice picked on the grid.
    pub sweep_at_advice: Option<f64>,
}

/// Everything a sweep produced.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepResult {
    /// Every cell, noise levels outer, sides inner.
    pub cells: Vec<Cell>,
    /// Best sides per noise level and method.
    pub best: Vec<BestSide>,
}

/// A well-mixed seed for one trial.
fn trial_seed(seed: u64, level: usize, side: usize, trial: u32) -> u64 {
    let mut r = Rng::new(
        seed ^ (level as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (side as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ u64::from(trial).wrapping_mul(0x1656_67B1_9E37_79F9),
    );
    // One draw decorrelates neighbouring seeds.
    (r.uniform() * (1u64 << 53) as f64) as u64
}

/// Substeps per segment of a square of side `side_m`: `pilot_substeps` at [`PILOT_SIDE_M`],
/// proportionally many elsewhere (at least one), so each substep is the same length of travel.
/// (The quarter turns get the same count: their slip adds ≈ 2 % of a leg's heading variance at
/// 2 m and less on longer sides.)
pub fn substeps_for(pilot_substeps: u32, side_m: f64) -> u32 {
    ((f64::from(pilot_substeps) * side_m / PILOT_SIDE_M).round() as u32).max(1)
}

fn mc_args(a: &SweepArgs, side_m: f64, meas: f64, slip: f64) -> MonteCarloArgs {
    MonteCarloArgs {
        trials: a.trials,
        side: side_m,
        runs: a.runs,
        meas_sigma: meas,
        slip,
        substeps: substeps_for(a.substeps, side_m),
        eb: a.eb,
        ed: a.ed,
        seed: a.seed,
        slip_start: 0.0,
        slip_start_rad: 0.0,
        heading: false,
        meas_sigma_rad: 0.0,
        end_offset_mm: Vec::new(),
        format: Format::Text,
    }
}

/// One trial: relative `(ΔE_b, ΔE_d)` per method, `None` where it failed.
fn trial(
    a: &SweepArgs,
    truth: &Geometry,
    side_m: f64,
    meas: f64,
    slip: f64,
    seed: u64,
) -> [Option<(f64, f64)>; 5] {
    let nominal = Geometry::PAPER_NOMINAL;
    let mc = mc_args(a, side_m, meas, slip);
    let mut rng = Rng::new(seed);
    let recs = noisy_squares(&nominal, truth, side_m, a.runs, &mc, &mut rng);
    let obs = observations(&recs, side_m, &nominal);
    SWEEP_METHODS.map(|m| {
        calibrate(&obs, &nominal, m)
            .ok()
            .map(|c| (c.e_b / a.eb - 1.0, c.e_d / truth.diameter_ratio() - 1.0))
    })
}

fn stats(samples: &[[Option<(f64, f64)>; 5]], k: usize) -> MethodStats {
    let ok: Vec<(f64, f64)> = samples.iter().filter_map(|s| s[k]).collect();
    let n = ok.len();
    let mut s = MethodStats {
        n: n as u32,
        failed: (samples.len() - n) as u32,
        ..MethodStats::default()
    };
    if n == 0 {
        s.rms_error = f64::NAN;
        return s;
    }
    let nf = n as f64;
    s.e_b_mean = ok.iter().map(|v| v.0).sum::<f64>() / nf;
    s.e_d_mean = ok.iter().map(|v| v.1).sum::<f64>() / nf;
    let dof = (nf - 1.0).max(1.0);
    s.e_b_std = (ok.iter().map(|v| (v.0 - s.e_b_mean).powi(2)).sum::<f64>() / dof).sqrt();
    s.e_d_std = (ok.iter().map(|v| (v.1 - s.e_d_mean).powi(2)).sum::<f64>() / dof).sqrt();
    s.rms_error = (ok.iter().map(|v| v.0 * v.0 + v.1 * v.1).sum::<f64>() / nf).sqrt();
    s
}

/// The scatter an operator would observe: `runs`×5 slip-only squares per direction at
/// [`PILOT_SIDE_M`] (no measurement noise), pooled around their centres of gravity.
pub fn pilot_scatter(a: &SweepArgs, truth: &Geometry, slip: f64, seed: u64) -> Option<f64> {
    let nominal = Geometry::PAPER_NOMINAL;
    let mc = mc_args(a, PILOT_SIDE_M, 0.0, slip);
    let mut rng = Rng::new(seed);
    let recs = noisy_squares(
        &nominal,
        truth,
        PILOT_SIDE_M,
        5 * a.runs.max(1),
        &mc,
        &mut rng,
    );
    let obs = observations(&recs, PILOT_SIDE_M, &nominal);
    SquareStats::from_runs(&obs, true).ok()?.scatter_m()
}

/// Runs the sweep; `progress` is advanced by one per trial (use [`ProgressBar::hidden`] for
/// none).
///
/// # Errors
/// An invalid truth, an empty grid or non-positive sides.
pub fn sweep(a: &SweepArgs, progress: &ProgressBar) -> Result<SweepResult, String> {
    let nominal = Geometry::PAPER_NOMINAL;
    let truth = true_geometry(&nominal, a.eb, a.ed, TruthModel::Mean);
    truth
        .validate()
        .map_err(|e| format!("invalid truth: {e}"))?;
    if a.sides.is_empty() || a.meas_sigmas.is_empty() || a.slips.is_empty() || a.trials == 0 {
        return Err("empty grid: need sides, noise levels and trials ≥ 1".into());
    }
    if a.sides.iter().any(|&l| !(l > 0.0 && l.is_finite())) {
        return Err("sides must be positive".into());
    }
    let levels: Vec<(f64, f64)> = a
        .meas_sigmas
        .iter()
        .flat_map(|&m| a.slips.iter().map(move |&s| (m, s)))
        .collect();
    progress.set_length((levels.len() * a.sides.len()) as u64 * u64::from(a.trials));
    let max_side = a.sides.iter().copied().fold(0.0, f64::max);
    let mut cells = Vec::new();
    let mut best = Vec::new();
    for (li, &(meas, slip)) in levels.iter().enumerate() {
        let scatter = pilot_scatter(a, &truth, slip, trial_seed(a.seed, li, usize::MAX, 0));
        let input = TrackAdviceInput {
            belief: nominal,
            estimate: truth,
            measurement_sigma_m: meas,
            measurement_sigma_rad: 0.0,
            observed_scatter: scatter.map(|s| (s, PILOT_SIDE_M)),
            runs_per_direction: a.runs,
            max_side_m: max_side,
        };
        let first = cells.len();
        for (si, &side) in a.sides.iter().enumerate() {
            let samples: Vec<_> = (0..a.trials)
                .into_par_iter()
                .map(|t| {
                    let r = trial(a, &truth, side, meas, slip, trial_seed(a.seed, li, si, t));
                    progress.inc(1);
                    r
                })
                .collect();
            let mut methods = [MethodStats::default(); 5];
            for (k, m) in SWEEP_METHODS.iter().enumerate() {
                methods[k] = stats(&samples, k);
                methods[k].predicted = evaluate(&input, *m, side).map(|e| e.expected_error);
            }
            cells.push(Cell {
                meas_sigma_m: meas,
                slip,
                side_m: side,
                methods,
            });
        }
        let level = &cells[first..];
        for (k, m) in SWEEP_METHODS.iter().enumerate() {
            let pick = |f: &dyn Fn(&Cell) -> Option<f64>| {
                level
                    .iter()
                    .filter_map(|c| f(c).filter(|v| v.is_finite()).map(|v| (c.side_m, v)))
                    .min_by(|x, y| x.1.total_cmp(&y.1))
            };
            let advice_on_grid = pick(&|c| c.methods[k].predicted);
            best.push(BestSide {
                meas_sigma_m: meas,
                slip,
                pilot_scatter_m: scatter.unwrap_or(0.0),
                method: *m,
                sweep: pick(&|c| Some(c.methods[k].rms_error)),
                advice_on_grid,
                advice: advise(&input, *m).map(|x| (x.side_m, x.expected_error)),
                sweep_at_advice: advice_on_grid.and_then(|(l, _)| {
                    level
                        .iter()
                        .find(|c| c.side_m == l)
                        .map(|c| c.methods[k].rms_error)
                }),
            });
        }
    }
    Ok(SweepResult { cells, best })
}

/// The CSV text of a sweep: one row per (noise level, side, method).
pub fn csv(result: &SweepResult) -> String {
    let mut s = String::from(
        "meas_sigma_m,slip,side_m,method,trials_ok,failed,e_b_err_mean,e_b_err_std,e_d_err_mean,e_d_err_std,rms_error,advice_predicted\n",
    );
    for c in &result.cells {
        for (m, st) in SWEEP_METHODS.iter().zip(c.methods.iter()) {
            let _ = writeln!(
                s,
                "{},{},{},{},{},{},{:e},{:e},{:e},{:e},{:e},{}",
                c.meas_sigma_m,
                c.slip,
                c.side_m,
                m.as_str(),
                st.n,
                st.failed,
                st.e_b_mean,
                st.e_b_std,
                st.e_d_mean,
                st.e_d_std,
                st.rms_error,
                st.predicted.map_or(String::new(), |p| format!("{p:e}"))
            );
        }
    }
    s
}

/// The figure of one noise level: RMS parameter error against side per method
/// (thick lines: sweep; thin lines: the advice's prediction).
pub fn figure(result: &SweepResult, meas_sigma_m: f64, slip: f64) -> Figure {
    let level: Vec<&Cell> = result
        .cells
        .iter()
        .filter(|c| c.meas_sigma_m == meas_sigma_m && c.slip == slip)
        .collect();
    let mut series = Vec::new();
    for (k, m) in SWEEP_METHODS.iter().enumerate() {
        let measured: Vec<(f64, f64)> = level
            .iter()
            .map(|c| (c.side_m, c.methods[k].rms_error))
            .collect();
        let predicted: Vec<(f64, f64)> = level
            .iter()
            .filter_map(|c| c.methods[k].predicted.map(|p| (c.side_m, p)))
            .collect();
        series.push(Series::new(m.as_str(), measured, Style::Line, k));
        series.push(Series::new(
            format!("{} (advice)", m.as_str()),
            predicted,
            Style::ThinLine,
            k,
        ));
    }
    Figure {
        title: format!(
            "Parameter error vs square side (σ_meas = {} mm, slip σ = {})",
            meas_sigma_m * 1e3,
            slip
        ),
        x_label: "square side L [m]".into(),
        y_label: "RMS of sqrt(ΔE_b² + ΔE_d²)".into(),
        log_x: true,
        log_y: true,
        series,
        ..Figure::default()
    }
}

/// Writes `sweep.csv` and one SVG per noise level into `dir`; returns the paths written.
///
/// # Errors
/// File or drawing errors.
pub fn write_outputs(
    result: &SweepResult,
    dir: &Path,
) -> Result<Vec<PathBuf>, Box<dyn std::error::Error>> {
    std::fs::create_dir_all(dir)?;
    let mut written = Vec::new();
    let path = dir.join("sweep.csv");
    std::fs::write(&path, csv(result))?;
    written.push(path);
    let mut levels: Vec<(f64, f64)> = Vec::new();
    for c in &result.cells {
        if !levels.contains(&(c.meas_sigma_m, c.slip)) {
            levels.push((c.meas_sigma_m, c.slip));
        }
    }
    for (meas, slip) in levels {
        let path = dir.join(format!(
            "sweep-meas{}mm-slip{}.svg",
            meas * 1e3,
            slip.to_string().replace('.', "p")
        ));
        write_svg(&path, &figure(result, meas, slip))?;
        written.push(path);
    }
    Ok(written)
}

/// A progress bar for `total` trials on stderr (hidden when `quiet`).
pub fn progress_bar(quiet: bool, message: &'static str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(0);
    if let Ok(style) =
        ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} ({elapsed}, eta {eta})")
    {
        pb.set_style(style.progress_chars("=> "));
    }
    pb.set_message(message);
    pb
}
