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

mod support;
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

#[test]
fn guided_session() {
    let bin = host_sim();

    // 1. A full session, applied and saved, recalibrated offline from its log.
    let sim = Sim::start(&bin);
    // The plan from an answers file (L in centimetres, converted) and the first run started
    // with the board's button; the rest by --yes and stdin.
    let (mut tool, log) = tool_answering(&sim, "full", "150cm\n5\nb\n");
    let mut measured = 0;
    tool.converse(&sim, &mut measured, None);
    let (ok, text) = tool.finish();
    assert!(ok, "the session failed:\n{text}");
    // Ten runs and the check square after the calibration.
    assert_eq!(measured, 11, "{text}");
    assert!(text.contains("board: odocal "), "{text}");
    assert!(
        text.contains("plan: 5 CW + 5 CCW squares of L = 1.500 m"),
        "{text}"
    );
    assert!(text.contains("run 10/10: square ccw"), "{text}");

    assert!(text.contains("  progress 100 %"), "{text}");
    let verified = text
        .lines()
        .find(|l| l.starts_with("verified: params shows calibration exact E_d="))
        .unwrap_or_else(|| panic!("not verified:\n{text}"));
    assert!(log.with_file_name("session.svg").exists());

    let entries = json_lines(&log);
    let runs: Vec<_> = entries.iter().filter(|v| v["kind"] == "run").collect();
    // The check square is logged, then dropped: it is no calibration run.
    assert_eq!(runs.len(), 11);
    assert_eq!(entries.iter().filter(|v| v["kind"] == "drop").count(), 1);
    for r in &runs {
        let record = r["record"].as_array().unwrap();
        assert!(
            record
                .iter()
                .any(|l| l.as_str().unwrap().starts_with("knot 90 "))
        );
        assert!(!record.iter().any(|l| l == "measured none"));
    }
    // Run 1 came from the board's button, the others from the tool's `run`.
    let line_of = |v: &serde_json::Value| v["line"].as_str().unwrap_or("").to_string();
    assert!(entries.iter().any(|v| v["kind"] == "rx"
        && line_of(v) == "event button: ok run 1 started: square cw L=1.500 m"));
    let runs_sent: Vec<String> = entries
        .iter()
        .filter(|v| v["kind"] == "tx" && line_of(v).starts_with("run "))
        .map(line_of)
        .collect();
    assert_eq!(runs_sent.len(), 10, "{runs_sent:?}");
    assert_eq!(runs_sent[0], "run ccw 1.5");
    // The session leaves the board echoing, as a boot does.
    let last_tx = entries
        .iter()
        .rev()
        .find(|v| v["kind"] == "tx")
        .map(line_of);
    assert_eq!(last_tx.as_deref(), Some("echo on"));
    for kind in ["tx", "rx", "measure", "apply", "save", "verify"] {
        assert!(entries.iter().any(|v| v["kind"] == kind), "no {kind} entry");
    }
    assert!(entries.iter().all(|v| v["t"].as_f64().is_some()));
    let logged = tables(&entries);
    assert_eq!(logged.len(), 1);
    let (source, board) = &logged[0];
    assert_eq!(source, "board");
    assert!(
        board
            .last()
            .unwrap()
            .starts_with("ok 6 solved from 10 measured runs (cw 5, ccw 5)"),
        "{board:#?}"
    );
    // Offline, every method: the board's reply line for line.
    let offline = recalibrate(&log, None);
    assert_eq!(&offline, board);
    // One method: its row is the board's, to the last digit.
    let exact = recalibrate(&log, Some("exact"));
    let board_row = row(board, "exact");
    // Asked alone, no row is marked as the lowest leave-one-out error of several.
    let unmarked = board_row.trim_end_matches(odocal::protocol::token::LOWEST_LOO);
    assert_eq!(row(&exact, "exact"), unmarked);
    let w: Vec<&str> = board_row.split_whitespace().collect();
    assert!(
        verified.contains(&format!("E_d={} E_b={}", w[1], w[2])),
        "{verified} vs {board_row}"
    );
    println!("board:   {board_row}\noffline: {}", row(&exact, "exact"));
    drop(sim);

    // 2. The tool dies after run 3 and the board is reset; the session resumes from the log.
    let (sim, log, mut measured) = killed_after_three_runs(&bin, "resumed", false);
    let text = resume(&sim, &log, &mut measured);
    // Every run measured once: a fourth run the killed tool had started (kept in the board's
    // flash across the reset) is measured by the resumed tool; then the check square.
    assert_eq!(measured, 11, "{text}");
    assert!(
        text.contains("resuming: 3 measured run(s) in the log"),
        "{text}"
    );
    // The board keeps its runs across a reset: the session continues on the board.
    assert!(
        text.contains("the board still holds the 3 logged run(s): continuing on the board"),
        "{text}"
    );
    assert!(
        text.contains("verified: params shows calibration exact"),
        "{text}"
    );
    let entries = json_lines(&log);
    let runs = entries.iter().filter(|v| v["kind"] == "run").count();
    assert_eq!(runs, 11);
    let logged = tables(&entries);
    let (source, resumed) = logged.last().unwrap();
    assert_eq!(source, "board");
    assert!(
        resumed
            .last()
            .unwrap()
            .starts_with("ok 6 solved from 10 measured runs (cw 5, ccw 5)"),
        "{resumed:#?}"
    );
    assert_eq!(&recalibrate(&log, None), resumed);
    drop(sim);

    // 3. The same with a board that lost its runs in the reset (firmware without run
    //    persistence, or the flash wiped): the log keeps them, the missing runs are driven, and
    //    the calibration of all ten is computed on the PC with the library.
    let (sim, log, mut measured) = killed_after_three_runs(&bin, "lost", true);
    // A run the killed tool had started went with them.
    let lost = sim.count("sim: true end pose in the run's start frame: ") - measured;
    measured += lost;
    let text = resume(&sim, &log, &mut measured);
    assert_eq!(measured - lost, 10, "{text}");
    assert!(
        text.contains("the board holds none of the 3 logged run(s) (it was reset)"),
        "{text}"
    );
    let entries = json_lines(&log);
    assert_eq!(entries.iter().filter(|v| v["kind"] == "run").count(), 10);
    let logged = tables(&entries);
    let (source, offline) = logged.last().unwrap();
    assert_eq!(source, "offline");
    assert!(
        offline
            .last()
            .unwrap()
            .starts_with("ok 6 solved from 10 measured runs (cw 5, ccw 5)"),
        "{offline:#?}"
    );
    assert_eq!(&recalibrate(&log, None), offline);
    // Nothing was applied from the board's partial runs without asking.
    assert!(!entries.iter().any(|v| v["kind"] == "apply"));
}

/// Ctrl-C during a run stops the robot first (the stop key on the wire), then the tool ends
/// saying how to resume; the run is reported aborted. The simulated board runs in real time
/// here, so the run is still driving when Ctrl-C comes.
#[test]
fn ctrl_c_stops_the_robot() {
    let sim = Sim::start_with(&host_sim(), &[]);
    let (mut tool, log) = tool_answering(&sim, "ctrl-c", "");
    while let Some(l) = tool.next() {
        if l.starts_with("  progress") {
            break;
        }
    }
    let pid = tool.child.id().to_string();
    assert!(
        Command::new("kill")
            .args(["-INT", &pid])
            .status()
            .unwrap()
            .success()
    );
    let (code, text, err) = tool.end();
    assert_eq!(code, Some(130), "{text}\n{err}");
    assert!(err.contains("Ctrl-C: the robot is stopped"), "{err}");
    // The command it names runs as typed (`cargo console` already ends its arguments with `--`).
    let resume_hint = format!(
        "continue with `cargo console --port {} --resume {}`",
        sim.pty,
        log.display()
    );
    assert!(err.contains(&resume_hint), "{err}");
    let entries = json_lines(&log);
    let lines = |kind: &str| -> Vec<String> {
        entries
            .iter()
            .filter(|v| v["kind"] == kind)
            .map(|v| v["line"].as_str().unwrap().to_string())
            .collect()
    };
    let tx = lines("tx");
    let stop = tx.iter().position(|l| l == "^C").expect("stop key sent");
    // After the stop, the pose stream is turned off and the echo on again: a terminal opened
    // next is quiet and shows what is typed.
    assert_eq!(tx[tx.len() - 2..], ["stream off", "echo on"], "{tx:#?}");
    assert!(stop < tx.len() - 2, "{tx:#?}");
    let rx = lines("rx");
    assert!(rx.iter().any(|l| l == "event stopped (Ctrl-C)"), "{rx:#?}");
    assert!(
        rx.iter()
            .any(|l| l.starts_with("event run 1 aborted, not stored"))
    );
}

/// The board is reset while a run drives (its reset button, a power dip, the watchdog): the
/// tool sees the boot line, says the run was not stored, turns the echo off and the pose stream
/// on again (a boot turns the echo on and the stream off) and drives the run again; the
/// session ends calibrated. The simulated board runs in real time, so the run is still driving
/// when the reset comes.
#[test]
fn reset_during_a_run_drives_it_again() {
    let mut sim = Sim::start_with(&host_sim(), &[]);
    let (mut tool, log) = tool_answering(&sim, "reset-during-run", "0.2m\n1\n");
    while let Some(l) = tool.next() {
        if l.starts_with("  progress") {
            break;
        }
    }
    sim.reboot();
    let mut measured = 0;
    tool.converse(&sim, &mut measured, None);
    let (ok, text) = tool.finish();
    assert!(ok, "the session failed:\n{text}");
    assert_eq!(measured, 3, "{text}");
    assert!(
        text.contains("the board was reset during the run (event boot: "),
        "{text}"
    );
    assert_eq!(text.matches("run 1/2: square cw").count(), 2, "{text}");
    assert!(
        text.contains("verified: params shows calibration exact"),
        "{text}"
    );
    let entries = json_lines(&log);
    let sent = |line: &str| {
        entries
            .iter()
            .filter(|v| v["kind"] == "tx" && v["line"] == line)
            .count()
    };
    assert_eq!(sent("echo off"), 2);
    assert_eq!(sent("stream on 10"), 2);
    // The run driven again was followed on the stream.
    let again = text.rfind("run 1/2: square cw").unwrap();
    assert!(text[again..].contains("  progress  25 %"), "{text}");
}

/// The board is reset while the tool waits for its button to start a run: the tool sees the
/// boot line, turns the echo off and the pose stream on again, and asks again how to start; the
/// run then started by the tool is followed on the stream (its progress bar moves).
#[test]
fn reset_while_waiting_for_the_button_asks_again() {
    let mut sim = Sim::start_with(&host_sim(), &[]);
    let (mut tool, log) = tool_answering(&sim, "reset-waiting-for-button", "0.2m\n1\nb\n");
    while let Some(l) = tool.next() {
        if l == "  waiting for the button (short press)" {
            break;
        }
    }
    sim.reboot();
    let mut measured = 0;
    tool.converse(&sim, &mut measured, None);
    let (ok, text) = tool.finish();
    assert!(ok, "the session failed:\n{text}");
    assert_eq!(measured, 3, "{text}");
    assert!(
        text.contains("the board was reset while waiting for the button (event boot: "),
        "{text}"
    );
    let entries = json_lines(&log);
    let sent = |line: &str| {
        entries
            .iter()
            .filter(|v| v["kind"] == "tx" && v["line"] == line)
            .count()
    };
    assert_eq!(sent("stream on 10"), 2);
    // (Warnings go to stderr, after the transcript in `text`.)
    let after = text.find("  waiting for the button (short press)").unwrap();
    assert!(text[after..].contains("  progress  25 %"), "{text}");
}

/// A miswired robot (right motor reversed): the run stops with the following-error fault and
/// the tool shows the board's account of it — which wheel, how far off — with the likely cause.
#[test]
fn a_fault_is_shown_with_the_wheel_and_the_likely_cause() {
    let mut sim = Sim::start_with(&host_sim(), &["--wiring", "right-motor-reversed"]);
    let (mut tool, _) = tool_answering(&sim, "fault", "0.2m\n1\n");
    let mut measured = 0;
    assert!(!tool.converse(&sim, &mut measured, Some("  likely cause: ")));
    let _ = sim.child.kill();
    let _ = sim.child.wait();
    let (_, text, _) = tool.end();
    let detail = text
        .lines()
        .find(|l| l.starts_with("  fault: "))
        .unwrap_or_else(|| panic!("no fault detail:\n{text}"));
    assert!(
        detail.starts_with("  fault: Right wheel following error ")
            && detail.ends_with("check its motor and encoder polarity"),
        "{text}"
    );
    assert_eq!(measured, 0, "{text}");
}

/// The board goes away in the middle of a session (cable pulled; here the simulator ends): the
/// tool says so and how to resume, and the log keeps the measured run.
#[test]
fn disconnect_is_reported_and_the_log_keeps_the_runs() {
    let mut sim = Sim::start(&host_sim());
    let (mut tool, log) = tool_answering(&sim, "disconnect", "");
    let mut measured = 0;
    assert!(!tool.converse(&sim, &mut measured, Some("run 2/10:")));
    let _ = sim.child.kill();
    let _ = sim.child.wait();
    let (code, text, err) = tool.end();
    assert_eq!(code, Some(1), "{text}\n{err}");
    assert!(err.contains("lost the connection to the board"), "{err}");
    assert!(
        err.contains(&format!(
            "`cargo console --port <PORT> --resume {}`",
            log.display()
        )),
        "{err}"
    );
    let entries = json_lines(&log);
    assert_eq!(entries.iter().filter(|v| v["kind"] == "run").count(), 1);
    assert!(
        entries
            .iter()
            .any(|v| v["kind"] == "note" && v["what"] == "disconnect")
    );
}

/// The operator types run 3's y with the wrong sign; `calibrate` flags the run, and the
/// operator chooses to measure it again instead of driving it again: the board replaces the
/// measurement (`measure #3`), the calibration is computed again, and the session ends applied
/// with ten runs driven, not eleven. The log holds both records of the run's slot; a reader
/// (`--resume`, `recalibrate`) keeps the newer.
#[test]
fn a_flagged_run_is_measured_again_instead_of_driven_again() {
    let sim = Sim::start(&host_sim());
    // The plan (L = 1.5 m, 5 + 5); every other question is answered on stdin below.
    let (mut tool, log) = tool_with_answers(&sim, "remeasure", "150cm\n5\n", false);
    let (mut measured, mut again, mut asked, mut stray) = (0, false, 0, false);
    while let Some(l) = tool.next() {
        // A question waiting for an answer ends with its colon (one answered from the file
        // shows the answer after it).
        let waiting = l.starts_with("? ") && l.trim_end().ends_with(':');
        if l == "  waiting for the button (short press)" {
            sim.press_button();
        } else if !waiting {
            continue;
        } else if l.starts_with("? Measured end pose of run") {
            if again {
                // The run's true pose this time (it was the third measured).
                let pose = sim.true_end(2);
                tool.answer(&pose);
                again = false;
                continue;
            }
            let pose = sim.true_end(measured);
            measured += 1;
            if measured == 3 {
                // y typed with the wrong sign (it is positive to the left).
                let mut w: Vec<String> = pose.split_whitespace().map(str::to_string).collect();
                w[1] = match w[1].strip_prefix('-') {
                    Some(v) => v.to_string(),
                    None => format!("-{}", w[1]),
                };
                tool.answer(&w.join(" "));
            } else {
                tool.answer(&pose);
            }
        } else if l.starts_with("? Run 3 disagrees with the others: [m]easure it again") {
            asked += 1;
            tool.answer("m");
            again = true;
        } else if l.trim_end().ends_with("(y/n):") {
            // Apply and save: a typed yes.
            tool.answer("y");
        } else if l.starts_with("? Enter starts the run") && !stray {
            // A measurement typed once more where the start is asked: it must not move the
            // robot; the question comes again.
            stray = true;
            tool.answer("-9.1mm, -9.2mm");
        } else {
            // Every other question: its default (start the run, apply the recommended method,
            // save).
            tool.answer("");
        }
    }
    let (ok, text) = tool.finish();
    assert!(ok, "the session failed:\n{text}");
    assert_eq!(asked, 1, "{text}");
    // Ten runs and the check square.
    assert_eq!(measured, 11, "{text}");
    assert!(text.contains("measured (replaced x="), "{text}");
    assert!(
        text.contains(
            "  `-9.1mm, -9.2mm` starts nothing: press Enter (or type go) to start the run, or b \
             to wait for the board's button"
        ),
        "{text}"
    );
    assert_eq!(
        text.matches("? Enter starts the run").count(),
        12,
        "the stray answer asks again: {text}"
    );
    assert!(
        text.contains("verified: params shows calibration exact"),
        "{text}"
    );
    let entries = json_lines(&log);
    let runs_sent = entries
        .iter()
        .filter(|v| v["kind"] == "tx" && v["line"].as_str().unwrap_or("").starts_with("run "))
        .count();
    assert_eq!(runs_sent, 11);
    let slot_2: Vec<&serde_json::Value> = entries
        .iter()
        .filter(|v| v["kind"] == "run" && v["slot"] == 2)
        .collect();
    assert_eq!(slot_2.len(), 2, "both records of the run's slot are logged");
    // The only run dropped is the check square (slot 10).
    assert!(
        entries
            .iter()
            .all(|v| v["kind"] != "drop" || v["slot"] == 10)
    );
    // Offline from the log (the newer record of slot 2): the board's second table, line for
    // line.
    let logged = tables(&entries);
    assert_eq!(logged.len(), 2);
    assert_eq!(&recalibrate(&log, None), &logged[1].1);
    assert_ne!(logged[0].1, logged[1].1);
    println!("{text}");
}

/// The flat `key: value` entries of a `diff_drive_controller` parameter file (comments and the
/// two header keys skipped; a `[a, b, …]` list kept as its text).
fn yaml_entries(yaml: &str) -> Vec<(String, String)> {
    yaml.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .filter_map(|l| {
            let (k, v) = l.split_once(':')?;
            let v = v.trim();
            (!v.is_empty()).then(|| (k.trim().to_string(), v.to_string()))
        })
        .collect()
}

fn yaml_number(entries: &[(String, String)], key: &str) -> f64 {
    entries
        .iter()
        .find(|(k, _)| k == key)
        .unwrap_or_else(|| panic!("no {key} in {entries:#?}"))
        .1
        .parse()
        .unwrap_or_else(|e| panic!("{key}: {e}"))
}

/// `odocal-console export LOG --format F -o OUT`: the file written.
fn export(log: &Path, format: &str, out: &Path) -> String {
    let status = Command::new(env!("CARGO_BIN_EXE_odocal-console"))
        .arg("export")
        .arg(log)
        .args(["--format", format, "-o"])
        .arg(out)
        .status()
        .unwrap();
    assert!(status.success(), "export {format} of {}", log.display());
    std::fs::read_to_string(out).unwrap()
}

/// The ROS 2 export of a guided session's log: its `wheel_separation` and wheel radius
/// multipliers give back the geometry the board applied (its `params` after `apply`) to 1e-9 m,
/// read back from the YAML; the pose covariance is there, with the unobserved components large.
/// A plain terminal capture that holds only the board's lines (its `params` reply) exports the
/// same geometry.
#[test]
fn ros2_export() {
    let sim = Sim::start(&host_sim());
    let (mut tool, log) = tool_answering(&sim, "export", "0.5m\n1\n");
    let mut measured = 0;
    tool.converse(&sim, &mut measured, None);
    let (ok, text) = tool.finish();
    assert!(ok, "the session failed:\n{text}");
    assert!(
        text.contains("verified: params shows calibration exact"),
        "{text}"
    );
    // The board's applied geometry: the `active` line of its last `params` reply.
    let entries = json_lines(&log);
    let rx: Vec<String> = entries
        .iter()
        .filter(|v| v["kind"] == "rx")
        .map(|v| v["line"].as_str().unwrap().to_string())
        .collect();
    let active = rx
        .iter()
        .rev()
        .find_map(|l| l.trim().strip_prefix("active "))
        .unwrap_or_else(|| panic!("no params reply in the log"));
    let value = |key: &str| -> f64 {
        active
            .split_whitespace()
            .find_map(|w| w.strip_prefix(key)?.strip_prefix('='))
            .unwrap()
            .parse()
            .unwrap()
    };
    let (d_r, d_l, b) = (value("d_right"), value("d_left"), value("wheelbase"));
    assert!((d_r / d_l - 0.995).abs() < 1e-5, "{active}");

    let check = |yaml: &str| {
        let e = yaml_entries(yaml);
        let r = yaml_number(&e, "wheel_radius");
        let (sep, ml, mr) = (
            yaml_number(&e, "wheel_separation"),
            yaml_number(&e, "left_wheel_radius_multiplier"),
            yaml_number(&e, "right_wheel_radius_multiplier"),
        );
        assert!((sep - b).abs() <= 1e-9, "b {sep} vs {b}\n{yaml}");
        assert!(
            (2.0 * r * mr - d_r).abs() <= 1e-9,
            "D_R {} vs {d_r}\n{yaml}",
            2.0 * r * mr
        );
        assert!(
            (2.0 * r * ml - d_l).abs() <= 1e-9,
            "D_L {} vs {d_l}\n{yaml}",
            2.0 * r * ml
        );
        assert_eq!(yaml_number(&e, "wheel_separation_multiplier"), 1.0);
        e
    };
    let dir = log.parent().unwrap();
    let yaml = export(&log, "ros2", &dir.join("diff_drive.yaml"));
    let e = check(&yaml);
    assert!(yaml.starts_with("# odocal calibration `exact`"), "{yaml}");
    assert!(
        yaml.contains("diff_drive_controller:\n  ros__parameters:\n"),
        "{yaml}"
    );
    let cov = &e
        .iter()
        .find(|(k, _)| k == "pose_covariance_diagonal")
        .unwrap()
        .1;
    let cov: Vec<f64> = cov
        .trim_matches(['[', ']'])
        .split(',')
        .map(|v| v.trim().parse().unwrap())
        .collect();
    assert_eq!(cov.len(), 6, "{yaml}");
    assert!(cov[0] > 0.0 && cov[1] > 0.0 && cov[5] > 0.0, "{yaml}");
    assert!(cov[2..5].iter().all(|&v| v >= 1e3), "{yaml}");

    // The board's lines alone, as a terminal program captures them (CR LF, echo on).
    let capture: String = std::iter::once("params".to_string())
        .chain(rx.iter().cloned())
        .map(|l| format!("{l}\r\n"))
        .collect();
    let capture_file = dir.join("terminal.log");
    std::fs::write(&capture_file, capture).unwrap();
    let yaml = export(&capture_file, "ros2", &dir.join("from-terminal.yaml"));
    check(&yaml);

    // The URDF's joints sit at ±b/2, its wheels have the applied radii.
    let urdf = export(&log, "urdf", &dir.join("wheels.urdf"));
    let attr = |name: &str| -> Vec<f64> {
        urdf.match_indices(&format!("{name}=\""))
            .map(|(i, m)| {
                let rest = &urdf[i + m.len()..];
                rest[..rest.find('"').unwrap()].to_string()
            })
            .map(|v| {
                v.split_whitespace()
                    .nth(if name == "xyz" { 1 } else { 0 })
                    .unwrap_or("0")
                    .parse()
                    .unwrap()
            })
            .collect()
    };
    let radii = attr("radius");
    assert!(
        (radii[0] - d_l / 2.0).abs() <= 1e-9 && (radii[1] - d_r / 2.0).abs() <= 1e-9,
        "{urdf}"
    );
    let y: Vec<f64> = attr("xyz").into_iter().filter(|v| *v != 0.0).collect();
    assert!(
        (y[0] - b / 2.0).abs() <= 1e-9 && (y[1] + b / 2.0).abs() <= 1e-9,
        "{urdf}"
    );
    // The JSON: the runs and the 1σ.
    let json: serde_json::Value =
        serde_json::from_str(&export(&log, "json", &dir.join("calibration.json"))).unwrap();
    assert_eq!(json["runs"].as_array().unwrap().len(), 2);
    assert!(json["sd"]["e_b"].as_f64().unwrap() >= 0.0);
    assert_eq!(json["method"], "exact");

    // Drop-in: the controller's name, its wheels, and the twist covariance.
    let named = Command::new(env!("CARGO_BIN_EXE_odocal-console"))
        .arg("export")
        .arg(&log)
        .args(["--controller", "base_controller"])
        .args([
            "--left-wheel",
            "wheel_l_joint",
            "--right-wheel",
            "wheel_r_joint",
        ])
        .output()
        .unwrap();
    assert!(named.status.success());
    let yaml = String::from_utf8(named.stdout).unwrap();
    assert!(
        yaml.contains("base_controller:\n  ros__parameters:\n"),
        "{yaml}"
    );
    let e = check(&yaml);
    let value = |key: &str| &e.iter().find(|(k, _)| k == key).unwrap().1;
    assert_eq!(value("left_wheel_names"), "[\"wheel_l_joint\"]");
    assert_eq!(value("right_wheel_names"), "[\"wheel_r_joint\"]");
    let twist: Vec<f64> = value("twist_covariance_diagonal")
        .trim_matches(['[', ']'])
        .split(',')
        .map(|v| v.trim().parse().unwrap())
        .collect();
    assert!(
        twist.len() == 6 && twist[0] > 0.0 && twist[5] > 0.0,
        "{yaml}"
    );

    // A log whose last `params` reply came before a `reset-params` the board accepted is
    // refused, naming the line.
    let mut stale = std::fs::read_to_string(&log).unwrap();
    let line = stale.lines().count() + 1;
    stale.push_str(
        "{\"kind\":\"tx\",\"line\":\"reset-params\",\"t\":0}\n\
         {\"kind\":\"rx\",\"line\":\"ok parameters reset to defaults (not saved; save to keep)\",\"t\":0}\n",
    );
    let stale_log = dir.join("stale.jsonl");
    std::fs::write(&stale_log, stale).unwrap();
    let refused = Command::new(env!("CARGO_BIN_EXE_odocal-console"))
        .arg("export")
        .arg(&stale_log)
        .output()
        .unwrap();
    let why = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success(), "a stale log exported");
    assert!(
        why.contains(&format!("stale.jsonl:{line}: `reset-params` came after")),
        "{why}"
    );
}

/// The whole procedure on a factory-default board whose right motor is wired the other way
/// round, typed by the operator on stdin: the tool says the board holds the factory defaults,
/// takes the nominal geometry in the operator's units, runs the bring-up check (push, then
/// wheels up) and applies its proposal on a yes, checks again (`wiring ok`), identifies the
/// motors on the floor, drives 2 + 2 squares whose measurements are typed in millimetres (a
/// bare millimetre value is refused, the units named; `help` and an empty answer explain),
/// applies and saves only on a typed yes, drives the check square and ends
/// with the summary.
/// The whole procedure typed on a factory-default board whose right motor is wired the other
/// way round: the board, whether the tool ended well, its transcript (each answer after its
/// question), its log, and the poses measured.
fn factory_session(name: &str) -> (Sim, bool, String, PathBuf, usize) {
    let sim = Sim::start_with(&host_sim(), &["--fast", "--wiring", "right-motor-reversed"]);
    let dir = out_dir(name);
    let log = dir.join("session.jsonl");
    let mut tool = Tool::start(&["--port", &sim.pty, "--log", log.to_str().unwrap()]);
    let (mut measured, mut helped, mut bare, mut empty_apply) = (0, false, false, false);
    let mut questions = 0;
    while let Some(l) = tool.next() {
        let waiting = l.starts_with("? ") && l.trim_end().ends_with(':');
        if !waiting {
            continue;
        }
        // A question that keeps coming back would never end the session.
        questions += 1;
        assert!(questions < 200, "{}", tool.transcript.join("\n"));
        let q = &l[2..];
        let answer: String = if q.starts_with("Nominal geometry") {
            "e".into()
        } else if q.starts_with("Right wheel diameter") {
            "150mm".into()
        } else if q.starts_with("Wheelbase b") {
            "38.5 cm".into()
        } else if q.starts_with("Measured end pose of run") {
            if !helped {
                helped = true;
                "help".into()
            } else {
                let pose = sim.true_end(measured);
                let w: Vec<f64> = pose
                    .split_whitespace()
                    .map(|v| v.trim_end_matches(char::is_alphabetic).parse().unwrap())
                    .collect();
                if !bare && measured == 1 {
                    // Millimetres typed without their unit: refused, the units named.
                    bare = true;
                    format!("{:.1} {:.1}", w[0] * 1e3, w[1] * 1e3)
                } else {
                    measured += 1;
                    // The exact value in millimetres, the heading in degrees.
                    format!("{:.3}mm {:.3}mm {}deg", w[0] * 1e3, w[1] * 1e3, w[2])
                }
            }
        } else if q.starts_with("Square side L") {
            "1 m".into()
        } else if q.starts_with("Runs per direction") {
            "2".into()
        } else if q.starts_with("Apply exact") && !empty_apply {
            // An empty answer is no yes: asked again.
            empty_apply = true;
            String::new()
        } else if q.trim_end().ends_with("(y/n):") {
            "y".into()
        } else {
            // Every other question: its default (the setup steps on a factory board, Enter to
            // start, the recommended method, the check square).
            String::new()
        };
        tool.answer(&answer);
    }
    let (code, text, _) = tool.end();
    (sim, code == Some(0), text, log, measured)
}

#[test]
fn factory_default_board_full_procedure() {
    let (sim, ok, text, log, mut measured) = factory_session("factory");
    println!("{text}");
    assert!(ok, "the session failed:\n{text}");
    for expected in [
        "the board holds the factory defaults",
        "step: nominal geometry (factory default on the board",
        "  ok d_right = 0.150000000 m",
        "  ok wheelbase = 0.385000000 m",
        "  event bringup push: right encoder",
        "  event bringup propose: set motor_right_sign -1",
        "? Apply the proposed correction (set motor_right_sign -1)? (y/n):",
        "  ok motor_right_sign = -1",
        "  wiring ok",
        "  event identify done (floor): speed-loop tuning applied",
        "plan: 2 CW + 2 CCW squares of L = 1.000 m",
        "  Measure where the axle midpoint stopped",
        "verified: params shows calibration exact",
        "summary:",
        "  calibration: exact E_d=",
    ] {
        assert!(text.contains(expected), "no `{expected}` in:\n{text}");
    }
    // The bare millimetres: refused before anything is sent, the units named.
    let refused = text
        .lines()
        .find(|l| l.contains("has no unit") && l.contains("mm, cm or m"))
        .unwrap_or_else(|| panic!("no unit question:\n{text}"));
    assert!(refused.starts_with("  `"), "{refused}");
    // Apply asked twice (the empty answer is no yes), save once.
    assert_eq!(text.matches("? Apply exact").count(), 2, "{text}");
    assert!(text.contains("  ok saved"), "{text}");
    // The check square ends far closer than the runs did before.
    let check = text
        .lines()
        .find(|l| l.starts_with("check square ") && l.contains(": end error "))
        .unwrap_or_else(|| panic!("no check square:\n{text}"));
    let mm: Vec<f64> = check
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect();
    assert!(mm[0] * 5.0 < mm[1], "{check}");
    assert_eq!(measured, 5, "{text}");
    let entries = json_lines(&log);
    let sent: Vec<String> = entries
        .iter()
        .filter(|v| v["kind"] == "tx")
        .map(|v| v["line"].as_str().unwrap().to_string())
        .collect();
    for line in [
        "set d_right 0.15",
        "set wheelbase 0.385",
        "bringup push",
        "bringup",
        "set motor_right_sign -1",
        "identify floor",
        "save",
    ] {
        assert!(
            sent.iter().any(|l| l == line),
            "`{line}` not sent: {sent:#?}"
        );
    }
    // The measurements went to the board as typed, units included.
    assert!(
        sent.iter()
            .any(|l| l.starts_with("measure #") && l.contains("mm ") && l.ends_with("deg")),
        "{sent:#?}"
    );
    // Applied and saved only after the typed yes.
    let apply = sent.iter().position(|l| l.starts_with("apply ")).unwrap();
    let save = sent.iter().position(|l| l == "save").unwrap();
    assert!(apply < save, "{sent:#?}");

    // The same board again: it holds the setup and the calibration, so the setup steps default
    // to skipping; the operator keeps the calibration and only checks it (the board's runs from
    // before dropped, the default).
    let dir = out_dir("factory-again");
    let answers = dir.join("answers.txt");
    std::fs::write(&answers, "k\n\n\nc\n").unwrap();
    let log = dir.join("session.jsonl");
    let mut tool = Tool::start(&[
        "--port",
        &sim.pty,
        "--log",
        log.to_str().unwrap(),
        "--answers",
        answers.to_str().unwrap(),
        "--yes",
    ]);
    tool.converse(&sim, &mut measured, None);
    let (ok, text) = tool.finish();
    println!("{text}");
    assert!(ok, "the second session failed:\n{text}");
    for expected in [
        "the board holds: geometry factory default, wiring corrected, motor tuning identified or \
         entered, calibration applied",
        // (An empty answer from the file takes the default.)
        "? Bring-up check (r: run it, s: skip it) [s]: \n",
        "? Motor identification (f: floor, l: lifted, s: skip) [s]: \n",
        "? The board holds a calibration (n: new runs, c: check it only) [n]: c",
        "the board holds 4 run(s) from before this session",
        "  ok dropped all 4 runs",
        "check square cw: end error ",
        "  calibration: exact E_d=",
    ] {
        assert!(text.contains(expected), "no `{expected}` in:\n{text}");
    }
    assert!(!text.contains("? Square side L"), "{text}");
    assert_eq!(measured, 6, "{text}");
    let sent: Vec<String> = json_lines(&log)
        .iter()
        .filter(|v| v["kind"] == "tx")
        .map(|v| v["line"].as_str().unwrap().to_string())
        .collect();
    assert!(
        !sent.iter().any(|l| l.starts_with("apply") || l == "save"),
        "{sent:#?}"
    );
}

/// A flagged run that the operator keeps: the board refuses `apply` while the run is flagged
/// (`err 25`), the tool shows that and applies only on a second typed yes (`apply exact yes`);
/// a no there would apply nothing.
#[test]
fn a_kept_flagged_run_is_applied_only_on_a_second_yes() {
    let sim = Sim::start(&host_sim());
    let (mut tool, log) = tool_with_answers(&sim, "kept-flagged", "150cm\n5\n", false);
    let (mut measured, mut confirmations) = (0, Vec::new());
    while let Some(l) = tool.next() {
        let waiting = l.starts_with("? ") && l.trim_end().ends_with(':');
        if !waiting {
            continue;
        }
        if l.starts_with("? Measured end pose of run") {
            let pose = sim.true_end(measured);
            measured += 1;
            let answer = if measured == 3 {
                // y typed with the wrong sign.
                with_other_sign(&pose, &[1])
            } else {
                pose
            };
            tool.answer(&answer);
        } else if l.starts_with("? Run 3 disagrees with the others") {
            tool.answer("k");
        } else if l.trim_end().ends_with("(y/n):") {
            confirmations.push(l.clone());
            tool.answer("y");
        } else {
            tool.answer("");
        }
    }
    let (ok, text) = tool.finish();
    assert!(ok, "the session failed:\n{text}");
    assert!(text.contains("[with flagged run 3]"), "{text}");
    assert!(
        text.lines()
            .any(|l| l.starts_with("  err 25: run 3 is flagged")),
        "{text}"
    );
    assert_eq!(confirmations.len(), 3, "{confirmations:#?}");
    assert!(confirmations[0].starts_with("? Apply exact (E_d="));
    assert!(confirmations[1].starts_with("? Apply exact anyway, with the flagged run in it?"));
    assert!(confirmations[2].starts_with("? Save it"));
    let sent: Vec<String> = json_lines(&log)
        .iter()
        .filter(|v| v["kind"] == "tx")
        .map(|v| v["line"].as_str().unwrap().to_string())
        .collect();
    let apply: Vec<&String> = sent.iter().filter(|l| l.starts_with("apply ")).collect();
    assert_eq!(apply, ["apply exact", "apply exact yes"], "{sent:#?}");
    assert!(
        text.contains("verified: params shows calibration exact"),
        "{text}"
    );
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

/// `back` at every step of the guided session, on a factory-default board: each answer below is
/// given to the question the script expects, so the question asked after each `back` is checked
/// (`POSE`: the simulator's true end pose of the next stored run). Going back drives nothing
/// and loses nothing: the push check, the runs and the apply are sent only when Enter or a typed
/// yes starts them, a measurement asked again is kept with `keep`, and the session ends applied
/// and saved.
#[test]
fn back_at_every_question_returns_to_the_one_before() {
    const POSE: &str = "<pose>";
    let script: &[(&str, &str)] = &[
        // Geometry: before the first question there is none; within the step, the question
        // before; from the choice of the next step, this step again (keeping is the default).
        (
            "Nominal geometry (e: enter it, k: keep the board's) [e]",
            "back",
        ),
        (
            "Nominal geometry (e: enter it, k: keep the board's) [e]",
            "e",
        ),
        ("Right wheel diameter D_R", "150mm"),
        ("Left wheel diameter D_L", "back"),
        ("Right wheel diameter D_R", "150mm"),
        ("Left wheel diameter D_L", "150mm"),
        ("Wheelbase b", "38.5cm"),
        ("Encoder counts per wheel revolution", "back"),
        ("Wheelbase b", "38.5cm"),
        ("Encoder counts per wheel revolution", ""),
        // Bring-up: back to the geometry, then within the check.
        ("Bring-up check (r: run it, s: skip it) [r]", "back"),
        (
            "Nominal geometry (e: enter it, k: keep the board's) [k]",
            "",
        ),
        ("Bring-up check (r: run it, s: skip it) [r]", "r"),
        ("Enter starts the push check", "back"),
        ("Bring-up check (r: run it, s: skip it) [r]", "r"),
        ("Enter starts the push check", ""),
        ("Enter starts the motor check", "back"),
        ("Enter starts the push check", ""),
        ("Enter starts the motor check", ""),
        // Identification: back to the bring-up (now done: skipping is the default).
        (
            "Motor identification (f: floor, l: lifted, s: skip) [f]",
            "back",
        ),
        ("Bring-up check (r: run it, s: skip it) [s]", ""),
        (
            "Motor identification (f: floor, l: lifted, s: skip) [f]",
            "f",
        ),
        ("Robot on the floor", "back"),
        (
            "Motor identification (f: floor, l: lifted, s: skip) [f]",
            "s",
        ),
        // Plan.
        ("Square side L", "back"),
        (
            "Motor identification (f: floor, l: lifted, s: skip) [f]",
            "s",
        ),
        ("Square side L", "1m"),
        ("Runs per direction", "back"),
        ("Square side L", "1m"),
        ("Runs per direction", "2"),
        // Runs: before the first run, back is the plan; at a driven run's measurement it is
        // not possible (the robot stands at the run's end); at the next run's start it is the
        // last measurement, which `keep` keeps.
        ("Enter starts the run", "back"),
        ("Square side L (with its unit: 2m, 150cm) [1.000m]", ""),
        ("Runs per direction [2]", ""),
        ("Enter starts the run", ""),
        ("Measured end pose of run 1", "back"),
        ("Measured end pose of run 1", POSE),
        ("Enter starts the run", "back"),
        ("Measured end pose of run 1", "keep"),
        ("Enter starts the run", ""),
        ("Measured end pose of run 2", POSE),
        ("Enter starts the run", ""),
        ("Measured end pose of run 3", POSE),
        ("Enter starts the run", ""),
        ("Measured end pose of run 4", POSE),
        // Results: back to the last measurement, and on to the plan; within the apply, back
        // is the method question.
        ("Apply which method", "back"),
        ("Measured end pose of run 4", "back"),
        ("Square side L", ""),
        ("Runs per direction", ""),
        ("Apply which method", ""),
        ("Apply exact", "back"),
        ("Apply which method", ""),
        ("Apply exact", "n"),
        ("Not applied. Now", "m"),
        ("Which run", "back"),
        ("Not applied. Now", "m"),
        ("Which run", "1"),
        ("Run 1 chosen", "m"),
        ("Measured end pose of run 1", "back"),
        ("Run 1 chosen", "back"),
        ("Not applied. Now", "back"),
        ("Apply which method", ""),
        ("Apply exact", "y"),
        // Back from the save: the method question; the applied calibration is offered for
        // save when nothing more is applied.
        ("Save it", "back"),
        ("Apply which method", "none"),
        ("Save the changes made this session (calibration)", "back"),
        ("Apply which method", ""),
        ("Apply exact", "y"),
        ("Save it", "y"),
        // Check square: back to the results (calibrated again; the saved calibration kept).
        ("Check square", "back"),
        ("Apply which method", "none"),
        ("Check square", "s"),
    ];
    let sim = Sim::start(&host_sim());
    let (text, sent, measured) = scripted(&sim, "back", script);
    assert_eq!(measured, 4, "{text}");
    for expected in [
        "  (at every question, back returns to the previous one)",
        "  back: there is no question before this one; asked again",
        "  back to: nominal geometry",
        "  back to: bring-up check",
        "  back to: motor identification",
        "  back to: plan",
        "  back to: runs",
        "  back to: calibration",
        "  back: run 1 is driven and stays where it stopped",
        "  back: run 1's measurement again",
        "  run 1's measurement kept as it was",
        "  calibration: exact E_d=",
        "applied and saved",
    ] {
        assert!(text.contains(expected), "no `{expected}` in:\n{text}");
    }
    assert_eq!(
        text.matches("(at every question, back returns to the previous one)")
            .count(),
        1,
        "{text}"
    );
    // Nothing moved or changed on a `back`: two push checks and one motor check (each after
    // its Enter), four runs, the geometry sent once, apply only after each typed yes, one save.
    let count = |want: &dyn Fn(&str) -> bool| sent.iter().filter(|l| want(l)).count();
    assert_eq!(count(&|l| l == "bringup push"), 2, "{sent:#?}");
    assert_eq!(count(&|l| l == "bringup"), 1, "{sent:#?}");
    assert_eq!(count(&|l| l.starts_with("run ")), 4, "{sent:#?}");
    assert_eq!(count(&|l| l == "set d_right 0.15"), 1, "{sent:#?}");
    assert_eq!(count(&|l| l.starts_with("measure #")), 4, "{sent:#?}");
    assert_eq!(count(&|l| l.starts_with("apply ")), 2, "{sent:#?}");
    assert_eq!(count(&|l| l == "save"), 1, "{sent:#?}");
    assert_eq!(count(&|l| l.starts_with("identify")), 0, "{sent:#?}");

    // The same board again: it holds the calibration. Back from its question is the
    // identification; from the runs left from before, that question; from the check square's
    // start, the check square question.
    let script: &[(&str, &str)] = &[
        (
            "Nominal geometry (e: enter it, k: keep the board's) [e]",
            "k",
        ),
        ("Bring-up check (r: run it, s: skip it) [s]", ""),
        (
            "Motor identification (f: floor, l: lifted, s: skip) [f]",
            "s",
        ),
        (
            "The board holds a calibration (n: new runs, c: check it only) [n]",
            "back",
        ),
        (
            "Motor identification (f: floor, l: lifted, s: skip) [f]",
            "s",
        ),
        (
            "The board holds a calibration (n: new runs, c: check it only) [n]",
            "c",
        ),
        ("Runs from before (d: drop them, u: use them) [d]", "back"),
        (
            "The board holds a calibration (n: new runs, c: check it only) [n]",
            "c",
        ),
        ("Runs from before (d: drop them, u: use them) [d]", "d"),
        ("Check square (r: run it, s: skip it) [r]", "r"),
        ("Enter starts the run", "back"),
        ("Check square (r: run it, s: skip it) [r]", "s"),
    ];
    let (text, sent, _) = scripted(&sim, "back-again", script);
    for expected in [
        "  back to: motor identification",
        "  ok dropped all 4 runs",
        "  calibration: exact E_d=",
    ] {
        assert!(text.contains(expected), "no `{expected}` in:\n{text}");
    }
    assert_eq!(
        sent.iter().filter(|l| l.starts_with("drop all")).count(),
        1,
        "{sent:#?}"
    );
    assert!(!sent.iter().any(|l| l.starts_with("run ")), "{sent:#?}");
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
