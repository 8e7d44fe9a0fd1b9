//! The operator's side: messages, questions and the run progress bar.
//!
//! On a terminal, the progress bar redraws in place; without one (a pipe, a log file, a
//! script) every message is a plain line and the progress is printed at each quarter. Answers
//! come from `--answers FILE` (one a line, in the order of the questions) first, then from
//! `--yes` (the default of every question that has one), then from stdin. stdin is read on a
//! thread, so Ctrl-C ends a question at once. On a terminal, what was typed before a question
//! was shown (an Enter pressed twice, text typed while the robot drove) is not taken as its
//! answer: it is shown as ignored, so a stray Enter cannot start the next run before the robot
//! is back on its marks.
//!
//! `back` is read at every question, before anything else: [`AskError::Back`], for the caller to
//! return to the previous question (or to say why there is none). The first question of a
//! session says so once.

use std::io::{BufRead, BufReader, IsTerminal, Write};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::Duration;

/// How often a question that needs a typed yes is asked before no answer counts as no.
const EXPLICIT_TRIES: usize = 3;

/// Where answers come from and how output looks.
pub struct Ui {
    tty: bool,
    answers: std::vec::IntoIter<String>,
    yes: bool,
    stdin: Option<Receiver<Option<String>>>,
    /// stdin is a terminal: lines typed before a question are not its answer.
    discard_typeahead: bool,
    /// stdin ended (seen while discarding typed-ahead lines).
    stdin_ended: bool,
    /// Progress quarter last printed (no-TTY mode).
    quarter: Option<u32>,
    bar_shown: bool,
    /// The one-time hint that `back` works at every question is still to be shown.
    back_hint: bool,
}

/// The answer that returns to the previous question, at every question.
pub const BACK: &str = "back";

/// The one-time hint shown before the first question.
pub const BACK_HINT: &str = "  (at every question, back returns to the previous one)";

/// Why a question got no answer.
#[derive(Debug)]
pub enum AskError {
    /// Ctrl-C.
    Interrupted,
    /// stdin ended and nothing else had an answer.
    NoAnswer(String),
    /// `back` was answered: return to the previous question.
    Back,
}

impl std::fmt::Display for AskError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AskError::Interrupted => f.write_str("interrupted (Ctrl-C)"),
            AskError::NoAnswer(q) => write!(
                f,
                "no answer for `{q}` (stdin ended; give it in --answers or run interactively)"
            ),
            AskError::Back => f.write_str("back to the previous question"),
        }
    }
}

impl Ui {
    /// Answers from `answers` (lines), `--yes`, then stdin.
    pub fn new(answers: Vec<String>, yes: bool) -> Ui {
        let terminal = std::io::stdin().is_terminal();
        Ui {
            tty: std::io::stdout().is_terminal(),
            answers: answers.into_iter(),
            yes,
            // On a terminal, read from the start, so what is typed before the first question
            // (while the tool connects) is seen as typed ahead too.
            stdin: terminal.then(spawn_stdin_reader),
            discard_typeahead: terminal,
            stdin_ended: false,
            quarter: None,
            bar_shown: false,
            back_hint: true,
        }
    }

    fn end_bar(&mut self) {
        if self.bar_shown {
            println!();
            self.bar_shown = false;
        }
    }

    /// A message line.
    pub fn say(&mut self, text: &str) {
        self.end_bar();
        println!("{text}");
    }

    /// A warning or error line (stderr, so it stands out in a pipe too).
    pub fn warn(&mut self, text: &str) {
        self.end_bar();
        let _ = std::io::stdout().flush();
        eprintln!("console: {text}");
    }

    /// Drops the lines typed before the question now being asked and says so.
    fn discard_typeahead(&mut self) {
        let Some(rx) = &self.stdin else {
            return;
        };
        let mut typed = Vec::new();
        while let Ok(line) = rx.try_recv() {
            match line {
                Some(l) => typed.push(l.trim().to_string()),
                None => {
                    self.stdin_ended = true;
                    break;
                }
            }
        }
        if typed.is_empty() {
            return;
        }
        let text: Vec<&str> = typed
            .iter()
            .map(String::as_str)
            .filter(|l| !l.is_empty())
            .collect();
        if text.is_empty() {
            println!("  (ignored: Enter pressed before this question)");
        } else {
            println!(
                "  (ignored: `{}` typed before this question)",
                text.join("`, `")
            );
        }
    }

    fn stdin_line(&mut self) -> Result<Option<String>, AskError> {
        if self.stdin_ended {
            return Ok(None);
        }
        let rx = self.stdin.get_or_insert_with(spawn_stdin_reader);
        loop {
            if crate::interrupted() {
                return Err(AskError::Interrupted);
            }
            match rx.recv_timeout(Duration::from_millis(100)) {
                Ok(line) => return Ok(line),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return Ok(None),
            }
        }
    }

    /// Asks `question`; an empty answer takes `default`.
    ///
    /// # Errors
    /// [`AskError`]; [`AskError::Back`] for the answer [`BACK`] (any case).
    pub fn ask(&mut self, question: &str, default: Option<&str>) -> Result<String, AskError> {
        let a = self.answer(question, default)?;
        if a.eq_ignore_ascii_case(BACK) {
            return Err(AskError::Back);
        }
        Ok(a)
    }

    /// The answer to `question`, `back` included.
    fn answer(&mut self, question: &str, default: Option<&str>) -> Result<String, AskError> {
        self.end_bar();
        if std::mem::take(&mut self.back_hint) {
            println!("{BACK_HINT}");
        }
        let prompt = match default {
            Some(d) => format!("? {question} [{d}]: "),
            None => format!("? {question}: "),
        };
        if let Some(a) = self.answers.next() {
            println!("{prompt}{a}");
            return Ok(pick(a, default));
        }
        if self.yes
            && let Some(d) = default
        {
            println!("{prompt}{d}");
            return Ok(d.to_string());
        }
        if self.discard_typeahead {
            self.discard_typeahead();
        }
        if self.tty {
            print!("{prompt}");
            let _ = std::io::stdout().flush();
        } else {
            // A plain line, so a program reading the output sees the question at once.
            println!("{prompt}");
        }
        match self.stdin_line()? {
            Some(a) => Ok(pick(a, default)),
            None => Err(AskError::NoAnswer(question.to_string())),
        }
    }

    /// A yes/no question.
    ///
    /// # Errors
    /// [`AskError`].
    pub fn confirm(&mut self, question: &str, default_yes: bool) -> Result<bool, AskError> {
        loop {
            let a = self.ask(question, Some(if default_yes { "y" } else { "n" }))?;
            match a.to_ascii_lowercase().as_str() {
                "y" | "yes" => return Ok(true),
                "n" | "no" => return Ok(false),
                _ => self.say("  please answer y or n"),
            }
        }
    }

    /// A yes/no question without a default: only a typed `y`/`yes` (or one in `--answers`) is a
    /// yes; `--yes` does not answer it, an empty answer asks again, and after
    /// [`EXPLICIT_TRIES`] answers that are neither it is a no. For what changes the
    /// board's parameters or flash on the operator's word (apply, save, a wiring correction).
    ///
    /// # Errors
    /// [`AskError`].
    pub fn confirm_explicit(&mut self, question: &str) -> Result<bool, AskError> {
        let yes = self.yes;
        self.yes = false;
        let mut answer = None;
        for _ in 0..EXPLICIT_TRIES {
            let a = match self.ask(&format!("{question}? (y/n)"), None) {
                Ok(a) => a,
                Err(e) => {
                    self.yes = yes;
                    return Err(e);
                }
            };
            match a.to_ascii_lowercase().as_str() {
                "y" | "yes" => answer = Some(true),
                "n" | "no" => answer = Some(false),
                _ => self.say("  type y (yes) or n (no)"),
            }
            if answer.is_some() {
                break;
            }
        }
        self.yes = yes;
        // A script that answers everything with Enter does not loop here: no yes is a no.
        Ok(answer.unwrap_or_else(|| {
            self.say("  no y given: taken as no");
            false
        }))
    }

    /// Starts a run's progress display.
    pub fn progress_start(&mut self) {
        self.quarter = None;
    }

    /// Progress of the running path (0..1) and the odometry pose.
    pub fn progress(&mut self, fraction: f64, x: f64, y: f64, theta_deg: f64) {
        let f = fraction.clamp(0.0, 1.0);
        let pose = format!("x={x:+.3} m y={y:+.3} m theta={theta_deg:+.1} deg");
        if self.tty {
            let filled = (f * 30.0).round() as usize;
            print!(
                "\r  [{}{}] {:3.0} %  {pose}   ",
                "#".repeat(filled),
                "-".repeat(30 - filled),
                f * 100.0
            );
            let _ = std::io::stdout().flush();
            self.bar_shown = true;
        } else {
            let q = (f * 4.0).floor() as u32;
            if self.quarter.is_none_or(|old| q > old) {
                self.quarter = Some(q);
                println!("  progress {:3} %  {pose}", q * 25);
            }
        }
    }
}

/// Reads stdin line by line on a thread (`None` at its end), so Ctrl-C ends a wait at once.
fn spawn_stdin_reader() -> Receiver<Option<String>> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut lines = BufReader::new(std::io::stdin()).lines();
        loop {
            let line = lines.next().and_then(Result::ok);
            let end = line.is_none();
            if tx.send(line).is_err() || end {
                return;
            }
        }
    });
    rx
}

fn pick(answer: String, default: Option<&str>) -> String {
    let a = answer.trim();
    if a.is_empty() {
        default.unwrap_or("").to_string()
    } else {
        a.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `Ui` whose stdin is `lines` (already typed, then the end of input).
    fn ui_with_stdin(lines: &[&str], terminal: bool) -> Ui {
        let (tx, rx) = mpsc::channel();
        for l in lines {
            tx.send(Some((*l).to_string())).unwrap();
        }
        tx.send(None).unwrap();
        let mut ui = Ui::new(Vec::new(), false);
        ui.stdin = Some(rx);
        ui.discard_typeahead = terminal;
        ui
    }

    #[test]
    fn a_terminal_does_not_answer_with_what_was_typed_before_the_question() {
        // An Enter pressed twice after a measurement, and text typed while the robot drove:
        // neither starts the next run.
        let mut ui = ui_with_stdin(&["", "0.01 0.02"], true);
        match ui.ask("Enter starts the run", Some("go")) {
            Err(AskError::NoAnswer(q)) => assert_eq!(q, "Enter starts the run"),
            other => panic!("a typed-ahead line was taken as the answer: {other:?}"),
        }
    }

    #[test]
    fn only_a_typed_yes_is_a_yes() {
        let mut ui = ui_with_stdin(&["", "yes"], false);
        ui.yes = true;
        assert!(ui.confirm_explicit("Apply exact").unwrap());
        // Enter three times: a no, not a question asked for ever.
        let mut ui = ui_with_stdin(&["", "", "", "y"], false);
        assert!(!ui.confirm_explicit("Save it").unwrap());
        assert_eq!(ui.ask("next", None).unwrap(), "y");
    }

    #[test]
    fn back_is_read_at_every_question() {
        let mut ui = ui_with_stdin(&["BACK", " back ", "back", "n"], false);
        assert!(matches!(
            ui.ask("Wheelbase b", Some("0.385m")),
            Err(AskError::Back)
        ));
        assert!(matches!(
            ui.confirm("Clear the fault now", true),
            Err(AskError::Back)
        ));
        // A question that needs a typed yes: `back` is no answer to it, and `--yes` is still
        // set afterwards.
        ui.yes = true;
        assert!(matches!(
            ui.confirm_explicit("Apply exact"),
            Err(AskError::Back)
        ));
        assert!(ui.yes);
        ui.yes = false;
        assert!(!ui.confirm("Save it", true).unwrap());
        // The hint was shown once, before the first question.
        assert!(!ui.back_hint);
    }

    #[test]
    fn a_pipe_answers_in_order() {
        // Scripts pipe their answers ahead of the questions: each line answers the next one.
        let mut ui = ui_with_stdin(&["", "0.01 0.02"], false);
        assert_eq!(ui.ask("Enter starts the run", Some("go")).unwrap(), "go");
        assert_eq!(ui.ask("Measured end pose", None).unwrap(), "0.01 0.02");
        assert!(matches!(
            ui.ask("Enter starts the run", Some("go")),
            Err(AskError::NoAnswer(_))
        ));
    }
}
