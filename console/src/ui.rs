//! The operator's side: messages, questions and the run progress bar.
//!
//! On a terminal, the progress bar redraws in place; without one (a pipe, a log file, a
//! script) every message is a plain line and the progress is printed at each quarter. Answers
//! come from `--answers FILE` (one a line, in the order of the questions) first, then from
//! `--yes` (the default of every question that has one), then from stdin. stdin is read on a
//! thread, so Ctrl-C ends a question at once.

use std::io::{BufRead, BufReader, IsTerminal, Write};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::Duration;

/// Where answers come from and how output looks.
pub struct Ui {
    tty: bool,
    answers: std::vec::IntoIter<String>,
    yes: bool,
    stdin: Option<Receiver<Option<String>>>,
    /// Progress quarter last printed (no-TTY mode).
    quarter: Option<u32>,
    bar_shown: bool,
}

/// Why a question got no answer.
#[derive(Debug)]
pub enum AskError {
    /// Ctrl-C.
    Interrupted,
    /// stdin ended and nothing else had an answer.
    NoAnswer(String),
}

impl std::fmt::Display for AskError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AskError::Interrupted => f.write_str("interrupted (Ctrl-C)"),
            AskError::NoAnswer(q) => write!(
                f,
                "no answer for `{q}` (stdin ended; give it in --answers or run interactively)"
            ),
        }
    }
}

impl Ui {
    /// Answers from `answers` (lines), `--yes`, then stdin.
    pub fn new(answers: Vec<String>, yes: bool) -> Ui {
        Ui {
            tty: std::io::stdout().is_terminal(),
            answers: answers.into_iter(),
            yes,
            stdin: None,
            quarter: None,
            bar_shown: false,
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

    fn stdin_line(&mut self) -> Result<Option<String>, AskError> {
        let rx = self.stdin.get_or_insert_with(|| {
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
        });
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
    /// [`AskError`].
    pub fn ask(&mut self, question: &str, default: Option<&str>) -> Result<String, AskError> {
        self.end_bar();
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

fn pick(answer: String, default: Option<&str>) -> String {
    let a = answer.trim();
    if a.is_empty() {
        default.unwrap_or("").to_string()
    } else {
        a.to_string()
    }
}
