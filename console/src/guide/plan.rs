//! The plan step: the square side and the runs per direction, chosen and sent to the board.

use odocal::protocol::command::PATH_RANGE_M;
use odocal::protocol::{Command, ParamName};
use serde_json::json;

use super::{Guide, Stop, length};

impl Guide {
    pub(super) fn plan(&mut self) -> Result<(), Stop> {
        self.ui.say(
            "plan: UMBmark squares, CW and CCW alternating. Bigger squares make the systematic \
             error larger against the tape measure's error; after `calibrate` the board \
             advises the best L for your robot's scatter.",
        );
        // The questions in turn: `back` goes to the one before (from the first: the step
        // before).
        let mut question = 0;
        loop {
            match question {
                0 => {
                    self.plan_side()?;
                    question = 1;
                }
                1 => match self.plan_runs() {
                    Err(Stop::Back) => question = 0,
                    r => {
                        r?;
                        question = 2;
                    }
                },
                _ => {
                    self.send_plan()?;
                    if self.done.runs_from_before {
                        return Ok(());
                    }
                    // Runs left on the board from before belong to another session.
                    let runs = self.cmd(Command::Runs)?;
                    let stored = runs.data.len();
                    if stored > 0 {
                        match self.runs_from_before(stored) {
                            Err(Stop::Back) => {
                                question = 1;
                                continue;
                            }
                            r => r?,
                        }
                    }
                    self.done.runs_from_before = true;
                    return Ok(());
                }
            }
        }
    }

    /// The square side L; a session with measured squares keeps theirs.
    pub(super) fn plan_side(&mut self) -> Result<(), Stop> {
        loop {
            let a = self.ui.ask(
                "Square side L (with its unit: 2m, 150cm)",
                Some(&format!("{:.3}m", self.side_m)),
            )?;
            if a.eq_ignore_ascii_case("help") || a == "?" {
                self.ui.say(
                    "  L is the side of the squares, 0.1..10 m: the room needs L plus about 0.5 m \
                     around it. Bigger squares make the systematic error larger against your \
                     tape measure's error (2 m is a good start; 1 m in a small room); the \
                     advice after `calibrate` gives the best L for this robot.",
                );
                continue;
            }
            match length(&a, super::SQUARE_SIDE_M) {
                Ok(v) if (PATH_RANGE_M.0..=PATH_RANGE_M.1).contains(&v) => {
                    let (cw, ccw) = self.counts();
                    if cw + ccw > 0 && (v - self.side_m).abs() > 1e-9 * self.side_m {
                        self.ui.say(&format!(
                            "  the session's {} measured square(s) have L = {:.3} m: squares of \
                             another side do not calibrate together (the closed forms need one \
                             side); keep L",
                            cw + ccw,
                            self.side_m
                        ));
                        continue;
                    }
                    self.side_m = v;
                    return Ok(());
                }
                Ok(_) => self.ui.say("  L must be within 0.1..10 m"),
                Err(e) => self.ui.say(&format!("  {e}")),
            }
        }
    }

    /// The runs per direction.
    pub(super) fn plan_runs(&mut self) -> Result<(), Stop> {
        loop {
            let a = self
                .ui
                .ask("Runs per direction", Some(&self.per_direction.to_string()))?;
            match a.parse::<u32>() {
                Ok(n) if (1..=6).contains(&n) => {
                    self.per_direction = n;
                    return Ok(());
                }
                _ => self.ui.say(
                    "  a whole number within 1..6: squares per direction (UMBmark: 5 + 5; more \
                     runs narrow the 1-sigma)",
                ),
            }
        }
    }

    pub(super) fn send_plan(&mut self) -> Result<(), Stop> {
        for command in [
            Command::Set {
                name: ParamName::SquareSide,
                value: self.side_m,
            },
            Command::Set {
                name: ParamName::RunsPerDirection,
                value: f64::from(self.per_direction),
            },
        ] {
            let line = command.to_string();
            let r = self.cmd(command)?;
            if !r.ok() {
                return Err(Stop::Failed(format!("{line}: {}", r.last)));
            }
        }
        self.link.log.entry(
            "plan",
            json!({ "side_m": self.side_m, "runs_per_direction": self.per_direction }),
            true,
        );
        self.ui.say(&format!(
            "plan: {n} CW + {n} CCW squares of L = {:.3} m",
            self.side_m,
            n = self.per_direction
        ));
        Ok(())
    }
}
