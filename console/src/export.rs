//! `cargo console export LOG --format ros2|urdf|json [-o FILE]`: the calibration a session left
//! on the board, in a form a robot stack loads.
//!
//! LOG is the console's session log (JSON lines) or a plain capture of a terminal session with
//! the board (picocom's `--logfile`, `screen -L`, a copy of the terminal): what counts is the
//! board's own reply to `params` (the last one in the log), whose `active …` line is the
//! geometry the board drives with and whose `calibration …` line names the method applied. When
//! the log also holds the session's runs (a session log), the same method is solved again on the
//! PC with the board's library from those runs: if that agrees with the board's printed `active`
//! geometry to its 9 decimals, the full-precision values are written, otherwise the board's.
//!
//! The 1σ of E_d and E_b comes from that solution, or else from the method's row of the last
//! `calibrate` table in the log. The pose covariance is derived from it (see
//! [`pose_covariance`]).

use std::fmt::Write as _;
use std::path::Path;

use odocal::calibration::synth;
use odocal::kinematics::geometry::Geometry;
use odocal::motion::run::{Direction, PathKind, RunRecord};
use odocal::protocol::ParamName;
use odocal::protocol::reply::{self, FinalLine};
use odocal::protocol::token::{self, TableRow};
use odocal::session::Calibrator;
use odocal::session::library::LibraryCalibrator;
use serde_json::{Value, json};

use crate::log::{LogContents, calibration_of, nominal_of, param};

use crate::covariance::{
    self, Floor, PoseCovariance, RandomError, UNOBSERVED_VARIANCE, Uncertainty,
};
use odocal::calibration::covariance::RandomEstimate;
use odocal::kinematics::reference::ArcModel;

/// What the ROS 2 parameter file is for: the controller's name (its top key), the wheel
/// joints, and the inputs of the covariance model that are not in the log.
#[derive(Clone, Debug, PartialEq)]
pub struct Target {
    /// The controller's name in the controller manager's configuration.
    pub controller: String,
    /// The left wheel's joint.
    pub left_wheel: String,
    /// The right wheel's joint.
    pub right_wheel: String,
    /// Random travel error of each wheel after one metre (1σ, m); `None`: estimated from the
    /// log's runs (their scatter), or the default without runs.
    pub slip_m: Option<f64>,
    /// Keep the calibration's own 1σ of E_d and E_b, below the between-session floor.
    pub trust_session_sd: bool,
    /// The controller's update rate, Hz.
    pub rate_hz: f64,
    /// The controller's `velocity_rolling_window_size`: its speeds are the mean over this many
    /// updates (the twist's averaging period, with `rate_hz`).
    pub rolling_window: u32,
}

/// `diff_drive_controller`'s default `velocity_rolling_window_size`.
pub const ROLLING_WINDOW_DEFAULT: u32 = 10;

impl Default for Target {
    fn default() -> Self {
        Target {
            controller: "diff_drive_controller".into(),
            left_wheel: "left_wheel_joint".into(),
            right_wheel: "right_wheel_joint".into(),
            slip_m: None,
            trust_session_sd: false,
            rate_hz: 100.0,
            rolling_window: ROLLING_WINDOW_DEFAULT,
        }
    }
}

/// The output formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// ROS 2 `diff_drive_controller` parameter file (YAML).
    Ros2,
    /// URDF snippet: the wheel links and joints.
    Urdf,
    /// The calibration, its uncertainty and the runs (JSON).
    Json,
}

/// What a log says about the board's calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct Export {
    /// The nominal geometry (`params`).
    pub nominal: Geometry,
    /// The geometry the board drives with.
    pub applied: Geometry,
    /// The applied method, `None` for an uncalibrated board.
    pub method: Option<String>,
    /// `(E_d, E_b, E_s)` of the applied geometry.
    pub factors: (f64, f64, f64),
    /// 1σ of E_d and E_b, when the log says.
    pub sd: Option<(f64, f64)>,
    /// Where the applied geometry's digits come from.
    pub source: String,
    /// The square side the pose covariance refers to (the board's `square_side`).
    pub side_m: f64,
    /// The board's `max_accel` (the speed loop's limit, for the twist covariance), m/s².
    pub max_accel: f64,
    /// The runs of a session log.
    pub runs: Vec<RunRecord>,
    /// When the oldest of `runs` was logged (Unix seconds): the calibration's age.
    pub runs_logged_s: Option<f64>,
    /// The last `calibrate` table in the log (its lines).
    pub table: Vec<String>,
}

/// The board's replies found in a sequence of received lines: the last `params` data lines and
/// the last `calibrate` table (its lines, the final one included).
#[derive(Debug, Default)]
struct Replies {
    params: Option<Vec<String>>,
    table: Option<Vec<String>>,
}

#[derive(PartialEq)]
enum Block {
    Params,
    Table,
    Other,
}

/// Scans the board's output: data lines (two leading spaces) up to a final `ok`/`err` line form
/// a reply; `event`/`stream` lines between them are skipped, anything else (an echoed command,
/// a prompt) ends the reply being read.
fn scan<'a>(lines: impl Iterator<Item = &'a str>) -> Replies {
    let mut found = Replies::default();
    let mut current: Option<(Block, Vec<String>)> = None;
    for raw in lines {
        let l = raw.trim_end_matches(['\r', '\n']);
        if let Some(data) = reply::data(l) {
            let data = data.trim_start().to_string();
            let (_, lines) = current.get_or_insert_with(|| {
                let kind = if token::is_params_start(&data) {
                    Block::Params
                } else if data.starts_with(token::TABLE_HEADER) {
                    Block::Table
                } else {
                    Block::Other
                };
                (kind, Vec::new())
            });
            lines.push(data);
        } else if let Some(last) = FinalLine::parse(l) {
            match current.take() {
                Some((Block::Params, lines)) if last == FinalLine::Ok("") => {
                    found.params = Some(lines)
                }
                Some((Block::Table, mut lines)) => {
                    lines.push(l.to_string());
                    found.table = Some(lines);
                }
                _ => {}
            }
        } else if !(l.starts_with(token::EVENT) || l.starts_with(token::STREAM)) {
            current = None;
        }
    }
    found
}

/// `key=value` of a text, as a number.
fn number_after(text: &str, key: &str) -> Option<f64> {
    text.split_whitespace()
        .find_map(|w| w.strip_prefix(key)?.strip_prefix('='))
        .and_then(|v| v.parse().ok())
}

/// The `active d_right=… d_left=… wheelbase=… m` line of a `params` reply.
pub(crate) fn active_of(params: &[String], counts_per_rev: u32) -> Option<Geometry> {
    let line = params.iter().find_map(|l| l.strip_prefix(token::ACTIVE))?;
    Some(Geometry {
        diameter_right_m: number_after(line, ParamName::DiameterRight.as_str())?,
        diameter_left_m: number_after(line, ParamName::DiameterLeft.as_str())?,
        wheelbase_m: number_after(line, ParamName::Wheelbase.as_str())?,
        counts_per_rev,
    })
}

/// `(sd_E_d, sd_E_b)` of `method`'s row in a `calibrate` table, read by the header's column
/// names.
fn sd_of(table: &[String], method: &str) -> Option<(f64, f64)> {
    let row = table.iter().find_map(|l| {
        TableRow::parse(l)
            .filter(|r| matches!(r, TableRow::Solved { method: m, .. } if *m == method))
    })?;
    Some((row.value("sd_E_d")?, row.value("sd_E_b")?))
}

/// `v` as a YAML float that YAML 1.1 readers (PyYAML) take as a number too: the shortest
/// digits that read back to the same `f64`, with a decimal point in the mantissa and a signed
/// exponent (`1.0e-5`, not `1e-5`).
pub fn yaml_float(v: f64) -> String {
    let s = format!("{v:?}");
    match s.split_once('e') {
        Some((mantissa, exp)) => {
            let mantissa = if mantissa.contains('.') {
                mantissa.to_string()
            } else {
                format!("{mantissa}.0")
            };
            let exp = if exp.starts_with('-') {
                exp.to_string()
            } else {
                format!("+{exp}")
            };
            format!("{mantissa}e{exp}")
        }
        None => s,
    }
}

/// The printed resolution of the `active` line (9 decimals) plus the error of its parse.
const PRINTED: f64 = 0.5e-9 + 1e-15;

fn within_print(a: &Geometry, b: &Geometry) -> bool {
    (a.diameter_right_m - b.diameter_right_m).abs() <= PRINTED
        && (a.diameter_left_m - b.diameter_left_m).abs() <= PRINTED
        && (a.wheelbase_m - b.wheelbase_m).abs() <= PRINTED
}

impl Export {
    /// Reads a session log (JSON lines) or a plain terminal capture.
    ///
    /// # Errors
    /// No `params` reply of the board in it, or an unreadable file, as text.
    pub fn read(path: &Path) -> Result<Export, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let session_log = text
            .lines()
            .find(|l| !l.trim().is_empty())
            .is_some_and(|l| serde_json::from_str::<Value>(l).is_ok_and(|v| v["kind"].is_string()));
        let stale = if session_log {
            let entries: Vec<(usize, String, Option<bool>)> = text
                .lines()
                .enumerate()
                .filter_map(|(i, l)| {
                    let v = serde_json::from_str::<Value>(l).ok()?;
                    let tx = match v["kind"].as_str()? {
                        "tx" => true,
                        "rx" => false,
                        _ => return None,
                    };
                    Some((i + 1, v["line"].as_str()?.to_string(), Some(tx)))
                })
                .collect();
            crate::stale::stale_params(entries.iter().map(|(n, l, t)| (*n, l.as_str(), *t)))
        } else {
            crate::stale::stale_params(text.lines().enumerate().map(|(i, l)| (i + 1, l, None)))
        };
        if let Some(s) = stale {
            return Err(format!(
                "{}:{}: `{}` came after the board's last `params` reply (line {}) and changed \
                 its geometry: the board no longer holds the calibration that reply shows; type \
                 `params` on the board and export a log that ends with its reply",
                path.display(),
                s.line,
                s.command,
                s.params_line
            ));
        }
        let (replies, runs, tables, runs_logged_s) = if session_log {
            let c = LogContents::read(path)?;
            let rx: Vec<String> = text
                .lines()
                .filter_map(|l| serde_json::from_str::<Value>(l).ok())
                .filter(|v| v["kind"] == "rx")
                .filter_map(|v| v["line"].as_str().map(str::to_string))
                .collect();
            let mut replies = scan(rx.iter().map(String::as_str));
            // The console logs its data lines too (without the board's two spaces).
            if replies.params.is_none() {
                replies.params = last_logged_params(&text);
            }
            let logged = c.oldest_live_run_s();
            (replies, c.live_runs(), c.tables, logged)
        } else {
            (scan(text.lines()), Vec::new(), Vec::new(), None)
        };
        let params = replies.params.ok_or_else(|| {
            format!(
                "{}: no reply of the board to `params` in it (type `params` on the board's \
                 console while the log is being written)",
                path.display()
            )
        })?;
        let nominal = nominal_of(&params)
            .ok_or_else(|| format!("{}: its `params` reply has no geometry", path.display()))?;
        let active = active_of(&params, nominal.counts_per_rev).ok_or_else(|| {
            format!(
                "{}: its `params` reply has no `active` line (a firmware too old to say)",
                path.display()
            )
        })?;
        let calibration = calibration_of(&params);
        let method = calibration
            .split_whitespace()
            .next()
            .filter(|m| *m != "none")
            .map(str::to_string);
        let table = tables
            .last()
            .map(|(_, t)| t.clone())
            .or(replies.table)
            .unwrap_or_default();
        let side_m = param(&params, "square_side").unwrap_or(2.0);
        let max_accel = param(&params, "max_accel").unwrap_or(0.3);
        let mut export = Export {
            nominal,
            applied: active,
            method: method.clone(),
            factors: (
                number_after(&calibration, "E_d").unwrap_or(active.diameter_ratio()),
                number_after(&calibration, "E_b")
                    .unwrap_or(active.wheelbase_m / nominal.wheelbase_m),
                number_after(&calibration, "E_s").unwrap_or(1.0),
            ),
            sd: None,
            source: "the board's `params` (active geometry, 9 decimals)".into(),
            side_m,
            max_accel,
            runs,
            runs_logged_s,
            table,
        };
        let Some(method) = method else {
            export.source =
                "the board's `params`: no calibration applied (nominal geometry)".into();
            return Ok(export);
        };
        export.sd = sd_of(&export.table, &method);
        if !export.runs.is_empty()
            && let Ok(sol) =
                LibraryCalibrator::default().solve(&export.runs, &export.nominal, &method)
            && within_print(&sol.geometry, &active)
        {
            export.applied = sol.geometry;
            export.factors = (sol.e_d, sol.e_b, sol.e_s);
            export.sd = match (sol.sd_e_d, sol.sd_e_b) {
                (Some(d), Some(b)) => Some((d, b)),
                _ => export.sd,
            };
            export.source = format!(
                "`{method}` solved again from the log's {} runs with the board's library (equal \
                 to the board's `params` to its 9 decimals)",
                export.runs.len()
            );
        }
        Ok(export)
    }

    /// The nominal wheel radius the multipliers refer to: half the nominal mean diameter.
    pub fn wheel_radius(&self) -> f64 {
        0.25 * (self.nominal.diameter_right_m + self.nominal.diameter_left_m)
    }

    /// Writes the export in `format` for `target`.
    pub fn write_for(&self, format: Format, log: &Path, target: &Target) -> String {
        match format {
            Format::Ros2 => self.ros2(log, target),
            Format::Urdf => self.urdf(log),
            Format::Json => self.json(log).to_string() + "\n",
        }
    }

    fn origin(&self, log: &Path) -> String {
        match &self.method {
            Some(m) => format!(
                "odocal calibration `{m}` (E_d={} E_b={} E_s={}) from {}",
                self.factors.0,
                self.factors.1,
                self.factors.2,
                log.display()
            ),
            None => format!(
                "odocal nominal geometry (no calibration) from {}",
                log.display()
            ),
        }
    }

    fn ros2(&self, log: &Path, t: &Target) -> String {
        let g = &self.applied;
        let r = self.wheel_radius();
        let list = |v: &[f64]| {
            v.iter()
                .map(|v| yaml_float(*v))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let mut s = String::new();
        let _ = writeln!(s, "# {}", self.origin(log));
        let _ = writeln!(s, "# Digits: {}.", self.source);
        let _ = writeln!(
            s,
            "# D_R = 2 * wheel_radius * right_wheel_radius_multiplier = {} m,\n\
             # D_L = 2 * wheel_radius * left_wheel_radius_multiplier = {} m, b = wheel_separation.",
            g.diameter_right_m, g.diameter_left_m
        );
        let _ = writeln!(s, "{}:\n  ros__parameters:", t.controller);
        let _ = writeln!(s, "    left_wheel_names: [\"{}\"]", t.left_wheel);
        let _ = writeln!(s, "    right_wheel_names: [\"{}\"]", t.right_wheel);
        let _ = writeln!(s, "    wheel_separation: {}", yaml_float(g.wheelbase_m));
        let _ = writeln!(s, "    wheel_radius: {}", yaml_float(r));
        let _ = writeln!(s, "    wheel_separation_multiplier: 1.0");
        let _ = writeln!(
            s,
            "    left_wheel_radius_multiplier: {}",
            yaml_float(g.diameter_left_m / (2.0 * r))
        );
        let _ = writeln!(
            s,
            "    right_wheel_radius_multiplier: {}",
            yaml_float(g.diameter_right_m / (2.0 * r))
        );
        // A parameter file is used on days to come: the between-session floor.
        let (u, source) = self.uncertainty(t.slip_m, t.trust_session_sd, None);
        let pose = self.pose_covariance(&u);
        let _ = writeln!(
            s,
            "    # Variances of x, y (m^2), z, roll, pitch (unobserved) and yaw (rad^2): the end \
             pose's spread after one {side} m square, from {source} (relative sd_E_d={:.3e}, \
             sd_E_b={:.3e}, sd_E_s={:.3e}; slip {:.3e} m^2/m, scrub {:.3e} m^2/rad); \
             docs/operator.md.",
            u.sd_d,
            u.sd_b,
            u.sd_s,
            u.slip_m2_per_m,
            u.scrub_m2_per_rad,
            side = self.side_m,
        );
        let _ = writeln!(s, "    pose_covariance_diagonal: [{}]", list(&pose));
        let twist = self.twist_covariance(t.rate_hz, t.rolling_window);
        let _ = writeln!(
            s,
            "    # Variances of vx (m^2/s^2), vy, vz, wx, wy (unobserved) and wz (rad^2/s^2) of \
             the controller's speeds, means over velocity_rolling_window_size = {} updates at \
             {} Hz: encoder counts ({} counts/rev) and the speed loop's max_accel ({} m/s^2).",
            t.rolling_window, t.rate_hz, self.nominal.counts_per_rev, self.max_accel
        );
        let _ = writeln!(s, "    velocity_rolling_window_size: {}", t.rolling_window);
        let _ = writeln!(s, "    twist_covariance_diagonal: [{}]", list(&twist));
        let _ = writeln!(
            s,
            "    # Left at the controller's defaults: wheels_per_side, odom_frame_id, \
             base_frame_id, open_loop, position_feedback, enable_odom_tf, cmd_vel_timeout, \
             publish_limited_velocity, the linear and angular limits; publish_rate {} Hz if \
             this rate_hz is not the controller manager's update_rate.",
            t.rate_hz
        );
        s
    }

    fn urdf(&self, log: &Path) -> String {
        let g = &self.applied;
        let mut s = String::new();
        let _ = writeln!(s, "<?xml version=\"1.0\"?>");
        let _ = writeln!(s, "<!-- {} -->", self.origin(log));
        let _ = writeln!(
            s,
            "<!-- base_link: the wheel axle's midpoint (the pose odocal calibrates), x forward, y \
             to the left. Wheel joints at y = +-b/2, b = {:?} m; the cylinders carry the wheel \
             radii (their length is not calibrated). -->",
            g.wheelbase_m
        );
        s.push_str("<robot name=\"odocal_wheels\">\n  <link name=\"base_link\"/>\n");
        for (side, y, d) in [
            ("left", 0.5 * g.wheelbase_m, g.diameter_left_m),
            ("right", -0.5 * g.wheelbase_m, g.diameter_right_m),
        ] {
            let _ = write!(
                s,
                "  <link name=\"{side}_wheel\">\n    <collision>\n      <geometry><cylinder \
                 radius=\"{r:?}\" length=\"0.02\"/></geometry>\n    </collision>\n  </link>\n  \
                 <joint name=\"{side}_wheel_joint\" type=\"continuous\">\n    <parent \
                 link=\"base_link\"/>\n    <child link=\"{side}_wheel\"/>\n    <origin xyz=\"0 \
                 {y:?} 0\" rpy=\"-1.5707963267948966 0 0\"/>\n    <axis xyz=\"0 0 1\"/>\n  \
                 </joint>\n",
                r = 0.5 * d
            );
        }
        s.push_str("</robot>\n");
        s
    }

    fn json(&self, log: &Path) -> Value {
        let g = &self.applied;
        let n = &self.nominal;
        let runs: Vec<Value> = self
            .runs
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let (kind, size) = match r.path {
                    PathKind::Square { direction, side_m } => {
                        (format!("square {}", direction.as_str()), side_m)
                    }
                    PathKind::Line { length_m } => ("line".into(), length_m),
                    PathKind::Circle {
                        direction,
                        radius_m,
                    } => (format!("circle {}", direction.as_str()), radius_m),
                };
                json!({
                    "run": i + 1,
                    "path": kind,
                    "size_m": size,
                    "odometry_end": { "x_m": r.odometry_end.x_m, "y_m": r.odometry_end.y_m,
                        "theta_rad": r.odometry_end.theta_rad },
                    "measured": r.measured.map(|m| json!({ "x_m": m.x_m, "y_m": m.y_m,
                        "theta_rad": m.theta_rad })),
                })
            })
            .collect();
        json!({
            "log": log.display().to_string(),
            "source": self.source,
            "method": self.method,
            "nominal": { "d_right_m": n.diameter_right_m, "d_left_m": n.diameter_left_m,
                "wheelbase_m": n.wheelbase_m, "counts_per_rev": n.counts_per_rev },
            "applied": { "d_right_m": g.diameter_right_m, "d_left_m": g.diameter_left_m,
                "wheelbase_m": g.wheelbase_m, "counts_per_rev": g.counts_per_rev },
            "factors": { "e_d": self.factors.0, "e_b": self.factors.1, "e_s": self.factors.2 },
            "sd": self.sd.map(|(d, b)| json!({ "e_d": d, "e_b": b })),
            "pose_covariance_diagonal": self.pose_covariance(&self.uncertainty(None, false, None).0),
            "twist_covariance_diagonal": self.twist_covariance(
                Target::default().rate_hz,
                Target::default().rolling_window
            ),
            "covariance_square_side_m": self.side_m,
            "table": self.table,
            "runs": runs,
        })
    }

    /// The covariance model's inputs, and where they come from: the calibration's relative 1σ
    /// of E_d and E_b from the log, raised to the floor for its age at `now_s` (Unix seconds;
    /// `None`, a file used on days to come: the between-session floor) unless `trust_session`,
    /// or the floor for a calibrated board without one, or a nominal geometry's; a tape's 1σ of
    /// E_s; slip and scrub from the scatter of the log's runs around their path's mean (with the
    /// applied geometry), unless `slip_m` is given, or the defaults.
    pub fn uncertainty(
        &self,
        slip_m: Option<f64>,
        trust_session: bool,
        now_s: Option<f64>,
    ) -> (Uncertainty, String) {
        let model = ArcModel::from_geometry(&self.applied);
        let mut estimate = RandomEstimate::default();
        let mut paths: Vec<PathKind> = Vec::new();
        for r in &self.runs {
            if !paths.contains(&r.path) {
                paths.push(r.path);
            }
        }
        for path in paths {
            let group =
                self.runs.iter().filter(|r| r.path == path).filter_map(|r| {
                    Some((r.knots.as_slice(), r.measured.map(|m| (m.x_m, m.y_m))?))
                });
            estimate.add_group(&model, group);
        }
        let (mut random, mut source) = match estimate.random_error() {
            Some(r) => (
                r,
                format!("slip and scrub of {} runs' scatter", estimate.runs),
            ),
            None => (RandomError::DEFAULT, "default slip and scrub".to_string()),
        };
        if let Some(m) = slip_m {
            random.slip_m2_per_m = m * m;
            source = format!("slip {m} m/m as given");
        }
        let age_s = now_s.zip(self.runs_logged_s).map(|(now, t)| now - t);
        let floor = Floor::for_age(age_s, trust_session);
        let u = match (self.sd, &self.method) {
            (Some((d, b)), _) => Uncertainty::calibrated(
                Some((d / self.factors.0, b / self.factors.1)),
                None,
                random,
                floor,
            ),
            (None, Some(_)) => Uncertainty::calibrated(None, None, random, floor),
            (None, None) => Uncertainty::nominal(random),
        };
        let sd = match (self.sd, &self.method, floor) {
            (Some(_), _, Floor::TrustSession) => "the calibration's 1-sigma",
            (Some(_), _, Floor::SameDay) => {
                "the calibration's 1-sigma, at least the same day's drift (its runs are less than \
                 a day old)"
            }
            (Some(_), _, Floor::BetweenSessions) => {
                "the calibration's 1-sigma, at least the between-session drift"
            }
            (None, Some(_), _) => "the between-session drift (the log has no 1-sigma)",
            (None, None, _) => "a nominal geometry's 1-sigma",
        };
        (u, format!("{sd}; {source}"))
    }

    /// The diagonal of the pose covariance `[x, y, z, roll, pitch, yaw]` for a robot stack
    /// whose covariance is a constant: the [`covariance`] model's at the end of one square of
    /// the plan's side L (CW and CCW, the larger of the two), driven with the applied geometry,
    /// with the model's inputs `u` ([`Export::uncertainty`]).
    pub fn pose_covariance(&self, u: &Uncertainty) -> [f64; 6] {
        let g = &self.applied;
        let u = *u;
        let per_tick = |d: f64| std::f64::consts::PI * d / f64::from(g.counts_per_rev);
        let mut var = [0.0f64; 3];
        for direction in [Direction::Cw, Direction::Ccw] {
            let knots = synth::square_knots(g, direction, self.side_m);
            let mut model = PoseCovariance::new(g.wheelbase_m, u);
            for pair in knots.windows(2) {
                let dr = (pair[1].right - pair[0].right) as f64 * per_tick(g.diameter_right_m);
                let dl = (pair[1].left - pair[0].left) as f64 * per_tick(g.diameter_left_m);
                const SUB: usize = 100;
                for _ in 0..SUB {
                    model.step(dr / SUB as f64, dl / SUB as f64);
                }
            }
            let c = model.xy_yaw();
            for k in 0..3 {
                var[k] = var[k].max(c[k][k]);
            }
        }
        [
            var[0],
            var[1],
            UNOBSERVED_VARIANCE,
            UNOBSERVED_VARIANCE,
            UNOBSERVED_VARIANCE,
            var[2],
        ]
    }

    /// The diagonal of the twist covariance `[vx, vy, vz, wx, wy, wz]` of speeds averaged over
    /// one update at `rate_hz` ([`covariance::twist_variance`]).
    pub fn twist_covariance(&self, rate_hz: f64, rolling_window: u32) -> [f64; 6] {
        let g = &self.applied;
        let (v, w) = covariance::twist_variance(
            0.5 * (g.diameter_right_m + g.diameter_left_m),
            g.counts_per_rev,
            g.wheelbase_m,
            f64::from(rolling_window.max(1)) / rate_hz,
            self.max_accel,
        );
        let c = covariance::twist_ros(v, w);
        [c[0], c[7], c[14], c[21], c[28], c[35]]
    }
}

/// The data lines of the last `nominal` or `verify` entry of a session log (the console logs
/// the board's `params` there).
fn last_logged_params(text: &str) -> Option<Vec<String>> {
    text.lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .filter(|v| v["kind"] == "nominal" || v["kind"] == "verify")
        .filter_map(|v| {
            v["params"].as_array().map(|a| {
                a.iter()
                    .filter_map(|s| s.as_str().map(str::to_string))
                    .collect::<Vec<String>>()
            })
        })
        .next_back()
}

/// `export`: reads `log`, writes `format` to `out` (stdout when `None`).
///
/// # Errors
/// As text.
pub fn run(log: &Path, format: Format, target: &Target, out: Option<&Path>) -> Result<(), String> {
    let export = Export::read(log)?;
    let text = export.write_for(format, log, target);
    match out {
        Some(p) => {
            std::fs::write(p, text).map_err(|e| format!("{}: {e}", p.display()))?;
            eprintln!(
                "{}: {} ({})",
                p.display(),
                export.origin(log),
                export.source
            );
        }
        None => print!("{text}"),
    }
    Ok(())
}

#[cfg(test)]
mod tests;
