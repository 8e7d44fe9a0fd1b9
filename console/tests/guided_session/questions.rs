//! `guided_session`: going back at every question.

use super::*;

/// An answer that is the simulator's true end pose of the next stored run.
const POSE: &str = "<pose>";

/// The answers of the first session, each to the question (its start) the script expects.
const BACK_SCRIPT: &[(&str, &str)] = &[
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

/// The answers of the same board's second session: it holds the calibration. Back from its
/// question is the identification; from the runs left from before, that question; from the
/// check square's start, the check square question.
const BACK_AGAIN_SCRIPT: &[(&str, &str)] = &[
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

/// `back` at every step of the guided session, on a factory-default board: each answer below is
/// given to the question the script expects, so the question asked after each `back` is checked
/// (`POSE`: the simulator's true end pose of the next stored run). Going back drives nothing
/// and loses nothing: the push check, the runs and the apply are sent only when Enter or a typed
/// yes starts them, a measurement asked again is kept with `keep`, and the session ends applied
/// and saved.
#[test]
fn back_at_every_question_returns_to_the_one_before() {
    let sim = Sim::start(&host_sim());
    let (text, sent, measured) = scripted(&sim, "back", BACK_SCRIPT);
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

    // The same board again (BACK_AGAIN_SCRIPT).
    let (text, sent, _) = scripted(&sim, "back-again", BACK_AGAIN_SCRIPT);
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
