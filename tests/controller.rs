//! Controller API tests against a small plant model: each wheel is the first-order motor the
//! default speed tuning assumes (1 m/s at full duty, τ = 50 ms), integrated exactly per period.
//! The closed-loop behaviour with sub-stepping, slip, true geometry and motor mismatch is
//! tested in `host-sim/tests/closed_loop.rs`.

#[path = "support/arcs.rs"]
mod arcs;

use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::motion::bringup::{CheckKind, CheckReport};
use odocal::motion::button::Press;
use odocal::motion::controller::{
    ButtonAction, ConfigError, Controller, ControllerConfig, DriveError, Fault, MotorCommand,
    MotorsRunning, SetError, StartError, Status, Wheel,
};
use odocal::motion::identify::{IdentifyFailure, IdentifyMode, IdentifyProblem};
use odocal::motion::motor::StopMode;
use odocal::motion::profile::{LimitsError, MotionLimits};
use odocal::motion::routine::RunPlan;
use odocal::motion::run::{Direction, MAX_KNOTS, PathKind};
use odocal::session::library::{ControllerLock, LockedController};

/// Two lagged motors; positions and speeds in ticks and ticks/s.
struct Plant {
    pos: [f64; 2],
    vel: [f64; 2],
    dt: f64,
    /// Largest |duty| the motors act on (a supply limit below 1 saturates them).
    max_duty: f32,
}

impl Plant {
    fn new(rate_hz: u32) -> Self {
        Plant {
            pos: [0.0; 2],
            vel: [0.0; 2],
            dt: 1.0 / f64::from(rate_hz),
            max_duty: 1.0,
        }
    }

    /// Raw counters like the board's: right 32-bit, left 16-bit counting down.
    fn raw(&self) -> (u32, u32) {
        let r = self.pos[0].floor() as i64;
        let l = self.pos[1].floor() as i64;
        (r as u32, u32::from((l as u16).wrapping_neg()))
    }

    fn step(&mut self, c: &mut Controller) -> odocal::motion::controller::StepOutput {
        let (r, l) = self.raw();
        let out = c.step(r, l);
        let duty = match out.command {
            MotorCommand::Duty { right, left } => [right, left],
            MotorCommand::Stop(_) => [0.0, 0.0],
        };
        let k = 1.0 / Geometry::PAPER_NOMINAL.meters_per_tick_right(); // ticks/s at duty 1
        let tau = 0.05;
        let e = (-self.dt / tau).exp();
        for (i, d) in duty.iter().enumerate() {
            let target = k * f64::from(d.clamp(-self.max_duty, self.max_duty));
            self.pos[i] += target * self.dt + (self.vel[i] - target) * tau * (1.0 - e);
            self.vel[i] = target + (self.vel[i] - target) * e;
        }
        out
    }
}

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
        Err(StartError::Path(odocal::motion::routine::PathError::Size))
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
    // 2.3 m/s: 2.3 × 1.5 × 200,000 / (π × 0.150) / 1000 = 1,464.3 counts per period.
    limits.max_speed_mps = 2.3;
    c.set_limits(limits).unwrap();
    assert_eq!(c.config().right_encoder.max_step, 1465);
    assert_eq!(c.config().left_encoder.max_step, 1465);
    // 1,400 counts in one period were a glitch under the 2 m/s bound (1,274) and are within
    // the new one (1,465).
    plant.pos[0] += 1_400.0;
    plant.pos[1] += 1_400.0;
    assert_eq!(plant.step(&mut c).fault, None);
    // The encoders count 1,000,000 counts/s: 2.36 m/s on these wheels. 2.4 m/s is refused,
    // and so is a turn rate whose pivot turns a wheel that fast (12.5 rad/s × 0.1925 m).
    limits.max_speed_mps = 2.4;
    assert_eq!(
        c.set_limits(limits),
        Err(SetError::Limits(LimitsError::BeyondEncoders))
    );
    limits.max_speed_mps = 0.3;
    limits.max_turn_rate_radps = 12.5;
    assert_eq!(
        c.set_limits(limits),
        Err(SetError::Limits(LimitsError::BeyondEncoders))
    );
    // The refused limits changed nothing.
    assert_eq!(c.config().limits.max_speed_mps, 2.3);
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

/// Steps a lifted motor identification on `plant` until its closing period; returns that
/// period's output and the number of periods.
fn identify_until_finished(
    c: &mut Controller,
    plant: &mut Plant,
) -> (odocal::motion::controller::StepOutput, u32) {
    plant.step(c);
    c.start_check(CheckKind::Identify(IdentifyMode::Lifted))
        .unwrap();
    for n in 1..=20_000 {
        let out = plant.step(c);
        assert_eq!(out.fault, None);
        if c.finished_identification().is_some() {
            return (out, n);
        }
    }
    panic!("the identification did not finish");
}

/// The closing period of a motor identification stops the motors and freezes its statistics;
/// the fit runs when the report is taken, and a copy's fit (the firmware's console task, outside
/// the controller's lock) gives the same report.
#[test]
fn identification_is_fitted_when_its_report_is_taken() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    let (closing, periods) = identify_until_finished(&mut c, &mut plant);
    // Four passes of 3 × 400 + 500 + 300 ms at 1 kHz, and a probe per wheel: stairs of 300 ms
    // at 4, 6 and 8 % duty (this plant runs at 1 m/s per unit duty, so 8 % is the first stair
    // past 25 % of the 0.3 m/s cap, 6 % the one before it, moving) and a 300 ms brake; the next
    // period closes the last pass.
    assert_eq!(periods, 4 * 2_000 + 2 * (3 * 300 + 300) + 1);
    // Stopped in the closing period (coasting, as a plausible identification always ended).
    assert_eq!(closing.command, MotorCommand::Stop(StopMode::Coast));
    assert_eq!(
        c.status(),
        Status::Checking(CheckKind::Identify(IdentifyMode::Lifted))
    );
    let frozen = *c.finished_identification().unwrap();
    // Until the report is taken: stopped as when idle, frozen, busy for new motion; a stop
    // or a fault does not lose it.
    for _ in 0..5 {
        assert_eq!(
            plant.step(&mut c).command,
            MotorCommand::Stop(StopMode::Brake)
        );
    }
    assert_eq!(c.finished_identification(), Some(&frozen));
    assert_eq!(
        c.start(PathKind::Line { length_m: 0.5 }),
        Err(StartError::Busy)
    );
    c.abort();
    assert_eq!(c.finished_identification(), Some(&frozen));

    let mut copy = c.clone();
    let report = c.take_check_report();
    let Some(CheckReport::Identify(r)) = report else {
        panic!("{report:?}");
    };
    assert_eq!(c.status(), Status::Idle);
    assert_eq!(c.take_check_report(), None);
    // The plant's motors: 1 m/s at full duty, τ = 50 ms, no dead-band; without noise but
    // through the counters' floor every parameter is within 1 %.
    for fit in [r.right, r.left] {
        let p = fit.params;
        for gain in [p.gain_forward_mps, p.gain_backward_mps] {
            assert!((gain - 1.0).abs() < 0.01, "{p:?}");
        }
        assert!((p.time_constant_s - 0.05).abs() < 0.01 * 0.05, "{p:?}");
        assert!(p.deadband < 0.01, "{p:?}");
    }

    // The console task's way: the fit of a copy between two short locks, the same report.
    let mut locks = 0;
    let mut robot = LockedController(Counting {
        controller: &mut copy,
        locks: &mut locks,
    });
    assert_eq!(
        odocal::session::Robot::take_check_report(&mut robot),
        report
    );
    assert_eq!(odocal::session::Robot::take_check_report(&mut robot), None);
    assert_eq!(locks, 3);
    assert_eq!(copy.status(), Status::Idle);
}

/// A failure only the fit detects (saturation) latches the `identify` fault when the report is
/// taken, and is reported as a failure found in a period is.
#[test]
fn a_failure_the_fit_finds_is_latched_when_the_report_is_taken() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    // The steps aim at 25/50/75 % of the 0.3 m/s cap (7.5, 15, 22.5 % duty on this plant):
    // the top one gains little above the 19 % the supply allows.
    plant.max_duty = 0.19;
    let (closing, _) = identify_until_finished(&mut c, &mut plant);
    assert_eq!(closing.command, MotorCommand::Stop(StopMode::Coast));
    assert_eq!(c.fault(), None);
    let failure = IdentifyFailure {
        wheel: Wheel::Right,
        problem: IdentifyProblem::Saturated,
    };
    assert_eq!(
        c.take_check_report(),
        Some(CheckReport::IdentifyFailed(failure))
    );
    assert_eq!(c.fault(), Some(Fault::Identify(failure)));
    assert_eq!(c.take_check_report(), None);
    assert_eq!(
        plant.step(&mut c).command,
        MotorCommand::Stop(StopMode::Brake)
    );
    assert_eq!(
        c.start(PathKind::Line { length_m: 0.5 }),
        Err(StartError::Faulted)
    );
}

/// A fault latched between the closing period and the report (here an encoder glitch) does not
/// turn a finished identification into a failed one: its statistics were complete.
#[test]
fn a_fault_after_the_closing_period_keeps_the_identification() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    identify_until_finished(&mut c, &mut plant);
    let (r, l) = plant.raw();
    let out = c.step(r.wrapping_add(100_000), l);
    assert!(
        matches!(out.fault, Some(Fault::EncoderGlitch { .. })),
        "{out:?}"
    );
    assert!(matches!(
        c.take_check_report(),
        Some(CheckReport::Identify(_))
    ));
    assert!(matches!(c.fault(), Some(Fault::EncoderGlitch { .. })));
}

/// Lends the controller and counts the locks.
struct Counting<'a> {
    controller: &'a mut Controller,
    locks: &'a mut u32,
}

impl ControllerLock for Counting<'_> {
    fn with_controller<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> R {
        *self.locks += 1;
        f(self.controller)
    }
}

/// Missed control periods: counted and faulted only while the robot moves (an erase stall with
/// the motors stopped is harmless), a gap of 5 ms latches `overrun` and stops the motors.
#[test]
fn missed_periods_while_moving_are_counted_and_a_long_gap_latches_overrun() {
    let mut c = controller();
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    c.note_missed_periods(3_000);
    assert_eq!((c.missed_periods(), c.fault()), (0, None));
    c.start_check(CheckKind::Identify(IdentifyMode::Lifted))
        .unwrap();
    plant.step(&mut c);
    // 4 ms late at 1 kHz: counted, no fault.
    c.note_missed_periods(4);
    assert_eq!((c.missed_periods(), c.fault()), (4, None));
    c.note_missed_periods(5);
    assert_eq!(c.missed_periods(), 9);
    assert_eq!(c.fault(), Some(Fault::Overrun { missed: 5 }));
    assert_eq!(
        plant.step(&mut c).command,
        MotorCommand::Stop(StopMode::Brake)
    );
}

/// A robot rolled back by hand while a flash erase stalls the control task (10 kHz, 0.3 s, no
/// period runs): the counts of the whole stall arrive in one period. They are taken as motion,
/// not a glitch (the limit is 127 counts per period at 10 kHz), and the pose includes them, as
/// long as the left wheel's 16-bit counter cannot have wrapped; beyond half its range (judged on
/// the right wheel's exact 32-bit count) the pose is reported as lost.
#[test]
fn counts_during_an_erase_stall_are_motion_and_the_pose_includes_them() {
    let mut c = Controller::new(ControllerConfig::new(Geometry::PAPER_NOMINAL, 10_000)).unwrap();
    let mut plant = Plant::new(10_000);
    plant.step(&mut c);
    let per_m = 1.0 / Geometry::PAPER_NOMINAL.meters_per_tick_right();
    for (push_m, lost) in [(0.03, false), (-0.05, true)] {
        let x0 = c.pose().to_f64().x_m;
        c.note_missed_periods(3_000);
        plant.pos[0] += push_m * per_m;
        plant.pos[1] += push_m * per_m;
        let out = plant.step(&mut c);
        assert_eq!(out.fault, None, "push {push_m} m");
        let moved = c.pose().to_f64().x_m - x0;
        assert!(
            (moved - push_m).abs() < 1e-4,
            "push {push_m} m: pose moved {moved} m"
        );
        assert_eq!(c.pose_lost(), lost, "push {push_m} m");
        // The next period is an ordinary one again: 200 counts are a glitch.
        assert_eq!(plant.step(&mut c).fault, None);
    }
    plant.pos[0] += 200.0;
    assert!(matches!(
        plant.step(&mut c).fault,
        Some(Fault::EncoderGlitch { .. })
    ));
}

/// A flash erase stalls the control task for 4 s (10 kHz, no period runs) while the robot is
/// pivoted by hand about one wheel: 40,000 counts on the left wheel alone reach its 16-bit
/// counter as −25,536, which the widened check takes as motion, so the pose is marked lost;
/// 20,000 counts on the right wheel alone likewise (the left counter could have wrapped as
/// well). 3,000 counts (7 mm) on either wheel cannot have wrapped: the pose is kept.
#[test]
fn stall_motion_on_either_wheel_marks_the_pose_lost() {
    for (right, left, lost) in [
        (0.0, 40_000.0, true),
        (20_000.0, 0.0, true),
        (3_000.0, -3_000.0, false),
    ] {
        let mut c =
            Controller::new(ControllerConfig::new(Geometry::PAPER_NOMINAL, 10_000)).unwrap();
        let mut plant = Plant::new(10_000);
        plant.step(&mut c);
        c.note_missed_periods(40_000);
        plant.pos[0] += right;
        plant.pos[1] += left;
        let out = plant.step(&mut c);
        assert_eq!(out.fault, None, "right {right}, left {left}");
        assert_eq!(c.pose_lost(), lost, "right {right}, left {left}");
    }
}

/// Missed periods while the robot drives at 0.9 m/s (382 counts per period, glitch limit 1,273
/// at 1 kHz): 3 missed periods bring 4 periods' counts (1,528) at once, which are motion, not an
/// encoder glitch; the speed loop takes a quarter of them per period (its position error moves
/// by less than a period's counts, not by three), and the periods are counted. One miss in 10
/// periods kept up latches `overrun` within 0.2 s; one in 25 never does.
#[test]
fn missed_periods_while_moving_are_overruns() {
    let limits = MotionLimits {
        max_speed_mps: 1.0,
        ..MotionLimits::DEFAULT
    };
    // Drives at 0.9 m/s for `periods`, missing one period every `every` (0: none); the plant
    // moves through each missed period at the speed it had.
    let run = |c: &mut Controller, plant: &mut Plant, periods: u32, every: u32| {
        for i in 1..=periods {
            if every > 0 && i % every == 0 {
                for w in 0..2 {
                    plant.pos[w] += plant.vel[w] * plant.dt;
                }
                c.note_missed_periods(1);
            }
            let _ = c.drive(0.9, 0.0);
            if plant.step(c).fault.is_some() {
                return Some(i);
            }
        }
        None
    };
    let mut c = controller();
    c.set_limits(limits).unwrap();
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    assert_eq!(run(&mut c, &mut plant, 4_000, 0), None);
    let before = c.wheel_errors_ticks();
    for w in 0..2 {
        plant.pos[w] += 3.0 * plant.vel[w] * plant.dt;
    }
    c.note_missed_periods(3);
    let _ = c.drive(0.9, 0.0);
    let out = plant.step(&mut c);
    assert_eq!(out.fault, None, "4 periods' counts at once are motion");
    assert_eq!(c.missed_periods(), 3);
    let after = c.wheel_errors_ticks();
    let per_period = 0.9 / Geometry::PAPER_NOMINAL.meters_per_tick_right() / 1000.0;
    for (b, a) in [(before.0, after.0), (before.1, after.1)] {
        assert!(
            f64::from((a - b).abs()) < per_period,
            "speed loop error {b} -> {a} ticks"
        );
    }
    // One in 25 for 2 s: counted, never latched.
    assert_eq!(run(&mut c, &mut plant, 2_000, 25), None);
    assert_eq!(c.missed_periods(), 3 + 80);
    // One in 10: latched within 0.2 s.
    let latched = run(&mut c, &mut plant, 2_000, 10);
    assert!(latched.is_some_and(|i| i <= 200), "{latched:?}");
    assert!(matches!(c.fault(), Some(Fault::Overrun { .. })));
}
