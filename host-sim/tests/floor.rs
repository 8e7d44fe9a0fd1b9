//! The operator on the floor at a raw terminal: units are never guessed, a run is measured or
//! dropped before the next one starts, nothing is applied or dropped wholesale without a yes,
//! and the replies say what is not saved and what to wait for. The simulated board over the
//! serial protocol, with the library's session behind it.

use host_sim::commands::bringup::{BringupArgs, bringup_session};
use host_sim::sim::board::{Board, measure_line};
use host_sim::sim::flash::SimParamFlash;
use host_sim::sim::robot::{WiringOption, sim_config};

/// Longest run here: a 1 m square takes ~20 s; 60 s of 1 kHz periods is a generous cap.
const MAX_RUN_PERIODS: u64 = 60_000;

fn boot(flash: &mut SimParamFlash) -> Board<'_> {
    let mut out = String::new();
    Board::boot(sim_config(0.995, 1.010, 0.0, 1, 1000), flash, &mut out).expect("boot")
}

/// Drives `line` (a run command) to its end; returns everything the board wrote.
fn drive(b: &mut Board<'_>, line: &str) -> String {
    let mut out = b.send(line);
    assert!(out.starts_with("ok run "), "{line}: {out}");
    assert!(b.run_until_rest(MAX_RUN_PERIODS, &mut out) < MAX_RUN_PERIODS);
    out
}

#[test]
fn measure_asks_for_the_unit() {
    let mut flash = SimParamFlash::erased();
    let mut b = boot(&mut flash);
    b.send("set square_side 1");
    let log = drive(&mut b, "run cw 1");
    assert!(log.contains("event run 1 finished"), "{log}");
    // Bare values: no unit is inferred (not metres, not the one that would fit); the reply
    // names the units.
    assert_eq!(
        b.send("measure -0.5355 -0.5326"),
        "err 26: <x> -0.5355 has no unit: write mm, cm or m after it (-0.5355mm), or declare \
         one for this session: set measure_unit mm|cm|m\r\n"
    );
    assert_eq!(b.session.runs()[0].measured, None);
    // With the units written the values are read exactly, and echoed as read: -0.16 rad is
    // -9.17 degrees.
    let reply = b.send("measure -5.356mm -5.326mm -0.16rad");
    assert!(
        reply.starts_with(
            "ok run 1 square cw L=1.000 m measured: read x=-5.356 mm y=-5.326 mm theta=-9.17 deg; \
             error vs odometry"
        ),
        "{reply}"
    );
    let m = b.session.runs()[0].measured.expect("measured");
    assert_eq!((m.x_m, m.y_m), (-5.356e-3, -5.326e-3));
    assert!((m.theta_rad.expect("heading") + 0.16).abs() < 1e-15);
    // A unit apart from its number, centimetres and degrees.
    let reply = b.send("measure #1 -0.5356 cm 5.326 mm -9.1 deg");
    assert!(
        reply.starts_with("ok run 1 square cw L=1.000 m measured (replaced "),
        "{reply}"
    );
    assert!(
        reply.contains(": read x=-5.356 mm y=+5.326 mm theta=-9.10 deg;"),
        "{reply}"
    );
    // Centimetres typed as metres: far beyond the 1 m square's bound, kept only with yes.
    let reply = b.send("measure #1 -0.5355m -0.5326m");
    assert!(
        reply.starts_with("err 22: run 1 square cw L=1.000 m: measured end "),
        "{reply}"
    );
    assert!(reply.ends_with("or add yes to keep it\r\n"), "{reply}");
}

#[test]
fn measure_n_keeps_the_heading_and_plain_measure_names_its_run() {
    let mut flash = SimParamFlash::erased();
    let mut b = boot(&mut flash);
    b.send("set square_side 1");
    drive(&mut b, "run ccw");
    let line = measure_line(&b).expect("a run was driven");
    let reply = b.send(&line);
    assert!(
        reply.starts_with("ok run 1 square ccw L=1.000 m measured: "),
        "{reply}"
    );
    let theta = b.session.runs()[0].measured.unwrap().theta_rad;
    assert!(theta.is_some());
    // Re-entering x and y only keeps the heading measured before, and says so.
    let reply = b.send("measure #1 1mm 2mm");
    assert!(reply.contains(" (heading kept: theta_deg="), "{reply}");
    assert_eq!(b.session.runs()[0].measured.unwrap().theta_rad, theta);
}

#[test]
fn next_run_waits_for_measurement() {
    let mut flash = SimParamFlash::erased();
    let mut b = boot(&mut flash);
    let log = drive(&mut b, "run cw 0.5");
    assert!(log.contains("event run 1 finished"), "{log}");
    let refusal = "err 24: run 1 (square cw L=0.500 m) is not measured yet: measure it or drop \
                   it first (measure x y [theta], or drop 1)\r\n";
    // Nothing moves the robot from the end it is to be measured at.
    for start in [
        "run cw 0.5",
        "next",
        "line 0.5",
        "circle ccw 0.3",
        "drive 0.1 0",
        "identify floor",
        "identify lifted",
        "bringup motors",
        "bringup push",
    ] {
        assert_eq!(b.send(start), refusal, "{start}");
    }
    // The button refuses too, and the console says why.
    let mut out = String::new();
    b.press_button(false, &mut out);
    assert_eq!(out, format!("event button: {refusal}"));
    // …and the board's fault LED blinks for it (the app core hands the refusal on).
    assert!(b.session.take_press_refused());
    assert!(!b.session.take_press_refused());
    assert!(b.at_rest());
    assert_eq!(b.session.runs().len(), 1);
    // Measured, the next run starts; dropped, too.
    let line = measure_line(&b).expect("a run was driven");
    assert!(b.send(&line).starts_with("ok run 1 "));
    drive(&mut b, "run ccw 0.5");
    assert!(
        b.send("next")
            .starts_with("err 24: run 2 (square ccw L=0.500 m)")
    );
    assert!(
        b.send("drop 2")
            .starts_with("ok dropped run 2: square ccw L=0.500 m; 1 run left")
    );
    let mut out = String::new();
    b.press_button(false, &mut out);
    assert!(
        out.starts_with("event button: ok run 3 started: square "),
        "{out}"
    );
    assert!(!b.session.take_press_refused());
}

#[test]
fn set_says_not_saved() {
    let mut flash = SimParamFlash::erased();
    let mut b = boot(&mut flash);
    assert_eq!(
        b.send("set max_speed 0.5"),
        "ok max_speed = 0.500 m/s (not saved; save to keep)\r\n"
    );
    assert_eq!(
        b.send("set squareside 1"),
        "err 7: <name> must be one of the parameters listed by params; did you mean \
         square_side?\r\n"
    );
    assert_eq!(
        b.send("set color 1"),
        "err 7: <name> must be one of the parameters listed by params\r\n"
    );
}

#[test]
fn reset_params_resets_ram_only() {
    let mut flash = SimParamFlash::erased();
    {
        let mut b = boot(&mut flash);
        b.send("set max_speed 0.5");
        b.send("set motor_left_sign -1");
        // The motors count as stopped once still for a moment after boot.
        let mut out = String::new();
        b.run_until_rest(1_000, &mut out);
        for _ in 0..200 {
            b.step(&mut out);
        }
        assert_eq!(b.send("save"), "ok saved\r\n");
        // Saved: nothing is discarded, no question.
        assert_eq!(
            b.send("reset-params"),
            "ok parameters reset to defaults (not saved; save to keep)\r\n"
        );
        // Every part is back in RAM, the wiring too.
        let params = b.send("params");
        assert!(params.contains("  max_speed 0.300 m/s\r\n"), "{params}");
        assert!(params.contains("  motor_left_sign 1 "), "{params}");
    }
    // The flash still holds what was saved.
    let mut out = String::new();
    let mut b =
        Board::boot(sim_config(0.995, 1.010, 0.0, 1, 1000), &mut flash, &mut out).expect("reboot");
    assert_eq!(out, "event boot: parameters loaded\r\n");
    let params = b.send("params");
    assert!(params.contains("  max_speed 0.500 m/s\r\n"), "{params}");
    assert!(params.contains("  motor_left_sign -1 "), "{params}");
}

#[test]
fn reset_params_asks_before_discarding_a_change() {
    let mut flash = SimParamFlash::erased();
    let mut b = boot(&mut flash);
    b.send("set max_speed 0.5");
    assert_eq!(
        b.send("reset-params"),
        "err 25: reset-params discards changes not saved: type reset-params yes to do it (save \
         first to keep them)\r\n"
    );
    assert!(b.send("params").contains("  max_speed 0.500 m/s\r\n"));
    assert_eq!(
        b.send("reset-params yes"),
        "ok parameters reset to defaults (not saved; save to keep)\r\n"
    );
    assert!(b.send("params").contains("  max_speed 0.300 m/s\r\n"));
    // At the defaults there is nothing to discard.
    assert_eq!(
        b.send("reset-params"),
        "ok parameters reset to defaults (not saved; save to keep)\r\n"
    );
}

#[test]
fn runs_keep_their_numbers() {
    let mut flash = SimParamFlash::erased();
    let mut b = boot(&mut flash);
    for dir in ["cw", "ccw"] {
        drive(&mut b, &format!("run {dir} 0.5"));
        let line = measure_line(&b).expect("a run was driven");
        assert!(b.send(&line).starts_with("ok run "));
    }
    assert!(
        b.send("drop 1")
            .starts_with("ok dropped run 1: square cw L=0.500 m; 1 run left")
    );
    let runs = b.send("runs");
    assert!(
        runs.starts_with("  run 2 square ccw L=0.500 m odometry "),
        "{runs}"
    );
    assert!(runs.ends_with("ok 1 run, 1 measured\r\n"), "{runs}");
    assert_eq!(b.send("drop 1"), "err 14: no run 1 (1 stored)\r\n");
    let log = drive(&mut b, "run cw 0.5");
    assert!(
        log.contains("ok run 3 started") && log.contains("event run 3 finished"),
        "{log}"
    );
}

#[test]
fn drop_all_asks() {
    let mut flash = SimParamFlash::erased();
    let mut b = boot(&mut flash);
    drive(&mut b, "line 0.3");
    assert_eq!(
        b.send("drop all"),
        "err 25: drop all forgets 1 run and their measurements, in flash too: type drop all \
         yes to do it\r\n"
    );
    assert_eq!(b.session.runs().len(), 1);
    assert_eq!(
        b.send("drop all no"),
        "err 7: <confirmation> must be one of yes\r\n"
    );
    assert_eq!(b.send("drop all yes"), "ok dropped all 1 run\r\n");
    assert_eq!(b.send("runs"), "ok 0 runs, 0 measured\r\n");
}

#[test]
fn commands_refused_during_a_run_say_to_wait() {
    let mut flash = SimParamFlash::erased();
    let mut b = boot(&mut flash);
    assert!(b.send("run cw 0.5").starts_with("ok run 1 started"));
    let mut out = String::new();
    for _ in 0..100 {
        b.step(&mut out);
    }
    let wait = "err 10: a run is in progress (square cw L=0.500 m): wait for it to finish\r\n";
    for line in [
        "calibrate",
        "set max_speed 0.4",
        "reset-params",
        "run ccw",
        "drop all yes",
    ] {
        assert_eq!(b.send(line), wait, "{line}");
    }
}

#[test]
fn events_never_land_inside_a_line_being_typed() {
    let mut flash = SimParamFlash::erased();
    let mut b = boot(&mut flash);
    assert!(b.send("line 0.3").starts_with("ok run 1 started"));
    // The operator starts typing while the robot drives; the run finishes meanwhile.
    let mut out = String::new();
    b.receive(b"ru", &mut out);
    assert!(b.run_until_rest(MAX_RUN_PERIODS, &mut out) < MAX_RUN_PERIODS);
    assert_eq!(out, "ru", "an unsolicited line cut into the echo");
    b.receive(b"ns\r", &mut out);
    b.process(&mut out, false);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines[0], "runs", "{out}");
    assert!(
        lines[1].starts_with("event run 1 finished: line d=0.300 m"),
        "{out}"
    );
    assert_eq!(lines.last(), Some(&"ok 1 run, 0 measured"), "{out}");
}

#[test]
fn bringup_push_never_says_wiring_ok_with_a_reversed_motor() {
    let o = bringup_session(&BringupArgs {
        wiring: WiringOption::RightMotorReversed,
        side: 0.5,
        rate: 1000,
    })
    .expect("bring-up session");
    let done: Vec<&String> = o
        .transcript
        .iter()
        .filter(|l| l.contains("event bringup done"))
        .collect();
    // The push checks the encoders only: it must not call the wiring ok.
    assert!(
        done[0].ends_with(
            "event bringup done: encoders count forward (the push checks the encoders only; \
             bringup motors checks the motors)"
        ),
        "{done:?}"
    );
    // The pulses find the motor, with one proposal for the one finding.
    assert!(
        done[1].ends_with(
            "event bringup done: 1 finding; apply the proposal with set, then save and check \
             again"
        ),
        "{done:?}"
    );
    assert_eq!(o.proposals, ["set motor_right_sign -1"]);
    assert_eq!(o.recheck, "event bringup done: wiring ok");
}

/// Limits or a geometry that would turn the wheels faster than the encoders count (1,000,000
/// counts/s; 0.236 m/s with 2,000,000 counts per revolution on 150 mm wheels) are refused with
/// the reason, and change nothing.
#[test]
fn limits_the_encoders_cannot_count_are_refused() {
    let mut flash = SimParamFlash::erased();
    let mut b = boot(&mut flash);
    let reply = b.send("set counts_per_rev 2000000");
    assert!(
        reply.starts_with("err 10: refused: limits not accepted: the wheels would turn faster than the encoders can count"),
        "{reply}"
    );
    assert!(b.send("params").contains("counts_per_rev 200000 "));
    assert!(b.send("set max_speed 0.2").starts_with("ok "));
    assert!(b.send("set max_turn_rate 1").starts_with("ok "));
    assert!(b.send("set counts_per_rev 2000000").starts_with("ok "));
    let reply = b.send("set max_speed 0.3");
    assert!(
        reply.contains("faster than the encoders can count"),
        "{reply}"
    );
    assert!(b.send("params").contains("max_speed 0.200 "));
}

/// The crash the last reset came from (the board's record in RAM the startup code leaves alone)
/// stays on `status` until `clear`.
#[test]
fn status_names_the_last_crash_until_clear() {
    use odocal::session::crash::CrashRecord;
    let mut flash = SimParamFlash::erased();
    let mut b = boot(&mut flash);
    assert!(!b.send("status").contains("reset="));
    b.session
        .note_crash(CrashRecord::panic("src/session/mod.rs", 321));
    let status = b.send("status");
    assert!(
        status.ends_with(" reset=\"panic at src/session/mod.rs:321\"\r\n"),
        "{status}"
    );
    assert_eq!(b.send("clear"), "ok reset cause cleared\r\n");
    assert!(!b.send("status").contains("reset="));
    assert_eq!(b.send("clear"), "ok no fault latched\r\n");
}
