//! Driving the runs: each square started (or the button awaited), its progress from the pose
//! stream, the measured end pose checked with the library's plausibility rule before `measure`,
//! and the run's record logged with its measurement.

use odocal::protocol::unit::{parse_angle, parse_length};
use std::time::Duration;

use odocal::motion::run::{Direction, PathKind, RunRecord};
use odocal::protocol::stream::StreamSample;
use odocal::protocol::token::{self, EventTag};
use odocal::protocol::{Command, ErrorCode};
use serde_json::json;

use super::{Guide, RUN_TIMEOUT, Slot, Stop, event_tag, field, path_text};

/// What became of a measurement question.
pub(super) enum Measured {
    /// The board took it: the run's record as it now holds it, and its lines.
    Taken(Box<RunRecord>, Vec<String>),
    /// The run was dropped, to be driven again.
    Dropped,
    /// The run was dropped, and no more runs are driven.
    Skip,
    /// A measurement asked again was kept as it was (`keep`).
    Kept,
}

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
            if self.stop_runs {
                return Ok(());
            }
            let (cw, ccw) = self.counts();
            let n = self.per_direction;
            let (n_cw, n_ccw) = (
                n.saturating_sub(self.less[0]),
                n.saturating_sub(self.less[1]),
            );
            let direction = if cw < n_cw && (cw <= ccw || ccw >= n_ccw) {
                Direction::Cw
            } else if ccw < n_ccw {
                Direction::Ccw
            } else {
                return Ok(());
            };
            let title = format!("run {}/{}", cw + ccw + 1, n_cw + n_ccw);
            match self.drive_one(direction, &title) {
                // The question before a run's start: the last run's measurement (`back` there:
                // the step before the runs).
                Err(Stop::Back) => self.measure_last_again()?,
                r => r?,
            }
        }
    }

    /// The session's last measured run's measurement, asked again (after `back` at the next
    /// run's start, or from the results): typed again it replaces the board's (`measure #n`),
    /// `keep` leaves it as it is.
    ///
    /// # Errors
    /// [`Stop::Back`] for `back` there, or when there is no run to ask about: the step before the
    /// runs comes next.
    pub(super) fn measure_last_again(&mut self) -> Result<(), Stop> {
        let Some(slot) = (0..self.slots.len())
            .rev()
            .find(|&i| self.slots[i].record.is_some())
        else {
            return Err(Stop::Back);
        };
        let (Some(n), Some(old)) = (self.board_number(slot), self.slots[slot].record.clone())
        else {
            self.ui.say(
                "  the last run's measurement is in the log only (the board lost it in its \
                 reset): it stays as it is",
            );
            return Err(Stop::Back);
        };
        self.ui.say(&format!(
            "  back: run {n}'s measurement again (keep leaves it as it is; back goes to the \
             step before the runs)"
        ));
        if let Measured::Taken(record, lines) = self.send_measurement(n, &old, false)? {
            // The same slot again: a log reader keeps the newer record.
            self.log_run(slot, n, &lines);
            self.slots[slot].record = Some(*record);
        }
        Ok(())
    }

    /// Drives one square and measures it; a run that is aborted is offered again.
    pub(super) fn drive_one(&mut self, direction: Direction, title: &str) -> Result<(), Stop> {
        let dir = direction.as_str();
        self.ui.say(&format!(
            "{title}: square {dir} L={:.3} m. Put the robot on the start marks (axle \
             midpoint on the origin mark, heading along the +x mark).",
            self.side_m
        ));
        let Some(start) = self.start_run(direction)? else {
            return Ok(());
        };
        let Some(path) = self.follow_run(start)? else {
            return self.after_aborted_run();
        };
        let Some(n) = self.board_numbers()?.last().copied() else {
            return Err(Stop::Failed("the finished run is not in `runs`".into()));
        };
        let (record, _) = self.fetch_record(n)?;
        self.ui.say(&format!(
            "{title} finished: {} odometry end x={:+.6} y={:+.6} theta={:+.4} deg",
            path_text(&record.path),
            record.odometry_end.x_m,
            record.odometry_end.y_m,
            record.odometry_end.theta_rad.to_degrees()
        ));
        self.measure(n, &record, path)
    }

    /// Starts the run on Enter (or waits for the board's button): the odometry pose it starts
    /// from (x, y, heading in radians), or `None` when the operator dropped the previous run or
    /// ended the runs instead.
    fn start_run(&mut self, direction: Direction) -> Result<Option<(f64, f64, f64)>, Stop> {
        loop {
            let a = self.ui.ask(
                "Enter starts the run (b: wait for the board's button; help, drop, skip)",
                Some("go"),
            )?;
            // Only Enter (or `go`) moves the robot: anything else typed here (a measurement
            // typed once more, a stray word) asks again.
            let button = match a.to_ascii_lowercase().as_str() {
                "go" => false,
                "b" => true,
                "help" | "?" => {
                    self.ui.say(
                        "  Enter (or go) starts the square now; b waits for a short press of the \
                         board's button (start it from the robot's side). drop forgets the \
                         previous run (bumped, mis-measured) and drives it again; skip drives \
                         no more runs and calibrates with those measured (one per direction at \
                         least). Ctrl-C stops the robot at any time.",
                    );
                    continue;
                }
                "drop" => {
                    self.drop_last_run()?;
                    return Ok(None);
                }
                "skip" => {
                    if self.both_directions_measured() {
                        self.stop_runs = true;
                        return Ok(None);
                    }
                    self.ui.say(
                        "  skip needs a measured run in each direction (CW and CCW) to \
                         calibrate: drive this one",
                    );
                    continue;
                }
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
            let pose = self.cmd(Command::Pose)?;
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
                let l = self.wait_event_of(&[EventTag::Button, EventTag::Boot], 3600)?;
                let event = EventTag::parse(&l);
                if matches!(event, Some((EventTag::Boot, _))) {
                    // A reset while waiting: the new boot has the echo on and the stream off.
                    self.ui.warn(&format!(
                        "the board was reset while waiting for the button ({l})"
                    ));
                    self.after_reset()?;
                    continue;
                }
                if event.is_some_and(|(_, text)| token::parse_run_started(text).is_some()) {
                    return Ok(Some(start));
                }
                self.ui.say(&format!("  {l}"));
                continue;
            }
            // Not retried when busy: a run started meanwhile (the button) is followed instead
            // of starting another after it.
            let run = Command::Run {
                direction,
                side_m: Some(self.side_m),
            };
            let r = self.link.command(&run.to_string(), super::REPLY)?;
            if r.ok() {
                return Ok(Some(start));
            }
            if r.is_err(ErrorCode::Busy) {
                let status = self.cmd(Command::Status)?;
                if field(status.text(), "state") == Some("running") {
                    self.ui.say(&format!(
                        "  the board is busy ({}): a run was started on the board; following it",
                        r.text()
                    ));
                    return Ok(Some(start));
                }
            }
            self.ui
                .warn(&format!("the board refused the run: {}", r.last));
            if r.is_err(ErrorCode::Fault) {
                self.ui
                    .say("  a fault is latched: `clear` is sent, then try again");
                let c = self.cmd(Command::Clear)?;
                self.ui.say(&format!("  {}", c.last));
            } else if r.is_err(ErrorCode::StoreFull) {
                return Err(Stop::Failed(
                    "the board's run store is full: calibrate or drop runs".into(),
                ));
            } else if r.is_err(ErrorCode::Unmeasured) {
                // A run on the board that this session does not know is unmeasured.
                return Err(Stop::Failed(format!(
                    "the board holds an unmeasured run this session did not drive: measure or \
                     drop it on a terminal ({})",
                    r.last
                )));
            }
        }
    }

    /// Follows the run on the pose stream with a progress line until it ends: the path in the
    /// run's start frame when it finished, `None` when it was aborted or the board was reset.
    fn follow_run(&mut self, start: (f64, f64, f64)) -> Result<Option<Vec<(f64, f64)>>, Stop> {
        // Live progress from the pose stream.
        let (x0, y0, t0) = start;
        let (c, s) = (t0.cos(), t0.sin());
        let total_m = 4.0 * self.side_m + 4.0 * std::f64::consts::FRAC_PI_2 * 0.2;
        let mut done_m = 0.0;
        let mut last: Option<(f64, f64, f64)> = None;
        let mut path = vec![(0.0, 0.0)];
        self.ui.progress_start();
        let deadline = std::time::Instant::now() + RUN_TIMEOUT;
        loop {
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
            if let Some(sample) = StreamSample::parse(&l) {
                let (x, y, th) = (sample.x_m, sample.y_m, sample.theta_rad);
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
            } else if matches!(event_tag(&l), Some(EventTag::RunFinished(_))) {
                return Ok(Some(path));
            } else if matches!(event_tag(&l), Some(EventTag::RunAborted(_))) {
                self.ui.warn(&l);
                return Ok(None);
            } else if event_tag(&l) == Some(EventTag::Boot) {
                // A reset (the reset button, a power dip, the watchdog): the run had not
                // finished, so the board did not store it; the new boot has the echo on and
                // the stream off.
                self.ui.warn(&format!(
                    "the board was reset during the run ({l}): the run was not stored"
                ));
                self.after_reset()?;
                return Ok(None);
            } else if l.starts_with(token::EVENT) {
                self.ui.say(&format!("  {l}"));
            }
        }
    }

    /// After an aborted run: a latched fault explained and cleared on a yes (or the session
    /// ends), and the run offered again.
    fn after_aborted_run(&mut self) -> Result<(), Stop> {
        let s = self.cmd(Command::Status)?;
        if let Some(f) = field(s.text(), "fault").filter(|f| *f != "none") {
            self.ui.warn(&format!(
                "fault: {f}: the motors are stopped. Fix the cause, then the fault is \
                 cleared and the run driven again"
            ));
            // The board's own account of it (which wheel, how far off), sent right after
            // the aborted run.
            if let Some(detail) = self
                .link
                .take_pending(|l| event_tag(l) == Some(EventTag::Fault))
            {
                let detail = detail.strip_prefix(token::EVENT).unwrap_or(&detail);
                self.ui.say(&format!("  {detail}"));
            }
            if let Some(cause) = fault_cause(f) {
                self.ui.say(&format!("  likely cause: {cause}"));
            }
            let again = self.no_back(
                "the run was aborted: clear the fault and drive it again (y), or end the \
                 session (n)",
                |g| {
                    Ok(g.ui.confirm("Clear the fault and drive the run again", true)?)
                },
            )?;
            if again {
                let _ = self.cmd(Command::Clear)?;
            } else {
                return Err(Stop::Failed(format!("fault {f}")));
            }
        }
        self.ui
            .say("the run was aborted and not stored: it is driven again");
        Ok(())
    }

    /// Asks for the measured end pose and sends it (or drops the run), then logs the run's
    /// record with the measurement.
    pub(super) fn measure(
        &mut self,
        n: usize,
        record: &RunRecord,
        path: Vec<(f64, f64)>,
    ) -> Result<(), Stop> {
        match self.send_measurement(n, record, true)? {
            Measured::Taken(record, lines) => self.adopt(n, *record, lines, path),
            Measured::Dropped | Measured::Kept => {}
            Measured::Skip => self.stop_runs = true,
        }
        Ok(())
    }

    /// What to type at the measurement question, and what the board will do with it.
    fn measure_help(&mut self, n: usize, record: &RunRecord, may_drop: bool) {
        let o = &record.odometry_end;
        self.ui.say(&format!(
            "  Measure where the axle midpoint stopped, in the run's start frame: x along the \
             start heading (forward positive), y to the left (positive left), and if you can \
             the heading change theta (CCW positive), e.g. `41.8mm -39.5mm -2.3deg`.\n  \
             Every value with its unit (mm, cm, m; deg, rad), against the number or apart from \
             it: `41.8 mm`, `4.18cm`, `-0.04rad`; a bare number is refused. The board checks it \
             against the odometry end (x={:+.4} y={:+.4} m) and what the nominal geometry's \
             tolerance allows on this path, and asks before keeping a value beyond that.{}",
            o.x_m,
            o.y_m,
            if may_drop {
                format!(
                    "\n  drop: forget run {n} (bumped, not measurable) and drive it again; \
                     skip: forget it and drive no more runs (calibrate with those measured)."
                )
            } else {
                format!(
                    "\n  keep: leave run {n}'s measurement as the board holds it; back: the \
                     question before."
                )
            }
        ));
    }

    /// Asks for board run `n`'s measured end pose until the board takes it (`measure #n …`
    /// with the words as typed, units included: the board reads them; it also replaces an
    /// earlier measurement). With `may_drop` (a run just driven), `drop` and `skip` drop the run
    /// instead, and `back` is answered here (the run is driven: its end is measured or it is
    /// dropped); without it (a measurement asked again), `keep` leaves the one the board holds.
    ///
    /// # Errors
    /// [`Stop::Back`] for `back` without `may_drop`.
    pub(super) fn send_measurement(
        &mut self,
        n: usize,
        record: &RunRecord,
        may_drop: bool,
    ) -> Result<Measured, Stop> {
        loop {
            let a = self.ui.ask(
                &format!(
                    "Measured end pose of run {n}: x y [theta], each with its unit (41.8mm \
                     -39.5mm -2.3deg; y to the left; help{})",
                    if may_drop { ", drop, skip" } else { ", keep" }
                ),
                None,
            );
            let a = match a {
                Err(crate::ui::AskError::Back) if may_drop => {
                    self.ui.say(&format!(
                        "  back: run {n} is driven and stays where it stopped: measure its end \
                         now, or drop it (drop forgets it and drives it again)"
                    ));
                    continue;
                }
                r => r?,
            };
            let word = a.trim().to_ascii_lowercase();
            match word.as_str() {
                "keep" if !may_drop => {
                    self.ui
                        .say(&format!("  run {n}'s measurement kept as it was"));
                    return Ok(Measured::Kept);
                }
                "" | "help" | "?" => {
                    self.measure_help(n, record, may_drop);
                    continue;
                }
                "drop" | "skip" if may_drop => {
                    if word == "skip" && !self.both_directions_measured() {
                        self.ui.say(
                            "  skip needs a measured run in each direction (CW and CCW) to \
                             calibrate: measure this one, or drop it and drive it again",
                        );
                        continue;
                    }
                    let r = self.cmd(Command::Drop { index: n })?;
                    self.ui.say(&format!("  {}", r.last));
                    if !r.ok() {
                        return Err(Stop::Failed(format!("drop {n}: {}", r.last)));
                    }
                    return Ok(if word == "drop" {
                        self.ui.say("  the run is driven again");
                        Measured::Dropped
                    } else {
                        Measured::Skip
                    });
                }
                _ => {}
            }
            let words = super::measurement_words(&a);
            if !(2..=3).contains(&words.len()) {
                self.ui.say(&format!(
                    "  `{a}`: x y [theta], two or three values (e.g. `0.0418 -0.0395` or \
                     `41.8mm -39.5mm -2.3deg`); help explains"
                ));
                continue;
            }
            if let Some(bare) = bare_value(&words) {
                self.ui.say(&format!(
                    "  `{bare}` has no unit: type each value with its unit (mm, cm or m; deg or \
                     rad), e.g. `41.8mm -39.5mm -2.3deg`"
                ));
                continue;
            }
            // Read by the board's own grammar before it is sent: a value it would refuse is
            // said here, as the board would say it.
            let typed = format!("measure #{n} {}", words.join(" "));
            let mut measure = match Command::parse(&typed) {
                Ok(c @ Command::Measure { .. }) => c,
                Ok(_) => return Err(Stop::Failed(format!("`{typed}` is not a measurement"))),
                Err(e) => {
                    self.ui.say(&format!("  `{a}`: {e}"));
                    continue;
                }
            };
            let mut r = self.cmd(measure)?;
            if r.is_err(ErrorCode::Implausible) {
                // Beyond what the nominal geometry's tolerance allows: kept only on a yes.
                self.ui.say(&format!("  {}", r.last));
                let keep = match self.ui.confirm_explicit(
                    "Keep this measurement anyway (check the values, units and signs first)",
                ) {
                    // Back to the measurement question: nothing stored.
                    Err(crate::ui::AskError::Back) => false,
                    r => r?,
                };
                if !keep {
                    self.ui.say("  nothing stored; type it again");
                    continue;
                }
                if let Command::Measure { confirmed, .. } = &mut measure {
                    *confirmed = true;
                }
                r = self.cmd(measure)?;
            }
            let line = measure.to_string();
            self.link.log.entry(
                "measure",
                json!({ "board": n, "line": line, "reply": r.last }),
                true,
            );
            self.ui.say(&format!("  {}", r.last));
            if !r.ok() {
                self.ui.say("  (nothing stored; type it again)");
                continue;
            }
            let (record, lines) = self.fetch_record(n)?;
            return Ok(Measured::Taken(Box::new(record), lines));
        }
    }

    /// Whether the session has a measured square in each direction.
    pub(super) fn both_directions_measured(&self) -> bool {
        let (cw, ccw) = self.counts();
        cw > 0 && ccw > 0
    }

    /// Runs the board holds from before this session: dropped (`drop all yes`, the default) or
    /// used as the session's first runs (measured ones as they are; an unmeasured one is
    /// measured now).
    pub(super) fn runs_from_before(&mut self, stored: usize) -> Result<(), Stop> {
        self.ui.say(&format!(
            "the board holds {stored} run(s) from before this session"
        ));
        let choice = self.choose(
            "Runs from before",
            &[("d", "drop them"), ("u", "use them")],
            "d",
            "  d drops them for a clean session (`drop all yes`); u makes them this session's \
             first runs (e.g. squares driven from a terminal): their measurements as entered, an \
             unmeasured one is measured now",
        )?;
        if choice == "d" {
            // The board asks for `drop all yes`: the operator chose to drop them just now.
            let r = self.cmd(Command::DropAll { confirmed: true })?;
            self.ui.say(&format!("  {}", r.last));
            if !r.ok() {
                return Err(Stop::Failed(format!("drop all: {}", r.last)));
            }
            return Ok(());
        }
        for n in self.board_numbers()? {
            let (record, lines) = self.fetch_record(n)?;
            self.ui.say(&format!(
                "  board run {n}: {}{}",
                path_text(&record.path),
                if record.measured.is_some() {
                    ", measured"
                } else {
                    ", not measured"
                }
            ));
            if record.measured.is_some() {
                self.adopt(n, record, lines, Vec::new());
            } else {
                self.measure(n, &record, Vec::new())?;
            }
        }
        Ok(())
    }

    /// Drops the session's last run (on the board too, when it holds it): it is driven again.
    pub(super) fn drop_last_run(&mut self) -> Result<(), Stop> {
        let Some(slot) = (0..self.slots.len())
            .rev()
            .find(|&i| self.slots[i].record.is_some())
        else {
            self.ui.say("  there is no run to drop yet");
            return Ok(());
        };
        self.drop_slot(slot, true)?;
        self.ui
            .say("  the previous run is dropped: it is driven again");
        Ok(())
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
        // Run n is the board's newest: any entry from n on is stale.
        self.board.retain(|&(m, _)| m < n);
        self.board.push((n, slot));
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

/// The first measured value typed without a unit, if any (the words as the board reads them:
/// x, y, then θ).
fn bare_value(words: &[String]) -> Option<&str> {
    words.iter().enumerate().find_map(|(i, w)| {
        let bare = match i {
            0 | 1 => parse_length(w).is_ok_and(|l| l.unit.is_none()),
            _ => parse_angle(w).is_ok_and(|a| a.unit.is_none()),
        };
        bare.then_some(w.as_str())
    })
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
