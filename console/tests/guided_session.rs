//! `guided_session`: the console tool, as an operator runs it, against the simulated board on
//! its pseudo-terminal (`host-sim serial --pty --fast`, the same serial-port code path as a
//! USB-UART).
//!
//! The test is the operator: it answers the tool's questions on stdin (`--yes` takes the
//! defaults: the board's plan of 5 + 5 squares, start each run, the recommended method), and
//! for each "measured end pose" question it types the pose the simulated tape measure reports
//! (the simulator prints the true end pose of every run on its stderr). Then:
//! 1. a full session: applied, saved, `params` read back; the log's `calibrate` table from the
//!    board equals, line for line, `odocal-console recalibrate LOG` (every method) and
//!    `recalibrate LOG --method exact`'s row — the same factors to the last printed digit;
//! 2. a session whose tool is killed after its third run and whose board is restarted
//!    (`reboot` on the simulator's stdin: a new board over the same flash, which keeps the runs)
//!    before `--resume`: the session continues on the board with nothing lost (3 + 7 = 10
//!    measured runs in the board's calibration, applied, saved, verified) and the log
//!    recalibrates offline to the board's table.
//!
//! `factory_default_board_full_procedure` types the whole procedure on a factory-default board
//! (setup, bring-up, identification, runs, apply, save, check square), and `ros2_export` exports
//! a guided session's log for ROS 2 and checks it against the board's applied geometry.

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

#[path = "guided_session/export.rs"]
mod export;
#[path = "guided_session/flagged.rs"]
mod flagged;
#[path = "guided_session/questions.rs"]
mod questions;
#[path = "guided_session/session.rs"]
mod session;
mod support;
use export::factory_session;
use support::{host_sim, lines_of};

/// Generous limit for any one wait (only to avoid a hang; nothing is timed).
const WAIT: Duration = Duration::from_secs(120);

fn target_dir() -> PathBuf {
    // target/<profile>/deps/guided_session-… → target/<profile>
    let exe = std::env::current_exe().unwrap();
    exe.parent().unwrap().parent().unwrap().to_path_buf()
}

struct Sim {
    child: Child,
    stdin: ChildStdin,
    pty: String,
    stderr: Arc<Mutex<Vec<String>>>,
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Sim {
    fn start(bin: &Path) -> Sim {
        Sim::start_with(bin, &["--fast"])
    }

    fn start_with(bin: &Path, args: &[&str]) -> Sim {
        let mut child = Command::new(bin)
            .args(["serial", "--pty"])
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("host-sim starts");
        let mut out = BufReader::new(child.stdout.take().unwrap());
        let mut first = String::new();
        out.read_line(&mut first).unwrap();
        let pty = first
            .trim()
            .strip_prefix("pty ")
            .unwrap_or_else(|| panic!("no pty line: {first:?}"))
            .to_string();
        let stderr = Arc::new(Mutex::new(Vec::new()));
        let sink = stderr.clone();
        let err = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            for l in BufReader::new(err).lines().map_while(Result::ok) {
                sink.lock().unwrap().push(l);
            }
        });
        let stdin = child.stdin.take().unwrap();
        Sim {
            child,
            stdin,
            pty,
            stderr,
        }
    }

    /// The `k`-th (0-based) true end pose of a stored run, as `x y theta`.
    fn true_end(&self, k: usize) -> String {
        let deadline = Instant::now() + WAIT;
        loop {
            let found = self
                .stderr
                .lock()
                .unwrap()
                .iter()
                .filter_map(|l| l.strip_prefix("sim: true end pose in the run's start frame: "))
                .nth(k)
                .map(|m| m.strip_prefix("measure ").unwrap().to_string());
            if let Some(m) = found {
                return m;
            }
            assert!(Instant::now() < deadline, "no true end pose {k}");
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    fn count(&self, prefix: &str) -> usize {
        let l = self.stderr.lock().unwrap();
        l.iter().filter(|l| l.starts_with(prefix)).count()
    }

    /// Types one line into the board's console (as a person at a terminal would) and returns
    /// its reply: the first `err` line or line starting with `reply` (output still queued for
    /// the killed tool comes first and is skipped).
    fn type_line(&self, line: &str, reply: &str) -> String {
        let mut port = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&self.pty)
            .unwrap();
        write!(port, "{line}\r").unwrap();
        let mut reader = BufReader::new(port);
        let mut l = String::new();
        loop {
            l.clear();
            reader.read_line(&mut l).unwrap();
            let t = l.trim();
            if t.starts_with(reply) || t.starts_with("err") {
                return t.to_string();
            }
        }
    }

    /// A short press of the board's button (the simulator's stdin).
    fn press_button(&self) {
        let mut stdin = &self.stdin;
        writeln!(stdin, "button").unwrap();
    }

    fn reboot(&mut self) {
        let boots = self.count("sim: event boot");
        writeln!(self.stdin, "reboot").unwrap();
        let deadline = Instant::now() + WAIT;
        while self.count("sim: event boot") == boots {
            assert!(Instant::now() < deadline, "the board did not reboot");
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

struct Tool {
    child: Child,
    stdin: ChildStdin,
    lines: Receiver<String>,
    transcript: Vec<String>,
    stderr: Arc<Mutex<String>>,
    stderr_done: Option<std::thread::JoinHandle<()>>,
}

impl Drop for Tool {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Tool {
    fn start(args: &[&str]) -> Tool {
        let mut child = Command::new(env!("CARGO_BIN_EXE_odocal-console"))
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("the console starts");
        let err = child.stderr.take().unwrap();
        let stderr = Arc::new(Mutex::new(String::new()));
        let sink = stderr.clone();
        let stderr_done = std::thread::spawn(move || {
            for l in BufReader::new(err).lines().map_while(Result::ok) {
                eprintln!("{l}");
                sink.lock().unwrap().push_str(&format!("{l}\n"));
            }
        });
        let lines = lines_of(child.stdout.take().unwrap());
        let stdin = child.stdin.take().unwrap();
        Tool {
            child,
            stdin,
            lines,
            transcript: Vec::new(),
            stderr,
            stderr_done: Some(stderr_done),
        }
    }

    /// The next output line; `None` at the end of the output.
    fn next(&mut self) -> Option<String> {
        let l = self.lines.recv_timeout(WAIT);
        match l {
            Ok(l) => {
                self.transcript.push(l.clone());
                Some(l)
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => None,
            Err(mpsc::RecvTimeoutError::Timeout) => {
                panic!(
                    "the console said nothing for {WAIT:?}:\n{}",
                    self.transcript.join("\n")
                )
            }
        }
    }

    /// Types `text`; the transcript shows it after the question it answers, as `--answers`
    /// shows a file's answers.
    fn answer(&mut self, text: &str) {
        writeln!(self.stdin, "{text}").unwrap();
        if let Some(last) = self.transcript.last_mut()
            && last.starts_with("? ")
        {
            if !last.ends_with(' ') {
                last.push(' ');
            }
            last.push_str(text);
        }
    }

    /// Runs the dialogue: answers every measurement question with the simulator's true end
    /// pose (`measured` counts the poses used so far); stops early when `stop_at` is printed.
    fn converse(&mut self, sim: &Sim, measured: &mut usize, stop_at: Option<&str>) -> bool {
        while let Some(l) = self.next() {
            if stop_at.is_some_and(|s| l.starts_with(s)) {
                return false;
            }
            if l == "  waiting for the button (short press)" {
                sim.press_button();
            }
            if l.starts_with("? Measured end pose of run") {
                let pose = sim.true_end(*measured);
                *measured += 1;
                self.answer(&pose);
            }
            // Apply and save need a typed yes (`--yes` does not give it).
            if l.starts_with("? ") && l.trim_end().ends_with("(y/n):") {
                self.answer("y");
            }
        }
        true
    }

    /// Waits for the tool to end: its exit code, stdout and stderr.
    fn end(mut self) -> (Option<i32>, String, String) {
        let status = self.child.wait().unwrap();
        // The output threads end with the process.
        while self.next().is_some() {}
        if let Some(t) = self.stderr_done.take() {
            t.join().unwrap();
        }
        let text = std::mem::take(&mut self.transcript).join("\n");
        let err = self.stderr.lock().unwrap().clone();
        (status.code(), text, err)
    }

    fn finish(self) -> (bool, String) {
        let (code, text, err) = self.end();
        (code == Some(0), format!("{text}\n{err}"))
    }
}

/// The log's entries; at most one line (the one the killed tool was writing) may be torn.
fn json_lines(path: &Path) -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(path).unwrap();
    let entries: Vec<serde_json::Value> = text
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    assert!(
        text.lines().count() - entries.len() <= 1,
        "torn lines in {}",
        path.display()
    );
    entries
}

/// The `calibrate` tables logged (source, lines without the final line's prefix changes).
fn tables(log: &[serde_json::Value]) -> Vec<(String, Vec<String>)> {
    log.iter()
        .filter(|v| v["kind"] == "calibrate")
        .map(|v| {
            (
                v["source"].as_str().unwrap().to_string(),
                v["table"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|s| s.as_str().unwrap().to_string())
                    .collect(),
            )
        })
        .collect()
}

/// `odocal-console recalibrate LOG [--method M]`: the table lines (two leading spaces removed).
fn recalibrate(log: &Path, method: Option<&str>) -> Vec<String> {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_odocal-console"));
    cmd.arg("recalibrate").arg(log);
    if let Some(m) = method {
        cmd.args(["--method", m]);
    }
    let out = cmd.output().unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(out.status.success(), "{text}");
    text.lines()
        .skip(1)
        .map(|l| l.strip_prefix("  ").unwrap_or(l).to_string())
        .collect()
}

fn row<'a>(table: &'a [String], method: &str) -> &'a str {
    table
        .iter()
        .find(|l| l.split_whitespace().next() == Some(method))
        .unwrap_or_else(|| panic!("no {method} row in {table:#?}"))
}

fn out_dir(name: &str) -> PathBuf {
    let dir = target_dir().join("guided-session").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The tool on `sim`'s port with its session log in a fresh `out_dir(name)`, the plan's answers
/// from `answers` (an answers file) and `--yes` for the rest; returns it and the log's path.
fn tool_answering(sim: &Sim, name: &str, answers: &str) -> (Tool, PathBuf) {
    tool_with_answers(sim, name, answers, true)
}

/// The answers that skip the robot's setup (keep the geometry, skip the bring-up check and the
/// motor identification): the sessions below are about the runs.
const SKIP_SETUP: &str = "k\ns\ns\n";

/// The tool with its first answers from a file (after [`SKIP_SETUP`]); then, with `yes`, every
/// default (`--yes`), without it, whatever the test types on its stdin.
fn tool_with_answers(sim: &Sim, name: &str, answers: &str, yes: bool) -> (Tool, PathBuf) {
    let dir = out_dir(name);
    let log = dir.join("session.jsonl");
    let file = dir.join("answers.txt");
    std::fs::write(&file, format!("{SKIP_SETUP}{answers}")).unwrap();
    let mut args = vec![
        "--port",
        &sim.pty,
        "--log",
        log.to_str().unwrap(),
        "--answers",
        file.to_str().unwrap(),
    ];
    if yes {
        args.push("--yes");
    }
    (Tool::start(&args), log)
}

/// A session on a new simulated board whose tool is killed when it announces run 4 (three runs
/// measured), then the board is reset (`reboot`; with `wipe`, its runs are dropped too, as on a
/// board that does not keep them). Returns the board, the log and the poses measured.
fn killed_after_three_runs(bin: &Path, name: &str, wipe: bool) -> (Sim, PathBuf, usize) {
    let mut sim = Sim::start(bin);
    let (mut tool, log) = tool_answering(&sim, name, "");
    let mut measured = 0;
    assert!(!tool.converse(&sim, &mut measured, Some("run 4/10:")));
    assert_eq!(measured, 3);
    let _ = tool.child.kill();
    let _ = tool.finish();
    sim.reboot();
    if wipe {
        let dropped = sim.type_line("drop all yes", "ok dropped all");
        assert!(dropped.starts_with("ok dropped all"), "{dropped}");
    }
    (sim, log, measured)
}

/// `--resume LOG --yes` on the board to the end; returns the transcript.
fn resume(sim: &Sim, log: &Path, measured: &mut usize) -> String {
    let mut tool = Tool::start(&[
        "--port",
        &sim.pty,
        "--resume",
        log.to_str().unwrap(),
        "--yes",
    ]);
    tool.converse(sim, measured, None);
    let (ok, text) = tool.finish();
    assert!(ok, "the resumed session failed:\n{text}");
    text
}

/// Every run measured with y to the right (y and the heading negated: the commonest slip with a
/// tape and a square): the board's fit check says the runs fit no geometry and names `y-right`;
/// the tool stops there with the choices, `c` re-reads every run (`convention y-right`), the fit
/// is then good, and exact is applied without a second yes, its factors those of the simulated
/// robot (E_d 0.995, E_b 1.010) to 2e-3. Without the convention they would be about 1.004 and
/// 0.990 (the issue's y-right session).
#[test]
fn a_poor_fit_stops_with_the_choices() {
    let sim = Sim::start(&host_sim());
    let (mut tool, log) = tool_with_answers(&sim, "poor-fit", "100cm\n3\n", false);
    let (mut measured, mut choices) = (0, Vec::new());
    while let Some(l) = tool.next() {
        let waiting = l.starts_with("? ") && l.trim_end().ends_with(':');
        if !waiting {
            continue;
        }
        if l.starts_with("? Measured end pose of run") {
            let pose = sim.true_end(measured);
            measured += 1;
            // y and theta with the other sign.
            tool.answer(&with_other_sign(&pose, &[1, 2]));
        } else if l.starts_with("? The fit is poor. Now") {
            choices.push(l.clone());
            tool.answer("c");
        } else if l.trim_end().ends_with("(y/n):") {
            tool.answer("y");
        } else {
            tool.answer("");
        }
    }
    let (ok, text) = tool.finish();
    println!("{text}");
    assert!(ok, "the session failed:\n{text}");
    assert_eq!(choices.len(), 1, "{text}");
    assert!(
        choices[0].contains("c: convention y-right"),
        "{}",
        choices[0]
    );
    assert!(text.contains("POOR FIT"), "{text}");
    assert!(text.contains("  ok convention y-right"), "{text}");
    let sent: Vec<String> = json_lines(&log)
        .iter()
        .filter(|v| v["kind"] == "tx")
        .map(|v| v["line"].as_str().unwrap().to_string())
        .collect();
    assert!(sent.iter().any(|l| l == "convention y-right"), "{sent:#?}");
    let apply: Vec<&String> = sent.iter().filter(|l| l.starts_with("apply ")).collect();
    assert_eq!(apply, ["apply exact"], "{sent:#?}");
    let verified = text
        .lines()
        .find(|l| l.starts_with("verified: params shows calibration exact"))
        .unwrap_or_else(|| panic!("{text}"));
    let factor = |key: &str| -> f64 {
        let at = verified.find(key).unwrap() + key.len();
        verified[at..]
            .split_whitespace()
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    let (e_d, e_b) = (factor("E_d="), factor("E_b="));
    assert!(
        (e_d - 0.995).abs() < 2e-3 && (e_b - 1.010).abs() < 2e-3,
        "E_d {e_d} E_b {e_b}"
    );
}

/// A guided session on `sim` (log in `out_dir(name)`) whose every question must start as the
/// next entry of `script` says, answered with that entry's answer (`<pose>`: the simulator's
/// true end pose of the next stored run). Returns the transcript, the lines sent to the board
/// and the poses typed.
fn scripted(sim: &Sim, name: &str, script: &[(&str, &str)]) -> (String, Vec<String>, usize) {
    let dir = out_dir(name);
    let log = dir.join("session.jsonl");
    let mut tool = Tool::start(&["--port", &sim.pty, "--log", log.to_str().unwrap()]);
    let (mut asked, mut measured) = (0, 0);
    while let Some(l) = tool.next() {
        let waiting = l.starts_with("? ") && l.trim_end().ends_with(':');
        if !waiting {
            continue;
        }
        let Some(&(expected, answer)) = script.get(asked) else {
            panic!(
                "question {asked} after the script: {l}\n{}",
                tool.transcript.join("\n")
            );
        };
        assert!(
            l[2..].starts_with(expected),
            "question {asked}: expected `{expected}`, asked `{l}`:\n{}",
            tool.transcript.join("\n")
        );
        asked += 1;
        if answer == "<pose>" {
            let pose = sim.true_end(measured);
            measured += 1;
            tool.answer(&pose);
        } else {
            tool.answer(answer);
        }
    }
    let (ok, text) = tool.finish();
    println!("{text}");
    assert!(ok, "the session failed:\n{text}");
    assert_eq!(asked, script.len(), "{text}");
    let sent = json_lines(&log)
        .iter()
        .filter(|v| v["kind"] == "tx")
        .map(|v| v["line"].as_str().unwrap().to_string())
        .collect();
    (text, sent, measured)
}

/// The marker line that opens docs/operator.md's guided-session transcript.
const TRANSCRIPT_START: &str = "$ cargo console --port /dev/pts/0 --log session.jsonl";

/// docs/operator.md's guided-session transcript is what the console prints today for the
/// procedure it describes (`factory_session`: a factory-default board with a reversed motor),
/// its pty and output folder written as the docs write them. Stale, it fails with the new text;
/// `ODOCAL_UPDATE_DOCS=1` rewrites the block from this run.
#[test]
fn operator_transcript_is_current() {
    let (_sim, ok, text, log, _) = factory_session("transcript");
    assert!(ok, "the session failed:\n{text}");
    let folder = format!("{}/", log.parent().unwrap().display());
    let mut today = vec![TRANSCRIPT_START.to_string()];
    for l in text.lines() {
        let l = l.replace(&folder, "");
        // The pty's number: the one the docs name.
        let l = match l.find("/dev/pts/") {
            Some(at) => {
                let rest = &l[at + "/dev/pts/".len()..];
                let digits = rest.chars().take_while(char::is_ascii_digit).count();
                format!("{}/dev/pts/0{}", &l[..at], &rest[digits..])
            }
            None => l,
        };
        today.push(l.trim_end().to_string());
    }
    let docs_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/operator.md");
    let docs = std::fs::read_to_string(&docs_path).unwrap();
    let start = docs
        .find(TRANSCRIPT_START)
        .unwrap_or_else(|| panic!("no `{TRANSCRIPT_START}` in docs/operator.md"));
    let end = start
        + docs[start..]
            .find("\n```")
            .expect("the transcript's block ends");
    let written: Vec<&str> = docs[start..end].lines().collect();
    if std::env::var_os("ODOCAL_UPDATE_DOCS").is_some() {
        let updated = format!("{}{}{}", &docs[..start], today.join("\n"), &docs[end..]);
        std::fs::write(&docs_path, updated).unwrap();
        return;
    }
    // The measured values depend, in their last digits, on when the PC's commands land in the
    // simulated board's time (a run's end to a micrometre, the bring-up's coast, the factors to
    // 1e-7, and so the table's padding): every signed or decimal number is compared as `#`, and
    // runs of spaces as one; the progress lines, samples of the pose stream (how many arrive
    // before a run's end depends on the same timing), not at all. The words, the units, the
    // columns and the whole numbers (runs, counts, steps) must match.
    let steady = |lines: &mut dyn Iterator<Item = &str>| -> Vec<String> {
        lines
            .filter(|l| !l.starts_with("  progress "))
            .map(|l| {
                numbers_masked(l)
                    .split_whitespace()
                    .collect::<Vec<_>>()
                    .join(" ")
            })
            .collect()
    };
    let written = steady(&mut written.iter().copied());
    let today_steady = steady(&mut today.iter().map(String::as_str));
    let first_difference = written
        .iter()
        .zip(&today_steady)
        .position(|(a, b)| a != b)
        .unwrap_or(written.len().min(today_steady.len()));
    assert!(
        written == today_steady,
        "docs/operator.md's transcript is stale from its line {} on (docs: {:?}, today: {:?}); \
         ODOCAL_UPDATE_DOCS=1 cargo test -p odocal-console --test guided_session \
         operator_transcript_is_current rewrites it from this run:\n{}",
        first_difference + 1,
        written.get(first_difference),
        today_steady.get(first_difference),
        today.join("\n")
    );
}

/// A typed pose (`x y theta`, each with its unit) with the values at `positions` given the other
/// sign: an operator's sign mistake.
fn with_other_sign(pose: &str, positions: &[usize]) -> String {
    pose.split_whitespace()
        .enumerate()
        .map(
            |(i, w)| match (positions.contains(&i), w.strip_prefix('-')) {
                (false, _) => w.to_string(),
                (true, Some(v)) => v.to_string(),
                (true, None) => format!("-{w}"),
            },
        )
        .collect::<Vec<_>>()
        .join(" ")
}

/// `line` with every signed or decimal number (`+0.003`, `-54.731`, `1.25e-4`, `+21231`) written
/// `#`; unsigned whole numbers stay.
fn numbers_masked(line: &str) -> String {
    let chars: Vec<char> = line.chars().collect();
    let mut out = String::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let signed = (c == '+' || c == '-') && chars.get(i + 1).is_some_and(char::is_ascii_digit);
        // A number starts at a digit or a sign before one, not inside a word (`E_d`, `L=1`).
        let starts = (c.is_ascii_digit() || signed)
            && !i
                .checked_sub(1)
                .and_then(|j| chars.get(j))
                .is_some_and(|p| p.is_ascii_alphanumeric() || *p == '_' || *p == '.');
        if !starts {
            out.push(c);
            i += 1;
            continue;
        }
        let mut j = i + usize::from(signed);
        let mut decimal = false;
        while let Some(&d) = chars.get(j) {
            let exponent = (d == 'e' || d == 'E')
                && chars
                    .get(j + 1)
                    .is_some_and(|n| n.is_ascii_digit() || *n == '-' || *n == '+');
            if d.is_ascii_digit() {
                j += 1;
            } else if d == '.' && chars.get(j + 1).is_some_and(char::is_ascii_digit) {
                decimal = true;
                j += 1;
            } else if exponent && decimal {
                j += 2;
            } else {
                break;
            }
        }
        if signed || decimal {
            out.push('#');
        } else {
            out.extend(&chars[i..j]);
        }
        i = j;
    }
    out
}

#[test]
fn numbers_are_masked_but_words_and_whole_numbers_stay() {
    assert_eq!(
        numbers_masked("  exact  0.995000 1.25e-4 run 12 L=1.000 m +21231 counts E_d=0.99"),
        "  exact  # # run 12 L=# m # counts E_d=#"
    );
    assert_eq!(
        numbers_masked("ok 27 commands, 200000 counts/rev"),
        "ok 27 commands, 200000 counts/rev"
    );
}
