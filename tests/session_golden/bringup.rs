//! The wiring check, the motor identification and its tuning, and the store: runs and
//! measurements kept across a reset, a store that cannot write.

use super::*;

/// The wiring check: the operator's instructions, and the verdicts and proposals from the
/// controller's counts. The pulses alone cannot tell a reversed motor from a reversed encoder;
/// after a hand push that shows the left encoder counting backward, they can.
#[test]
fn bringup_replies_and_proposals_are_exact() {
    use odocal::motion::bringup::{PulseCounts, PulseReport, PushReport, WheelPulses};
    let mut b = Bench::new();
    assert_eq!(
        b.send("bringup"),
        "ok bringup motors: wheels must be off the ground; pulsing right then left at 25 % duty, 2 s\r\n"
    );
    assert_eq!(b.robot.check, Some(CheckKind::Pulses));
    let healthy = WheelPulses {
        forward: PulseCounts {
            own: 30_000,
            other: 12,
        },
        backward: PulseCounts {
            own: -29_000,
            other: -3,
        },
    };
    let reversed = WheelPulses {
        forward: PulseCounts {
            own: -30_000,
            other: 0,
        },
        backward: PulseCounts {
            own: 29_000,
            other: 0,
        },
    };
    b.robot.check_reports.push(CheckReport::Pulses(PulseReport {
        right: healthy,
        left: reversed,
    }));
    assert_eq!(
        b.poll(0),
        "event bringup motors: right forward +30000 back -29000 (other wheel +12/-3): ok\r\n\
         event bringup motors: left forward -30000 back +29000 (other wheel +0/+0): counts run against the duty: motor or encoder reversed; run `bringup push` to tell which\r\n\
         event bringup done: 1 finding, no setting fixes it: see above, then check again\r\n"
    );
    assert_eq!(
        b.send("bringup push"),
        "ok bringup push: motors off; push the robot straight forward by hand about 5 cm within 5 s\r\n"
    );
    b.robot.check_reports.push(CheckReport::Push(PushReport {
        right: 21_000,
        left: -20_900,
    }));
    assert_eq!(
        b.poll(0),
        "event bringup push: right encoder +21000 counts, counts forward: ok\r\n\
         event bringup push: left encoder -20900 counts, counts backward: encoder reversed\r\n\
         event bringup propose: set encoder_left_sign -1\r\n\
         event bringup done: 1 finding; apply the proposal with set, then save and check again\r\n"
    );
    b.send("bringup");
    b.robot.check_reports.push(CheckReport::Pulses(PulseReport {
        right: healthy,
        left: reversed,
    }));
    let events = b.poll(0);
    assert!(
        events.contains("left forward -30000 back +29000 (other wheel +0/+0): encoder reversed (push check)\r\nevent bringup propose: set encoder_left_sign -1\r\n"),
        "{events}"
    );
    assert_eq!(
        b.send("set encoder_left_sign -1"),
        "ok encoder_left_sign = -1 (1 standard, -1 reversed) (not saved; save to keep)\r\n"
    );
    assert_eq!(b.robot.wiring.map(|w| w.encoder_left_reversed), Some(true));
    assert!(b.send("set encoder_left_sign 0").starts_with("err "));
    assert!(b.send("bringup sideways").starts_with("err "));
}

#[test]
fn runs_and_measurements_are_stored_as_they_change_and_restored_after_a_reset() {
    let mut b = Bench::new();
    b.measured_run("cw", 0.01, -0.02, 0.012, -0.018);
    b.measured_run("ccw", 0.02, 0.01, 0.021, 0.012);
    assert_eq!(b.store.runs, b.session.runs());
    assert!(b.store.runs.iter().all(|r| r.measured.is_some()));
    // Every change told the calibrator (a kept exact fit is stale): 2 runs, 2 measurements.
    assert_eq!(b.session.calibrator().runs_changes, 4);
    // While the motors run nothing is written (a page change would erase a sector): the drop
    // is stored once they stop.
    assert_eq!(b.send("drive 0.1 0"), "ok\r\n");
    assert!(b.send("drop 1").starts_with("ok dropped run 1"));
    assert_eq!(b.store.runs.len(), 2);
    assert!(!b.session.runs_stored());
    b.robot.driving = false;
    assert_eq!(b.poll(0), "");
    assert_eq!(b.store.runs, b.session.runs());
    // A flash failure is reported once, and the next change tries again.
    b.store.fail_runs = true;
    // The run left keeps its number: run 2 (a dropped run leaves a gap).
    assert!(
        b.send("measure #1 0.022m 0.011m")
            .starts_with("err 14: no run 1 (1 stored)")
    );
    let reply = b.send("measure #2 0.022m 0.011m");
    assert!(
        reply.ends_with("\r\nevent runs not stored: flash error: flash driver error\r\n"),
        "{reply}"
    );
    b.store.fail_runs = false;
    assert_eq!(b.poll(0), "");
    assert!(!b.session.runs_stored());
    assert!(b.send("measure #2 0.023m 0.011m").starts_with("ok run 2"));
    assert!(b.session.runs_stored());
    assert_eq!(b.store.runs, b.session.runs());
    // A reset: a new session over the same storage resumes with the runs and measurements.
    let listing = b.send("runs");
    let mut resumed = Session::new(
        Settings::default(),
        KnownCalibrator {
            solves: 0,
            runs_changes: 0,
        },
    );
    let mut out = String::new();
    resumed.restore_runs(&mut b.store, &mut out).unwrap();
    assert_eq!(out, "event runs restored: 1 run, 1 measured\r\n");
    b.session = resumed;
    // A reboot starts a new session: the restored runs are numbered from 1 again.
    assert!(listing.starts_with("  run 2 square ccw"), "{listing}");
    assert_eq!(b.send("runs"), listing.replacen("  run 2 ", "  run 1 ", 1));
    // `drop all` asks first.
    assert_eq!(
        b.send("drop all"),
        "err 25: drop all forgets 1 run and their measurements, in flash too: type drop all \
         yes to do it\r\n"
    );
    assert_eq!(b.session.runs().len(), 1);
    assert_eq!(b.send("drop all yes"), "ok dropped all 1 run\r\n");
    assert!(b.store.runs.is_empty());
}

/// Motor identification: the operator's instructions per mode, the result lines, the tuning it
/// applies (seen by the robot and in `params`), and the refusal of an implausible response.
#[test]
fn identify_replies_are_exact_and_the_result_becomes_the_tuning() {
    use odocal::motion::identify::{
        IdentifyFailure, IdentifyMode, IdentifyProblem, IdentifyReport, MotorFit,
    };
    let mut b = Bench::new();
    assert_eq!(
        b.send("identify"),
        "ok identify lifted: wheels must be off the ground; right then left; a slow probe, then steps to 25/50/75 % of max_speed 0.30 m/s forward and backward, about 11 s\r\n"
    );
    assert_eq!(
        b.robot.check,
        Some(CheckKind::Identify(IdentifyMode::Lifted))
    );
    let fit = |k_fwd: f32, k_back: f32, tau: f32, d0: f32| MotorFit {
        params: MotorParams {
            gain_forward_mps: k_fwd,
            gain_backward_mps: k_back,
            time_constant_s: tau,
            deadband: d0,
        },
        coast_decel_mps2: 0.4375,
        coast_from_mps: 0.2125,
        residual_mps: 0.00016,
    };
    let report = IdentifyReport {
        mode: IdentifyMode::Lifted,
        right: fit(0.5, 0.48, 0.12, 0.05),
        left: fit(0.6, 0.61, 0.15, 0.04),
    };
    b.robot.check_reports.push(CheckReport::Identify(report));
    assert_eq!(
        b.poll(0),
        "event identify right: gain_fwd=0.5000 gain_back=0.4800 m/s per duty, tau=0.1200 s, deadband=0.0500, coast 0.438 m/s^2 from 0.213 m/s, residual 0.00016 m/s\r\n\
         event identify left: gain_fwd=0.6000 gain_back=0.6100 m/s per duty, tau=0.1500 s, deadband=0.0400, coast 0.438 m/s^2 from 0.213 m/s, residual 0.00016 m/s\r\n\
         event identify done (lifted): speed-loop tuning applied, bandwidth 30.0 rad/s (not saved; save to keep)\r\n"
    );
    let applied = b.robot.tuning.expect("the tuning reached the robot");
    assert_eq!(applied.right, report.right.params);
    assert_eq!(applied.left, report.left.params);
    assert_eq!(
        applied.bandwidth_radps,
        SpeedTuning::DEFAULT.bandwidth_radps
    );
    let params = b.send("params");
    assert!(
        params.contains("  motor_right_tau 0.1200 s\r\n  motor_right_deadband 0.0500 duty\r\n"),
        "{params}"
    );
    // Derived by pole placement at 30 rad/s: kp = (3·30·0.12 − 1)/0.49, ff = 1/K per direction.
    assert!(
        params.contains(
            "  speed_loop right kp=20.000 ki=661.224 kii=6612.245 ff_fwd=2.0000 ff_back=2.0833 ff_accel=0.2400 deadband=0.0500\r\n"
        ),
        "{params}"
    );
    // Saved with the rest of the parameters.
    assert_eq!(b.send("save"), "ok saved\r\n");
    assert_eq!(b.store.saved.as_ref().map(|s| s.tuning), Some(applied));

    assert_eq!(
        b.send("identify floor"),
        "ok identify floor: robot on the floor with 1 m free ahead and behind (it stays within 1 m, with lower steps if that needs them); both wheels; a slow probe, then steps to 25/50/75 % of max_speed 0.30 m/s forward and backward, about 7 s\r\n"
    );
    b.robot
        .check_reports
        .push(CheckReport::IdentifyFailed(IdentifyFailure {
            wheel: Wheel::Left,
            problem: IdentifyProblem::Reversed,
        }));
    b.robot.fault = Some(Fault::Identify(IdentifyFailure {
        wheel: Wheel::Left,
        problem: IdentifyProblem::Reversed,
    }));
    assert_eq!(
        b.poll(0),
        "event identify err 23: left motor: counts run against the duty: motor or encoder reversed (run bringup); motors stopped, tuning unchanged, fault latched (clear)\r\n"
    );
    assert_eq!(b.robot.tuning, Some(applied));
    assert!(
        b.send("identify")
            .starts_with("err 11: fault latched: identify")
    );
    assert!(b.send("identify sideways").starts_with("err 7: "));
}

/// The tuning parameters follow the geometry's rules: each value within its range (parser),
/// the set as a whole consistent (a motor's two directions within 0.5..2 of each other), a
/// value equal to the current one changes nothing.
#[test]
fn tuning_parameters_are_validated_like_the_geometry() {
    let mut b = Bench::new();
    assert_eq!(
        b.send("set motor_left_gain_fwd 0.6"),
        "ok motor_left_gain_fwd = 0.6000 m/s per duty (not saved; save to keep)\r\n"
    );
    assert_eq!(b.robot.tuning.map(|t| t.left.gain_forward_mps), Some(0.6));
    assert_eq!(
        b.send("set motor_left_gain_fwd 0.6"),
        "ok motor_left_gain_fwd = 0.6000 m/s per duty (unchanged)\r\n"
    );
    assert_eq!(
        b.send("set motor_left_gain_back 0.25"),
        "err 17: a motor's forward/backward gain ratio must be within 0.5..2 (change the other direction first, or both in steps)\r\n"
    );
    assert!(b.send("set motor_right_tau 5").starts_with("err 6: "));
    assert!(b.send("set speed_bandwidth 0").starts_with("err 6: "));
    assert_eq!(
        b.send("set speed_bandwidth 20"),
        "ok speed_bandwidth = 20.0000 rad/s (not saved; save to keep)\r\n"
    );
    assert_eq!(b.robot.tuning.map(|t| t.bandwidth_radps), Some(20.0));
}

/// A store that can never write (a part's flash smaller than the storage map) says so before
/// the motors are asked about: `save` names the store even while the robot drives, as the board
/// does on a 512 KiB part before its control loop has run (fil/degraded_boot_test.py).
#[test]
fn save_names_a_store_that_cannot_write_before_the_motors() {
    let mut b = Bench::new();
    b.store.unusable = Some(StoreError::FlashTooSmall(FlashTooSmall {
        part_kib: 512,
        needed_kib: 1024,
    }));
    b.send("drive 0.1 0");
    assert_eq!(
        b.send("save"),
        "err 19: flash error: no storage: this part's flash is smaller than the storage map\r\n"
    );
    assert!(b.store.saved.is_none());
    b.store.unusable = None;
    assert!(b.send("save").starts_with("err 18: "));
}
