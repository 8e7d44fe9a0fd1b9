//! The session's figures (SVG, [`crate::sim::plot`]), after the paper's:
//! - `squares-before.svg`, `squares-after.svg`: the CW/CCW squares of the calibration runs
//!   (nominal parameters) and of the verification runs on the rebooted board (calibrated), true
//!   path vs odometry, each in its run's start frame (Fig. 7–8);
//! - `end-clouds.svg`: end errors of fresh squares with each method's parameters (Fig. 9/14),
//!   `end-clouds-before.svg` the same with the nominal ones for scale;
//! - `rectangle-growth.svg`: position error over distance on the rectangle test, nominal and
//!   every method (Fig. 11–12), `rectangle-paths.svg` the paths with nominal and applied
//!   parameters;
//! - `param-error-vs-side.svg`, `sweep.csv`: parameter error against square side (Fig. 5).
//!
//! Also the transcript of the serial session (`session.log`) and the printed report
//! (`summary.txt`).

use std::path::{Path, PathBuf};

use odocal::motion::run::Direction;

use super::{RunTrace, SessionReport, report};
use crate::sim::plot::{Figure, Series, Style, write_svg};

fn squares_figure(title: &str, runs: &[RunTrace]) -> Figure {
    let mut series = Vec::new();
    for (k, dir) in [Direction::Cw, Direction::Ccw].into_iter().enumerate() {
        let name = dir.as_str().to_uppercase();
        for (i, r) in runs.iter().filter(|r| r.direction == dir).enumerate() {
            let first = i == 0;
            series.push(Series::new(
                if first {
                    format!("{name} true")
                } else {
                    String::new()
                },
                r.true_path.clone(),
                Style::Line,
                2 * k,
            ));
            series.push(Series::new(
                if first {
                    format!("{name} odometry")
                } else {
                    String::new()
                },
                r.odometry_path.clone(),
                Style::ThinLine,
                2 * k + 1,
            ));
        }
    }
    Figure {
        title: title.into(),
        x_label: "x [m] (run start frame)".into(),
        y_label: "y [m]".into(),
        equal_aspect: true,
        series,
        ..Figure::default()
    }
}

fn clouds_figure(r: &SessionReport, with_nominal: bool) -> Figure {
    let mut series = Vec::new();
    for (k, v) in r.verifications.iter().enumerate() {
        let include = if with_nominal {
            v.label == "nominal" || v.label == r.args.method
        } else {
            v.label != "nominal"
        };
        if !include {
            continue;
        }
        for dir in [Direction::Cw, Direction::Ccw] {
            let pts: Vec<(f64, f64)> = v
                .ends
                .iter()
                .filter(|e| e.0 == dir)
                .map(|e| (e.1 * 1e3, e.2 * 1e3))
                .collect();
            // One legend entry per parameter set: the CW and CCW clouds lie apart anyway.
            let label = if dir == Direction::Cw {
                v.label.clone()
            } else {
                String::new()
            };
            series.push(Series::new(label, pts, Style::Points, k));
        }
    }
    Figure {
        title: if with_nominal {
            format!(
                "End errors of {n}+{n} squares, L = {} m: nominal vs {}",
                r.side_m,
                r.args.method,
                n = r.args.runs
            )
        } else {
            format!(
                "End errors of {n}+{n} squares, L = {} m, per calibration method",
                r.side_m,
                n = r.args.runs
            )
        },
        x_label: "true − odometry x [mm]".into(),
        y_label: "true − odometry y [mm]".into(),
        equal_aspect: true,
        series,
        ..Figure::default()
    }
}

fn growth_figure(r: &SessionReport) -> Figure {
    let series = r
        .verifications
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let pts = v
                .rectangle
                .growth
                .iter()
                // From 1 m on: the log axis has no place for the zero error at the start.
                .filter(|&&(d, e)| d >= 1.0 && e > 0.0)
                .copied()
                .collect();
            Series::new(
                format!("{} ({:.3} m)", v.label, v.rectangle.final_error_m),
                pts,
                Style::Line,
                k,
            )
        })
        .collect();
    Figure {
        title: format!(
            "Rectangle test ({} CCW laps of 3.6 m × 8.7 m): odometry error over distance",
            r.args.laps
        ),
        x_label: "distance travelled [m]".into(),
        y_label: "position error [m]".into(),
        log_y: true,
        series,
        ..Figure::default()
    }
}

fn rectangle_paths_figure(r: &SessionReport) -> Figure {
    let mut series = Vec::new();
    if let Some(v) = r.verifications.first() {
        series.push(Series::new(
            "true path",
            v.rectangle.true_path.clone(),
            Style::Line,
            0,
        ));
    }
    for (k, v) in r.verifications.iter().enumerate() {
        if v.label == "nominal" || v.label == r.args.method {
            series.push(Series::new(
                format!("odometry, {}", v.label),
                v.rectangle.odometry_path.clone(),
                Style::ThinLine,
                k + 1,
            ));
        }
    }
    Figure {
        title: "Rectangle test: true path vs odometry".into(),
        x_label: "x [m]".into(),
        y_label: "y [m]".into(),
        equal_aspect: true,
        series,
        ..Figure::default()
    }
}

/// Writes every figure, the transcript and the report into `dir`; returns the paths.
///
/// # Errors
/// File or drawing errors.
pub fn write_all(
    r: &SessionReport,
    dir: &Path,
) -> Result<Vec<PathBuf>, Box<dyn std::error::Error>> {
    std::fs::create_dir_all(dir)?;
    let mut written = Vec::new();
    let mut svg = |name: &str, fig: &Figure| -> Result<(), Box<dyn std::error::Error>> {
        let p = dir.join(name);
        write_svg(&p, fig)?;
        written.push(p);
        Ok(())
    };
    svg(
        "squares-before.svg",
        &squares_figure(
            &format!(
                "Calibration runs (nominal parameters), L = {} m: true vs odometry",
                r.side_m
            ),
            &r.runs,
        ),
    )?;
    svg(
        "squares-after.svg",
        &squares_figure(
            &format!(
                "Verification after reboot ({} parameters), L = {} m",
                r.args.method, r.side_m
            ),
            &r.after_runs,
        ),
    )?;
    svg("end-clouds.svg", &clouds_figure(r, false))?;
    svg("end-clouds-before.svg", &clouds_figure(r, true))?;
    svg("rectangle-growth.svg", &growth_figure(r))?;
    svg("rectangle-paths.svg", &rectangle_paths_figure(r))?;
    if let Some(sw) = &r.sweep {
        let mut fig = crate::experiments::sweep::figure(sw, r.args.meas_mm * 1e-3, r.sweep_slip);
        fig.title = format!(
            "Parameter error vs square side ({} trials, σ_meas = {} mm, observed scatter)",
            r.args.sweep_trials, r.args.meas_mm
        );
        svg("param-error-vs-side.svg", &fig)?;
        let p = dir.join("sweep.csv");
        std::fs::write(&p, crate::experiments::sweep::csv(sw))?;
        written.push(p);
    }
    let p = dir.join("session.log");
    std::fs::write(&p, &r.transcript)?;
    written.push(p);
    let p = dir.join("summary.txt");
    std::fs::write(&p, report::text(r))?;
    written.push(p);
    Ok(written)
}
