//! Random protocol traffic against the whole simulated board (controller, session, calibration,
//! storage): no panic, exactly one final `ok`/`err` line per non-blank command, bounded state.

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
    "measure 0.01 -0.02",
    "measure 0.01m -0.02m",
    "measure 10 mm -20 mm 1.5 deg",
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
