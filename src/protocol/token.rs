//! The tokens of the board's lines that a program reads: event tags, the wiring verdict, the
//! run-started reply and the rows of the `calibrate` table (docs/protocol.md, *Tokens*).
//!
//! The board writes each token through this module and the PC console reads it through the same
//! module, so the words around a token (what a person reads) may change without breaking the
//! console. A line's text after its token stays free prose.

use core::fmt::{self, Write};

use super::param::ParamName;

/// The first word of every unsolicited event line.
pub const EVENT: &str = "event ";
/// The first word of every pose-stream line: `stream <t> <x> <y> <theta_deg> <v_r> <v_l>`.
pub const STREAM: &str = "stream ";

/// What an `event` line announces: the words after `event ` up to the free text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EventTag {
    /// `event boot: ` the board started (parameters loaded or defaults, reset cause).
    Boot,
    /// `event button: ` what a button press did (its reply follows).
    Button,
    /// `event run <n> finished: ` run `n` ended and is stored.
    RunFinished(usize),
    /// `event run <n> aborted, not stored: ` run `n` ended early and is not stored.
    RunAborted(usize),
    /// `event fault: ` a latched fault in full, or a fault found at boot.
    Fault,
    /// `event stopped ` the motors were stopped (a stop key, the button).
    Stopped,
    /// `event bringup propose: ` a `set` that fixes a finding of the bring-up check.
    BringupPropose,
    /// `event bringup done: ` the bring-up check ended; [`WIRING_OK`] follows when it found
    /// nothing to fix.
    BringupDone,
    /// `event identify done ` the motor identification applied its result.
    IdentifyDone,
    /// `event identify err ` the motor identification refused its result.
    IdentifyErr,
}

/// `run ` of the run events, before the run's number.
const RUN: &str = "run ";
/// After a finished run's number and a space.
const FINISHED: &str = "finished: ";
/// After an aborted run's number and a space.
const ABORTED: &str = "aborted, not stored: ";

impl EventTag {
    /// The tags without a number, in the order [`EventTag::parse`] tries them.
    const FIXED: [EventTag; 8] = [
        EventTag::Boot,
        EventTag::Button,
        EventTag::Fault,
        EventTag::Stopped,
        EventTag::BringupPropose,
        EventTag::BringupDone,
        EventTag::IdentifyDone,
        EventTag::IdentifyErr,
    ];

    /// The tag's words after `event ` (with their separator); `None` for the run events.
    fn fixed_text(self) -> Option<&'static str> {
        Some(match self {
            EventTag::Boot => "boot: ",
            EventTag::Button => "button: ",
            EventTag::Fault => "fault: ",
            EventTag::Stopped => "stopped ",
            EventTag::BringupPropose => "bringup propose: ",
            EventTag::BringupDone => "bringup done: ",
            EventTag::IdentifyDone => "identify done ",
            EventTag::IdentifyErr => "identify err ",
            EventTag::RunFinished(_) | EventTag::RunAborted(_) => return None,
        })
    }

    /// Writes `event ` and the tag; the free text follows.
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    pub fn write(self, out: &mut dyn Write) -> fmt::Result {
        out.write_str(EVENT)?;
        match self {
            EventTag::RunFinished(n) => write!(out, "{RUN}{n} {FINISHED}"),
            EventTag::RunAborted(n) => write!(out, "{RUN}{n} {ABORTED}"),
            tag => out.write_str(tag.fixed_text().unwrap_or("")),
        }
    }

    /// The tag of an event line and the free text after it; `None` for any other line or
    /// event.
    pub fn parse(line: &str) -> Option<(EventTag, &str)> {
        let rest = line.strip_prefix(EVENT)?;
        for tag in Self::FIXED {
            if let Some(text) = tag.fixed_text().and_then(|t| rest.strip_prefix(t)) {
                return Some((tag, text));
            }
        }
        let (number, after) = rest.strip_prefix(RUN)?.split_once(' ')?;
        let n = number.parse().ok()?;
        if let Some(text) = after.strip_prefix(FINISHED) {
            Some((EventTag::RunFinished(n), text))
        } else {
            after
                .strip_prefix(ABORTED)
                .map(|text| (EventTag::RunAborted(n), text))
        }
    }
}

/// The verdict of a bring-up check that found nothing to fix: the whole text of its
/// [`EventTag::BringupDone`] event.
pub const WIRING_OK: &str = "wiring ok";

/// Whether the free text of an [`EventTag::BringupDone`] event is the [`WIRING_OK`] verdict.
pub fn is_wiring_ok(text: &str) -> bool {
    text == WIRING_OK
}

/// Writes `ok run <n> started: `, the reply (and the button's event text) of a started run;
/// the path follows.
///
/// # Errors
/// Only if `out` refuses the text.
pub fn write_run_started(out: &mut dyn Write, run: usize) -> fmt::Result {
    write!(out, "ok {RUN}{run} started: ")
}

/// The run number of an `ok run <n> started: …` text.
pub fn parse_run_started(text: &str) -> Option<usize> {
    let super::reply::FinalLine::Ok(ok) = super::reply::FinalLine::parse(text)? else {
        return None;
    };
    let (number, after) = ok.strip_prefix(RUN)?.split_once(' ')?;
    after.starts_with("started: ").then_some(())?;
    number.parse().ok()
}

/// After the number of lines the input queue dropped, in the text of their `err 10`.
const LINES_DROPPED: &str = "line(s) dropped: ";

/// The text of the `err 10` for lines the board's input queue dropped:
/// `<n> line(s) dropped: input queue full` (one notice for a whole paste).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinesDropped(pub u32);

impl LinesDropped {
    /// The notice in the text of an `err` reply (after `err 10: `), if it is one.
    pub fn parse(text: &str) -> Option<Self> {
        let (number, after) = text.split_once(' ')?;
        after.starts_with(LINES_DROPPED).then_some(())?;
        number.parse().ok().map(LinesDropped)
    }
}

impl fmt::Display for LinesDropped {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {LINES_DROPPED}input queue full", self.0)
    }
}

/// The end of a `set` reply that changed nothing: `ok <name>=<value> (unchanged)`.
pub const UNCHANGED: &str = " (unchanged)";

/// The text of a `drive` reply whose command the board cut to its motion limits:
/// `ok limited to v=… m/s w=… rad/s (max_speed, max_turn_rate)`.
pub const DRIVE_LIMITED: &str = "limited to ";

/// Whether `reply` is a `drive` the board cut to its limits.
pub fn is_drive_limited(reply: &str) -> bool {
    super::reply::FinalLine::parse(reply)
        .is_some_and(|l| l.is_ok() && l.text().starts_with(DRIVE_LIMITED))
}

/// The end of the reply of a change held in RAM only (`set`, `reset-params`, `apply`):
/// `ok d_right = 0.150000000 m (not saved; save to keep)`; `save` writes it to flash.
pub const NOT_SAVED: &str = " (not saved; save to keep)";

/// Whether a reply line ends with [`NOT_SAVED`] (its change is not in flash yet); the line's
/// `\r\n` or trailing spaces do not count.
pub fn is_not_saved(reply: &str) -> bool {
    reply.trim_end().ends_with(NOT_SAVED)
}

/// A method that failed, in its `calibrate` row: `<method> failed: <why>`.
pub const METHOD_FAILED: &str = "failed: ";
/// The end of a `calibrate` row computed with runs the robust fit flagged:
/// `  [with flagged run 3]`, `  [with flagged runs 3 5]`.
pub const WITH_FLAGGED: &str = "  [with flagged run";
/// The end of a residual row of a run the robust fit flagged: `run 4  dx=… weight=0.00 DISAGREES`.
pub const DISAGREES: &str = " DISAGREES";
/// The start of the `calibrate` line that follows flagged residual rows:
/// `the runs disagree by more than the robust scale …`, naming the culprit when leaving one run
/// out makes the others agree.
pub const RUNS_DISAGREE: &str = "the runs disagree ";
/// Before the culprit's number in the [`RUNS_DISAGREE`] line.
const WITHOUT_RUN: &str = "without run ";
/// After the culprit's number in the [`RUNS_DISAGREE`] line.
const OTHERS_AGREE: &str = " the others agree";

/// Writes the culprit of a [`RUNS_DISAGREE`] line: `without run <n> the others agree`.
///
/// # Errors
/// Only if `out` refuses the text.
pub fn write_culprit(out: &mut dyn Write, run: usize) -> fmt::Result {
    write!(out, "{WITHOUT_RUN}{run}{OTHERS_AGREE}")
}

/// The first data line of a `params` reply starts with the first parameter's name
/// ([`ParamName::ALL`]) and a space; a program tells a `params` reply by it.
pub fn is_params_start(data: &str) -> bool {
    data.trim_start()
        .strip_prefix(ParamName::ALL[0].as_str())
        .is_some_and(|rest| rest.starts_with(' '))
}

/// The `params` reply's line of the geometry in force: `active d_right=… d_left=… wheelbase=…
/// m` (each value after its parameter's name and `=`).
pub const ACTIVE: &str = "active ";

/// The `params` reply's line of the applied calibration: `calibration none` or `calibration
/// <method> E_d=… E_b=… E_s=… runs=… E_max=… mm`.
pub const CALIBRATION: &str = "calibration ";

/// The header line of the `calibrate` table: `method  E_d  E_b …`.
pub const TABLE_HEADER: &str = "method ";
/// The calibrate table's columns after the method's name, in order, as its header names them.
pub const TABLE_COLUMNS: [&str; 10] = [
    "E_d", "E_b", "E_s", "D_R_mm", "D_L_mm", "b_mm", "loo_mm", "E_max_mm", "sd_E_d", "sd_E_b",
];

/// The end of the `calibrate` table's row of the method with the lowest leave-one-out error
/// (`loo_mm`): the one the board recommends, and the guided console proposes.
pub const LOWEST_LOO: &str = "  [lowest loo]";

/// The goodness-of-fit line of `calibrate`: `fit exact chi2=… dof=… p=…: …`.
pub const FIT: &str = "fit ";
/// In a [`FIT`] line: the runs agree with no geometry within the noise assumed.
pub const POOR_FIT: &str = "POOR FIT";
/// The line after a poor [`FIT`]: `mistake <convention>: …` (the convention whose re-reading of
/// every run fits) or `mistake none: …`.
pub const MISTAKE: &str = "mistake ";
/// The [`MISTAKE`] line's word when no consistent mistake explains the fit.
pub const NO_MISTAKE: &str = "none";

/// A track-size advice line of `calibrate` and `advice`: `advice <method> …`.
pub const ADVICE: &str = "advice ";
/// A per-run residual line of `calibrate`: `run <n> dx=… dy=…`.
const RESIDUAL: &str = RUN;

/// One data line of the `calibrate` table, as a program reads it (the leading indentation of
/// data lines removed or not).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableRow<'a> {
    /// A method's solved row: its name, its columns (space-separated numbers, `-` and `n/a`),
    /// whether it has the lowest leave-one-out error, and the runs it was computed with that
    /// the robust fit flagged (`None`: none).
    Solved {
        /// The method's name.
        method: &'a str,
        /// The columns after the name, as [`TABLE_COLUMNS`] names them.
        columns: &'a str,
        /// The row is marked [`LOWEST_LOO`].
        lowest: bool,
        /// The numbers of the flagged runs, space-separated.
        flagged: Option<&'a str>,
    },
    /// A method that failed, and why.
    Failed {
        /// The method's name.
        method: &'a str,
        /// The reason, as the board words it.
        why: &'a str,
    },
    /// A per-run residual line.
    Residual {
        /// The run's number.
        run: usize,
        /// Whether the robust fit flagged the run ([`DISAGREES`]).
        disagrees: bool,
    },
    /// The [`RUNS_DISAGREE`] line: the run whose removal makes the others agree, if one does.
    Disagree {
        /// The run to check (`None`: leaving out one run at a time did not tell which).
        culprit: Option<usize>,
    },
    /// A track-size advice line (the text after `advice `).
    Advice(&'a str),
    /// The goodness-of-fit line: whether the fit is poor ([`POOR_FIT`]).
    Fit {
        /// The runs agree with no geometry within the noise assumed.
        poor: bool,
    },
    /// The measuring mistake a poor fit is explained by, by its convention's name (`None`:
    /// none explains it).
    Mistake(Option<&'a str>),
}

impl<'a> TableRow<'a> {
    /// Reads one data line of the table; `None` for an empty line.
    pub fn parse(line: &'a str) -> Option<Self> {
        let line = line.trim_start();
        if line.starts_with(RUNS_DISAGREE) {
            let culprit = line.find(WITHOUT_RUN).and_then(|i| {
                let (number, after) = line[i + WITHOUT_RUN.len()..].split_once(' ')?;
                after.starts_with(OTHERS_AGREE.trim_start()).then_some(())?;
                number.parse().ok()
            });
            return Some(TableRow::Disagree { culprit });
        }
        if let Some(rest) = line.strip_prefix(ADVICE) {
            return Some(TableRow::Advice(rest));
        }
        if let Some(rest) = line.strip_prefix(FIT) {
            return Some(TableRow::Fit {
                poor: rest.contains(POOR_FIT),
            });
        }
        if let Some(rest) = line.strip_prefix(MISTAKE) {
            let name = rest.split(':').next().unwrap_or("").trim();
            return Some(TableRow::Mistake((name != NO_MISTAKE).then_some(name)));
        }
        if let Some(rest) = line.strip_prefix(RESIDUAL) {
            let run = rest.split_whitespace().next()?.parse().ok()?;
            return Some(TableRow::Residual {
                run,
                disagrees: rest.trim_end().ends_with(DISAGREES),
            });
        }
        let (method, rest) = line.split_once(' ').unwrap_or((line, ""));
        if method.is_empty() {
            return None;
        }
        let rest = rest.trim_start();
        if let Some(why) = rest.strip_prefix(METHOD_FAILED) {
            return Some(TableRow::Failed { method, why });
        }
        let (columns, flagged) = match rest.split_once(WITH_FLAGGED.trim_start()) {
            Some((columns, runs)) => {
                let runs = runs.trim_start_matches('s').trim_end_matches(']').trim();
                (columns.trim_end(), Some(runs))
            }
            None => (rest.trim_end(), None),
        };
        let (columns, lowest) = match columns.strip_suffix(LOWEST_LOO.trim_start()) {
            Some(c) => (c.trim_end(), true),
            None => (columns, false),
        };
        Some(TableRow::Solved {
            method,
            columns,
            lowest,
            flagged,
        })
    }
}

impl<'a> TableRow<'a> {
    /// A solved row's text in the column the header names `name` ([`TABLE_COLUMNS`]), as the
    /// board printed it; `None` for another row or an unknown column.
    pub fn text(&self, name: &str) -> Option<&'a str> {
        let TableRow::Solved { columns, .. } = *self else {
            return None;
        };
        let at = TABLE_COLUMNS.iter().position(|c| *c == name)?;
        columns.split_ascii_whitespace().nth(at)
    }

    /// A solved row's value in the column the header names `name`; `None` for another row, an
    /// unknown column, or a value the row does not have (`-`, `n/a`).
    pub fn value(&self, name: &str) -> Option<f64> {
        super::number::parse_f64(self.text(name)?).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn written(tag: EventTag, text: &str) -> String {
        let mut line = String::new();
        tag.write(&mut line).unwrap();
        line.push_str(text);
        line
    }

    /// Every token the board writes reads back as itself through the same module, whatever
    /// the free text after it says.
    #[test]
    fn reply_grammar_round_trip() {
        let tags = EventTag::FIXED
            .into_iter()
            .chain([EventTag::RunFinished(12), EventTag::RunAborted(3)]);
        for tag in tags {
            let line = written(tag, "any words: at all");
            assert!(line.starts_with(EVENT), "{line}");
            assert_eq!(
                EventTag::parse(&line),
                Some((tag, "any words: at all")),
                "{line}"
            );
        }
        // The board's exact run lines.
        assert_eq!(
            written(EventTag::RunFinished(2), "square cw L=2.000 m"),
            "event run 2 finished: square cw L=2.000 m"
        );
        assert_eq!(
            written(EventTag::RunAborted(2), ""),
            "event run 2 aborted, not stored: "
        );
        // Not events, or events the console does not read.
        for line in [
            "ok run 2 started: line d=1.000 m",
            "event runs restored: 3, 2 measured",
            "event run discarded: run store full",
            "stream 1.000000 0 0 0 0 0",
        ] {
            assert_eq!(EventTag::parse(line), None, "{line}");
        }

        // A `params` listing starts with the first parameter's name.
        assert!(is_params_start("d_right 0.150000000 m"));
        assert!(is_params_start("    d_right 0.15 m"));
        assert!(!is_params_start("d_right_x 1") && !is_params_start("method  E_d"));

        let done = written(EventTag::BringupDone, WIRING_OK);
        let Some((EventTag::BringupDone, verdict)) = EventTag::parse(&done) else {
            panic!("{done}");
        };
        assert!(is_wiring_ok(verdict));
        assert!(!is_wiring_ok("1 finding, 1 proposal: see above"));

        let mut started = String::new();
        write_run_started(&mut started, 7).unwrap();
        started.push_str("square ccw L=1.500 m");
        assert_eq!(parse_run_started(&started), Some(7));
        assert_eq!(parse_run_started("ok run 7 measured"), None);

        let mut set = String::from("ok d_right = 0.150000000 m");
        set.push_str(NOT_SAVED);
        assert!(is_not_saved(&set));
        assert!(is_not_saved(&format!("{set}\r\n")));
        assert!(!is_not_saved("ok saved"));
        assert!(!is_not_saved(&format!(
            "ok d_right = 0.150000000 m{UNCHANGED}"
        )));

        let notice = LinesDropped(5).to_string();
        assert_eq!(notice, "5 line(s) dropped: input queue full");
        assert_eq!(LinesDropped::parse(&notice), Some(LinesDropped(5)));
        assert_eq!(LinesDropped::parse("a run is in progress"), None);
    }

    /// The `calibrate` table's rows as the board writes them (the session's golden) read back
    /// as their kinds.
    #[test]
    fn calibrate_rows_read_back() {
        let solved = "  alpha        0.995000000  1.010000000  1.000000000  149.6241   150.3759   \
                      388.8500   1.200     2.500e-4  -";
        assert_eq!(
            TableRow::parse(solved),
            Some(TableRow::Solved {
                method: "alpha",
                columns: "0.995000000  1.010000000  1.000000000  149.6241   150.3759   \
                          388.8500   1.200     2.500e-4  -",
                lowest: false,
                flagged: None,
            })
        );
        let lowest = format!("  exact        1.0  1.0  1.0  1  1  1  0.5  -  -  -{LOWEST_LOO}");
        let Some(TableRow::Solved {
            lowest, columns, ..
        }) = TableRow::parse(&lowest)
        else {
            panic!("{lowest}");
        };
        assert!(lowest);
        assert!(columns.ends_with("-  -  -"), "{columns}");
        let flagged = format!("  exact        1.0  1.0  1.0  1  1  1  -  -  -{WITH_FLAGGED}s 3 5]");
        let Some(TableRow::Solved { flagged, .. }) = TableRow::parse(&flagged) else {
            panic!("{flagged}");
        };
        assert_eq!(flagged, Some("3 5"));
        let failed = format!("  beta         {METHOD_FAILED}solver did not converge");
        assert_eq!(
            TableRow::parse(&failed),
            Some(TableRow::Failed {
                method: "beta",
                why: "solver did not converge"
            })
        );
        let mut verdict = format!("  {RUNS_DISAGREE}by more than the robust scale; ");
        write_culprit(&mut verdict, 4).unwrap();
        verdict.push_str(" (each run left out in turn): check run 4");
        assert_eq!(
            TableRow::parse(&verdict),
            Some(TableRow::Disagree { culprit: Some(4) })
        );
        let unknown = format!("  {RUNS_DISAGREE}by more than the robust scale; leaving out");
        assert_eq!(
            TableRow::parse(&unknown),
            Some(TableRow::Disagree { culprit: None })
        );
        let advice = format!("  {ADVICE}exact        L=2.000 m: expected error 0.1 %");
        assert!(matches!(
            TableRow::parse(&advice),
            Some(TableRow::Advice(a)) if a.starts_with("exact")
        ));
        assert_eq!(
            TableRow::parse("  run 1  dx=+0.100 mm dy=-0.200 mm weight=1.00"),
            Some(TableRow::Residual {
                run: 1,
                disagrees: false
            })
        );
        assert_eq!(
            TableRow::parse(&format!(
                "  run 12 dx=+141.167 mm dy=-164.262 mm weight=0.00{DISAGREES}"
            )),
            Some(TableRow::Residual {
                run: 12,
                disagrees: true
            })
        );
        assert_eq!(TableRow::parse("   "), None);
    }

    /// A solved row's values read by the header's column names; the board's header names the
    /// same columns in the same order.
    #[test]
    fn a_solved_rows_values_are_read_by_column_name() {
        let line = "  alpha        0.995000000  1.010000000  1.000000000  149.6241   150.3759   \
                    388.8500   2.000     1.200     2.500e-4  n/a";
        let row = TableRow::parse(line).unwrap();
        assert_eq!(row.value("loo_mm"), Some(2.0));
        assert_eq!(row.value("E_max_mm"), Some(1.2));
        assert_eq!(row.value("E_d"), Some(0.995));
        assert_eq!(row.value("b_mm"), Some(388.85));
        assert_eq!(row.value("sd_E_d"), Some(2.5e-4));
        assert_eq!(row.value("sd_E_b"), None);
        assert_eq!(row.value("no_such_column"), None);
    }
}
