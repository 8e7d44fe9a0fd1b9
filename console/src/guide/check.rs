//! After the calibration: one check square driven with it, its end error against the runs'
//! before, and the session's summary.

use odocal::motion::run::{Direction, PathKind, RunRecord};
use odocal::protocol::Command;
use serde_json::json;

use super::{Guide, Stop};
use crate::log::calibration_of;

/// The end position error of a measured run (measured − odometry), metres.
fn end_error(r: &RunRecord) -> Option<f64> {
    let m = r.measured?;
    Some((m.x_m - r.odometry_end.x_m).hypot(m.y_m - r.odometry_end.y_m))
}

fn direction_of(r: &RunRecord) -> Option<Direction> {
    match r.path {
        PathKind::Square { direction, .. } => Some(direction),
        _ => None,
    }
}

/// The board's run store holds this many runs.
const STORE: usize = 12;

impl Guide {
    /// The mean end error of the session's measured squares in `direction`, metres.
    fn mean_error(&self, direction: Direction) -> Option<f64> {
        let e: Vec<f64> = self
            .slots
            .iter()
            .filter_map(|s| s.record.as_ref())
            .filter(|r| direction_of(r) == Some(direction))
            .filter_map(end_error)
            .collect();
        (!e.is_empty()).then(|| e.iter().sum::<f64>() / e.len() as f64)
    }

    /// Offers one square with the applied calibration, in the direction whose runs ended worst;
    /// shows its end error against theirs, then drops it from the board's runs (it was driven
    /// with the new geometry and is no calibration run).
    pub(super) fn check_square(&mut self) -> Result<(), Stop> {
        let worst = [Direction::Cw, Direction::Ccw]
            .into_iter()
            .filter_map(|d| Some((d, self.mean_error(d)?)))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let (direction, before) = match worst {
            Some((d, e)) => (d, Some(e)),
            None => (Direction::Cw, None),
        };
        let dir = direction.as_str();
        self.ui.say(&format!(
            "step: check square: one {dir} square of L = {:.3} m with the calibration; its end \
             error should be a few mm{}",
            self.side_m,
            before.map_or(String::new(), |b| format!(
                " instead of the {:.1} mm the {dir} runs ended with",
                b * 1e3
            ))
        ));
        if self.board.len() >= STORE || !self.board_has_all() {
            self.ui.say(
                "  (the board's run store has no place for it, or lost the session's runs: \
                 drive it from a terminal after `drop all yes`)",
            );
            return Ok(());
        }
        let slots = self.slots.len();
        loop {
            // `back` here: the step before (the results).
            let choice = self.choose(
                "Check square",
                &[("r", "run it"), ("s", "skip it")],
                "r",
                "  r drives one more square with the calibration and shows its end error \
                 against the runs' before; it is not used for the calibration. s skips it.",
            )?;
            if choice == "s" {
                return Ok(());
            }
            self.stop_runs = false;
            match self.drive_one(direction, "check square") {
                // Back at its start: the check square question again.
                Err(Stop::Back) => continue,
                r => r?,
            }
            break;
        }
        let Some(slot) = (slots..self.slots.len()).find(|&i| self.slots[i].record.is_some()) else {
            self.ui.say("  no check square measured");
            return Ok(());
        };
        let after = self.slots[slot].record.as_ref().and_then(end_error);
        // Not a calibration run: off the board's store and out of the session's runs.
        self.drop_slot(slot, false)?;
        if let Some(after) = after {
            self.link.log.entry(
                "check",
                json!({ "slot": slot, "direction": dir, "after_m": after, "before_m": before }),
                true,
            );
            self.ui.say(&format!(
                "check square {dir}: end error {:.1} mm with the calibration{}",
                after * 1e3,
                before.map_or(String::new(), |b| format!(
                    ", {:.1} mm before (mean of the {dir} runs)",
                    b * 1e3
                ))
            ));
            self.check = Some((after, before));
        }
        Ok(())
    }

    /// On a board that holds a calibration: whether the operator keeps it and only checks it
    /// (`c`), instead of new runs (`n`, the default).
    pub(super) fn keep_calibration(&mut self) -> Result<bool, Stop> {
        if !self.holds.calibration {
            return Ok(false);
        }
        let choice = self.choose(
            "The board holds a calibration",
            &[("n", "new runs"), ("c", "check it only")],
            "n",
            "  n plans and drives new squares and calibrates again (from the calibrated \
             geometry: it refines the one held); c keeps it and drives one check square with \
             it.",
        )?;
        Ok(choice == "c")
    }

    /// The check square alone with the board's calibration (the summary follows). `back` at its
    /// first question returns to the choice of [`Guide::keep_calibration`].
    pub(super) fn check_only(&mut self) -> Result<(), Stop> {
        // Runs on the board from before: dropped or used, so the check square's number is
        // known.
        let runs = self.cmd(Command::Runs)?;
        if !runs.data.is_empty() && !self.done.runs_from_before {
            self.runs_from_before(runs.data.len())?;
            self.done.runs_from_before = true;
        }
        let r = self.cmd(Command::Stream {
            on: Some(Some(self.opts.stream_hz)),
        })?;
        if !r.ok() {
            return Err(Stop::Failed(format!("stream on: {}", r.last)));
        }
        self.check_square()
    }

    /// What the session leaves on the board, and what to do with it.
    pub(super) fn summary(&mut self) -> Result<(), Stop> {
        let params = self.cmd(Command::Params)?;
        let n = crate::log::nominal_of(&params.data).unwrap_or(self.nominal);
        let (cw, ccw) = self.counts();
        self.ui.say("summary:");
        self.ui.say(&format!(
            "  nominal geometry: D_R={} m D_L={} m b={} m, {} counts/rev",
            n.diameter_right_m, n.diameter_left_m, n.wheelbase_m, n.counts_per_rev
        ));
        if cw + ccw > 0 {
            self.ui.say(&format!(
                "  runs: {} measured (cw {cw}, ccw {ccw}), L = {:.3} m",
                cw + ccw,
                self.side_m
            ));
        } else {
            self.ui.say("  runs: none in this session");
        }
        self.ui.say(&format!(
            "  calibration: {} ({})",
            calibration_of(&params.data),
            match (&self.applied, self.saved) {
                (Some(_), true) => "applied and saved",
                (Some(_), false) => "applied, not saved: lost at the next reset",
                (None, _) => "none applied in this session",
            }
        ));
        if let Some((after, before)) = self.check {
            self.ui.say(&format!(
                "  check square: end error {:.1} mm{}",
                after * 1e3,
                before.map_or(String::new(), |b| format!(" (before: {:.1} mm)", b * 1e3))
            ));
        }
        if self.applied.is_some() {
            self.ui.say(&format!(
                "  for a ROS 2 robot: cargo console export {} --format ros2 -o \
                 diff_drive_controller.yaml (or --format urdf, --format json)",
                self.link.log.path.display()
            ));
        }
        Ok(())
    }
}
