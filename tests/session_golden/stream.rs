//! The pose, odometry and drive commands, the pose stream and the session's RAM.

use super::*;

#[test]
fn pose_odom_drive_golden() {
    let mut b = Bench::new();
    b.robot.pose = PoseF64::new(1.25, -0.5, -190f64.to_radians());
    assert_eq!(
        b.send("pose"),
        "ok x=+1.250000 y=-0.500000 theta_deg=+170.0000\r\n"
    );
    assert_eq!(b.send("odom reset"), "ok odometry reset\r\n");
    assert_eq!(b.robot.pose, PoseF64::default());
    assert_eq!(b.send("drive 0.3 -0.25"), "ok\r\n");
    assert_eq!(b.robot.drives, vec![(0.3, -0.25)]);
    assert_eq!(
        b.send("odom reset"),
        "err 10: drive is in progress: wait for the motors to stop (500 ms after the last drive)\r\n"
    );
    b.send("stop");
    b.send("run cw");
    assert_eq!(
        b.send("drive 0.1 0"),
        "err 10: a run is in progress (square cw L=2.000 m): wait for it to finish\r\n"
    );
    b.robot.fault = Some(Fault::Stall {
        wheel: Wheel::Right,
    });
    b.robot.running = None;
    assert_eq!(
        b.send("run cw"),
        "event run 1 aborted, not stored: square cw L=2.000 m (fault: stall)\r\n\
         event fault: Right wheel stalled\r\n\
         err 11: fault latched: stall\r\n"
    );
    assert_eq!(b.send("clear"), "ok fault cleared (stall)\r\n");
    assert_eq!(b.robot.fault, None);
    assert_eq!(b.send("clear"), "ok no fault latched\r\n");
    // A drive beyond the limits is limited, and the reply says so.
    assert_eq!(
        b.send("drive 1.5 0"),
        "ok limited to v=+0.300 m/s w=+0.000 rad/s (max_speed, max_turn_rate)\r\n"
    );
    b.send("stop");
    assert_eq!(
        b.send("run cw"),
        "ok run 1 started: square cw L=2.000 m\r\n"
    );
    assert_eq!(b.send(""), "");
    assert_eq!(b.send("warp 9"), "err 1: unknown command (try help)\r\n");
}

#[test]
fn stream_schedule_and_text() {
    let mut b = Bench::new();
    b.robot.pose = PoseF64::new(0.5, 0.25, 0.1);
    assert_eq!(b.poll(0), "");
    assert_eq!(b.send("stream on 100"), "ok stream on 100 Hz\r\n");
    // First line at the first poll (no speed yet), then one per 10 ms period.
    assert_eq!(
        b.poll(5_000),
        "stream 0.005000 +0.500000 +0.250000 +5.7296 +0.0000 +0.0000\r\n"
    );
    assert_eq!(b.poll(14_999), "");
    // 2000 and -1000 ticks in 10 ms: v = ticks × π·0.150 m / 200000 / 0.01 s
    // = +0.4712 and -0.2356 m/s.
    b.robot.totals = WheelTicks::new(2000, -1000);
    assert_eq!(
        b.poll(15_000),
        "stream 0.015000 +0.500000 +0.250000 +5.7296 +0.4712 -0.2356\r\n"
    );
    let mut lines = 0;
    // Poll every 1 ms for 1 s: exactly 99 more lines (due at 25 ms, 35 ms, … 1005 ms).
    for t in (16_000..=1_005_000).step_by(1_000) {
        lines += b.poll(t).lines().count();
    }
    assert_eq!(lines, 99);
    // A stall of several periods restarts the schedule instead of bursting.
    assert_eq!(b.poll(2_000_000).lines().count(), 1);
    assert_eq!(b.poll(2_005_000).lines().count(), 0);
    assert_eq!(b.poll(2_010_000).lines().count(), 1);
    // The clock going backwards (a wrapped timer) restarts the schedule too.
    assert_eq!(b.poll(1_000).lines().count(), 1);
    assert_eq!(b.poll(5_000).lines().count(), 0);
    assert_eq!(b.poll(11_000).lines().count(), 1);
    assert_eq!(b.send("stream on"), "ok stream on 10 Hz\r\n");
    assert_eq!(b.send("stream off"), "ok stream off\r\n");
    assert_eq!(b.poll(3_000_000), "");
}

#[test]
fn the_stream_holds_while_a_line_is_typed() {
    let mut b = Bench::new();
    assert_eq!(b.send("stream on 100"), "ok stream on 100 Hz\r\n");
    assert_eq!(b.poll(0).lines().count(), 1);
    // A person types a line (echoed as typed): no stream line lands between the characters,
    // however long it takes.
    b.session.set_typing(true);
    for t in (1_000..=500_000).step_by(1_000) {
        assert_eq!(b.poll(t), "", "at {t} µs");
    }
    // Enter: the stream resumes at once and keeps its period from there.
    b.session.set_typing(false);
    assert_eq!(b.poll(501_000).lines().count(), 1);
    assert_eq!(b.poll(505_000), "");
    assert_eq!(b.poll(511_000).lines().count(), 1);
}

#[test]
fn run_store_ram() {
    // The store holds MAX_RUNS records inline; report its size so the RAM budget is visible.
    let record = size_of::<RunRecord>();
    let session = size_of::<Session<KnownCalibrator>>();
    println!("RunRecord {record} B, Session {session} B for {MAX_RUNS} runs");
    // MAX_KNOTS knots × 16 B, plus path, geometry, poses and measurement: under 300 B more.
    let knots = MAX_KNOTS * size_of::<WheelTicks>();
    assert!(record >= knots && record < knots + 300, "{record}");
    // The session is the store, where each run is stored in flash, plus settings (with the
    // speed-loop tuning: 40 B) and the stream state: under 600 B more.
    let ids = MAX_RUNS * size_of::<Option<StoredRun>>();
    let numbers = MAX_RUNS * size_of::<u16>();
    assert!(
        session < MAX_RUNS * record + ids + numbers + 600,
        "{session}"
    );
}
