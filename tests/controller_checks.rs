//! The controller's checks and its missed periods, against the lagged-motor plant of
//! `tests/controller.rs`: the motor identification's closing period, report and failures; the
//! travel bound of an identification on the floor when periods are missed; missed periods
//! while moving (counted, overrun), and counts that arrive after an erase stall.

#[path = "support/lag_plant.rs"]
mod lag_plant;

use lag_plant::Plant;
use odocal::kinematics::geometry::Geometry;
use odocal::motion::bringup::{CheckKind, CheckReport};
use odocal::motion::controller::{
    Controller, ControllerConfig, Fault, MISS_WEIGHT, MotorCommand, StartError, Status, Wheel,
};
use odocal::motion::identify::{
    IdentifyFailure, IdentifyMode, IdentifyProblem, STOP_TIME_S, TRAVEL_LIMIT_M,
};
use odocal::motion::motor::StopMode;
use odocal::motion::profile::MotionLimits;
use odocal::motion::run::PathKind;
use odocal::session::library::{ControllerLock, LockedController};

fn controller() -> Controller {
    Controller::new(ControllerConfig::new(Geometry::PAPER_NOMINAL, 1000)).unwrap()
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

/// A floor identification at 1 kHz (max_speed 2 m/s) on a board that misses one control period
/// in every `every` (0: none; one in 21 is the highest rate that never latches `overrun`, one
/// in [`MISS_WEIGHT`] + 1), the robot pushed on at 0.5 m/s from its first coast (4 s in: the
/// probe and the first pass's steps have taken it 0.66 m) until the routine stops it. The plant
/// moves through each missed period as through any other. Returns how the identification
/// ended and where the robot would come to rest if stopped then (its centre's distance from the
/// start plus its speed times [`STOP_TIME_S`], the quantity the bound limits), m.
fn pushed_floor_identification(every: u32) -> (Option<Fault>, f64) {
    const PUSH_MPS: f64 = 0.5;
    let mut c = controller();
    c.set_limits(MotionLimits {
        max_speed_mps: 2.0,
        ..MotionLimits::DEFAULT
    })
    .unwrap();
    let mut plant = Plant::new(1000);
    plant.step(&mut c);
    c.start_check(CheckKind::Identify(IdentifyMode::Floor))
        .unwrap();
    let m_per_tick = Geometry::PAPER_NOMINAL.meters_per_tick_right();
    for i in 1..=40_000 {
        let push_mps = if i > 4_000 { PUSH_MPS } else { 0.0 };
        let push = push_mps / m_per_tick * plant.dt;
        if every > 0 && i % every == 0 {
            for w in 0..2 {
                plant.pos[w] += plant.vel[w] * plant.dt + push;
            }
            c.note_missed_periods(1);
        }
        for w in 0..2 {
            plant.pos[w] += push;
        }
        let out = plant.step(&mut c);
        if out.fault.is_some() {
            let at = 0.5 * (plant.pos[0] + plant.pos[1]) * m_per_tick;
            let v = 0.5 * (plant.vel[0] + plant.vel[1]) * m_per_tick + push_mps;
            return (out.fault, at.abs() + v.abs() * STOP_TIME_S);
        }
        assert!(
            c.finished_identification().is_none(),
            "a pushed robot's identification finished"
        );
    }
    panic!("the identification did not end");
}

/// The floor identification's 1 m bound counts every count, those of missed periods included:
/// the controller hands the routine's period logic one period's share of a catch-up, and the
/// travel bound the rest. Pushed on past its planned travel, the robot is stopped where it would
/// come to rest at 1 m from its start, with or without missed periods, within 2 mm (the push and
/// the last step move it ~1 mm a period, two at a catch-up, past the instant the bound is
/// crossed). Counting only each period's share, a miss in 21 let it reach 1.044 m.
#[test]
fn identify_bound_counts_missed_periods() {
    let failure = Some(Fault::Identify(IdentifyFailure {
        wheel: Wheel::Right,
        problem: IdentifyProblem::TooFar,
    }));
    for every in [0, MISS_WEIGHT + 1] {
        let (fault, rest_m) = pushed_floor_identification(every);
        assert_eq!(fault, failure, "a miss in {every}");
        assert!(
            (TRAVEL_LIMIT_M..TRAVEL_LIMIT_M + 0.002).contains(&rest_m),
            "a miss in {every}: would come to rest at {rest_m:.4} m"
        );
    }
}
