//! `guided_session`: flagged runs: measured again, or applied only on a second yes.

use super::*;

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
