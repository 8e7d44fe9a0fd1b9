//! `guided_session`: the guided session and how it survives interruptions.

use super::*;

#[test]
fn guided_session() {
    let bin = host_sim();
    full_session_applied_saved_and_recalibrated(&bin);
    resumed_on_the_board_after_a_reset(&bin);
    resumed_on_the_pc_when_the_board_lost_its_runs(&bin);
}

/// The first part: a full session, applied and saved, recalibrated offline from its log.
fn full_session_applied_saved_and_recalibrated(bin: &Path) {
    let sim = Sim::start(bin);
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
}

/// The second part: the tool dies after run 3 and the board is reset; the session resumes from
/// the log.
fn resumed_on_the_board_after_a_reset(bin: &Path) {
    let (sim, log, mut measured) = killed_after_three_runs(bin, "resumed", false);
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
}

/// The third part: the same with a board that lost its runs in the reset (firmware without run
/// persistence, or the flash wiped): the log keeps them, the missing runs are driven, and the
/// calibration of all ten is computed on the PC with the library.
fn resumed_on_the_pc_when_the_board_lost_its_runs(bin: &Path) {
    let (sim, log, mut measured) = killed_after_three_runs(bin, "lost", true);
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
