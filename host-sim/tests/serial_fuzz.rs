//! Random protocol traffic against the whole simulated board (controller, session, calibration,
//! storage): no panic, exactly one final `ok`/`err` line per non-blank command, and that line
//! answers that command (its own reply, or a refusal the board's state explains), bounded state.

use host_sim::sim::board::Board;
use host_sim::sim::flash::SimParamFlash;
use host_sim::sim::robot::sim_config;
use odocal::session::MAX_RUNS;

#[path = "../../tests/support/rng.rs"]
mod rng;
use rng::Rng;

const LINES: &[&str] = &[
    "help",
    "status",
    "params",
    "runs",
    "pose",
    "odom reset",
    "stop",
    "clear",
    "next",
    "run cw 0.2",
    "run ccw 0.2",
    "line 0.2",
    "circle cw 0.2",
    "measure 10mm -20mm",
    "measure 10mm -20mm 1.5deg",
    "measure 0.01 -0.02",
    "measure 0.01m -0.02m",
    "measure 10 mm -20 mm 1.5 deg",
    "measure 0.01m -0.02m 0.01rad",
    "measure #2 1cm 2cm yes",
    "set measure_unit mm",
    "set heading_unit rad",
    "measure nan 0",
    "drop 1",
    "drop 12",
    "calibrate",
    "calibrate exact",
    "calibrate lee-x",
    "apply exact",
    "apply umbmark-x",
    "save",
    "reset-params",
    "stream on 100",
    "stream off",
    "drive 0.2 0.5",
    "drive -0.1 0",
    "set max_speed 0.5",
    "set wheelbase 0.39",
    "set runs_per_direction 2",
    "set square_side 0.2",
    "set counts_per_rev 4096",
    "set counts_per_rev 200000",
    "bogus",
    "",
    "  ",
    "run up",
];

/// Whether `fin`, the final line of the reply to `line`, answers that command: its own success
/// reply (echoing its arguments where it does), or one of the refusals its documented
/// preconditions allow (a run or a drive in progress, a latched fault, an unmeasured run, too
/// few measured runs, motors running).
fn answers(line: &str, fin: &str) -> bool {
    let busy = fin.starts_with("err 10: a run is in progress (")
        || fin.starts_with("err 10: drive is in progress: ");
    let fault = fin.starts_with("err 11: fault latched: ");
    let unmeasured = fin.starts_with("err 24: run ") && fin.contains(" is not measured");
    let refused_start = busy || fault || unmeasured;
    let started =
        |what: &str| fin.starts_with("ok run ") && fin.ends_with(&format!(" started: {what}"));
    let set = |reply: &str| fin.starts_with(reply) || busy;
    let measured = (fin.starts_with("ok run ") && fin.contains(" measured: "))
        || fin.starts_with("err 10: a run is driving")
        || fin.starts_with("err 12: ")
        || fin.starts_with("err 22: ");
    let calibrate_refused = busy || fin.starts_with("err 13: ") || fin.starts_with("err 16: ");
    match line {
        "help" => fin.starts_with("ok ") && fin.ends_with(" commands"),
        "status" => fin.starts_with("ok state="),
        "params" => fin == "ok",
        "runs" => fin.starts_with("ok ") && fin.ends_with(" measured"),
        "pose" => fin.starts_with("ok x="),
        "odom reset" => fin == "ok odometry reset" || busy,
        "stop" => {
            fin == "ok stopped"
                || (fin.starts_with("ok stopped: run ") && fin.ends_with(" aborted, not stored"))
        }
        "clear" => fin == "ok no fault latched" || fin.starts_with("ok fault cleared ("),
        "next" => {
            (fin.starts_with("ok run ") && fin.contains(" started: square "))
                || fin.starts_with("err 20: all planned runs done")
                || refused_start
        }
        "run cw 0.2" => started("square cw L=0.200 m") || refused_start,
        "run ccw 0.2" => started("square ccw L=0.200 m") || refused_start,
        "line 0.2" => started("line d=0.200 m") || refused_start,
        "circle cw 0.2" => started("circle cw r=0.200 m") || refused_start,
        "measure 10mm -20mm"
        | "measure 10mm -20mm 1.5deg"
        | "measure 0.01m -0.02m"
        | "measure 10 mm -20 mm 1.5 deg"
        | "measure 0.01m -0.02m 0.01rad" => measured,
        // A bare value is read only in a declared unit; which one depends on what ran before.
        "measure 0.01 -0.02" => measured || fin.starts_with("err 26: <x> 0.01 has no unit"),
        "measure #2 1cm 2cm yes" => {
            (fin.starts_with("ok run 2 ") && fin.contains(" measured"))
                || fin.starts_with("err 14: no run 2 (")
                || fin.starts_with("err 10: a run is driving")
        }
        "set measure_unit mm" => {
            fin == "ok measure_unit = mm: bare measure values are mm (this session only, not saved)"
        }
        "set heading_unit rad" => {
            fin == "ok heading_unit = rad: bare heading values are rad (this session only, not saved)"
        }
        "measure nan 0" => fin == "err 5: <x> must be finite",
        "drop 1" => fin.starts_with("ok dropped run 1: ") || fin.starts_with("err 14: no run 1 ("),
        "drop 12" => {
            fin.starts_with("ok dropped run 12: ") || fin.starts_with("err 14: no run 12 (")
        }
        "calibrate" | "calibrate exact" | "calibrate lee-x" => {
            (fin.starts_with("ok ") && fin.contains(" solved from ")) || calibrate_refused
        }
        "apply exact" => fin.starts_with("ok applied exact: ") || calibrate_refused,
        "apply umbmark-x" => fin.starts_with("ok applied umbmark-x: ") || calibrate_refused,
        "save" => fin == "ok saved" || fin.starts_with("err 18: motors not confirmed stopped"),
        "reset-params" => {
            set("ok parameters reset to defaults")
                || fin.starts_with("err 25: reset-params discards ")
        }
        "stream on 100" => fin == "ok stream on 100 Hz",
        "stream off" => fin == "ok stream off",
        "drive 0.2 0.5" | "drive -0.1 0" => fin == "ok" || refused_start,
        "set max_speed 0.5" => set("ok max_speed = 0.500 m/s ("),
        "set wheelbase 0.39" => set("ok wheelbase = 0.390000000 m ("),
        "set runs_per_direction 2" => set("ok runs_per_direction = 2 runs ("),
        "set square_side 0.2" => set("ok square_side = 0.200 m ("),
        "set counts_per_rev 4096" => set("ok counts_per_rev = 4096 counts/rev ("),
        "set counts_per_rev 200000" => set("ok counts_per_rev = 200000 counts/rev ("),
        "bogus" => fin == "err 1: unknown command (try help)",
        "run up" => fin == "err 7: <direction> must be one of cw|ccw",
        _ => false,
    }
}

/// Catches a reply routed to the wrong command, a success reply that drops or alters the
/// command's arguments, a refusal the state does not explain, and a command answered twice or
/// not at all; and any panic on a sequence of commands the fixed cases do not reach.
#[test]
fn random_commands_against_the_simulated_board() {
    let mut out = String::new();
    let mut flash = SimParamFlash::erased();
    let mut b =
        Board::boot(sim_config(0.995, 1.01, 0.0, 7, 1000), &mut flash, &mut out).expect("boot");
    let mut rng = Rng(0x1234_5678_9ABC_DEF1);
    let mut replies = 0;
    for i in 0..3_000 {
        let line = rng.pick(LINES);
        let reply = b.send(line);
        let finals = reply
            .split_terminator("\r\n")
            .filter(|l| l.starts_with("ok") || l.starts_with("err "))
            .count();
        let expected = usize::from(!line.trim().is_empty());
        assert_eq!(finals, expected, "line {i} {line:?}: {reply:?}");
        if let Some(fin) = reply
            .split_terminator("\r\n")
            .find(|l| l.starts_with("ok") || l.starts_with("err "))
        {
            assert!(answers(line, fin), "line {i} {line:?} answered {fin:?}");
        }
        assert!(reply.is_empty() || reply.ends_with("\r\n"));
        replies += finals;
        assert!(b.session.runs().len() <= MAX_RUNS);
        // Let the robot move between commands: 0..2 s.
        let periods = rng.next() % 2_000;
        for _ in 0..periods {
            b.step(&mut out);
        }
        out.clear();
    }
    println!("{replies} replies");
}
