//! The session's serial steps: a line sent and its reply checked, the board's `calibrate` table
//! read, a planned square driven and measured, and the verification of one set of parameters.

use indicatif::ProgressBar;
use odocal::calibration::{Method, wrap_angle};
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;
use odocal::motion::run::{Direction, PathKind};
use odocal::motion::speed::SpeedTuning;

use crate::experiments::montecarlo::Rng;
use crate::experiments::rectangle::RectangleSpec;
use crate::experiments::square::{drive_path_tuned, e_max_and_scatter};
use crate::sim::board::Board;
use crate::sim::board::accepted;
use crate::sim::robot::SimConfig;
use odocal::protocol::{ErrorCode, FinalLine};

use super::{CalibrationRow, RunTrace, SessionArgs, Verification};

/// A line the board refused: the line and the reply's final line.
#[derive(Debug)]
pub(super) struct Refused {
    line: String,
    last: String,
}

impl Refused {
    /// Whether the board refused with `code`.
    pub(super) fn is(&self, code: ErrorCode) -> bool {
        FinalLine::parse(&self.last).is_some_and(|l| l.is_err(code))
    }
}

impl From<Refused> for String {
    fn from(r: Refused) -> String {
        format!("`{}` was refused: {}", r.line, r.last)
    }
}

/// Sends one line, logs it and its reply; `Err` unless the final reply line is `ok …`.
pub(super) fn send(board: &mut Board, line: &str, log: &mut String) -> Result<String, Refused> {
    log.push_str("> ");
    log.push_str(line);
    log.push('\n');
    let reply = board.send(line);
    log.push_str(&reply.replace("\r\n", "\n"));
    if accepted(&reply) {
        Ok(reply)
    } else {
        Err(Refused {
            line: line.to_string(),
            last: reply.lines().last().unwrap_or("").to_string(),
        })
    }
}

/// A number following `key` (e.g. `dx=`) in `text`.
pub fn field(text: &str, key: &str) -> Option<f64> {
    let start = text.find(key)? + key.len();
    let rest = &text[start..];
    let end = rest
        .find(|c: char| c.is_whitespace() || c == ',' || c == ';' || c == ')')
        .unwrap_or(rest.len());
    rest[..end].parse().ok()
}

/// Parses the method rows of a `calibrate` reply.
pub fn parse_calibration(reply: &str) -> Vec<CalibrationRow> {
    let mut rows = Vec::new();
    for line in reply.lines() {
        let Some(body) = line.strip_prefix("  ") else {
            continue;
        };
        let mut words = body.split_whitespace();
        let Some(name) = words.next() else { continue };
        if Method::parse(name).is_none() {
            continue;
        }
        let rest: Vec<&str> = words.collect();
        if rest.first() == Some(&"failed:") {
            rows.push(CalibrationRow {
                method: name.to_string(),
                factors: None,
                e_max_predicted_m: None,
                failure: Some(rest[1..].join(" ")),
            });
            continue;
        }
        let num = |i: usize| rest.get(i).and_then(|w| w.parse::<f64>().ok());
        let factors = match (num(0), num(1), num(2)) {
            (Some(d), Some(b), Some(s)) => Some((d, b, s)),
            _ => None,
        };
        rows.push(CalibrationRow {
            method: name.to_string(),
            factors,
            e_max_predicted_m: num(6).map(|mm| mm * 1e-3),
            failure: factors.is_none().then(|| "unreadable row".to_string()),
        });
    }
    rows
}

/// Steps the board through the run just started, tracing true and odometry paths, then enters
/// the noisy measurement of the true end pose.
pub(super) fn drive_and_measure(
    board: &mut Board,
    direction: Direction,
    args: &SessionArgs,
    rng: &mut Rng,
    log: &mut String,
) -> Result<RunTrace, String> {
    let t0 = board.sim.true_pose();
    let o0 = board.controller.pose().to_f64();
    let rate = u64::from(args.rate.max(1));
    let every = (rate / 10).max(1); // 10 samples per second
    let mut trace = RunTrace {
        direction,
        true_path: vec![(0.0, 0.0)],
        odometry_path: vec![(0.0, 0.0)],
        error: (0.0, 0.0),
        periods: 0,
    };
    let sample = |board: &Board, trace: &mut RunTrace| {
        let t = t0.relative(&board.sim.true_pose());
        let o = o0.relative(&board.controller.pose().to_f64());
        trace.true_path.push((t.x_m, t.y_m));
        trace.odometry_path.push((o.x_m, o.y_m));
    };
    let mut events = String::new();
    while !board.at_rest() {
        if trace.periods > 1200 * rate {
            return Err("run did not finish in 20 min of simulated time".into());
        }
        board.step(&mut events);
        trace.periods += 1;
        if trace.periods.is_multiple_of(every) {
            sample(board, &mut trace);
        }
    }
    sample(board, &mut trace);
    log.push_str(&events.replace("\r\n", "\n"));
    let p: PoseF64 = board
        .true_pose_in_run_frame()
        .ok_or("the board did not record the run start")?;
    let sigma = args.meas_mm * 1e-3;
    let line = format!(
        "measure {:.6}m {:.6}m {:.4}deg",
        p.x_m + sigma * rng.normal(),
        p.y_m + sigma * rng.normal(),
        wrap_angle(p.theta_rad).to_degrees() + args.meas_deg * rng.normal()
    );
    let reply = send(board, &line, log)?;
    trace.error = (
        field(&reply, "dx=").ok_or("no dx in the measure reply")?,
        field(&reply, "dy=").ok_or("no dy in the measure reply")?,
    );
    Ok(trace)
}

/// `runs` CW and CCW squares by `next` + `measure`.
pub(super) fn planned_runs(
    board: &mut Board,
    args: &SessionArgs,
    rng: &mut Rng,
    log: &mut String,
    pb: &ProgressBar,
) -> Result<Vec<RunTrace>, String> {
    let mut out = Vec::new();
    for _ in 0..2 * usize::from(args.runs) {
        let reply = send(board, "next", log)?;
        let direction = if reply.contains("square ccw") {
            Direction::Ccw
        } else {
            Direction::Cw
        };
        out.push(drive_and_measure(board, direction, args, rng, log)?);
        pb.inc(1);
    }
    Ok(out)
}

/// Fresh squares with `belief` (true end poses, common seeds across beliefs) and the rectangle.
pub(super) fn verify(
    label: &str,
    belief: Geometry,
    cfg: &SimConfig,
    tuning: SpeedTuning,
    side_m: f64,
    args: &SessionArgs,
) -> Result<Verification, String> {
    let mut ends = Vec::new();
    for (d, direction) in [Direction::Cw, Direction::Ccw].into_iter().enumerate() {
        for i in 0..u64::from(args.runs) {
            let mut c = *cfg;
            c.seed = args
                .seed
                .wrapping_mul(7919)
                .wrapping_add(500 + 100 * d as u64 + i);
            let r = drive_path_tuned(c, belief, tuning, PathKind::Square { direction, side_m })?;
            let o = r.record.odometry_end;
            ends.push((direction, r.true_end.x_m - o.x_m, r.true_end.y_m - o.y_m));
        }
    }
    let (e_max_m, _) = e_max_and_scatter(&ends);
    let spec = RectangleSpec {
        laps: args.laps,
        ..RectangleSpec::default()
    };
    let rectangle = crate::experiments::rectangle::run(&spec, &cfg.true_geometry, &belief)?;
    Ok(Verification {
        label: label.to_string(),
        belief,
        ends,
        e_max_m,
        rectangle,
    })
}
