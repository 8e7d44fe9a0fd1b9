//! The simulated board over the serial protocol: a full calibration session and the `drive`
//! deadman, with the library's controller, session, calibration and storage.

use host_sim::sim::board::{Board, measure_line};
use host_sim::sim::flash::SimParamFlash;
use host_sim::sim::robot::sim_config;
use odocal::calibration::{jung_chung, lee, umbmark, wrap_angle};
use odocal::kinematics::geometry::Geometry;
use odocal::motion::controller::Status;
use odocal::motion::run::{Direction, PathKind};

/// True robot: E_d = 0.995, E_b = 1.010 (the paper's example magnitudes), no slip.
const TRUE_ED: f64 = 0.995;
const TRUE_EB: f64 = 1.010;

/// Longest run: a 2 m square at 0.3 m/s takes ~35 s; 120 s of periods is a generous cap.
const MAX_RUN_PERIODS: u64 = 120_000;

fn boot(flash: &mut SimParamFlash) -> (Board<'_>, String) {
    let mut out = String::new();
    let board =
        Board::boot(sim_config(TRUE_ED, TRUE_EB, 0.0, 1, 1000), flash, &mut out).expect("boot");
    (board, out)
}

/// The factors of one method's row of the `calibrate` table.
fn row(table: &str, method: &str) -> (f64, f64) {
    let line = table
        .lines()
        .find(|l| l.split_whitespace().next() == Some(method))
        .unwrap_or_else(|| panic!("no row {method} in\n{table}"));
    let mut w = line.split_whitespace().skip(1);
    let e_d: f64 = w.next().unwrap().parse().unwrap();
    let e_b: f64 = w.next().unwrap().parse().unwrap();
    (e_d, e_b)
}

/// Each closed-form row of `table` is that method's formula (held to hand-computed values in
/// tests/calibration_closed_form.rs) on the centres of gravity of the board's stored runs' end
/// errors `measured − odometry` (5 + 5 squares of 2 m), evaluated here: catches rows swapped or
/// mislabelled, a wrong input (x for y, a missing direction) or a wrong wheelbase. The table
/// prints 9 decimals (±5e-10); the rows' own distance from the truth (up to 3.3e-3 in E_b, the
/// small-angle bias at 2 m) is not a property of the wiring.
fn closed_form_rows_are_their_formulas(b: &Board<'_>, table: &str) {
    let runs = b.session.runs();
    let centre = |d: Direction, f: &dyn Fn(&odocal::motion::run::RunRecord) -> f64| {
        let v: Vec<f64> = runs
            .iter()
            .filter(|r| matches!(r.path, PathKind::Square { direction, .. } if direction == d))
            .map(f)
            .collect();
        assert_eq!(v.len(), 5);
        v.iter().sum::<f64>() / 5.0
    };
    let ex = |r: &odocal::motion::run::RunRecord| r.measured.unwrap().x_m - r.odometry_end.x_m;
    let ey = |r: &odocal::motion::run::RunRecord| r.measured.unwrap().y_m - r.odometry_end.y_m;
    let et = |r: &odocal::motion::run::RunRecord| {
        wrap_angle(r.measured.unwrap().theta_rad.unwrap() - r.odometry_end.theta_rad)
    };
    let (x_cw, x_ccw) = (centre(Direction::Cw, &ex), centre(Direction::Ccw, &ex));
    let (y_cw, y_ccw) = (centre(Direction::Cw, &ey), centre(Direction::Ccw, &ey));
    let (t_cw, t_ccw) = (centre(Direction::Cw, &et), centre(Direction::Ccw, &et));
    let b0 = Geometry::PAPER_NOMINAL.wheelbase_m;
    for (m, f) in [
        ("umbmark-x", umbmark::umbmark_x(x_cw, x_ccw, 2.0, b0)),
        ("umbmark-y", umbmark::umbmark_y(y_cw, y_ccw, 2.0, b0)),
        ("lee-x", lee::lee_x(x_cw, x_ccw, 2.0, b0)),
        ("lee-y", lee::lee_y(y_cw, y_ccw, 2.0, b0)),
        ("jung-chung", jung_chung::jung_chung(t_cw, t_ccw, 2.0, b0)),
    ] {
        let f = f.unwrap();
        let (ed, eb) = row(table, m);
        assert!((ed - f.e_d).abs() < 1e-9, "{m} E_d {ed} vs {}", f.e_d);
        assert!((eb - f.e_b).abs() < 1e-9, "{m} E_b {eb} vs {}", f.e_b);
    }
}

#[test]
fn scripted_session_calibrate_save_reboot() {
    let mut flash = SimParamFlash::erased();
    let (mut b, boot_msg) = boot(&mut flash);
    assert_eq!(
        boot_msg,
        "event boot: default parameters (no stored parameters)\r\n"
    );
    // Before any run: the refusals the protocol promises.
    assert_eq!(
        b.send("measure 0m 0m"),
        "err 12: no finished run to measure (run cw|ccw or next first)\r\n"
    );
    let mut log = String::new();
    for i in 0..10 {
        let dir = if i % 2 == 0 { "cw" } else { "ccw" };
        let started = format!("ok run {} started: square {dir} L=2.000 m\r\n", i + 1);
        if i % 4 == 0 {
            // The button and the serial port drive the same session and plan.
            let mut reply = String::new();
            b.press_button(false, &mut reply);
            assert_eq!(reply, format!("event button: {started}"));
        } else {
            assert_eq!(b.send("next"), started);
        }
        let periods = b.run_until_rest(MAX_RUN_PERIODS, &mut log);
        assert!(periods < MAX_RUN_PERIODS, "run {i} did not finish");
        assert!(
            log.contains(&format!("event run {} finished", i + 1)),
            "{log}"
        );
        // The operator measures the true end pose in the run's start frame.
        let p = b.true_pose_in_run_frame().unwrap();
        let line = measure_line(&b).unwrap();
        assert_eq!(
            line,
            format!(
                "measure {:.6}m {:.6}m {:.4}deg",
                p.x_m,
                p.y_m,
                wrap_angle(p.theta_rad).to_degrees()
            )
        );
        let reply = b.send(&line);
        assert!(
            reply.starts_with(&format!("ok run {} square {dir}", i + 1)),
            "{reply}"
        );
        if i == 0 {
            // Only CW measured so far: calibrate is refused with the documented message.
            assert_eq!(
                b.send("calibrate"),
                "err 13: need measured square runs in both directions (measured: cw 1, ccw 0)\r\n"
            );
        }
    }
    assert!(b.send("next").starts_with("err 20: all planned runs done"));
    let table = b.send("calibrate");
    println!("{table}");
    assert!(table.ends_with(
        "ok 6 solved from 10 measured runs (cw 5, ccw 5); apply <method> to use one\r\n"
    ));
    // The exact method fits the recorded ticks with no small-angle approximation and the
    // measurements are exact (no slip, true pose): it must recover the truth to within the
    // 9-decimal print resolution plus encoder quantisation, far below 1e-5.
    let (ed, eb) = row(&table, "exact");
    assert!((ed - TRUE_ED).abs() < 1e-5, "exact E_d {ed} vs {TRUE_ED}");
    assert!((eb - TRUE_EB).abs() < 1e-5, "exact E_b {eb} vs {TRUE_EB}");
    closed_form_rows_are_their_formulas(&b, &table);
    assert!(b.send("apply exact").starts_with("ok applied exact: "));
    // The exact fit (seconds on the board) ran once for the table, the advice and `apply`.
    assert_eq!(b.session.calibrator().exact_solves(), 1);
    assert_eq!(b.send("save"), "ok saved\r\n");
    let params_before = b.send("params");
    let runs_before = b.send("runs");
    let calibrated = b.controller_geometry();
    assert_ne!(calibrated, Geometry::PAPER_NOMINAL);

    // Simulated reboot: a new board (controller, session) over the same flash.
    drop(b);
    let (mut b2, boot_msg) = boot(&mut flash);
    assert_eq!(
        boot_msg,
        "event boot: parameters loaded\r\nevent runs restored: 10 runs, 10 measured\r\n"
    );
    let params_after = b2.send("params");
    println!("{params_after}");
    assert_eq!(params_after, params_before);
    assert!(
        params_after.contains("  calibration exact E_d="),
        "{params_after}"
    );
    // The controller runs with the stored calibration, bit for bit.
    assert_eq!(b2.controller_geometry(), calibrated);
    // The runs and measurements survived the reboot, bit for bit: the same list, and the same
    // calibration table from them (the session resumes where it was).
    assert_eq!(b2.send("runs"), runs_before);
    assert_eq!(b2.send("calibrate"), table);
    assert_eq!(b2.session.calibrator().exact_solves(), 1);
    assert!(b2.send("apply exact").starts_with("ok applied exact: "));
    assert_eq!(b2.session.calibrator().exact_solves(), 1);
    // A changed run store makes the kept fit stale: the next `calibrate` solves again.
    assert!(b2.send("drop 10").starts_with("ok dropped run 10"));
    let table9 = b2.send("calibrate");
    assert!(table9.contains("from 9 measured runs"), "{table9}");
    assert_eq!(b2.session.calibrator().exact_solves(), 2);
    // `drop all` forgets them in flash too: the next boot restores nothing.
    assert_eq!(
        b2.send("drop all"),
        "err 25: drop all forgets 9 runs and their measurements, in flash too: type drop all \
         yes to do it\r\n"
    );
    assert_eq!(b2.session.runs().len(), 9);
    assert_eq!(b2.send("drop all yes"), "ok dropped all 9 runs\r\n");
    // Flash is written once the wheels have been still for 0.1 s (the board just booted).
    let mut out = String::new();
    for _ in 0..200 {
        b2.step(&mut out);
    }
    assert!(b2.session.runs_stored(), "{out}");
    drop(b2);
    let (mut b3, boot_msg) = boot(&mut flash);
    assert_eq!(boot_msg, "event boot: parameters loaded\r\n");
    assert_eq!(b3.send("runs"), "ok 0 runs, 0 measured\r\n");
}

#[test]
fn drive_deadman_stops_within_500_ms_plus_one_period() {
    let mut flash = SimParamFlash::erased();
    let (mut b, _) = boot(&mut flash);
    let mut out = String::new();
    // 1 kHz control: one period is 1 ms. Commands every 100 ms for 1 s keep the robot moving.
    for _ in 0..10 {
        assert_eq!(b.send("drive 0.2 0.3"), "ok\r\n");
        for _ in 0..100 {
            let step = b.step(&mut out);
            assert!(
                !step.command.is_stop() || b.controller.status() != Status::Driving,
                "stopped while commands arrive"
            );
        }
    }
    assert_eq!(b.controller.status(), Status::Driving);
    // Last command, then silence: count periods until the first stop command.
    assert_eq!(b.send("drive 0.2 0.3"), "ok\r\n");
    let mut periods = 0u64;
    loop {
        let step = b.step(&mut out);
        periods += 1;
        if step.command.is_stop() {
            break;
        }
        assert!(periods <= 2_000, "deadman never fired");
    }
    println!("deadman: motors stopped {periods} periods (ms) after the last drive command");
    // 500 ms deadman + one 1 ms control period.
    assert!(periods <= 501, "stopped after {periods} ms");
    // And not long before it: the deadman is 500 ms, not a shorter timeout.
    assert!(periods >= 499, "stopped after {periods} ms");
    // The robot comes to rest and accepts a run afterwards.
    b.run_until_rest(5_000, &mut out);
    assert!(b.at_rest());
    assert!(b.send("run cw 0.5").starts_with("ok run 1 started"));
}

/// `set control_hz 10000` over the serial protocol: the simulated board's controller and robot
/// step at 10 kHz from the next period on (a 0.5 m line takes ten times the periods, the same
/// seconds), `save` keeps the rate, and the rebooted board runs at it without being told again.
#[test]
fn control_rate_set_saved_and_booted_at_10_khz() {
    let mut flash = SimParamFlash::erased();
    let mut log = String::new();
    // Each line is measured before the next one starts.
    let line_periods = |b: &mut Board, log: &mut String| {
        assert!(b.send("line 0.5").starts_with("ok run"));
        let periods = b.run_until_rest(20 * 10_000, log);
        let measure = measure_line(b).expect("a run was driven");
        assert!(b.send(&measure).contains("ok run"), "{measure}");
        periods
    };
    let (periods_1k, periods_10k) = {
        let (mut b, _) = boot(&mut flash);
        let at_1k = line_periods(&mut b, &mut log);
        assert_eq!(
            b.send("set control_hz 10000"),
            "ok control_hz = 10000 Hz (not saved; save to keep)\r\n"
        );
        assert_eq!(b.controller.config().rate_hz, 10_000);
        let at_10k = line_periods(&mut b, &mut log);
        assert!(b.send("save").starts_with("ok"));
        (at_1k, at_10k)
    };
    // The same motion, ten times the periods (the run ends after the profile and 50 ms of
    // settling; the rest window adds 0.1 s at either rate): within 1 %.
    let ratio = periods_10k as f64 / periods_1k as f64;
    assert!(
        (ratio - 10.0).abs() < 0.1,
        "{periods_1k} vs {periods_10k} periods"
    );
    let mut out = String::new();
    // The operator wants 10 kHz and the flash says so: no `set` at boot.
    let mut b = Board::boot(
        sim_config(TRUE_ED, TRUE_EB, 0.0, 1, 10_000),
        &mut flash,
        &mut out,
    )
    .expect("reboot");
    assert_eq!(
        out,
        "event boot: parameters loaded\r\nevent runs restored: 2 runs, 2 measured\r\n"
    );
    assert_eq!(b.controller.config().rate_hz, 10_000);
    assert_eq!(b.sim.config().rate_hz, 10_000);
    assert!(b.send("params").contains("  control_hz 10000 Hz\r\n"));
    let again = line_periods(&mut b, &mut log);
    assert!(
        again.abs_diff(periods_10k) < periods_10k / 100,
        "{again} vs {periods_10k}"
    );
    drop(b);
    // A reset (`serial` without `--rate-hz`, or its `reboot`): the board comes up at its stored
    // rate whatever the simulator's own default is, and nobody tells it otherwise.
    let mut out = String::new();
    let b = Board::boot_at_stored_rate(
        sim_config(TRUE_ED, TRUE_EB, 0.0, 1, 1_000),
        &mut flash,
        &mut out,
    )
    .expect("reset");
    assert!(!out.contains("control_hz"), "{out}");
    assert_eq!(b.controller.config().rate_hz, 10_000);
    assert_eq!(b.sim.config().rate_hz, 10_000);
    drop(b);
    // A rate the timers cannot divide to is refused at boot with the board's reply.
    let mut flash = SimParamFlash::erased();
    let err = Board::boot(
        sim_config(TRUE_ED, TRUE_EB, 0.0, 1, 3_000),
        &mut flash,
        &mut out,
    )
    .err()
    .unwrap();
    assert!(err.contains("err 17: control rate must be"), "{err}");
}
