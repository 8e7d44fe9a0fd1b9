//! After the calibration: one check square driven with it, its end error against the runs'
//! before, and the session's summary.

use odocal::motion::run::{Direction, PathKind, RunRecord};
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
        let before = [Direction::Cw, Direction::Ccw]
            .into_iter()
            .filter_map(|d| Some((d, self.mean_error(d)?)))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((direction, before)) = before else {
            return Ok(());
        };
        self.ui.say(&format!(
            "step: check square: one {} square of L = {:.3} m with the calibration; its end \
             error should be a few mm instead of the {:.1} mm the {} runs ended with",
            direction.as_str(),
            self.side_m,
            before * 1e3,
            direction.as_str()
        ));
        if self.board.len() >= STORE || !self.board_has_all() {
            self.ui.say(
                "  (the board's run store has no place for it, or lost the session's runs: \
                 drive it from a terminal after `drop all yes`)",
            );
            return Ok(());
        }
        let choice = self.choose(
            "Check square",
            &[("r", "run it"), ("s", "skip it")],
            "r",
            "  r drives one more square with the calibration and shows its end error against \
             the runs' before; it is not used for the calibration. s skips it.",
        )?;
        if choice == "s" {
            return Ok(());
        }
        let slots = self.slots.len();
        self.stop_runs = false;
        self.drive_one(direction, "check square")?;
        let Some(slot) = (slots..self.slots.len()).find(|&i| self.slots[i].record.is_some()) else {
            self.ui.say("  no check square measured");
            return Ok(());
        };
        let after = self.slots[slot].record.as_ref().and_then(end_error);
        // Not a calibration run: off the board's store and out of the session's runs.
        if let Some(pos) = self.board.iter().position(|&s| s == slot) {
            let r = self.cmd(&format!("drop {}", pos + 1))?;
            if !r.ok() {
                return Err(Stop::Failed(format!("drop {}: {}", pos + 1, r.last)));
            }
            self.board.remove(pos);
        }
        self.slots[slot].record = None;
        self.link.log.entry("drop", json!({ "slot": slot }), true);
        if let Some(after) = after {
            self.link.log.entry(
                "check",
                json!({ "slot": slot, "direction": direction.as_str(), "after_m": after,
                        "before_m": before }),
                true,
            );
            self.ui.say(&format!(
                "check square {}: end error {:.1} mm with the calibration, {:.1} mm before (mean \
                 of the {} runs)",
                direction.as_str(),
                after * 1e3,
                before * 1e3,
                direction.as_str()
            ));
            self.check = Some((after, before));
        }
        Ok(())
    }

    /// What the session leaves on the board, and what to do with it.
    pub(super) fn summary(&mut self) -> Result<(), Stop> {
        let params = self.cmd("params")?;
        let n = crate::log::nominal_of(&params.data).unwrap_or(self.nominal);
        let (cw, ccw) = self.counts();
        self.ui.say("summary:");
        self.ui.say(&format!(
            "  nominal geometry: D_R={} m D_L={} m b={} m, {} counts/rev",
            n.diameter_right_m, n.diameter_left_m, n.wheelbase_m, n.counts_per_rev
        ));
        self.ui.say(&format!(
            "  runs: {} measured (cw {cw}, ccw {ccw}), L = {:.3} m",
            cw + ccw,
            self.side_m
        ));
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
                "  check square: end error {:.1} mm (before: {:.1} mm)",
                after * 1e3,
                before * 1e3
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
