//! The board's stored runs against the session's slots: their numbers, a run's record fetched
//! page by page, a run dropped or forgotten, and a logged session resumed.

use odocal::motion::run::RunRecord;
use odocal::protocol::Command;
use serde_json::json;

use super::{Guide, Slot, Stop, path_text};
use crate::log::LogContents;

impl Guide {
    /// The numbers of the runs the board holds, in its store order (from `runs`).
    pub(super) fn board_numbers(&mut self) -> Result<Vec<usize>, Stop> {
        let r = self.cmd(Command::Runs)?;
        if !r.ok() {
            return Err(Stop::Failed(format!("runs: {}", r.last)));
        }
        Ok(run_numbers(&r.data))
    }

    /// The slot of board run number `n`, if the board holds it.
    pub(super) fn board_slot(&self, n: usize) -> Option<usize> {
        self.board.iter().find(|&&(m, _)| m == n).map(|&(_, s)| s)
    }

    /// The board's number of slot `slot`'s run, if the board holds it.
    pub(super) fn board_number(&self, slot: usize) -> Option<usize> {
        self.board
            .iter()
            .find(|&&(_, s)| s == slot)
            .map(|&(n, _)| n)
    }

    /// Drops slot `slot`'s run: from the board when it holds it (its reply shown when `say`),
    /// and from the session.
    pub(super) fn drop_slot(&mut self, slot: usize, say: bool) -> Result<(), Stop> {
        if let Some(n) = self.board_number(slot) {
            let r = self.cmd(Command::Drop { index: n })?;
            if say {
                self.ui.say(&format!("  {}", r.last));
            }
            if !r.ok() {
                return Err(Stop::Failed(format!("drop {n}: {}", r.last)));
            }
            self.board.retain(|&(_, s)| s != slot);
        }
        self.forget_slot(slot);
        Ok(())
    }

    /// Takes slot `slot`'s run out of the session (not from the board), logged.
    pub(super) fn forget_slot(&mut self, slot: usize) {
        self.slots[slot].record = None;
        self.link.log.entry("drop", json!({ "slot": slot }), true);
    }

    /// Fetches the record of board run `n` (all pages).
    pub(super) fn fetch_record(&mut self, n: usize) -> Result<(RunRecord, Vec<String>), Stop> {
        let mut lines = Vec::new();
        let mut reader = odocal::protocol::record::RecordReader::new();
        while let Some(first) = reader.next_first() {
            let r = self.cmd(Command::Record {
                index: n,
                first_knot: first,
            })?;
            if !r.ok() {
                return Err(Stop::Failed(format!("record {n}: {}", r.last)));
            }
            for l in &r.data {
                reader
                    .feed(l)
                    .map_err(|e| Stop::Failed(format!("record {n}: {e}: `{l}`")))?;
            }
            lines.extend(r.data);
        }
        let record = reader
            .finish()
            .map_err(|e| Stop::Failed(format!("record {n}: {e}")))?;
        Ok((record, lines))
    }

    pub(super) fn resume(&mut self, c: LogContents) -> Result<(), Stop> {
        let logged: Vec<usize> = (0..c.runs.len()).filter(|&i| c.runs[i].is_some()).collect();
        self.slots = c
            .runs
            .iter()
            .zip(c.paths.iter().cloned().chain(std::iter::repeat(Vec::new())))
            .map(|(r, path)| Slot {
                record: r.clone(),
                path,
            })
            .collect();
        if let Some((side, n)) = c.plan {
            self.side_m = side;
            self.per_direction = n;
        }
        self.ui.say(&format!(
            "resuming: {} measured run(s) in the log, plan {n} + {n} squares of L = {:.3} m",
            logged.len(),
            self.side_m,
            n = self.per_direction
        ));
        let numbers = self.board_numbers()?;
        let stored = numbers.len();
        // Does the board still hold the logged runs (firmware that keeps them in flash across
        // a reset)? Runs after them were driven after the last logged one (the tool died before
        // logging them): they join the session, and an unmeasured one is measured now.
        let mut board = Vec::new();
        for &n in &numbers {
            board.push(self.fetch_record(n)?);
        }
        let common = stored.min(logged.len());
        let same = (0..common).all(|i| self.slots[logged[i]].record.as_ref() == Some(&board[i].0));
        if same && stored >= logged.len() {
            self.board = numbers
                .iter()
                .copied()
                .zip(logged.iter().copied())
                .collect();
            if common > 0 {
                self.ui.say(&format!(
                    "the board still holds the {} logged run(s): continuing on the board",
                    common
                ));
            }
            self.send_plan()?;
            for (i, (record, lines)) in board.into_iter().enumerate().skip(common) {
                let n = numbers.get(i).copied().unwrap_or(i + 1);
                self.ui.say(&format!(
                    "board run {n} ({}) is not in the log yet: it joins the session",
                    path_text(&record.path)
                ));
                if record.measured.is_some() {
                    self.adopt(n, record, lines, Vec::new());
                } else {
                    self.measure(n, &record, Vec::new())?;
                }
            }
            return Ok(());
        }
        if stored == 0 {
            self.ui.say(&format!(
                "the board holds none of the {} logged run(s) (it was reset): they stay in the \
                 log, the remaining runs are driven now, and the calibration is computed on the \
                 PC from all of them with the board's library",
                logged.len()
            ));
            self.link.log.note(
                "board-lost-runs",
                &format!("{} logged runs not on the board", logged.len()),
            );
        } else {
            return Err(Stop::Failed(format!(
                "the board holds {stored} run(s) that differ from the log's {}: `drop all` on \
                 the board (the log keeps them) or start a new session",
                logged.len()
            )));
        }
        self.send_plan()
    }
}

/// The run numbers of a `runs` reply's data lines (`run <n> …`), in order.
fn run_numbers(data: &[String]) -> Vec<usize> {
    data.iter()
        .filter_map(|l| {
            let mut w = l.split_whitespace();
            (w.next() == Some("run")).then(|| w.next()?.parse().ok())?
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::run_numbers;

    #[test]
    fn run_numbers_are_read_from_the_runs_listing() {
        let data = [
            "  run 2 square ccw L=0.500 m odometry x=+0.001 y=+0.002 not measured".to_string(),
            "run 5 line d=1.000 m odometry x=+1.0 y=+0.0 not measured".to_string(),
        ];
        assert_eq!(run_numbers(&data), [2, 5]);
    }
}
