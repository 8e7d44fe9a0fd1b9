//! Runs: their lifecycle and numbers, stopping them, measuring their ends (units never
//! inferred) and the calibration they make possible.

use super::*;

#[test]
fn run_lifecycle_golden() {
    let mut b = Bench::new();
    assert_eq!(
        b.send("measure 0.01m 0.02m"),
        "err 12: no finished run to measure (run cw|ccw or next first)\r\n"
    );
    assert_eq!(
        b.send("run cw"),
        "ok run 1 started: square cw L=2.000 m\r\n"
    );
    assert_eq!(
        b.send("run ccw"),
        "err 10: a run is in progress (square cw L=2.000 m): wait for it to finish\r\n"
    );
    assert_eq!(
        b.send("status"),
        "ok state=running square cw L=2.000 m fault=none x=+0.000000 y=+0.000000 \
         theta_deg=+0.0000 plan cw 0/5 ccw 0/5 measured cw 0 ccw 0 runs 0/12 calibration=none\r\n"
    );
    b.robot.finish(0.0123, -0.0045);
    assert_eq!(
        b.poll(1_000),
        "event run 1 finished: square cw L=2.000 m odometry end x=+0.012300 y=-0.004500 \
         theta_deg=+0.0000; measure it\r\n"
    );
    assert_eq!(
        b.send("measure 0.0223m -0.0145m 0.5deg"),
        "ok run 1 square cw L=2.000 m measured: read x=+22.300 mm y=-14.500 mm theta=+0.50 deg; \
         error vs odometry dx=+0.010000 dy=-0.010000 m\r\n"
    );
    // A second plain `measure` never replaces silently: it needs the run number.
    assert_eq!(
        b.send("measure 0.0223m -0.0145m"),
        "err 12: run 1 is already measured (measure #1 x y [theta] replaces it)\r\n"
    );
    assert_eq!(
        b.send("measure #1 0.0233m -0.0145m"),
        "ok run 1 square cw L=2.000 m measured (replaced x=+0.022300 y=-0.014500 \
         theta_deg=+0.5000): read x=+23.300 mm y=-14.500 mm; error vs odometry dx=+0.011000 dy=-0.010000 m (heading kept: \
         theta_deg=+0.5000)\r\n"
    );
    assert_eq!(
        b.send("measure #2 0m 0m"),
        "err 14: no run 2 (1 stored)\r\n"
    );
    assert_eq!(b.send("line 1"), "ok run 2 started: line d=1.000 m\r\n");
    // A finished run is collected before the next command runs, without an explicit poll.
    b.robot.finish(1.0, 0.0);
    assert_eq!(
        b.send("runs"),
        "event run 2 finished: line d=1.000 m odometry end x=+1.000000 y=+0.000000 \
         theta_deg=+0.0000; measure it\r\n\
         \x20 run 1 square cw L=2.000 m odometry x=+0.012300 y=-0.004500 measured x=+0.023300 \
         y=-0.014500 theta_deg=+0.5000\r\n\
         \x20 run 2 line d=1.000 m odometry x=+1.000000 y=+0.000000 not measured\r\n\
         ok 2 runs, 1 measured\r\n"
    );
    assert_eq!(b.send("drop 3"), "err 14: no run 3 (2 stored)\r\n");
    // A run is measured or dropped before the next one starts (by command or button).
    // Nothing moves the robot away from the end it is to be measured at.
    for start in [
        "run cw",
        "next",
        "line",
        "circle cw 0.5",
        "drive 0.1 0",
        "identify floor",
        "identify",
        "bringup",
        "bringup push",
    ] {
        assert_eq!(
            b.send(start),
            "err 24: run 2 (line d=1.000 m) is not measured yet: measure it or drop it first \
             (measure x y [theta], or drop 2)\r\n",
            "{start}"
        );
    }
    let mut out = String::new();
    b.session.button_short(&mut b.robot, &mut out).unwrap();
    assert_eq!(
        out,
        "event button: err 24: run 2 (line d=1.000 m) is not measured yet: measure it or drop \
         it first (measure x y [theta], or drop 2)\r\n"
    );
    assert_eq!(b.robot.running, None);
    assert_eq!(
        b.send("measure 1.001m 0.002m"),
        "ok run 2 line d=1.000 m measured: read x=+1001.000 mm y=+2.000 mm; error vs odometry \
         dx=+0.001000 dy=+0.002000 m\r\n"
    );
    // Squares beyond the plan are counted apart.
    b.send("set runs_per_direction 1");
    for _ in 0..2 {
        b.send("run cw");
        b.robot.finish(0.0, 0.0);
        b.send("measure 0.001m 0.001m");
    }
    let status = b.send("status");
    assert!(
        status.contains(" plan cw 1/1 ccw 0/1 (+2 extra) measured cw 3 ccw 0 runs 4/12 "),
        "{status}"
    );
    b.send("drop 4");
    b.send("drop 3");
    b.send("set runs_per_direction 5");
    assert_eq!(
        b.send("drop 2"),
        "ok dropped run 2: line d=1.000 m; 1 run left\r\n"
    );
    assert_eq!(
        b.send("circle ccw"),
        "ok run 5 started: circle ccw r=1.000 m\r\n"
    );
    assert_eq!(
        b.send("measure 0.0223m -0.0145m"),
        "err 10: a run is driving: measure after its `event run … finished` line\r\n"
    );
    assert_eq!(
        b.send("stop"),
        "event run 5 aborted, not stored: circle ccw r=1.000 m\r\n\
         ok stopped: run 5 aborted, not stored\r\n"
    );
    assert_eq!(b.robot.aborts, 1);
    assert_eq!(b.send("stop"), "ok stopped\r\n");
    // The aborted run's measurement must not land on run 1.
    assert_eq!(
        b.send("measure 0.0223m -0.0145m"),
        "err 12: run 5 was aborted and not stored: nothing to measure (drive it again; \
         measure #<n> x y fills an earlier run)\r\n"
    );
    assert_eq!(b.session.runs().len(), 1);
}

#[test]
fn runs_keep_their_numbers_when_one_is_dropped() {
    let mut b = Bench::new();
    b.measured_run("cw", 0.01, -0.02, 0.012, -0.018);
    b.measured_run("ccw", 0.02, 0.01, 0.021, 0.012);
    assert_eq!(
        b.send("drop 1"),
        "ok dropped run 1: square cw L=2.000 m; 1 run left\r\n"
    );
    assert_eq!(
        b.send("runs"),
        "\x20 run 2 square ccw L=2.000 m odometry x=+0.020000 y=+0.010000 measured x=+0.021000 \
         y=+0.012000\r\n\
         ok 1 run, 1 measured\r\n"
    );
    // Numbers typed from the list before still mean the same runs.
    assert_eq!(b.send("drop 1"), "err 14: no run 1 (1 stored)\r\n");
    assert!(
        b.send("measure #2 21mm 13mm")
            .starts_with("ok run 2 square ccw")
    );
    assert!(b.send("record 2").contains("ok"));
    // The next run gets a new number, never a dropped one.
    assert_eq!(
        b.send("run cw"),
        "ok run 3 started: square cw L=2.000 m\r\n"
    );
    b.robot.finish(0.0, 0.0);
    assert!(b.poll(0).starts_with("event run 3 finished"));
    assert_eq!(
        b.send("drive 0.1 0"),
        "err 24: run 3 (square cw L=2.000 m) is not measured yet: measure it or drop it first \
         (measure x y [theta], or drop 3)\r\n"
    );
    assert!(b.send("measure 1mm 2mm").starts_with("ok run 3 "));
    assert_eq!(b.send("drive 0.1 0"), "ok\r\n");
}

#[test]
fn stop_keys_and_garbled_stop_lines_stop() {
    use odocal::protocol::{LineError, LineEvent, StopKey};
    let event = |b: &mut Bench, e: LineEvent<'_>| {
        let mut out = String::new();
        b.session
            .handle_event(e, &mut b.robot, &mut b.store, &mut out)
            .unwrap();
        out
    };
    let mut b = Bench::new();
    // Idle: nothing moves, nothing to say.
    assert_eq!(event(&mut b, LineEvent::Stop(StopKey::Escape)), "");
    assert_eq!(
        event(&mut b, LineEvent::Stop(StopKey::CtrlC)),
        "event stopped (Ctrl-C)\r\n"
    );
    b.send("run cw");
    assert_eq!(
        event(&mut b, LineEvent::Stop(StopKey::CtrlC)),
        "event stopped (Ctrl-C)\r\nevent run 1 aborted, not stored: square cw L=2.000 m\r\n"
    );
    b.send("drive 0.1 0");
    assert_eq!(
        event(&mut b, LineEvent::Stop(StopKey::Escape)),
        "event stopped (Esc)\r\n"
    );
    assert!(!b.robot.driving);
    b.send("run cw");
    assert_eq!(
        event(
            &mut b,
            LineEvent::Rejected {
                error: LineError::ReceiveError,
                stop: true
            }
        ),
        "event run 1 aborted, not stored: square cw L=2.000 m\r\n\
         ok stopped: run 1 aborted, not stored\r\n"
    );
    assert_eq!(
        event(
            &mut b,
            LineEvent::Rejected {
                error: LineError::ReceiveError,
                stop: false
            }
        ),
        "err 21: receive error (overrun, framing or noise) in this line, ignored\r\n"
    );
    // Stray text before `stop` does not keep it from stopping.
    b.send("run ccw");
    assert_eq!(
        b.send("~~ stop"),
        "event run 1 aborted, not stored: square ccw L=2.000 m\r\n\
         ok stopped: run 1 aborted, not stored\r\n"
    );
    // A fault ends the run too, and says so.
    b.send("run cw");
    b.robot.running = None;
    b.robot.fault = Some(Fault::Stall {
        wheel: Wheel::Right,
    });
    assert_eq!(
        b.poll(0),
        "event run 1 aborted, not stored: square cw L=2.000 m (fault: stall)\r\n\
         event fault: Right wheel stalled\r\n"
    );
    // Echo is on at boot, for a person at a terminal.
    assert!(b.session.echo());
    assert_eq!(b.send("echo off"), "ok echo off\r\n");
    assert!(!b.session.echo());
    assert_eq!(b.send("echo on"), "ok echo on\r\n");
}

#[test]
fn units_are_never_inferred_and_an_implausible_end_needs_yes() {
    let mut b = Bench::new();
    b.send("run cw");
    b.robot.finish(0.0123, -0.0045);
    b.poll(0);
    // A bare value has no unit until the session declares one: the reply names the units.
    assert_eq!(
        b.send("measure -0.5355 -0.5326"),
        "err 26: <x> -0.5355 has no unit: write mm, cm or m after it (-0.5355mm), or declare one for this session: set measure_unit mm|cm|m\r\n"
    );
    assert_eq!(
        b.send("measure 41.841mm 39.523mm -1.5"),
        "err 26: <theta> -1.5 has no unit: write deg or rad after it (-1.5deg), or declare one for this session: set heading_unit deg|rad\r\n"
    );
    // 41.841 mm typed as metres: far beyond what the nominal geometry's tolerance allows on a
    // 2 m square; kept only with yes.
    assert_eq!(
        b.send("measure 41.841m 39.523m"),
        "err 22: run 1 square cw L=2.000 m: measured end 57.551 m from the odometry end, more than 0.661 m (the nominal geometry's tolerance on this path, plus measuring): check the values, their units and signs, or add yes to keep it\r\n"
    );
    assert_eq!(
        b.send("measure 0.041841m 0.039523m 60deg"),
        "err 22: run 1 square cw L=2.000 m: measured heading +60.0 deg from the odometry heading, more than 28.3 deg (the nominal geometry's tolerance on this path, plus measuring): check the values, their units and signs, or add yes to keep it\r\n"
    );
    assert_eq!(b.session.runs()[0].measured, None);
    // Units written against the number or apart from it; the reply echoes the values as read.
    assert_eq!(
        b.send("measure 41.841 mm 3.9523 cm -0.02618 rad"),
        "ok run 1 square cw L=2.000 m measured: read x=+41.841 mm y=+39.523 mm theta=-1.50 deg; error vs odometry dx=+0.029541 dy=+0.044023 m\r\n"
    );
    let m = b.session.runs()[0].measured.unwrap();
    assert_eq!((m.x_m, m.y_m), (41.841 * 0.001, 3.9523 * 0.01));
    assert!((m.theta_rad.unwrap() + 0.02618).abs() < 1e-15);
    // A declared unit reads the bare values for the rest of the session.
    assert_eq!(
        b.send("set measure_unit cm"),
        "ok measure_unit = cm: bare measure values are cm (this session only, not saved)\r\n"
    );
    assert_eq!(
        b.send("set heading_unit deg"),
        "ok heading_unit = deg: bare heading values are deg (this session only, not saved)\r\n"
    );
    assert_eq!(
        b.send("measure #1 4.1841 3.9523 -1.5"),
        "ok run 1 square cw L=2.000 m measured (replaced x=+0.041841 y=+0.039523 theta_deg=-1.5000): read x=+41.841 mm y=+39.523 mm theta=-1.50 deg; error vs odometry dx=+0.029541 dy=+0.044023 m\r\n"
    );
    // Beyond the bound with yes: kept as typed.
    assert!(
        b.send("measure #1 41.841m 39.523m yes")
            .starts_with("ok run 1 ")
    );
    assert_eq!(b.session.runs()[0].measured.unwrap().x_m, 41.841);
    // The declarations are not settings: a new session (a reboot) has none.
    let mut fresh = Bench::new();
    fresh.send("run cw");
    fresh.robot.finish(0.0, 0.0);
    fresh.poll(0);
    assert!(
        fresh
            .send("measure 1 2")
            .starts_with("err 26: <x> 1 has no unit")
    );
}

#[test]
fn calibrate_refused_until_both_directions_measured() {
    let mut b = Bench::new();
    // A misspelt method is named as such before anything else.
    assert_eq!(
        b.send("calibrate exakt"),
        "err 7: unknown method; one of alpha|beta|wild\r\n"
    );
    assert_eq!(
        b.send("apply exakt"),
        "err 7: unknown method; one of alpha|beta|wild\r\n"
    );
    assert_eq!(
        b.send("calibrate"),
        "err 13: need measured square runs in both directions (measured: cw 0, ccw 0)\r\n"
    );
    b.measured_run("cw", 0.01, 0.0, 0.02, 0.01);
    b.measured_run("cw", 0.01, 0.0, 0.02, 0.01);
    // An unmeasured CCW run does not count.
    b.send("run ccw");
    b.robot.finish(0.0, 0.0);
    assert_eq!(
        b.send("calibrate"),
        "event run 3 finished: square ccw L=2.000 m odometry end x=+0.000000 y=+0.000000 \
         theta_deg=+0.0000; measure it\r\n\
         err 13: need measured square runs in both directions (measured: cw 2, ccw 0)\r\n"
    );
    assert_eq!(
        b.send("apply alpha"),
        "err 13: need measured square runs in both directions (measured: cw 2, ccw 0)\r\n"
    );
    assert_eq!(b.session.calibrator().solves, 0);
}
