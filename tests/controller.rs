//! Controller API tests against a small plant model: each wheel is the first-order motor the
//! default speed tuning assumes (1 m/s at full duty, τ = 50 ms), integrated exactly per period.
//! The closed-loop behaviour with sub-stepping, slip, true geometry and motor mismatch is
//! tested in `host-sim/tests/closed_loop.rs`.

#[path = "support/arcs.rs"]
mod arcs;

use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::motion::button::Press;
use odocal::motion::controller::{
    ButtonAction, ConfigError, Controller, ControllerConfig, DriveError, Fault, MotorsRunning,
    SetError, StartError, Status, Wheel,
};
use odocal::motion::profile::{LimitsError, MotionLimits};
use odocal::motion::routine::RunPlan;
use odocal::motion::run::{Direction, MAX_KNOTS, PathKind};

#[path = "support/lag_plant.rs"]
mod lag_plant;

use lag_plant::Plant;

fn controller() -> Controller {
    Controller::new(ControllerConfig::new(Geometry::PAPER_NOMINAL, 1000)).unwrap()
}

#[test]
fn config_is_validated() {
    let g = Geometry::PAPER_NOMINAL;
    assert_eq!(
        Controller::new(ControllerConfig::new(g, 500)).err(),
        Some(ConfigError::Rate)
    );
    assert_eq!(
        Controller::new(ControllerConfig::new(g, 20_000)).err(),
        Some(ConfigError::Rate)
    );
    // Within 1..10 kHz but not a whole number of microseconds per period.
    assert_eq!(
        Controller::new(ControllerConfig::new(g, 3_000)).err(),
        Some(ConfigError::Rate)
    );
    let mut cfg = ControllerConfig::new(g, 1000);
    cfg.limits.max_accel_mps2 = 0.0;
    assert!(matches!(
        Controller::new(cfg).err(),
        Some(ConfigError::Limits(_))
    ));
    let mut cfg = ControllerConfig::new(g, 1000);
    cfg.geometry.wheelbase_m = f64::NAN;
    assert!(matches!(
        Controller::new(cfg).err(),
        Some(ConfigError::Geometry(_))
    ));
    let mut cfg = ControllerConfig::new(g, 1000);
    cfg.deadman_ms = 0;
    assert_eq!(Controller::new(cfg).err(), Some(ConfigError::Deadman));
}

#[test]
fn refusals_while_not_ready_busy_or_faulted() {
    let mut c = controller();
    let line = PathKind::Line { length_m: 0.5 };
    assert_eq!(c.start(line), Err(StartError::NotReady));
    assert_eq!(c.drive(0.1, 0.0), Err(DriveError::NotReady));
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    assert_eq!(
        c.start(PathKind::Line { length_m: f64::NAN }),
        Err(StartError::Path(odocal::motion::path::PathError::Size))
    );
    c.start(line).unwrap();
    assert_eq!(c.start(line), Err(StartError::Busy));
    assert_eq!(c.drive(0.1, 0.0), Err(DriveError::Busy));
    assert_eq!(c.set_geometry(Geometry::PAPER_NOMINAL), Err(SetError::Busy));
    assert_eq!(c.set_limits(MotionLimits::DEFAULT), Err(SetError::Busy));
    assert!(matches!(c.status(), Status::Running { segment: 0, .. }));
    c.abort();
    assert_eq!(c.status(), Status::Idle);
    assert_eq!(c.drive(f32::NAN, 0.0), Err(DriveError::NotFinite));
}

#[test]
fn line_run_produces_a_record_once() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    c.start(PathKind::Line { length_m: 0.5 }).unwrap();
    let mut periods = 0;
    while c.status() != Status::Idle {
        plant.step(&mut c);
        periods += 1;
        assert!(periods < 10_000, "the line never finished");
    }
    let record = c.take_finished_run().expect("a record");
    assert!(c.take_finished_run().is_none());
    assert_eq!(record.knots.len(), MAX_KNOTS);
    assert_eq!(record.path, PathKind::Line { length_m: 0.5 });
    // The odometry end pose in the run's frame: 0.5 m ahead, within the 20-tick settle
    // tolerance (47 µm).
    assert!((record.odometry_end.x_m - 0.5).abs() < 5e-5, "{record:?}");
    assert!(record.odometry_end.y_m.abs() < 1e-6);
}

/// Drives a 0.2 m line to its end (the record not taken).
fn drive_line(c: &mut Controller, plant: &mut Plant) {
    c.start(PathKind::Line { length_m: 0.2 }).unwrap();
    let mut periods = 0;
    while c.status() != Status::Idle {
        plant.step(c);
        periods += 1;
        assert!(periods < 10_000, "the line never finished");
    }
}

#[test]
fn a_completed_run_waits_for_its_record_through_aborts_new_geometry_and_a_new_run() {
    let g = Geometry::PAPER_NOMINAL;
    let mut c = controller();
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    drive_line(&mut c, &mut plant);
    // Completed and not taken: idle, and an abort or a drive does not discard it.
    assert!(c.drive(0.0, 0.0).is_ok());
    c.abort();
    // A new geometry does not reach the record of a run driven with the old one.
    let calibrated = g.with_factors(0.995, 1.01, 1.0);
    c.set_geometry(calibrated).unwrap();
    // A second run while the first record waits: both come out, the older first.
    drive_line(&mut c, &mut plant);
    let first = c.take_finished_run().expect("the first record");
    let second = c.take_finished_run().expect("the second record");
    assert!(c.take_finished_run().is_none());
    assert_eq!(first.geometry, g);
    assert_eq!(second.geometry, calibrated);
    for r in [&first, &second] {
        assert!((r.odometry_end.x_m - 0.2).abs() < 5e-5, "{r:?}");
    }
}

#[test]
fn a_run_reports_its_end_pose_in_its_own_frame_after_a_turn_and_an_odometry_reset() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    // Turn the robot in place (about 0.6 rad) and let it come to rest: the odometry frame and
    // the next run's frame now differ by a rotation.
    let mut periods = 0;
    while periods < 2000 {
        if periods < 1000 {
            c.drive(0.0, 0.6).unwrap();
        }
        plant.step(&mut c);
        periods += 1;
    }
    let heading = c.pose().to_f64().theta_rad;
    assert!(heading > 0.3, "turned {heading} rad");
    // A line with the odometry reset half-way: the run keeps its start frame.
    c.start(PathKind::Line { length_m: 0.2 }).unwrap();
    for _ in 0..600 {
        plant.step(&mut c);
    }
    c.reset_odometry();
    while c.status() != Status::Idle {
        plant.step(&mut c);
    }
    let r = c.take_finished_run().expect("a record");
    // 0.2 m ahead within the 20-tick settle tolerance (47 µm); no sideways error beyond the
    // wheels' tracking (a few ticks).
    assert!((r.odometry_end.x_m - 0.2).abs() < 5e-5, "{r:?}");
    assert!(r.odometry_end.y_m.abs() < 5e-5, "{r:?}");
    assert!(r.odometry_end.theta_rad.abs() < 1e-3, "{r:?}");
}

#[test]
fn abort_stops_in_the_next_period() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    c.start(PathKind::Square {
        direction: Direction::Cw,
        side_m: 1.0,
    })
    .unwrap();
    for _ in 0..1500 {
        assert!(!plant.step(&mut c).command.is_stop());
    }
    c.abort();
    assert!(plant.step(&mut c).command.is_stop());
}

#[test]
fn deadman_counts_control_periods() {
    for rate in [1000, 4000] {
        let mut c = Controller::new(ControllerConfig::new(Geometry::PAPER_NOMINAL, rate)).unwrap();
        let mut plant = Plant::new(rate);
        plant.step(&mut c);
        c.drive(0.2, 0.0).unwrap();
        let mut driving = 0;
        while !plant.step(&mut c).command.is_stop() {
            driving += 1;
            assert!(driving <= rate, "no stop");
        }
        // 500 ms of driving periods; the next period stops.
        assert_eq!(driving, rate / 2, "rate {rate}");
        assert_eq!(c.status(), Status::Idle);
    }
}

#[test]
fn glitch_latches_and_stops_in_the_same_period() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    c.drive(0.2, 0.0).unwrap();
    for _ in 0..100 {
        plant.step(&mut c);
    }
    plant.pos[0] += 1e6;
    let out = plant.step(&mut c);
    assert!(out.command.is_stop());
    assert!(matches!(
        out.fault,
        Some(Fault::EncoderGlitch {
            wheel: Wheel::Right,
            ..
        })
    ));
    assert_eq!(c.drive(0.2, 0.0), Err(DriveError::Faulted));
    c.clear_fault();
    assert_eq!(c.status(), Status::Idle);
    c.drive(0.2, 0.0).unwrap();
}

#[test]
fn glitch_limit_follows_a_new_geometry() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    // 2 m/s of a 150 mm wheel with 200,000 counts/rev at 1 kHz, +50 %: 1,274 counts per period.
    let before = c.config().right_encoder.max_step;
    assert_eq!(before, 1274);
    // Ten times the resolution: ten times the counts for the same speed. The encoders count
    // 1,000,000 counts/s, 0.236 m/s on these wheels: the limits come down first.
    let mut fine = Geometry::PAPER_NOMINAL;
    fine.counts_per_rev = 2_000_000;
    assert_eq!(
        c.set_geometry(fine),
        Err(SetError::Limits(LimitsError::BeyondEncoders))
    );
    let mut slow = MotionLimits::DEFAULT;
    slow.max_speed_mps = 0.2;
    c.set_limits(slow).unwrap();
    c.set_geometry(fine).unwrap();
    assert_eq!(c.config().right_encoder.max_step, 12_733);
    assert_eq!(c.config().left_encoder.max_step, 12_733);
    // A jump of 5,000 counts in one period was a glitch before; it is a legal 1.2 m/s now.
    plant.pos[0] += 5_000.0;
    plant.pos[1] += 5_000.0;
    let out = plant.step(&mut c);
    assert_eq!(out.fault, None);
}

/// The glitch limit follows the motion limits above its 2 m/s floor, and limits the encoders
/// cannot count are refused: a legal `max_speed` never latches `encoder-glitch` mid-run.
#[test]
fn glitch_limit_follows_the_motion_limits_and_refuses_what_the_encoders_cannot_count() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    // Up to 2 m/s the floor holds: 1,274 counts per period (2 m/s on 150 mm, +50 %).
    let mut limits = MotionLimits::DEFAULT;
    limits.max_speed_mps = 1.5;
    c.set_limits(limits).unwrap();
    assert_eq!(c.config().right_encoder.max_step, 1274);
    // A pivot turns each wheel at ω·b/2: 9.2 rad/s on a 0.5 m wheelbase is 2.3 m/s, 2.3 × 1.5 ×
    // 200,000 / (π × 0.150) / 1000 = 1,464.3 counts per period.
    let mut wide = Geometry::PAPER_NOMINAL;
    wide.wheelbase_m = 0.5;
    c.set_geometry(wide).unwrap();
    assert_eq!(c.config().right_encoder.max_step, 1274);
    limits.max_turn_rate_radps = 9.2;
    c.set_limits(limits).unwrap();
    assert_eq!(c.config().right_encoder.max_step, 1465);
    assert_eq!(c.config().left_encoder.max_step, 1465);
    // 1,400 counts in one period were a glitch under the 2 m/s bound (1,274) and are within
    // the new one (1,465).
    plant.pos[0] += 1_400.0;
    plant.pos[1] += 1_400.0;
    assert_eq!(plant.step(&mut c).fault, None);
    // The encoders count 1,000,000 counts/s: 2.36 m/s on these wheels. A pivot at 9.6 rad/s
    // (2.4 m/s at each wheel) is refused.
    limits.max_turn_rate_radps = 9.6;
    assert_eq!(
        c.set_limits(limits),
        Err(SetError::Limits(LimitsError::BeyondEncoders))
    );
    // The refused limits changed nothing.
    assert_eq!(c.config().limits.max_turn_rate_radps, 9.2);
    assert_eq!(c.config().right_encoder.max_step, 1465);
}

#[test]
fn motors_stopped_after_a_tenth_of_a_second_at_rest() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    // The first step synchronises the encoders; 100 motionless periods follow it.
    for _ in 0..100 {
        plant.step(&mut c);
    }
    assert!(c.motors_stopped().is_err());
    plant.step(&mut c);
    assert!(c.motors_stopped().is_ok());
    c.drive(0.2, 0.0).unwrap();
    // The refusal every flash write gets while anything moves (`err 18`).
    assert_eq!(c.motors_stopped(), Err(MotorsRunning));
}

/// An encoder edge jittering by a count at rest (2.4 µm) does not block a save; a wheel rolling
/// at 20 mm/s (8.5 counts per period) leaves the 1 mm stillness bound after 50 periods and then
/// counts as moving.
#[test]
fn encoder_jitter_is_still_but_a_slow_roll_is_motion() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    for k in 0..300 {
        plant.pos[0] = if k % 2 == 0 { 0.5 } else { 1.5 };
        plant.pos[1] = if k % 3 == 0 { -0.5 } else { 0.5 };
        plant.step(&mut c);
    }
    assert!(
        c.motors_stopped().is_ok(),
        "jitter of one count counted as motion"
    );
    let per_period = 0.020 / Geometry::PAPER_NOMINAL.meters_per_tick_right() / 1000.0;
    let mut stopped_after_roll = 0;
    for _ in 0..500 {
        plant.pos[0] += per_period;
        plant.step(&mut c);
        if c.motors_stopped().is_ok() {
            stopped_after_roll += 1;
        }
    }
    // Only the first millimetre (50 periods, +1 for the count quantisation) may look still.
    assert!(
        stopped_after_roll <= 51,
        "{stopped_after_roll} periods looked still"
    );
    assert!(c.motors_stopped().is_err());
}

#[test]
fn new_geometry_applies_and_pose_continues() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    for k in 0..2000 {
        if k % 100 == 0 {
            c.drive(0.3, 0.0).unwrap();
        }
        plant.step(&mut c);
    }
    let before = c.pose().to_f64();
    let g = Geometry::PAPER_NOMINAL.with_factors(0.99, 1.02, 1.0);
    assert_eq!(c.set_geometry(g), Err(SetError::Busy));
    while !plant.step(&mut c).command.is_stop() {}
    let rest = c.pose().to_f64();
    assert!(rest.x_m > before.x_m);
    c.set_geometry(g).unwrap();
    assert_eq!(c.pose().to_f64(), rest);
    assert_eq!(c.config().geometry, g);
}

/// Catches a calibration that is stored but not applied to the running odometry (the new
/// geometry's `Odometry` not installed by `set_geometry`, so later ticks are still converted
/// with the old wheels and wheelbase), and one that moves or restarts the pose when applied.
/// The robot drives to a pose with the nominal geometry, the calibration (`E_d` 0.99, `E_b`
/// 1.02) is applied at rest, and it drives an arc of ~0.9 m turning ~1.5 rad; the pose is
/// compared with the independent arc model (`support/arcs.rs`) of the new geometry driving the
/// ticks the controller read, from the pose it had when the calibration was applied.
#[test]
fn a_calibration_applied_at_rest_converts_the_next_drive_with_the_new_geometry() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    let read =
        |plant: &Plant| WheelTicks::new(plant.pos[0].floor() as i64, plant.pos[1].floor() as i64);
    // Drive to a pose off the origin and off the x axis, then wait for rest.
    for k in 0..1500 {
        if k % 100 == 0 {
            c.drive(0.3, 0.4).unwrap();
        }
        plant.step(&mut c);
    }
    while !plant.step(&mut c).command.is_stop() {}
    // The plant's lag lets the wheels roll on after the stop: wait until they are still, so
    // that no tick the old geometry should convert is left for the new one.
    while plant.vel[0].abs() + plant.vel[1].abs() > 1e-3 {
        plant.step(&mut c);
    }
    // The counts the controller reads in its last period before the calibration: the first knot.
    let last_read = read(&plant);
    plant.step(&mut c);
    let start = c.pose().to_f64();
    assert!(start.x_m > 0.2 && start.y_m > 0.05, "{start:?}");
    let g = Geometry::PAPER_NOMINAL.with_factors(0.99, 1.02, 1.0);
    c.set_geometry(g).unwrap();
    assert_eq!(
        c.pose().to_f64(),
        start,
        "applying a calibration moves no pose"
    );
    let mut knots = vec![last_read];
    for k in 0..3000 {
        if k < 2000 && k % 100 == 0 {
            c.drive(0.3, 0.5).unwrap();
        }
        knots.push(read(&plant));
        plant.step(&mut c);
    }
    let end = c.pose().to_f64();
    let model = arcs::Robot::of(&g).drive(start, &knots);
    let (dx, dy, dth) = (
        end.x_m - model.x_m,
        end.y_m - model.y_m,
        end.theta_rad - model.theta_rad,
    );
    let nominal = arcs::Robot::of(&Geometry::PAPER_NOMINAL).drive(start, &knots);
    println!(
        "end {end:?}, model on the new geometry {model:?} (off by {:.3e} m, {dth:.2e} rad), \
         on the old one {nominal:?}",
        dx.hypot(dy)
    );
    assert!(end.distance_to(&start) > 0.5, "it drove: {end:?}");
    // Measured: 2.9e-10 m and 3e-15 rad off (the Q40 pose's per-period rounding over 3000
    // periods; the heading is a function of the tick totals). Bounds at 10× that; converting
    // with the old geometry is 11.7 mm and 0.039 rad off.
    assert!(dx.hypot(dy) < 3e-9, "{dx}, {dy}");
    assert!(dth.abs() < 1e-13, "{dth}");
}

#[test]
fn button_starts_alternating_runs_and_aborts() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    let mut plan = RunPlan::new(1.0, Direction::Cw);
    let square = |direction| PathKind::Square {
        direction,
        side_m: 1.0,
    };
    assert_eq!(
        c.on_press(Press::Short, &mut plan),
        ButtonAction::Started(square(Direction::Cw))
    );
    // Busy: refused, and the plan does not advance.
    assert_eq!(
        c.on_press(Press::Short, &mut plan),
        ButtonAction::StartRefused(StartError::Busy)
    );
    assert_eq!(c.on_press(Press::Long, &mut plan), ButtonAction::Aborted);
    assert!(plant.step(&mut c).command.is_stop());
    assert_eq!(
        c.on_press(Press::Short, &mut plan),
        ButtonAction::Started(square(Direction::Ccw))
    );
    // A glitch latches a fault: the first short press clears it, the next one starts.
    plant.pos[1] += 1e6;
    assert!(plant.step(&mut c).fault.is_some());
    assert_eq!(
        c.on_press(Press::Short, &mut plan),
        ButtonAction::ClearedFault
    );
    assert_eq!(
        c.on_press(Press::Short, &mut plan),
        ButtonAction::Started(square(Direction::Cw))
    );
}

/// Seconds from the first period after `start` until `done` holds, stepping `plant` (with
/// `each` applied to the plant before every period); at most 10 s.
fn seconds_until(
    c: &mut Controller,
    plant: &mut Plant,
    rate: u32,
    mut each: impl FnMut(&mut Plant),
    done: impl Fn(&Controller, &odocal::motion::controller::StepOutput) -> bool,
) -> f64 {
    let mut periods = 0u32;
    loop {
        each(plant);
        let out = plant.step(c);
        periods += 1;
        if done(c, &out) {
            return f64::from(periods) / f64::from(rate);
        }
        assert!(periods < 10 * rate, "not done after 10 s at {rate} Hz");
    }
}

/// The same routines at 1 kHz and 10 kHz: every time the controller keeps (deadman, stall,
/// following error, the routine's own profile and settling) comes out the same in seconds,
/// because each is converted from seconds with the rate, never counted as 1 kHz periods.
///
/// Tolerances: a time counted in periods is exact to one period (1 ms at 1 kHz); the deadman and
/// the stall are pure period counts (500 ms, 300 ms after the wheel stops). The following error
/// and the line's duration also depend on how the loop tracks, which a 10× finer period changes
/// slightly. The reversed wheel's error grows through the loop's positive feedback until the
/// duty saturates, and a period of sample-and-hold delay (1 ms vs 0.1 ms) changes that growth a
/// little: measured 275.0 vs 272.8 ms; the bound, 5 ms (2 % of it), is the 100 ms count's
/// period plus that. The line ends when both wheels have settled within 20 ticks for 50 ms
/// after the same profile; 10 ms covers the tracking lag difference.
#[test]
fn timed_faults_take_the_same_seconds_at_1_and_10_khz() {
    let g = Geometry::PAPER_NOMINAL;
    let at = |rate: u32| {
        let mut c = Controller::new(ControllerConfig::new(g, rate)).unwrap();
        let mut plant = Plant::new(rate);
        plant.step(&mut c);
        (c, plant)
    };
    let mut times = Vec::new();
    for rate in [1_000u32, 10_000] {
        // Deadman: one `drive`, then nothing.
        let (mut c, mut plant) = at(rate);
        c.drive(0.2, 0.0).unwrap();
        let deadman = seconds_until(&mut c, &mut plant, rate, |_| {}, |_, o| o.command.is_stop());
        // The line's duration (same profile, settled the same way).
        let (mut c, mut plant) = at(rate);
        c.start(PathKind::Line { length_m: 0.5 }).unwrap();
        let line = seconds_until(
            &mut c,
            &mut plant,
            rate,
            |_| {},
            |c, _| c.status() == Status::Idle,
        );
        // Stall: the right wheel blocked at cruise speed (1.5 s into a 2 m line).
        let (mut c, mut plant) = at(rate);
        c.start(PathKind::Line { length_m: 2.0 }).unwrap();
        for _ in 0..(3 * rate / 2) {
            plant.step(&mut c);
        }
        let blocked_at = plant.pos[0];
        let stall = seconds_until(
            &mut c,
            &mut plant,
            rate,
            |p| {
                p.pos[0] = blocked_at;
                p.vel[0] = 0.0;
            },
            |_, o| o.fault.is_some(),
        );
        assert_eq!(
            c.fault(),
            Some(Fault::Stall {
                wheel: Wheel::Right
            }),
            "{rate} Hz"
        );
        // Following error: the right motor wired reversed (the controller is told the standard
        // wiring), so the loop drives that wheel away from its reference.
        let mut cfg = ControllerConfig::new(g, rate);
        cfg.wiring.motor_right_reversed = true;
        let mut c = Controller::new(cfg).unwrap();
        let mut plant = Plant::new(rate);
        plant.step(&mut c);
        c.start(PathKind::Line { length_m: 2.0 }).unwrap();
        let following = seconds_until(&mut c, &mut plant, rate, |_| {}, |_, o| o.fault.is_some());
        assert!(
            matches!(
                c.fault(),
                Some(Fault::FollowingError {
                    wheel: Wheel::Right,
                    ..
                })
            ),
            "{rate} Hz: {:?}",
            c.fault()
        );
        println!(
            "{rate:>5} Hz: deadman {deadman:.4} s, line 0.5 m {line:.4} s, stall {stall:.4} s, \
             following error {following:.4} s"
        );
        // Counted times, exact to a period at each rate: 500 ms driving, stop in the next.
        let period = 1.0 / f64::from(rate);
        assert!(
            (deadman - (0.5 + period)).abs() < 1e-9,
            "{rate} Hz deadman {deadman}"
        );
        assert!(
            (stall - 0.3).abs() <= 2.0 * period + 1e-9,
            "{rate} Hz stall {stall}"
        );
        times.push((deadman, line, stall, following));
    }
    let (a, b) = (times[0], times[1]);
    assert!((a.0 - b.0).abs() <= 1e-3 + 1e-9, "deadman {a:?} vs {b:?}");
    assert!((a.2 - b.2).abs() <= 2e-3 + 1e-9, "stall {a:?} vs {b:?}");
    assert!((a.3 - b.3).abs() <= 5e-3, "following error {a:?} vs {b:?}");
    assert!((a.1 - b.1).abs() <= 10e-3, "line {a:?} vs {b:?}");
}

/// `set_rate` on an idle controller converts what it counts in periods: after switching from
/// 1 kHz to 10 kHz the deadman still stops the motors 500 ms after the last `drive`, and the
/// glitch limit (counts per period) is a tenth of what it was.
#[test]
fn set_rate_retimes_an_idle_controller() {
    let g = Geometry::PAPER_NOMINAL;
    let mut c = controller();
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    let step_1k = c.config().right_encoder.max_step;
    assert_eq!(c.set_rate(3_000), Err(SetError::Rate));
    c.set_rate(10_000).unwrap();
    assert_eq!(c.config().rate_hz, 10_000);
    // 2 m/s of a 150 mm wheel (+50 %) per 0.1 ms: a tenth of the 1 kHz limit (rounded).
    assert!(c.config().right_encoder.max_step.abs_diff(step_1k / 10) <= 1);
    assert_eq!(
        c.config().settle,
        ControllerConfig::new(g, 10_000).settle,
        "settling times follow the rate"
    );
    let mut plant = Plant { dt: 1e-4, ..plant };
    c.drive(0.2, 0.0).unwrap();
    let t = seconds_until(
        &mut c,
        &mut plant,
        10_000,
        |_| {},
        |_, o| o.command.is_stop(),
    );
    assert!((t - 0.5001).abs() < 1e-9, "deadman {t} s");
    // Only while idle.
    c.drive(0.2, 0.0).unwrap();
    assert_eq!(c.set_rate(1_000), Err(SetError::Busy));
}
