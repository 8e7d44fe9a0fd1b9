//! The results: `calibrate` (on the board, or on the PC when the board lost runs), the table
//! shown readably, flagged runs offered again, `apply`, `save`, `params` read back, and the SVG.

use std::path::PathBuf;

use odocal::calibration::Method;
use odocal::motion::run::{Direction, PathKind, RunRecord};
use odocal::protocol::token::{self, TableRow};
use odocal::protocol::{Command, ErrorCode, FinalLine};
use odocal::session::library::LibraryCalibrator;
use odocal::session::{Calibrator, Numbered, write_calibration};
use serde_json::json;

use super::runs::Measured;
use super::{CALIBRATE, Guide, Stop, field};
use crate::log::calibration_of;
use crate::plot::{self, PlotRun};
use crate::ui::AskError;

impl Guide {
    /// `calibrate` on the board (or on the PC when the board lost runs); shows the table.
    pub(super) fn calibrate(&mut self) -> Result<Vec<String>, Stop> {
        let (table, source) = if self.board_has_all() {
            self.ui
                .say("calibrate: the board computes every method (several seconds on the board)");
            let r = self.cmd_timeout(Command::Calibrate { method: None }, CALIBRATE)?;
            let mut t = r.data.clone();
            t.push(r.last.clone());
            if !r.ok() {
                return Err(Stop::Failed(format!("calibrate: {}", r.last)));
            }
            (t, "board")
        } else {
            self.ui.say(
                "calibrate: computed on the PC from every logged run (the board lost some in \
                 its reset)",
            );
            let mut out = String::new();
            let runs = self.live();
            let numbered = Numbered {
                runs: &runs,
                numbers: &[],
            };
            // Read as the board reads them: its measuring noise and convention.
            let reading = self.board_reading()?;
            write_calibration(
                &mut LibraryCalibrator::default(),
                numbered,
                &self.nominal,
                None,
                &reading,
                &mut out,
            )
            .map_err(|e| Stop::Failed(e.to_string()))?;
            let t: Vec<String> = out
                .lines()
                .map(|l| l.strip_prefix("  ").unwrap_or(l).to_string())
                .collect();
            (t, "offline")
        };
        self.link.log.entry(
            "calibrate",
            json!({ "source": source, "table": table }),
            true,
        );
        self.show_table(&table);
        Ok(table)
    }

    pub(super) fn show_table(&mut self, table: &[String]) {
        const SHOWN: [&str; 6] = ["E_d", "E_b", "loo_mm", "E_max_mm", "sd_E_d", "sd_E_b"];
        self.ui.say(
            "  method        E_d          E_b          loo_mm     E_max_mm   sd_E_d     sd_E_b",
        );
        let known = |method: &str| LibraryCalibrator::default().methods().contains(&method);
        for l in table {
            match TableRow::parse(l) {
                Some(TableRow::Failed { method, why }) if known(method) => {
                    let why = why.split_whitespace().collect::<Vec<_>>().join(" ");
                    self.ui
                        .say(&format!("  {method:<12}  {}{why}", token::METHOD_FAILED));
                }
                Some(row @ TableRow::Solved { method, lowest, .. }) if known(method) => {
                    // Each column by the name the board's header gives it.
                    let w: Vec<&str> = SHOWN.iter().map(|c| row.text(c).unwrap_or("-")).collect();
                    let flagged = l.find(token::WITH_FLAGGED).map_or("", |i| &l[i..]);
                    let mark = if lowest { token::LOWEST_LOO } else { "" };
                    self.ui.say(&format!(
                        "  {method:<12}  {}  {}  {:<9}  {:<9}  {:<9}  {}{mark}{flagged}",
                        w[0], w[1], w[2], w[3], w[4], w[5]
                    ));
                }
                Some(
                    TableRow::Residual { .. }
                    | TableRow::Disagree { .. }
                    | TableRow::Advice(_)
                    | TableRow::Fit { .. }
                    | TableRow::Mistake(_),
                ) => {
                    self.ui.say(&format!("  {l}"));
                }
                _ => {}
            }
            if FinalLine::parse(l).is_some_and(|f| f != FinalLine::Ok("")) {
                self.ui.say(&format!("  ({l})"));
            }
        }
    }

    /// For each run the robust fit flagged, offers to measure it again (a typing mistake: x and y
    /// swapped, a sign) or to drop it and drive it again; returns whether any run changed, so
    /// that the calibration is computed again.
    pub(super) fn review_flagged_runs(&mut self, table: &[String]) -> Result<bool, Stop> {
        let (flagged, culprit) = flagged_and_culprit(table);
        // What stays flagged when nothing changes (the runs kept), for the plot's title.
        self.flagged.clone_from(&flagged);
        // The run whose removal makes the others agree is the one to look at; when no single
        // run does, every flagged one.
        let review = match culprit {
            Some(n) => vec![n],
            None => flagged,
        };
        self.review_runs(&review, "disagrees with the others")
    }

    /// Offers each run of `review` (its number in the table) to be measured again, dropped,
    /// driven again or kept; `why` says why it is asked. Returns whether any run changed.
    ///
    /// # Errors
    /// [`Stop::Back`] for `back` at the question (a run changed before it stays changed).
    pub(super) fn review_runs(&mut self, review: &[usize], why: &str) -> Result<bool, Stop> {
        let mut changed = false;
        // The board's numbers stay valid when a run is dropped; the table computed on the PC
        // numbers the live runs 1, 2, … (highest first keeps them valid).
        let on_board = self.board_has_all();
        'runs: for &n in review.iter().rev() {
            let live: Vec<usize> = (0..self.slots.len())
                .filter(|&i| self.slots[i].record.is_some())
                .collect();
            let slot = if on_board {
                self.board_slot(n)
            } else {
                n.checked_sub(1).and_then(|i| live.get(i)).copied()
            };
            let Some(slot) = slot else {
                continue;
            };
            let question = format!(
                "Run {n} {why}: {}[d]rop it, [r]e-drive it (drop it and \
                 drive a new one), or [k]eep it",
                if on_board {
                    "[m]easure it again (a typing mistake: x/y swapped, a sign), "
                } else {
                    ""
                }
            );
            loop {
                // `back` here: to the caller (the step before, or the choice after a declined
                // apply).
                let a = self.ui.ask(&question, Some("r"))?.to_ascii_lowercase();
                match a.as_str() {
                    "m" | "measure" if on_board => {
                        let Some(old) = self.slots[slot].record.clone() else {
                            continue 'runs;
                        };
                        match self.send_measurement(n, &old, false) {
                            Ok(Measured::Taken(record, lines)) => {
                                // The same slot again: a log reader keeps the newer record.
                                self.log_run(slot, n, &lines);
                                self.slots[slot].record = Some(*record);
                            }
                            // Back to this question; kept: nothing changed.
                            Err(Stop::Back) => continue,
                            Ok(_) => continue 'runs,
                            Err(e) => return Err(e),
                        }
                        break;
                    }
                    "d" | "drop" | "r" | "re-drive" | "redrive" => {
                        let direction = match self.slots[slot].record.as_ref().map(|r| r.path) {
                            Some(PathKind::Square { direction, .. }) => Some(direction),
                            _ => None,
                        };
                        // Run `n` is the board's own when it holds them all (slot from its
                        // number); otherwise the table's, computed on the PC.
                        if on_board {
                            self.drop_slot(slot, true)?;
                        } else {
                            self.forget_slot(slot);
                        }
                        if a.starts_with('d') {
                            // Not driven again: one run less in its direction.
                            match direction {
                                Some(Direction::Cw) => self.less[0] += 1,
                                Some(Direction::Ccw) => self.less[1] += 1,
                                None => {}
                            }
                        }
                        break;
                    }
                    "k" | "keep" => continue 'runs,
                    "help" | "?" | "" => self.ui.say(
                        "  a run that disagrees is usually a typing mistake (x and y swapped, a \
                         sign: y is positive to the left) or a bumped robot. m types its \
                         measurement again; d drops it; r drops it and drives a new square in \
                         its place; k keeps it (the exact fit gives it a small weight; the \
                         closed forms do not)",
                    ),
                    _ => self.ui.say(if on_board {
                        "  m, d, r or k (help explains)"
                    } else {
                        "  d, r or k (help explains)"
                    }),
                }
            }
            changed = true;
        }
        Ok(changed)
    }

    /// Asks which method to apply, applies, saves and verifies it. A declined apply returns to
    /// the choice (a run measured again, dropped or driven again, another method, or nothing
    /// applied); returns whether the runs changed (`calibrate` again).
    pub(super) fn apply_save_verify(&mut self, table: &[String]) -> Result<bool, Stop> {
        let solved = solved_rows(table);
        // The recommended method: the one the board marks with the lowest leave-one-out error,
        // else exact (no small-angle approximation, robust), else the smallest predicted E_max.
        let recommended = solved
            .iter()
            .find(|r| r.lowest_loo)
            .or_else(|| solved.iter().find(|r| r.method == Method::Exact.as_str()))
            .or_else(|| {
                solved
                    .iter()
                    .min_by(|a, b| a.e_max_mm.total_cmp(&b.e_max_mm))
            })
            .map(|r| r.method.clone())
            .ok_or_else(|| Stop::Failed("no method solved".into()))?;
        'choice: loop {
            let method = loop {
                // `back` here: the step before (the last run's measurement).
                let a = self.ui.ask(
                    "Apply which method (none: keep the current parameters)",
                    Some(&recommended),
                )?;
                if a.eq_ignore_ascii_case("none") {
                    self.say_nothing_applied();
                    match self.offer_pending_save() {
                        Err(Stop::Back) => continue 'choice,
                        r => r?,
                    }
                    return Ok(false);
                }
                if let Some(r) = solved.iter().find(|r| r.method.eq_ignore_ascii_case(&a)) {
                    break r.method.as_str();
                }
                let names: Vec<&str> = solved.iter().map(|r| r.method.as_str()).collect();
                self.ui
                    .say(&format!("  one of {}, or none", names.join(", ")));
            };
            if !self.board_has_all() {
                self.ui.warn(&format!(
                    "the board holds {} of the session's {} runs: `apply {method}` on the board \
                     would compute from those only. The result from all runs is in the table \
                     above and in the log (`cargo console recalibrate LOG --method {method}`)",
                    self.board.len(),
                    self.live().len()
                ));
                let anyway = self
                    .ui
                    .confirm("Apply the board's result from its runs anyway", false);
                match self.go_on(anyway, table)? {
                    Proceed::Go => {}
                    Proceed::Choice => continue 'choice,
                    Proceed::Return(changed) => return Ok(changed),
                }
            }
            let row = solved
                .iter()
                .find(|r| r.method == method)
                .map(|r| format!(" (E_d={} E_b={})", r.e_d, r.e_b))
                .unwrap_or_default();
            let apply = self
                .ui
                .confirm_explicit(&format!("Apply {method}{row} to the board"));
            match self.go_on(apply, table)? {
                Proceed::Go => {}
                Proceed::Choice => continue 'choice,
                Proceed::Return(changed) => return Ok(changed),
            }
            let mut applied = self.cmd(Command::Apply {
                method,
                confirmed: false,
            })?;
            if applied.is_err(ErrorCode::NotConfirmed) {
                // A run is flagged or the fit is poor (the board's own checks): applied only on
                // a second yes.
                self.ui.say(&format!("  {}", applied.last));
                // Which check asked, from the table the board wrote (not the reply's words).
                let why = if !flagged_and_culprit(table).0.is_empty() {
                    "with the flagged run in it"
                } else {
                    "with runs that fit no geometry"
                };
                let anyway = self
                    .ui
                    .confirm_explicit(&format!("Apply {method} anyway, {why}"));
                match self.go_on(anyway, table)? {
                    Proceed::Go => {}
                    Proceed::Choice => continue 'choice,
                    Proceed::Return(changed) => return Ok(changed),
                }
                applied = self.cmd(Command::Apply {
                    method,
                    confirmed: true,
                })?;
            }
            match self.save_and_verify(method.to_string(), applied) {
                // Back from the save question: the method question (the calibration stays
                // applied, and offered for save).
                Err(Stop::Back) => continue 'choice,
                r => return r.map(|()| false),
            }
        }
    }

    /// Where a yes/no of the method choice leads: on with a yes; to the method question for
    /// `back`; after a no, wherever [`Self::after_decline`] leads.
    fn go_on(&mut self, answer: Result<bool, AskError>, table: &[String]) -> Result<Proceed, Stop> {
        let yes = match answer {
            Err(AskError::Back) => return Ok(Proceed::Choice),
            r => r?,
        };
        if yes {
            return Ok(Proceed::Go);
        }
        Ok(match self.after_decline(table)? {
            Declined::Again => Proceed::Choice,
            Declined::Changed => Proceed::Return(true),
            Declined::Skip => Proceed::Return(false),
        })
    }

    /// After an apply was declined: measure a run again, drop it, drive it again, pick another
    /// method, or apply nothing (pending changes are still offered for `save`).
    fn after_decline(&mut self, table: &[String]) -> Result<Declined, Stop> {
        let on_board = self.board_has_all();
        loop {
            // `back` here: the method question.
            let choice = match self.choose(
                "Not applied. Now",
                &[
                    ("m", "measure a run again"),
                    ("d", "drop a run"),
                    ("r", "re-drive a run"),
                    ("o", "another method"),
                    ("s", "skip: apply nothing"),
                ],
                // The default ends the question: a script answering every question with its
                // default (--yes) must not loop between the method and this choice.
                "s",
                "  m, d or r ask which run (its number in the table) and then what to do with \
                 it; o returns to the method question; s applies nothing (changes made this \
                 session are still offered for save)",
            ) {
                Err(Stop::Back) => return Ok(Declined::Again),
                r => r?,
            };
            match choice.as_str() {
                "o" => return Ok(Declined::Again),
                "s" => {
                    self.say_nothing_applied();
                    match self.offer_pending_save() {
                        Err(Stop::Back) => continue,
                        r => r?,
                    }
                    return Ok(Declined::Skip);
                }
                _ => {}
            }
            let a = match self
                .ui
                .ask("Which run (its number in the table; back)", None)
            {
                Err(AskError::Back) => continue,
                r => r?,
            };
            let Ok(n) = a.trim().parse::<usize>() else {
                self.ui.say("  a run number as the table lists it");
                continue;
            };
            if !table.iter().any(
                |l| matches!(TableRow::parse(l), Some(TableRow::Residual { run, .. }) if run == n),
            ) && on_board
            {
                self.ui.say(&format!("  the table lists no run {n}"));
            }
            match self.review_runs(&[n], "chosen") {
                Ok(true) => return Ok(Declined::Changed),
                // Back (or kept): the choice again.
                Ok(false) | Err(Stop::Back) => {}
                Err(e) => return Err(e),
            }
        }
    }

    /// Says that nothing (more) is applied: the board keeps its parameters, with the method
    /// applied earlier in the session if any (`back` from a later question led here).
    fn say_nothing_applied(&mut self) {
        match &self.applied {
            Some(m) => self.ui.say(&format!(
                "nothing more applied; the board keeps {m}, applied earlier in this session"
            )),
            None => self
                .ui
                .say("nothing applied; the board keeps its parameters"),
        }
    }

    /// Offers `save` for the changes made on the board this session when nothing is applied.
    ///
    /// # Errors
    /// [`Stop::Back`] for `back` at the question (nothing saved, the changes still pending).
    fn offer_pending_save(&mut self) -> Result<(), Stop> {
        if self.pending.is_empty() {
            return Ok(());
        }
        let what = self.pending.join(", ");
        if self.ui.confirm_explicit(&format!(
            "Save the changes made this session ({what}) to flash"
        ))? {
            let saved = self.cmd(Command::Save)?;
            self.link.log.entry(
                "save",
                json!({ "ok": saved.ok(), "reply": saved.last }),
                true,
            );
            self.ui.say(&format!("  {}", saved.last));
            if !saved.ok() {
                return Err(Stop::Failed(format!("save: {}", saved.last)));
            }
            self.saved = true;
            self.pending.clear();
        } else {
            self.ui.say(&format!(
                "  not saved ({what}): lost at the next reset (type `save` on a terminal to keep)"
            ));
        }
        Ok(())
    }

    /// Logs the apply, saves on a yes, and reads `params` back.
    ///
    /// # Errors
    /// [`Stop::Back`] for `back` at the save question (the calibration stays applied, and
    /// pending for `save`).
    fn save_and_verify(&mut self, method: String, applied: crate::link::Reply) -> Result<(), Stop> {
        self.link.log.entry(
            "apply",
            json!({ "method": method, "reply": applied.last }),
            true,
        );
        if !applied.ok() {
            return Err(Stop::Failed(format!("apply {method}: {}", applied.last)));
        }
        self.ui.say(&format!("  {}", applied.last));
        self.applied = Some(method.clone());
        // Applied in RAM: not saved until `save` (offered again when `back` leaves this
        // question).
        self.saved = false;
        if !self.pending.contains(&"calibration") {
            self.pending.push("calibration");
        }
        if self.ui.confirm_explicit(
            "Save it to the board's flash (kept at every boot, with the geometry, wiring and \
             motor tuning)",
        )? {
            let saved = self.cmd(Command::Save)?;
            self.link.log.entry(
                "save",
                json!({ "ok": saved.ok(), "reply": saved.last }),
                true,
            );
            if !saved.ok() {
                return Err(Stop::Failed(format!("save: {}", saved.last)));
            }
            self.ui.say(&format!("  {}", saved.last));
            self.saved = true;
            self.pending.clear();
        } else {
            self.ui.say(
                "  not saved: the board uses the calibration until it is reset (type `save` on \
                 a terminal to keep it)",
            );
        }
        let params = self.cmd(Command::Params)?;
        let line = calibration_of(&params.data);
        let want = (field(applied.text(), "E_d"), field(applied.text(), "E_b"));
        let ok = line.starts_with(&format!("{method} "))
            && field(&line, "E_d") == want.0
            && field(&line, "E_b") == want.1;
        self.link
            .log
            .entry("verify", json!({ "ok": ok, "params": params.data }), true);
        if !ok {
            return Err(Stop::Failed(format!(
                "verification failed: params shows `calibration {line}` after `{}`",
                applied.last
            )));
        }
        self.ui.say(&format!(
            "verified: params shows calibration {line}; {}",
            if self.saved {
                "stored in flash, used from the next run and at every boot"
            } else {
                "used from the next run, until a reset (not saved)"
            }
        ));
        Ok(())
    }

    /// Writes the SVG next to the log.
    pub(super) fn plot(&mut self) -> Option<PathBuf> {
        let runs: Vec<PlotRun<'_>> = self
            .slots
            .iter()
            .filter_map(|s| {
                Some(PlotRun {
                    record: s.record.as_ref()?,
                    path: &s.path,
                })
            })
            .collect();
        if runs.is_empty() {
            return None;
        }
        let records: Vec<RunRecord> = runs.iter().map(|r| r.record.clone()).collect();
        // The applied method's geometry from every run, by the library (none applied: exact).
        let method = self.applied.as_deref().unwrap_or("exact");
        let calibrated = LibraryCalibrator::default()
            .solve(&records, &self.nominal, method)
            .ok()
            .map(|s| s.geometry);
        let text = plot::svg(
            &runs,
            calibrated.as_ref(),
            &format!(
                "odocal session {}: {} runs; {}{}",
                self.link.log.path.display(),
                runs.len(),
                match &self.applied {
                    Some(m) => format!("applied {m}"),
                    None => "nothing applied (after: exact)".into(),
                },
                if self.flagged.is_empty() {
                    String::new()
                } else {
                    format!(
                        "; flagged and kept: run {}",
                        self.flagged
                            .iter()
                            .map(usize::to_string)
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                }
            ),
        );
        let path = self.link.log.path.with_extension("svg");
        match std::fs::write(&path, text) {
            Ok(()) => Some(path),
            Err(e) => {
                self.ui.warn(&format!("{}: {e}", path.display()));
                None
            }
        }
    }
}

/// What the operator chose after declining an apply.
/// Where the method choice goes after a yes/no ([`Guide::go_on`]).
enum Proceed {
    /// Yes: on with the apply.
    Go,
    /// Back to the method question.
    Choice,
    /// Leave the choice: whether the runs changed.
    Return(bool),
}

/// A solved row of the `calibrate` table, as the method choice needs it.
struct SolvedRow {
    /// The method's name.
    method: String,
    /// Its E_d and E_b columns as the board printed them.
    e_d: String,
    e_b: String,
    /// Its predicted E_max, mm (infinite when the board printed none).
    e_max_mm: f64,
    /// The board marks it as the lowest leave-one-out error.
    lowest_loo: bool,
}

/// The methods a `calibrate` table solved, read by the protocol's table grammar.
fn solved_rows(table: &[String]) -> Vec<SolvedRow> {
    table
        .iter()
        .filter_map(|l| match TableRow::parse(l)? {
            row @ TableRow::Solved { method, lowest, .. } if Method::parse(method).is_some() => {
                // Read by the header's column names.
                Some(SolvedRow {
                    method: method.to_string(),
                    e_d: row.text("E_d")?.to_string(),
                    e_b: row.text("E_b")?.to_string(),
                    e_max_mm: row.value("E_max_mm").unwrap_or(f64::INFINITY),
                    lowest_loo: lowest,
                })
            }
            _ => None,
        })
        .collect()
}

enum Declined {
    /// Ask for the method again.
    Again,
    /// A run changed: drive what is missing and calibrate again.
    Changed,
    /// Apply nothing.
    Skip,
}

/// The runs a `calibrate` table flags (`run <n> … DISAGREES`) and the one whose removal makes
/// the others agree (`… without run <n> the others agree …`), if the board could tell.
fn flagged_and_culprit(table: &[String]) -> (Vec<usize>, Option<usize>) {
    let mut flagged = Vec::new();
    let mut culprit = None;
    for l in table {
        match TableRow::parse(l) {
            Some(TableRow::Residual {
                run,
                disagrees: true,
            }) => flagged.push(run),
            Some(TableRow::Disagree { culprit: Some(n) }) => culprit = Some(n),
            _ => {}
        }
    }
    (flagged, culprit)
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_flagged_runs_and_the_one_to_check_are_read_from_the_table() {
        let table = [
            "run 2  dx=+0.1 mm dy=+0.2 mm weight=0.91".to_string(),
            "run 4  dx=+141.167 mm dy=-164.262 mm weight=0.00 DISAGREES".to_string(),
            "run 7  dx=+1.0 mm dy=-1.0 mm weight=0.31 DISAGREES".to_string(),
            "the runs disagree by more than the robust scale (x/y swapped, a sign, a unit?); \
             without run 4 the others agree (each run left out in turn): check run 4, then \
             measure #4 x y or drop 4, and calibrate again"
                .to_string(),
        ];
        assert_eq!(super::flagged_and_culprit(&table), (vec![4, 7], Some(4)));
        assert_eq!(super::flagged_and_culprit(&table[..3]), (vec![4, 7], None));
    }
}
