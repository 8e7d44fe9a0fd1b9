//! The simulated robot's tests: the slip layer (the model itself is tested in the library,
//! `odocal::plant`), and the host arithmetic against the portable one.

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
