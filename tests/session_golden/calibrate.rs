//! Calibrating, applying and saving; the button and the run plan; a full run store.

use super::*;

#[test]
fn calibrate_apply_save_golden() {
    let mut b = Bench::new();
    b.measured_run("cw", 0.01, 0.0, 0.02, 0.01);
    b.measured_run("ccw", 0.01, 0.0, 0.02, 0.01);
    let table = "  method       E_d          E_b          E_s          D_R_mm     D_L_mm     b_mm       \
                 loo_mm    E_max_mm  sd_E_d    sd_E_b\r\n\
                 \x20 alpha        0.995000000  1.010000000  1.000000000  149.6241   150.3759   388.8500   \
                 2.000     1.200     2.500e-4  n/a  [lowest loo]\r\n\
                 \x20 beta         failed: degenerate: the runs do not determine every factor\r\n\
                 \x20 wild         1.000000000  1.300000000  1.000000000  150.0000   150.0000   500.5000   \
                 50.000    -         n/a       n/a\r\n\
                 \x20 advice all L=2.000 m is adequate\r\n\
                 ok 2 solved from 2 measured runs (cw 1, ccw 1); apply <method> to use one\r\n";
    assert_eq!(b.send("calibrate"), table);
    // Runs are kept across calibrate: the same answer again.
    assert_eq!(b.send("calibrate"), table);
    assert_eq!(b.send("runs").lines().count(), 3);
    assert_eq!(
        b.send("calibrate gamma"),
        "err 7: unknown method; one of alpha|beta|wild\r\n"
    );
    // One method: its row and its advice only.
    assert_eq!(
        b.send("calibrate alpha").lines().last(),
        Some("ok 1 solved from 2 measured runs (cw 1, ccw 1); apply <method> to use one")
    );
    assert!(
        b.send("calibrate alpha")
            .contains("  advice alpha L=2.000 m")
    );
    assert_eq!(
        b.send("calibrate beta"),
        "  method       E_d          E_b          E_s          D_R_mm     D_L_mm     b_mm       \
         loo_mm    E_max_mm  sd_E_d    sd_E_b\r\n\
         \x20 beta         failed: degenerate: the runs do not determine every factor\r\n\
         err 16: no method succeeded (check the measurements: runs)\r\n"
    );
    // One rule for apply and save: what the record cannot store is not applied.
    let refused = "err 17: parameters not storable: E_d, E_b and E_s must be within 0.8..1.25\r\n";
    assert_eq!(b.send("apply wild"), refused);
    assert_eq!(b.session.settings().calibration, None);
    let mut wild = Settings::default();
    wild.active = wild.nominal.with_factors(1.0, 1.3, 1.0);
    wild.calibration = Some(odocal::session::AppliedCalibration {
        method: heapless::String::try_from("wild").unwrap(),
        e_d: 1.0,
        e_b: 1.3,
        e_s: 1.0,
        runs_used: 2,
        e_max_m: 0.0,
    });
    assert_eq!(
        format!(
            "err 17: {}\r\n",
            odocal::session::storable(&wild).unwrap_err()
        ),
        refused
    );
    assert_eq!(
        b.send("apply beta"),
        "err 16: degenerate: the runs do not determine every factor\r\n"
    );
    assert_eq!(
        b.send("apply ALPHA"),
        "ok applied alpha: E_d=0.995000000 E_b=1.010000000 E_s=1.000000000 (not saved; save to keep)\r\n"
    );
    let expected = Geometry::PAPER_NOMINAL.with_factors(0.995, 1.01, 1.0);
    assert_eq!(b.robot.geometry, Some(expected));
    let params = b.send("params");
    assert!(params.contains(
        "  active d_right=0.149624060 d_left=0.150375940 wheelbase=0.388850000 m\r\n\
         \x20 calibration alpha E_d=0.995000000 E_b=1.010000000 E_s=1.000000000 runs=2 E_max=1.200 mm\r\n"
    ), "{params}");
    b.send("drive 0.1 0");
    assert_eq!(
        b.send("save"),
        "err 18: motors not confirmed stopped (running, or the control loop has not run yet), flash \
         not written\r\n"
    );
    assert!(b.store.saved.is_none());
    // Nothing that takes seconds (the exact solve) or changes parameters while moving: the
    // console must stay free for `stop`.
    for busy in ["calibrate", "apply alpha", "set square_side 1"] {
        assert_eq!(
            b.send(busy),
            "err 10: drive is in progress: wait for the motors to stop (500 ms after the last drive)\r\n",
            "{busy}"
        );
    }
    b.send("stop");
    assert_eq!(b.send("save"), "ok saved\r\n");
    assert_eq!(b.store.saved.as_ref(), Some(b.session.settings()));
    // Re-entering a value changes nothing.
    assert_eq!(
        b.send("set d_left 0.150"),
        "ok d_left = 0.150000000 m (unchanged)\r\n"
    );
    assert!(b.session.settings().calibration.is_some());
    // A geometry change drops the calibration (its factors were relative to the old nominal),
    // says so, and setting the old value back restores it.
    let applied = b.session.settings().clone();
    assert_eq!(
        b.send("set d_left 0.151"),
        "ok d_left = 0.151000000 m (calibration alpha dropped: it is relative to the old \
         geometry; set the old value back to restore it) (not saved; save to keep)\r\n"
    );
    assert_eq!(b.session.settings().calibration, None);
    assert_eq!(
        b.send("set d_left 0.15"),
        "ok d_left = 0.150000000 m (calibration alpha restored) (not saved; save to keep)\r\n"
    );
    assert_eq!(b.session.settings(), &applied);
    assert_eq!(b.robot.geometry, Some(applied.active));
    b.send("set d_left 0.151");
    let saved = b.store.saved.clone();
    // A change not saved is not discarded without a yes.
    assert_eq!(
        b.send("reset-params"),
        "err 25: reset-params discards changes not saved: type reset-params yes to do it (save \
         first to keep them)\r\n"
    );
    assert_eq!(b.session.settings().nominal.diameter_left_m, 0.151);
    assert_eq!(
        b.send("reset-params yes"),
        "ok parameters reset to defaults (not saved; save to keep)\r\n"
    );
    assert_eq!(b.session.settings(), &Settings::default());
    // RAM only: the flash keeps what was saved until `save`.
    assert_eq!(b.store.saved, saved);
    assert_eq!(b.send("save"), "ok saved\r\n");
    assert_eq!(b.store.saved.as_ref(), Some(&Settings::default()));
}

#[test]
fn next_alternates_and_completes_the_plan() {
    let mut b = Bench::new();
    b.send("set runs_per_direction 2");
    let mut dirs = Vec::new();
    for k in 1..=4 {
        let reply = b.send("next");
        dirs.push(reply.clone());
        b.robot.finish(0.0, 0.0);
        let dir = if k % 2 == 1 { "cw" } else { "ccw" };
        assert_eq!(
            b.send("measure 0.001m 0m"),
            format!(
                "event run {k} finished: square {dir} L=2.000 m odometry end x=+0.000000 \
                 y=+0.000000 theta_deg=+0.0000; measure it\r\n\
                 ok run {k} square {dir} L=2.000 m measured: read x=+1.000 mm y=+0.000 mm; error \
                 vs odometry dx=+0.001000 \
                 dy=+0.000000 m\r\n"
            )
        );
    }
    assert_eq!(
        dirs,
        [
            "ok run 1 started: square cw L=2.000 m\r\n",
            "ok run 2 started: square ccw L=2.000 m\r\n",
            "ok run 3 started: square cw L=2.000 m\r\n",
            "ok run 4 started: square ccw L=2.000 m\r\n",
        ]
    );
    let done = b.send("next");
    assert!(
        done.ends_with("err 20: all planned runs done (calibrate, or run cw|ccw for more)\r\n"),
        "{done}"
    );
    // Dropping a CCW run re-opens the plan for that direction.
    b.send("drop 2");
    assert!(
        b.send("next")
            .ends_with("ok run 5 started: square ccw L=2.000 m\r\n")
    );
}

#[test]
fn button_starts_next_clears_faults_and_stops() {
    let mut b = Bench::new();
    let mut out = String::new();
    b.session.button_short(&mut b.robot, &mut out).unwrap();
    assert_eq!(
        out,
        "event button: ok run 1 started: square cw L=2.000 m\r\n"
    );
    out.clear();
    b.session.button_short(&mut b.robot, &mut out).unwrap();
    assert_eq!(
        out,
        "event button: err 10: a run is in progress (square cw L=2.000 m): wait for it to finish\r\n"
    );
    out.clear();
    b.session.button_long(&mut b.robot, &mut out).unwrap();
    assert_eq!(
        out,
        "event run 1 aborted, not stored: square cw L=2.000 m\r\nevent button: ok stopped\r\n"
    );
    assert_eq!(b.robot.aborts, 1);
    out.clear();
    b.robot.fault = Some(Fault::Stall {
        wheel: Wheel::Right,
    });
    b.session.button_short(&mut b.robot, &mut out).unwrap();
    // The fault is announced in full once (as the controller reports it), then cleared.
    assert_eq!(
        out,
        "event fault: Right wheel stalled\r\nevent button: ok fault cleared\r\n"
    );
    assert_eq!(b.robot.fault, None);
}

#[test]
fn store_full_refuses_new_runs() {
    let mut b = Bench::new();
    for _ in 0..MAX_RUNS {
        b.send("line 0.5");
        b.robot.finish(0.5, 0.0);
        assert!(b.send("measure 0.5m 0m").contains("\r\nok run "));
    }
    let reply = b.send("line 0.5");
    assert!(
        reply.ends_with("err 15: run store full (drop <n> first)\r\n"),
        "{reply}"
    );
    assert_eq!(b.session.runs().len(), MAX_RUNS);
}
