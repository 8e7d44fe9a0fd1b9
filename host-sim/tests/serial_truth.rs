//! `host-sim serial --pty --truth-hz --speed --wear`: the simulated robot's true pose on stdout
//! in the board's own time base, faster than real time, and its geometry changing mid-run.
//! Nothing here asserts how fast the wall clock goes (the machine may be loaded): only what the
//! board's clock, the truth lines and the console say, and the one bound any machine keeps
//! (the board's clock never runs ahead of `--speed` times the wall clock).

#[path = "support/pty_sim.rs"]
mod pty_sim;

use std::time::Instant;

use pty_sim::{PtySim, micros, truth};

/// The truth lines among `lines`: (T µs, X, Y, THETA).
fn truths(lines: &[String]) -> Vec<(u64, f64, f64, f64)> {
    lines.iter().filter_map(|l| truth(l)).collect()
}

#[test]
fn truth_lines_share_the_stream_time_base_and_the_clock_runs_at_speed() {
    let wall0 = Instant::now();
    let mut sim = PtySim::start(&["--speed", "20", "--truth-hz", "1000"]);
    sim.command("stream on 100");
    assert!(sim.command("line 1").starts_with("ok run 1 started: line"));
    let console = sim.console_until("the line's end", |l| l.starts_with("event run 1 finished"));
    // The truth lines up to the line's end (`stdout_until` returns once one is past it).
    let last_t = console
        .iter()
        .rev()
        .find_map(|l| {
            l.strip_prefix("stream ")?
                .split(' ')
                .next()
                .and_then(micros)
        })
        .unwrap();
    let lines = sim.stdout_until("the truth at the line's end", |l| {
        truth(l).is_some_and(|(t, ..)| t >= last_t)
    });
    let wall = wall0.elapsed().as_secs_f64();
    let t = truths(&lines);
    // One line per control period (1 kHz): exactly 1 ms apart from the first period on.
    assert_eq!(t[0].0, 1000, "{:?}", &lines[..3]);
    assert!(t.windows(2).all(|w| w[1].0 - w[0].0 == 1000));
    // Every stream line's time is a truth line's T (the same clock, the same digits), and the
    // odometry it prints is the true pose then: along the line within 1 mm (the odometry is
    // that of the counts read at the period's start, 0.3 mm behind at 0.3 m/s; a clock 3 ms
    // off would show), across it within the robot's calibration error over 1 m (E_d 0.995,
    // E_b 1.010: millimetres).
    let mut matched = 0;
    for l in console.iter().filter_map(|l| l.strip_prefix("stream ")) {
        let mut w = l.split(' ');
        let ts = micros(w.next().unwrap()).unwrap();
        let x: f64 = w.next().unwrap().parse().unwrap();
        let y: f64 = w.next().unwrap().parse().unwrap();
        let (_, tx, ty, _) = *t
            .iter()
            .find(|p| p.0 == ts)
            .unwrap_or_else(|| panic!("no truth line at stream t {ts} µs"));
        assert!(
            (x - tx).abs() < 0.001 && (y - ty).abs() < 0.01,
            "stream {l} vs truth ({tx}, {ty})"
        );
        matched += 1;
    }
    assert!(matched > 100, "{matched} stream lines");
    assert!(
        (t[t.len() - 1].1 - 1.0).abs() < 0.02,
        "{:?}",
        t[t.len() - 1]
    );
    // The bound any machine keeps: each 10 ms slice of wall clock runs 20 × 10 ms of board
    // time at most (the first one at once).
    let board = t[t.len() - 1].0 as f64 * 1e-6;
    println!("board time {board:.3} s in {wall:.3} s of wall clock (--speed 20)");
    assert!(board <= 20.0 * (wall + 0.01), "{board} s in {wall} s");
}

#[test]
fn a_wear_changes_the_true_heading_drift_and_not_the_pose() {
    // A perfect robot (E_d 1, E_b 1 of the board's nominal geometry) whose right tyre wears at
    // 6 s of board time to E_d 0.98, during a 3 m line (about 11 s) started at once.
    let mut sim = PtySim::start(&[
        "--ed",
        "1",
        "--eb",
        "1",
        "--wear",
        "6:0.98:1",
        "--speed",
        "4",
        "--truth-hz",
        "100",
    ]);
    assert!(sim.command("line 3").starts_with("ok run 1 started: line"));
    sim.console_until("the line's end", |l| l.starts_with("event run 1 finished"));
    let wear = sim.stderr_until("the wear line", |l| l.starts_with("wear at "));
    assert_eq!(wear.last().unwrap(), "wear at 6.000000 s: E_d 0.98, E_b 1");
    let lines = sim.stdout_until("a truth line 2.9 m along", |l| {
        truth(l).is_some_and(|(_, x, ..)| x > 2.9)
    });
    let t = truths(&lines);
    assert!(t.windows(2).all(|w| w[1].0 - w[0].0 == 10_000));
    // The pose is continuous across the wear: 10 ms apart, at most the 3 mm the robot moves at
    // 0.3 m/s, and the heading turns by less than a milliradian.
    for w in t.windows(2) {
        let (a, b) = (w[0], w[1]);
        assert!(
            (b.1 - a.1).hypot(b.2 - a.2) < 0.004 && (b.3 - a.3).abs() < 1e-3,
            "{a:?} → {b:?}"
        );
    }
    // Heading change per metre of true path, before and after the wear. Equal wheel turns (the
    // controller keeps the odometry straight) turn the worn robot by 2 (E_d − 1) / ((E_d + 1) b)
    // = −0.0525 rad/m; the perfect one not at all.
    let drift = |from: u64, to: u64| -> Option<f64> {
        let seg: Vec<_> = t.iter().filter(|p| p.0 >= from && p.0 <= to).collect();
        let path: f64 = seg
            .windows(2)
            .map(|w| (w[1].1 - w[0].1).hypot(w[1].2 - w[0].2))
            .sum();
        (path > 0.3).then(|| (seg[seg.len() - 1].3 - seg[0].3) / path)
    };
    let expected = 2.0 * (0.98 - 1.0) / (1.98 * 0.385);
    let after = drift(6_000_000, u64::MAX).expect("the line goes on after the wear");
    println!("after the wear: {after:.5} rad/m (expected {expected:.5})");
    assert!(
        (after - expected).abs() < 0.02 * expected.abs(),
        "{after} rad/m"
    );
    // Before it (when the line started early enough to tell: it does unless the machine held
    // the command back for seconds).
    match drift(0, 6_000_000) {
        Some(before) => assert!(before.abs() < 1e-4, "{before} rad/m before the wear"),
        None => println!("the line started too late to measure the drift before the wear"),
    }
}

#[test]
fn bad_speed_truth_rate_and_wear_are_named() {
    for (args, says) in [
        (
            &["--speed", "0"][..],
            "invalid value '0' for '--speed <K>': must be a finite number above 0",
        ),
        (
            &["--speed", "-2"],
            "invalid value '-2' for '--speed <K>': must be a finite number above 0",
        ),
        (
            &["--speed", "inf"],
            "invalid value 'inf' for '--speed <K>': must be a finite number above 0",
        ),
        (
            &["--pty", "--truth-hz", "0"],
            "invalid value '0' for '--truth-hz <HZ>': must be a finite number above 0",
        ),
        (
            &["--wear", "600:0.990"],
            "invalid value '600:0.990' for '--wear <T:ED:EB>': expected T:ED:EB, the board time \
             in seconds and the robot's true E_d and E_b from then on (e.g. --wear \
             600:0.990:1.010)",
        ),
        (
            &["--fast", "--speed", "2"],
            "the argument '--fast' cannot be used with '--speed <K>'",
        ),
    ] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .arg("serial")
            .args(args)
            .stdin(std::process::Stdio::null())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(says),
            "{args:?}: {err}"
        );
    }
}
