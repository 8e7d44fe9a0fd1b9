//! `host-sim serial --pty --replay`: the simulated board counts a recorded OptiOdom session's
//! wheel motion as its own encoders. Played at `--speed 100` (the 180 s of the free session's
//! two runs in about two seconds of wall clock; a loaded machine only takes longer), the board's
//! own odometry ends where the library's exact arc integration of the recorded ticks with the
//! session's nominal geometry ends, and the truth lines follow the recorded ground truth.

#[path = "support/pty_sim.rs"]
mod pty_sim;
#[path = "support/replay_data.rs"]
mod replay_data;

use host_sim::sim::optiodom::playback::Playback;
use odocal::calibration::wrap_angle;
use odocal::kinematics::reference::{ArcModel, PoseF64};
use pty_sim::{PtySim, field, truth};

#[test]
fn a_replayed_session_is_counted_by_the_boards_own_odometry() {
    let Some(dir) = replay_data::session_dir("free", "030120210001") else {
        return;
    };
    let session = host_sim::sim::optiodom::read_session(&dir).unwrap();
    assert_eq!(session.runs.len(), 2);
    let mut sim = PtySim::start(&[
        "--replay",
        dir.to_str().unwrap(),
        "--speed",
        "100",
        "--truth-hz",
        "20",
    ]);
    // The simulated operator set the session's geometry at boot (the resolution scaled: 43.7 ·
    // 64 · 10 counts per revolution, ticks ×10).
    let params = sim.reply("params").join("\n");
    for line in [
        "  d_right 0.084000000 m",
        "  d_left 0.084000000 m",
        "  wheelbase 0.200000000 m",
        "  counts_per_rev 27968 counts/rev",
    ] {
        assert!(params.contains(line), "{line:?} in\n{params}");
    }
    // Nothing plays, and no truth line comes, before `play`.
    assert_eq!(
        sim.command("pose"),
        "ok x=+0.000000 y=+0.000000 theta_deg=+0.0000"
    );
    sim.control("play");
    let before = sim.stdout_until("replay run 1 started", |l| l.starts_with("replay"));
    assert_eq!(before, ["replay run 1 started"]);
    let run1 = sim.stdout_until("replay run 2 started", |l| l.starts_with("replay"));
    let run2 = sim.stdout_until("replay done", |l| l.starts_with("replay"));
    assert_eq!(run1.last().unwrap(), "replay run 2 started");
    assert_eq!(run2.last().unwrap(), "replay done");

    // The truth lines of each run: 50 ms apart exactly, the run's aligned ground truth (in its
    // start frame) from its start to its end: the robot stands still at both, so the lines at
    // most a row (50 ms) from them show the origin and the recorded end pose within the motion
    // capture's jitter (below a millimetre and 0.01 rad here); none in the 2 s between the runs.
    let truths = |lines: &[String]| -> Vec<(u64, f64, f64, f64)> {
        lines.iter().filter_map(|l| truth(l)).collect()
    };
    let (t1, t2) = (truths(&run1), truths(&run2));
    for (t, run) in [(&t1, &session.runs[0]), (&t2, &session.runs[1])] {
        let secs = (run.knots.len() - 1) as f64 * 0.05;
        assert!(
            t.len() as f64 >= secs * 20.0 - 1.0,
            "{} truth lines for {secs} s",
            t.len()
        );
        assert!(t.windows(2).all(|w| w[1].0 - w[0].0 == 50_000), "{t:?}");
        let (first, last) = (t[0], t[t.len() - 1]);
        assert!(first.1.hypot(first.2) < 0.002, "{first:?}");
        let end = run.aligned[run.aligned.len() - 1];
        assert!(
            (last.1 - end.x_m).hypot(last.2 - end.y_m) < 0.002
                && wrap_angle(last.3 - end.theta_rad).abs() < 0.01,
            "{last:?} vs {end:?}"
        );
    }
    let gap = t2[0].0 - t1[t1.len() - 1].0;
    assert!(
        (2_000_000..2_150_000).contains(&gap),
        "{gap} µs between the runs' truth lines"
    );

    // The board's odometry over both runs, and the library's exact arcs through the recorded
    // knots with the session's nominal geometry (one arc a row): the same within 20 µm and the
    // `pose` reply's rounding of the heading (0.00005°). The heading comes from the tick totals
    // on both sides; the positions differ by the path within each row: the board's encoders
    // count the row's ticks spread over 50 control periods in whole counts, each wheel up to a
    // count off the row's arc (4.7e-5 rad of heading), a few micrometres over the session's 18 m
    // of wheel travel. Through the same counts period by period the library's arcs end where
    // the board does within 2 µm (its 0.1 mm/km budget) and the reply's 0.5 µm rounding.
    let pose = sim.command("pose");
    let arcs = ArcModel::from_geometry(&session.nominal);
    let end1 = arcs.integrate(PoseF64::default(), &session.runs[0].knots);
    let end = arcs.integrate(end1, &session.runs[1].knots);
    let playback = Playback::new(&session);
    let counted: Vec<_> = (0..=playback.duration_us() / 1000)
        .map(|ms| playback.at(ms * 1000).ticks())
        .collect();
    let fine = arcs.integrate(PoseF64::default(), &counted);
    let (x, y, theta_deg) = (
        field(&pose, "x"),
        field(&pose, "y"),
        field(&pose, "theta_deg"),
    );
    println!("board {pose}; arcs by row {end:?}; by period {fine:?}");
    let travel: f64 = session
        .runs
        .iter()
        .map(|r| r.wheel_travel_m(&session.nominal))
        .sum();
    assert!(travel > 15.0, "the session's wheels roll {travel} m");
    for (reference, tol) in [(end, 20e-6), (fine, 2.5e-6)] {
        assert!(
            (x - reference.x_m).abs() < tol && (y - reference.y_m).abs() < tol,
            "({x}, {y}) vs {reference:?} (±{tol} m)"
        );
        let heading = wrap_angle(reference.theta_rad).to_degrees();
        assert!(
            (theta_deg - heading).abs() < 1e-4,
            "theta {theta_deg}° vs {heading}°"
        );
    }
    // A second `play` is refused: the recording has played.
    sim.control("play");
    sim.stderr_until("the refusal", |l| {
        l.starts_with("sim: the replay has played")
    });
}
