//! The robot model's tests: counters, motors, and the exactness of the true pose.

use super::*;
use crate::kinematics::geometry::Geometry;
use crate::motion::controller::MotorCommand;
use crate::motion::wiring::Wiring;

#[test]
fn floor_i64_is_floor() {
    let cases = [
        0.0,
        -0.0,
        0.5,
        -0.5,
        1.0,
        -1.0,
        -1.0 - f64::EPSILON,
        2.0f64.powi(52) + 0.5,
        -(2.0f64.powi(52) + 0.5),
        2.0f64.powi(53) + 2.0,
        -(2.0f64.powi(62)),
        1e30,
        -1e30,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NAN,
        f64::MIN_POSITIVE,
        -f64::MIN_POSITIVE,
        123_456_789.999_999_99,
        -123_456_789.000_000_01,
    ];
    for x in cases {
        assert_eq!(floor_i64(x), x.floor() as i64, "{x:e}");
    }
}

#[test]
fn open_loop_motor_reaches_its_gain_and_counts_wrap() {
    let g = Geometry::PAPER_NOMINAL;
    let mut robot: SimRobot = SimRobot::new(RobotConfig::new(g, 1000));
    robot.apply(MotorCommand::Duty {
        right: 0.3,
        left: 0.3,
    });
    for _ in 0..1000 {
        robot.advance();
    }
    let (vr, vl) = robot.wheel_speeds_mps();
    // 20 time constants: the lag has settled to 1e-9 of the target.
    assert!((vr - 0.3).abs() < 1e-6, "{vr}");
    assert!((vl - 0.3 * 0.98).abs() < 1e-6, "{vl}");
    let (cr, cl) = robot.counts();
    let (raw_r, raw_l) = robot.raw();
    // The right counter started 20,000 below its wrap and has wrapped.
    assert_eq!(raw_r, (u32::MAX - 20_000).wrapping_add(cr as u32));
    assert!(cr > 20_000);
    assert_eq!(raw_l, u32::from(300u16.wrapping_sub(cl as u16)));
    assert_eq!(robot.periods(), 1000);
}

#[test]
fn brake_stops_faster_than_coast() {
    let g = Geometry::PAPER_NOMINAL;
    let speed_after_stop = |mode| {
        let mut robot: SimRobot = SimRobot::new(RobotConfig::new(g, 1000));
        robot.apply(MotorCommand::Duty {
            right: 0.5,
            left: 0.5,
        });
        for _ in 0..500 {
            robot.advance();
        }
        robot.apply(MotorCommand::Stop(mode));
        // 50 ms: two brake time constants (e^-2), a quarter of a coasting one (e^-0.25).
        for _ in 0..50 {
            robot.advance();
        }
        robot.wheel_speeds_mps().0
    };
    let braked = speed_after_stop(crate::motion::motor::StopMode::Brake);
    let coasted = speed_after_stop(crate::motion::motor::StopMode::Coast);
    assert!((braked - 0.5 * (-2.0f64).exp()).abs() < 1e-3, "{braked}");
    assert!((coasted - 0.5 * (-0.25f64).exp()).abs() < 1e-3, "{coasted}");
}

#[test]
fn a_reversed_motor_and_encoder_cancel_in_the_counts() {
    let g = Geometry::PAPER_NOMINAL;
    let mut cfg = RobotConfig::new(g, 1000);
    cfg.wiring = Wiring {
        motor_right_reversed: true,
        encoder_right_reversed: true,
        ..Wiring::STANDARD
    };
    let run = |cfg: RobotConfig| {
        let mut robot: SimRobot = SimRobot::new(cfg);
        robot.apply(MotorCommand::Duty {
            right: 0.3,
            left: 0.3,
        });
        for _ in 0..200 {
            robot.advance();
        }
        robot
    };
    let (standard, miswired) = (run(RobotConfig::new(g, 1000)), run(cfg));
    // The right wheel turns backward: the robot spins instead of driving straight...
    assert!(miswired.wheel_speeds_mps().0 < -0.2);
    assert!(miswired.true_pose().theta_rad < -0.1);
    // ...and its reversed encoder reports that backward turn as forward counts.
    let (r_std, _) = standard.counts();
    let (r_mis, _) = miswired.counts();
    assert_eq!(r_mis, -r_std - 1, "floor of the negated rotation");
    assert_eq!(
        miswired.raw().0,
        (u32::MAX - 20_000).wrapping_add((-r_mis) as u32)
    );
}

#[test]
fn true_pose_of_a_constant_arc_is_exact() {
    let g = Geometry::PAPER_NOMINAL;
    let mut cfg = RobotConfig::new(g, 1000);
    // Instant speed: a single constant-curvature arc.
    cfg.motor.time_constant_s = 0.0;
    cfg.motor.time_constant_left_s = 0.0;
    let mut robot: SimRobot = SimRobot::new(cfg);
    robot.apply(MotorCommand::Duty {
        right: 0.3,
        left: 0.1,
    });
    for _ in 0..5000 {
        robot.advance();
    }
    // The duties as the motors see them (f32 → f64).
    let vr = f64::from(0.3f32) * cfg.motor.gain_right_radps * 0.075;
    let vl = f64::from(0.1f32) * cfg.motor.gain_left_radps * 0.075;
    let theta = (vr - vl) * 5.0 / g.wheelbase_m;
    let r = 0.5 * (vr + vl) * 5.0 / theta;
    let p = robot.true_pose();
    // Exact arcs per period: only f64 summation error remains.
    assert!((p.x_m - r * theta.sin()).abs() < 1e-9, "{p:?}");
    assert!((p.y_m - r * (1.0 - theta.cos())).abs() < 1e-9, "{p:?}");
    // 5,000 period increments (of 10 sub-step rotations each) summed: ~1e-16 relative each.
    assert!((p.theta_rad - theta).abs() < 1e-11, "{p:?}");
}

#[test]
fn true_pose_of_a_fast_turn_is_exact() {
    // 100 Hz and the wheels at full and half duty in opposite directions: the heading
    // changes by 0.039 rad per period, beyond the chord's series, so every period takes the
    // library's sinc.
    let g = Geometry::PAPER_NOMINAL;
    let mut cfg = RobotConfig::new(g, 100);
    cfg.motor.time_constant_s = 0.0;
    cfg.motor.time_constant_left_s = 0.0;
    let mut robot: SimRobot = SimRobot::new(cfg);
    robot.apply(MotorCommand::Duty {
        right: 1.0,
        left: -0.5,
    });
    for _ in 0..500 {
        robot.advance();
    }
    let vr = cfg.motor.gain_right_radps * 0.075;
    let vl = -0.5 * cfg.motor.gain_left_radps * 0.075;
    let theta = (vr - vl) * 5.0 / g.wheelbase_m;
    let r = 0.5 * (vr + vl) * 5.0 / theta;
    let p = robot.true_pose();
    // About 3 turns in 5,000 exact arcs: f64 summation error only.
    assert!(theta > 19.0, "{theta}");
    assert!((p.x_m - r * theta.sin()).abs() < 1e-9, "{p:?}");
    assert!((p.y_m - r * (1.0 - theta.cos())).abs() < 1e-9, "{p:?}");
    assert!((p.theta_rad - theta).abs() < 1e-11, "{p:?}");
}

/// The true pose of `robot` driven through `duties` (one per period) by arcs `fine` times
/// finer than the model's one per period: each fine step an exact arc of the lag's exact
/// solution over it, the whole independent of the model's code.
fn fine_reference(cfg: &RobotConfig, duties: &[(f32, f32)], fine: u32) -> (f64, f64, f64) {
    let g = cfg.true_geometry;
    let m = cfg.motor;
    let h = 1.0 / (f64::from(cfg.rate_hz) * f64::from(fine));
    let rho = (0.5 * g.diameter_right_m, 0.5 * g.diameter_left_m);
    let (mut wr, mut wl) = (0.0f64, 0.0f64);
    let (mut x, mut y, mut th) = (0.0f64, 0.0f64, 0.0f64);
    // The exact lag solution over h: rotation and the speed at its end.
    let step = |w: &mut f64, target: f64, tau: f64| {
        let e = (-h / tau).exp();
        let phi = target * h + (*w - target) * tau * (1.0 - e);
        *w = target + (*w - target) * e;
        phi
    };
    for &(dr, dl) in duties {
        let (tr, tl) = (
            m.gain_right_radps * f64::from(dr),
            m.gain_left_radps * f64::from(dl),
        );
        for _ in 0..fine {
            let sr = step(&mut wr, tr, m.time_constant_s) * rho.0;
            let sl = step(&mut wl, tl, m.time_constant_left_s) * rho.1;
            let dth = (sr - sl) / g.wheelbase_m;
            let u = 0.5 * dth;
            let chord = 0.5 * (sr + sl) * if u == 0.0 { 1.0 } else { u.sin() / u };
            x += chord * (th + u).cos();
            y += chord * (th + u).sin();
            th += dth;
        }
    }
    (x, y, th)
}

#[test]
fn the_period_quadrature_is_the_fine_solution() {
    // Duty steps every 0.2 s (the lag's speeds change fastest right after them), unequal
    // motors and time constants: the curvature changes within every period, most after a step.
    // (One constant-curvature arc per period would be 1.8e-7 m off here, ten per period as the
    // model had before its quadrature 1.8e-9 m.)
    let g = Geometry::PAPER_NOMINAL;
    let mut cfg = RobotConfig::new(g, 1000);
    cfg.motor.time_constant_left_s = 0.03;
    let steps = [
        (0.3f32, 0.1f32),
        (0.5, 0.5),
        (-0.2, 0.4),
        (0.0, 0.6),
        (0.8, -0.8),
        (0.9, 0.2),
    ];
    let duties: std::vec::Vec<(f32, f32)> = steps
        .iter()
        .flat_map(|&d| core::iter::repeat_n(d, 200))
        .collect();
    let mut robot: SimRobot = SimRobot::new(cfg);
    for &(right, left) in &duties {
        robot.apply(MotorCommand::Duty { right, left });
        robot.advance();
    }
    let p = robot.true_pose();
    let (x, y, th) = fine_reference(&cfg, &duties, 1000);
    // 0.3 m of driving and 0.6 rad of turning: the quadrature is within 1e-11 m and rad of
    // arcs a thousand times finer (2e-13 m here, the finer arcs' own error), five orders
    // below the micrometre of a `measure` line.
    assert!(x.abs() + y.abs() > 0.3 && th.abs() > 0.5, "{x} {y} {th}");
    assert!((p.x_m - x).abs() < 1e-11, "{} {x}", p.x_m);
    assert!((p.y_m - y).abs() < 1e-11, "{} {y}", p.y_m);
    assert!((p.theta_rad - th).abs() < 1e-11, "{} {th}", p.theta_rad);
}
