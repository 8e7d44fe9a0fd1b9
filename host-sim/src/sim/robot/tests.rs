//! The simulated robot's tests: the slip layer (the model itself is tested in the library,
//! `odocal::plant`), the host arithmetic against the portable one, wear and played counts.

use super::*;

#[test]
fn slip_noise_is_reproducible() {
    let mut cfg = SimConfig::new(Geometry::PAPER_NOMINAL, 1000);
    cfg.slip_sigma = 0.01;
    let run = |cfg: SimConfig| {
        let mut sim = Sim::new(cfg);
        sim.apply(MotorCommand::Duty {
            right: 0.3,
            left: 0.3,
        });
        for _ in 0..500 {
            sim.advance();
        }
        sim.true_pose()
    };
    assert_eq!(run(cfg), run(cfg));
    let mut other = cfg;
    other.seed = 2;
    assert_ne!(run(cfg), run(other));
}

#[test]
fn host_arithmetic_follows_the_portable_model() {
    // The same robot on SSE2 lanes with the platform's exp/sin_cos and on plain pairs with
    // libm: a closed square with turns (the general pass included) ends within an ulp-level
    // difference of the transcendental functions.
    use odocal::plant::{Portable, SimRobot};
    let mut cfg = SimConfig::new(Geometry::PAPER_NOMINAL.with_factors(0.995, 1.01, 1.0), 100);
    cfg.robot.motor.time_constant_s = 0.03;
    let mut host = Sim::new(cfg);
    let mut portable: SimRobot<Portable> = SimRobot::new(cfg.robot);
    for (i, duty) in [(0.5f32, 0.45f32), (1.0, -0.5), (-0.2, 0.3)]
        .iter()
        .enumerate()
    {
        let command = MotorCommand::Duty {
            right: duty.0,
            left: duty.1,
        };
        host.apply(command);
        portable.apply(command);
        for _ in 0..200 * (i + 1) {
            host.advance();
            portable.advance();
        }
    }
    let (h, p) = (host.true_pose(), portable.true_pose());
    assert!(h.theta_rad.abs() > 1.0, "{h:?}");
    assert!(
        (h.x_m - p.x_m).abs() < 1e-12 && (h.y_m - p.y_m).abs() < 1e-12,
        "{h:?} {p:?}"
    );
    assert!((h.theta_rad - p.theta_rad).abs() < 1e-12, "{h:?} {p:?}");
    assert_eq!(host.counts(), portable.counts());
    assert_eq!(host.raw(), portable.raw());
}

#[test]
fn a_wear_changes_the_wheels_not_the_pose() {
    let mut sim = Sim::new(sim_config(1.0, 1.0, 0.0, 1, 1000));
    let forward = MotorCommand::Duty {
        right: 0.3,
        left: 0.3,
    };
    sim.apply(forward);
    let turn = |sim: &mut Sim| {
        let before = sim.true_pose().theta_rad;
        for _ in 0..500 {
            sim.advance();
        }
        sim.true_pose().theta_rad - before
    };
    turn(&mut sim);
    // At speed, the left motor 2 % weaker: the robot turns left.
    let unworn = turn(&mut sim);
    let (pose, counts, speeds) = (sim.true_pose(), sim.counts(), sim.wheel_speeds_mps());
    let wear = parse_wear("0.5:0.98:1.02").unwrap();
    sim.apply_wear(&wear);
    assert_eq!((sim.true_pose(), sim.counts()), (pose, counts));
    assert_eq!(sim.config().true_geometry, true_geometry(0.98, 1.02));
    // The wheels turn as fast as before: the right one, now 1 % smaller, rolls slower, the left
    // one faster, and the robot turns right of where it turned.
    let (r, l) = sim.wheel_speeds_mps();
    assert!(r < speeds.0 && l > speeds.1, "{speeds:?} → {:?}", (r, l));
    let worn = turn(&mut sim);
    assert!(unworn > 5e-3 && worn < unworn - 5e-3, "{unworn} → {worn}");
}

#[test]
fn wear_options_name_what_is_wrong() {
    assert_eq!(
        parse_wear("600:0.990:1.010"),
        Ok(Wear {
            at_s: 600.0,
            ed: 0.99,
            eb: 1.01
        })
    );
    for (bad, says) in [
        ("600:0.99", "expected T:ED:EB"),
        ("600:x:1", "ED \"x\" is not a number"),
        ("-1:1:1", "T -1 s is not within"),
        ("1:0:1", "must be positive"),
        (
            "1:1:100",
            "make no robot: wheelbase must be within 0.01..5 m",
        ),
    ] {
        let e = parse_wear(bad).unwrap_err();
        assert!(e.contains(says), "{bad}: {e}");
        assert!(e.ends_with("(e.g. --wear 600:0.990:1.010)") || !e.contains("T:ED:EB"));
    }
}

#[test]
fn played_counts_reach_the_controller_and_the_wheels_stay() {
    let mut sim = Sim::new(sim_config(1.0, 1.0, 0.0, 1, 1000));
    let mut controller = default_controller(Geometry::PAPER_NOMINAL, 1000).unwrap();
    sim.step(&mut controller);
    // The first call holds the wheels and takes 5, 5 as what the counters show now.
    sim.play_counts(WheelTicks::new(5, 5));
    sim.apply(MotorCommand::Duty {
        right: 1.0,
        left: 1.0,
    });
    // Past the left counter's 16-bit wrap (it starts at 300, counting down as the wheel rolls
    // forward), then the right wheel backwards, past the right counter's 32-bit wrap (it
    // starts 20,000 counts below it).
    for k in 1..=400i64 {
        sim.play_counts(WheelTicks::new(5 + 70 * k, 5 + 3 * k));
        sim.step(&mut controller);
    }
    assert_eq!(controller.totals(), WheelTicks::new(70 * 400, 3 * 400));
    for k in 1..=400i64 {
        sim.play_counts(WheelTicks::new(5 + 70 * 400 - 70 * k, 5 + 1200));
        sim.step(&mut controller);
    }
    assert_eq!(controller.totals(), WheelTicks::new(0, 1200));
    assert_eq!(sim.true_pose(), PoseF64::default());
    assert_eq!(sim.wheel_speeds_mps(), (0.0, 0.0));
}
