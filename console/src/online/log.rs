//! The online calibration's log (`--reference-log FILE`, JSON lines) and its offline twin
//! (`recalibrate --reference-log FILE`).
//!
//! - `{"k":"online", "nominal":[D_R, D_L, b, counts], "horizon_m", "fit_scale", "window_m", …}`:
//!   the estimator's settings, once at the start;
//! - `{"k":"window", "t0", "t1", "travel_m", "geometry":[…], "knots":[[R, L], …],
//!   "truth":[[x, y, θ], …], "end":[x, y, θ], "sd_xy_m", "sd_theta_rad", "weight", "accepted",
//!   "why"}`: every window, on the board's clock, with its wheel travel (the ticks), the
//!   reference's motion (in the window's start frame), its weight, and why it was rejected;
//! - `{"k":"estimate", "e_d", "e_b", "e_s", "sd_e_d", "sd_e_b", "sd_e_s", "windows", "travel_m"}`
//!   after every accepted window that gave one;
//! - `{"k":"applied", …}`: an estimate the bridge applied on the board, and where it came from.
//!
//! Numbers are written as the shortest text that reads back to the same `f64`, so the twin
//! fits the very same windows and finds the estimate bit for bit.

use std::fs::File;
use std::io::{BufRead, BufReader, Write};
use std::path::Path;

use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;
use serde_json::{Value, json};

use super::estimator::{Estimate, Estimator, EstimatorOptions};
use super::window::{Rejected, Window};

fn geometry_json(g: &Geometry) -> Value {
    json!([
        g.diameter_right_m,
        g.diameter_left_m,
        g.wheelbase_m,
        g.counts_per_rev
    ])
}

fn geometry_of(v: &Value) -> Option<Geometry> {
    let a = v.as_array()?;
    Some(Geometry {
        diameter_right_m: a.first()?.as_f64()?,
        diameter_left_m: a.get(1)?.as_f64()?,
        wheelbase_m: a.get(2)?.as_f64()?,
        counts_per_rev: u32::try_from(a.get(3)?.as_u64()?).ok()?,
    })
}

fn pose_json(p: &PoseF64) -> Value {
    json!([p.x_m, p.y_m, p.theta_rad])
}

fn pose_of(v: &Value) -> Option<PoseF64> {
    let a = v.as_array()?;
    Some(PoseF64::new(
        a.first()?.as_f64()?,
        a.get(1)?.as_f64()?,
        a.get(2)?.as_f64()?,
    ))
}

/// The settings record.
pub fn header(nominal: &Geometry, options: &EstimatorOptions, window_m: f64) -> Value {
    json!({
        "k": "online",
        "nominal": geometry_json(nominal),
        "horizon_m": options.horizon_m,
        "fit_scale": options.fit_scale,
        "window_m": window_m,
    })
}

/// A window's record.
pub fn window(w: &Window) -> Value {
    json!({
        "k": "window",
        "t0": w.t0_s,
        "t1": w.t1_s,
        "travel_m": w.travel_m,
        "geometry": geometry_json(&w.geometry),
        "knots": w.knots.iter().map(|k| json!([k.right, k.left])).collect::<Vec<_>>(),
        "truth": w.truth.iter().map(pose_json).collect::<Vec<_>>(),
        "end": pose_json(&w.end),
        "sd_xy_m": w.sd_xy_m,
        "sd_theta_rad": w.sd_theta_rad,
        "weight": w.weight(),
        "accepted": w.rejected.is_none(),
        "why": w.rejected.map(Rejected::as_str),
    })
}

/// An estimate's record.
pub fn estimate(e: &Estimate) -> Value {
    json!({
        "k": "estimate",
        "e_d": e.e_d,
        "e_b": e.e_b,
        "e_s": e.e_s,
        "sd_e_d": e.sd_e_d,
        "sd_e_b": e.sd_e_b,
        "sd_e_s": e.sd_e_s,
        "windows": e.windows,
        "travel_m": e.travel_m,
    })
}

fn window_of(v: &Value) -> Option<Window> {
    let knots = v["knots"]
        .as_array()?
        .iter()
        .map(|k| {
            Some(WheelTicks {
                right: k.get(0)?.as_i64()?,
                left: k.get(1)?.as_i64()?,
            })
        })
        .collect::<Option<Vec<_>>>()?;
    let truth = v["truth"]
        .as_array()?
        .iter()
        .map(pose_of)
        .collect::<Option<Vec<_>>>()?;
    Some(Window {
        t0_s: v["t0"].as_f64()?,
        t1_s: v["t1"].as_f64()?,
        geometry: geometry_of(&v["geometry"])?,
        knots,
        truth,
        end: pose_of(&v["end"])?,
        travel_m: v["travel_m"].as_f64()?,
        sd_xy_m: v["sd_xy_m"].as_f64()?,
        sd_theta_rad: v["sd_theta_rad"].as_f64()?,
        rejected: if v["accepted"].as_bool()? {
            None
        } else {
            Some(Rejected::parse(v["why"].as_str()?)?)
        },
    })
}

/// A log being written (nothing is written without a file).
pub struct LogFile(Option<File>);

impl LogFile {
    /// Creates (truncates) the file at `path`, or a log that writes nothing.
    ///
    /// # Errors
    /// The file cannot be created, as text.
    pub fn create(path: Option<&Path>) -> Result<LogFile, String> {
        match path {
            None => Ok(LogFile(None)),
            Some(p) => File::create(p)
                .map(|f| LogFile(Some(f)))
                .map_err(|e| format!("{}: {e}", p.display())),
        }
    }

    /// Appends a record (a failed write is said once on stderr and the log stops).
    pub fn write(&mut self, record: &Value) {
        if let Some(f) = &mut self.0
            && writeln!(f, "{record}").and_then(|()| f.flush()).is_err()
        {
            eprintln!("online: the reference log cannot be written any more");
            self.0 = None;
        }
    }
}

/// What the offline twin found.
#[derive(Debug)]
pub struct Replayed {
    pub estimate: Option<Estimate>,
    /// The last estimate the log holds.
    pub logged: Option<Estimate>,
    pub used: usize,
    pub rejected: usize,
}

fn estimate_of(v: &Value) -> Option<Estimate> {
    Some(Estimate {
        e_d: v["e_d"].as_f64()?,
        e_b: v["e_b"].as_f64()?,
        e_s: v["e_s"].as_f64()?,
        sd_e_d: v["sd_e_d"].as_f64()?,
        sd_e_b: v["sd_e_b"].as_f64()?,
        sd_e_s: v["sd_e_s"].as_f64()?,
        windows: usize::try_from(v["windows"].as_u64()?).ok()?,
        travel_m: v["travel_m"].as_f64()?,
    })
}

/// Redoes the estimate of a log: its windows through the same estimator.
///
/// # Errors
/// The file cannot be read, a line is not a record, or the settings record is missing.
pub fn replay(path: &Path) -> Result<Replayed, String> {
    let f = File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut estimator: Option<Estimator> = None;
    let mut logged = None;
    for (i, line) in BufReader::new(f).lines().enumerate() {
        let line = line.map_err(|e| format!("{}: {e}", path.display()))?;
        if line.trim().is_empty() {
            continue;
        }
        let bad = |what: &str| format!("{}:{}: {what}", path.display(), i + 1);
        let v: Value = serde_json::from_str(&line).map_err(|e| bad(&e.to_string()))?;
        match v["k"].as_str() {
            Some("online") => {
                let nominal = geometry_of(&v["nominal"]).ok_or_else(|| bad("no nominal"))?;
                let options = EstimatorOptions {
                    horizon_m: v["horizon_m"].as_f64().ok_or_else(|| bad("no horizon_m"))?,
                    fit_scale: v["fit_scale"]
                        .as_bool()
                        .ok_or_else(|| bad("no fit_scale"))?,
                };
                estimator = Some(Estimator::new(nominal, options));
            }
            Some("window") => {
                let e = estimator
                    .as_mut()
                    .ok_or_else(|| bad("a window before the settings record"))?;
                let w = window_of(&v).ok_or_else(|| bad("a malformed window"))?;
                // A failed fit leaves the estimate as it was, in the bridge as here.
                let _ = e.push(w);
            }
            Some("estimate") => logged = estimate_of(&v),
            _ => {}
        }
    }
    let e = estimator.ok_or_else(|| format!("{}: no settings record", path.display()))?;
    Ok(Replayed {
        estimate: e.estimate(),
        logged,
        used: e.used,
        rejected: e.rejected,
    })
}

/// `recalibrate --reference-log FILE`: the estimate, and whether it is the logged one.
///
/// # Errors
/// As [`replay`].
pub fn recalibrate(path: &Path) -> Result<(), String> {
    let r = replay(path)?;
    println!("windows: {} used, {} rejected", r.used, r.rejected);
    let Some(e) = r.estimate else {
        println!(
            "no estimate: fewer than {} windows",
            super::estimator::MIN_WINDOWS
        );
        return Ok(());
    };
    println!("{}", describe(&e));
    match r.logged {
        Some(l) if l == e => println!("the logged estimate, bit for bit"),
        Some(l) => {
            return Err(format!(
                "differs from the logged estimate ({})",
                describe(&l)
            ));
        }
        None => println!("the log holds no estimate to compare"),
    }
    Ok(())
}

/// One line for an estimate.
pub fn describe(e: &Estimate) -> String {
    format!(
        "online E_d={:.6}+-{:.6} E_b={:.6}+-{:.6} E_s={:.6}+-{:.6} from {} windows, {:.1} m",
        e.e_d, e.sd_e_d, e.e_b, e.sd_e_b, e.e_s, e.sd_e_s, e.windows, e.travel_m
    )
}
