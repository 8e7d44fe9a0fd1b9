//! Driving the runs: each square started (or the button awaited), its progress from the pose
//! stream, the measured end pose checked with the library's plausibility rule before `measure`,
//! and the run's record logged with its measurement.

use std::time::Duration;

use odocal::motion::run::{Direction, PathKind, RunRecord};
use odocal::session::measure::{self, Implausible};
use serde_json::json;

use super::{Guide, RUN_TIMEOUT, Slot, Stop, field, path_text, quantity};

impl Guide {
    pub(super) fn counts(&self) -> (u32, u32) {
        let mut n = (0, 0);
        for s in &self.slots {
            if let Some(PathKind::Square { direction, .. }) = s.record.as_ref().map(|r| r.path) {
                match direction {
                    Direction::Cw => n.0 += 1,
                    Direction::Ccw => n.1 += 1,
                }
            }
        }
        n
    }

    pub(super) fn drive_missing_runs(&mut self) -> Result<(), Stop> {
        loop {
            let (cw, ccw) = self.counts();
            let n = self.per_direction;
            let direction = if cw < n && cw <= ccw {
                Direction::Cw
            } else if ccw < n {
                Direction::Ccw
            } else {
                return Ok(());
            };
            self.drive_one(direction, cw + ccw + 1, 2 * n)?;
        }
    }

    /// Drives one square and measures it; a run that is aborted is offered again.
    pub(super) fn drive_one(
        &mut self,
        direction: Direction,
        k: u32,
        total: u32,
    ) -> Result<(), Stop> {
        let dir = direction.as_str();
        self.ui.say(&format!(
            "run {k}/{total}: square {dir} L={:.3} m. Put the robot on the start marks (axle \
             midpoint on the origin mark, heading along the +x mark).",
            self.side_m
        ));
        let start = loop {
            let a = self.ui.ask(
                "Enter starts the run (b: wait for the board's button)",
                Some("go"),
            )?;
            // Only Enter (or `go`) moves the robot: anything else typed here (a measurement
            // typed once more, a stray word) asks again.
            let button = match a.to_ascii_lowercase().as_str() {
                "go" => false,
                "b" => true,
                _ => {
                    self.ui.say(&format!(
                        "  `{a}` starts nothing: press Enter (or type go) to start the run, or b \
                         to wait for the board's button"
                    ));
                    continue;
                }
            };
            // Stream lines of the last run are dropped; a reset since then (the board's boot
            // line) needs the echo off and the stream on again.
            if let Some(boot) = self.link.drain()? {
                self.ui.say(&format!("  the board was reset: {boot}"));
                self.after_reset()?;
            }
            let pose = self.cmd("pose")?;
            let start = (
                field(pose.text(), "x").and_then(|v| v.parse::<f64>().ok()),
                field(pose.text(), "y").and_then(|v| v.parse::<f64>().ok()),
                field(pose.text(), "theta_deg").and_then(|v| v.parse::<f64>().ok()),
            );
            let start = match start {
                (Some(x), Some(y), Some(t)) => (x, y, t.to_radians()),
                _ => (0.0, 0.0, 0.0),
            };
            if button {
                self.ui.say("  waiting for the button (short press)");
                let l = self.wait_event_of(&["event button: ", "event boot:"], 3600)?;
                if l.starts_with("event boot:") {
                    // A reset while waiting: the new boot has the echo on and the stream off.
                    self.ui.warn(&format!(
                        "the board was reset while waiting for the button ({l})"
                    ));
                    self.after_reset()?;
                    continue;
                }
                if l.contains("ok run") {
                    break start;
                }
                self.ui.say(&format!("  {l}"));
                continue;
            }
            // Not retried when busy: a run started meanwhile (the button) is followed instead
            // of starting another after it.
            let r = self
                .link
                .command(&format!("run {dir} {}", self.side_m), super::REPLY)?;
            if r.ok() {
                break start;
            }
            if r.err_code() == Some(10) {
                let status = self.cmd("status")?;
                if field(status.text(), "state") == Some("running") {
                    self.ui.say(&format!(
                        "  the board is busy ({}): a run was started on the board; following it",
                        r.text()
                    ));
                    break start;
                }
            }
            self.ui
                .warn(&format!("the board refused the run: {}", r.last));
            if r.err_code() == Some(11) {
                self.ui
                    .say("  a fault is latched: `clear` is sent, then try again");
                let c = self.cmd("clear")?;
                self.ui.say(&format!("  {}", c.last));
            } else if r.err_code() == Some(15) {
                return Err(Stop::Failed(
                    "the board's run store is full: calibrate or drop runs".into(),
                ));
            }
        };
        // Live progress from the pose stream.
        let (x0, y0, t0) = start;
        let (c, s) = (t0.cos(), t0.sin());
        let total_m = 4.0 * self.side_m + 4.0 * std::f64::consts::FRAC_PI_2 * 0.2;
        let mut done_m = 0.0;
        let mut last: Option<(f64, f64, f64)> = None;
        let mut path = vec![(0.0, 0.0)];
        self.ui.progress_start();
        let deadline = std::time::Instant::now() + RUN_TIMEOUT;
        let finished = loop {
            if crate::interrupted() {
                return Err(Stop::Interrupted);
            }
            if std::time::Instant::now() > deadline {
                let _ = self.link.stop_key();
                return Err(Stop::Failed(
                    "the run did not end in time: robot stopped".into(),
                ));
            }
            let Some(l) = self.link.next_unsolicited(Duration::from_millis(100))? else {
                continue;
            };
            if let Some(rest) = l.strip_prefix("stream ") {
                let v: Vec<f64> = rest
                    .split_whitespace()
                    .filter_map(|w| w.parse().ok())
                    .collect();
                if let [_, x, y, th, ..] = v[..] {
                    let th = th.to_radians();
                    if let Some((px, py, pt)) = last {
                        let dth = odocal::calibration::wrap_angle(th - pt).abs();
                        done_m += (x - px).hypot(y - py) + dth * 0.2;
                    }
                    last = Some((x, y, th));
                    let (dx, dy) = (x - x0, y - y0);
                    path.push((c * dx + s * dy, -s * dx + c * dy));
                    self.ui.progress(
                        done_m / total_m,
                        path.last().map_or(0.0, |p| p.0),
                        path.last().map_or(0.0, |p| p.1),
                        odocal::calibration::wrap_angle(th - t0).to_degrees(),
                    );
                }
            } else if l.starts_with("event run ") && l.contains(" finished: ") {
                break true;
            } else if l.starts_with("event run ") && l.contains(" aborted") {
                self.ui.warn(&l);
                break false;
            } else if l.starts_with("event boot:") {
                // A reset (the reset button, a power dip, the watchdog): the run had not
                // finished, so the board did not store it; the new boot has the echo on and
                // the stream off.
                self.ui.warn(&format!(
                    "the board was reset during the run ({l}): the run was not stored"
                ));
                self.after_reset()?;
                break false;
            } else if l.starts_with("event ") {
                self.ui.say(&format!("  {l}"));
            }
        };
        if !finished {
            let s = self.cmd("status")?;
            if let Some(f) = field(s.text(), "fault").filter(|f| *f != "none") {
                self.ui.warn(&format!(
                    "fault: {f}: the motors are stopped. Fix the cause, then the fault is \
                     cleared and the run driven again"
                ));
                // The board's own account of it (which wheel, how far off), sent right after
                // the aborted run.
                if let Some(detail) = self.link.take_pending("event fault: ") {
                    self.ui.say(&format!("  {}", &detail["event ".len()..]));
                }
                if let Some(cause) = fault_cause(f) {
                    self.ui.say(&format!("  likely cause: {cause}"));
                }
                if self
                    .ui
                    .confirm("Clear the fault and drive the run again", true)?
                {
                    let _ = self.cmd("clear")?;
                } else {
                    return Err(Stop::Failed(format!("fault {f}")));
                }
            }
            self.ui
                .say("the run was aborted and not stored: it is driven again");
            return Ok(());
        }
        let runs = self.cmd("runs")?;
        let n = runs.data.len();
        let (record, _) = self.fetch_record(n)?;
        self.ui.say(&format!(
            "run {k} finished: {} odometry end x={:+.6} y={:+.6} theta={:+.4} deg",
            path_text(&record.path),
            record.odometry_end.x_m,
            record.odometry_end.y_m,
            record.odometry_end.theta_rad.to_degrees()
        ));
        self.measure(n, &record, path)
    }

    /// Asks for the measured end pose, checks it with the library's plausibility rule, sends
    /// `measure`, then logs the run's record with the measurement.
    pub(super) fn measure(
        &mut self,
        n: usize,
        record: &RunRecord,
        path: Vec<(f64, f64)>,
    ) -> Result<(), Stop> {
        let (record, lines) = self.send_measurement(n, record)?;
        self.adopt(n, record, lines, path);
        Ok(())
    }

    /// Asks for board run `n`'s measured end pose until the board takes it (`measure #n …`,
    /// which also replaces an earlier measurement); the run's record as the board now holds it.
    pub(super) fn send_measurement(
        &mut self,
        n: usize,
        record: &RunRecord,
    ) -> Result<(RunRecord, Vec<String>), Stop> {
        let line = loop {
            let a = self.ui.ask(
                &format!(
                    "Measured end pose of run {n}: x y [theta] (m, deg; y to the left; or 41.8mm)"
                ),
                None,
            )?;
            let words = super::measurement_words(&a);
            if !(2..=3).contains(&words.len()) {
                self.ui.say("  two or three numbers: x y [theta]");
                continue;
            }
            let parsed = (|| -> Result<(f64, f64, Option<f64>), String> {
                Ok((
                    quantity(&words[0], false)?,
                    quantity(&words[1], false)?,
                    words.get(2).map(|w| quantity(w, true)).transpose()?,
                ))
            })();
            let (x, y, t) = match parsed {
                Ok(v) => v,
                Err(e) => {
                    self.ui.say(&format!("  {e}"));
                    continue;
                }
            };
            if let Err(why) = measure::check(record, x, y, t) {
                self.ui.say(&format!("  not plausible for this run: {why}"));
                if let Implausible::Position {
                    unit_hint: Some(_), ..
                } = why
                {
                    self.ui
                        .say("  (type the unit: e.g. `41.8mm -39.5mm`, or metres: 0.0418)");
                }
                continue;
            }
            let mut line = format!("measure #{n} {x} {y}");
            if let Some(t) = t {
                line.push_str(&format!(" {t}"));
            }
            break line;
        };
        let r = self.cmd(&line)?;
        self.link.log.entry(
            "measure",
            json!({ "board": n, "line": line, "reply": r.last }),
            true,
        );
        if !r.ok() {
            self.ui.warn(&format!("the board refused it: {}", r.last));
            return self.send_measurement(n, record);
        }
        self.ui.say(&format!("  {}", r.last));
        self.fetch_record(n)
    }

    /// Logs board run `n`'s record as the session's next slot.
    pub(super) fn adopt(
        &mut self,
        n: usize,
        record: RunRecord,
        lines: Vec<String>,
        path: Vec<(f64, f64)>,
    ) {
        let slot = self.slots.len();
        self.slots.push(Slot {
            record: Some(record),
            path,
        });
        self.log_run(slot, n, &lines);
        // The board numbers its runs 1..k: run n is the last one.
        self.board.truncate(n - 1);
        self.board.push(slot);
    }

    /// Logs slot `slot` (board run `n`) with its record `lines` and its path.
    pub(super) fn log_run(&mut self, slot: usize, n: usize, lines: &[String]) {
        let path = &self.slots[slot].path;
        let entry = json!({ "slot": slot, "board": n, "record": lines, "path": path });
        self.link.log.entry("run", entry, true);
    }

    pub(super) fn live(&self) -> Vec<RunRecord> {
        self.slots.iter().filter_map(|s| s.record.clone()).collect()
    }

    /// Whether the board holds exactly the session's live runs.
    pub(super) fn board_has_all(&self) -> bool {
        self.board.len() == self.slots.iter().filter(|s| s.record.is_some()).count()
    }
}

/// What usually causes a latched fault, as README's troubleshooting says (`None` for a fault
/// without a usual cause).
pub(super) fn fault_cause(fault: &str) -> Option<&'static str> {
    match fault {
        "following-error" => Some(
            "a motor or encoder wired the other way round (run the bring-up check in a \
             terminal: `bringup push`, then `bringup`), a wheel slipping badly, or motors too \
             weak for the motion limits (lower `max_speed`, `max_accel`)",
        ),
        "stall" => Some("a blocked wheel, or no motor power"),
        "encoder-glitch" => {
            Some("an encoder count jumped: a loose connector or noise on its lines")
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::fault_cause;

    #[test]
    fn a_following_error_points_to_the_bring_up_check() {
        let cause = fault_cause("following-error").unwrap();
        assert!(cause.contains("`bringup push`, then `bringup`"), "{cause}");
        assert!(fault_cause("stall").is_some());
        assert_eq!(fault_cause("identify"), None);
    }
}
