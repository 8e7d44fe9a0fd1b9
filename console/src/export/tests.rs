//! The export's tests: a terminal capture read and written in each format, the ROS 2 file's
//! radius multipliers against the board's wheel diameters, the YAML numbers and the covariance
//! model.

use super::*;

/// A terminal capture: echo, events and the board's replies, CR LF line ends.
const CAPTURE: &str = "event boot: parameters loaded, reset: pin\r\n\
    params\r\n\
    \x20 d_right 0.150000000 m\r\n\
    \x20 d_left 0.150000000 m\r\n\
    \x20 wheelbase 0.385000000 m\r\n\
    \x20 counts_per_rev 200000 counts/rev\r\n\
    \x20 square_side 1.000 m\r\n\
    \x20 active d_right=0.149625438 d_left=0.150375438 wheelbase=0.388850000 m\r\n\
    \x20 calibration lee-y E_d=0.995012500 E_b=1.010000000 E_s=1.000000000 runs=10 E_max=3.6 mm\r\n\
    ok\r\n";

#[test]
fn a_terminal_capture_with_the_params_reply_exports() {
    let dir = std::env::temp_dir().join(format!("odocal-export-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("picocom.log");
    std::fs::write(&log, CAPTURE).unwrap();
    let e = Export::read(&log).unwrap();
    assert_eq!(e.method.as_deref(), Some("lee-y"));
    assert_eq!(e.applied.diameter_right_m, 0.149625438);
    assert_eq!(e.applied.wheelbase_m, 0.38885);
    assert_eq!(e.side_m, 1.0);
    // No calibrate table in the capture: no 1σ, no covariance.
    assert_eq!(e.sd, None);
    let yaml = e.write_for(Format::Ros2, &log, &Target::default());
    assert!(yaml.contains("    wheel_separation: 0.38885\n"), "{yaml}");
    assert!(yaml.contains("    wheel_radius: 0.075\n"), "{yaml}");
    assert!(
        yaml.contains("the between-session drift (the log has no 1-sigma)"),
        "{yaml}"
    );
    assert!(yaml.contains("    pose_covariance_diagonal: ["), "{yaml}");
    let urdf = e.write_for(Format::Urdf, &log, &Target::default());
    assert!(urdf.contains("<origin xyz=\"0 0.194425 0\""), "{urdf}");
    assert!(urdf.contains("radius=\"0.074812719\""), "{urdf}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The number after `    key: ` in a YAML text.
fn yaml_number(yaml: &str, key: &str) -> f64 {
    let prefix = format!("    {key}: ");
    yaml.lines()
        .find_map(|l| l.strip_prefix(&prefix))
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no {key} in\n{yaml}"))
}

#[test]
fn the_radius_multipliers_give_back_the_boards_right_and_left_diameters() {
    // The capture's board: nominal 150 mm wheels, active right 149.625438 mm and left
    // 150.375438 mm (E_d = 0.9950125). diff_drive_controller turns each wheel with the radius
    // wheel_radius × that side's multiplier: twice that is the board's diameter of the same
    // side (two roundings: 1e-15 m; the sides exchanged would be 0.75 mm off).
    let dir = std::env::temp_dir().join(format!("odocal-multipliers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("picocom.log");
    std::fs::write(&log, CAPTURE).unwrap();
    let e = Export::read(&log).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let yaml = e.write_for(Format::Ros2, &log, &Target::default());
    let radius = yaml_number(&yaml, "wheel_radius");
    assert_eq!(radius, 0.075, "half the nominal mean diameter");
    let right = 2.0 * radius * yaml_number(&yaml, "right_wheel_radius_multiplier");
    let left = 2.0 * radius * yaml_number(&yaml, "left_wheel_radius_multiplier");
    assert!(
        (right - 0.149625438).abs() < 1e-15,
        "right wheel {right} m, the board's D_R 0.149625438 m"
    );
    assert!(
        (left - 0.150375438).abs() < 1e-15,
        "left wheel {left} m, the board's D_L 0.150375438 m"
    );
    assert_eq!(yaml_number(&yaml, "wheel_separation_multiplier"), 1.0);
    assert_eq!(yaml_number(&yaml, "wheel_separation"), 0.38885);
}

#[test]
fn yaml_floats_read_back_exactly_and_as_numbers() {
    for v in [0.38885001234913696, 1e-5, 2.5e-13, 1e20, 0.075, 1.0, 1e6] {
        let s = yaml_float(v);
        assert_eq!(s.parse::<f64>().unwrap(), v, "{s}");
        assert!(s.contains('.'), "{s}");
        if let Some((_, exp)) = s.split_once('e') {
            assert!(exp.starts_with(['+', '-']), "{s}");
        }
    }
    assert_eq!(yaml_float(1e-5), "1.0e-5");
    assert_eq!(yaml_float(1e20), "1.0e+20");
}

/// The end pose's spread of one square when E_d and E_b move by ±1σ each, from the
/// library's exact-arc model (finite differences): the reference the covariance model's
/// first-order propagation must meet.
fn exact_arc_variance(e: &Export) -> [f64; 3] {
    use odocal::calibration::wrap_angle;
    use odocal::kinematics::reference::{ArcModel, PoseF64};
    let (sd_d, sd_b) = e.sd.unwrap();
    let g = &e.applied;
    let (e_d, e_b) = (g.diameter_ratio(), g.wheelbase_m / e.nominal.wheelbase_m);
    let end = |knots: &[odocal::kinematics::encoder::WheelTicks], d: f64, b: f64| {
        let moved = g.corrected(1.0 + d / e_d, 1.0 + b / e_b, 1.0);
        ArcModel::from_geometry(&moved).integrate(PoseF64::default(), knots)
    };
    let mut var = [0.0f64; 3];
    for direction in [Direction::Cw, Direction::Ccw] {
        let knots = synth::square_knots(g, direction, e.side_m);
        let mut v = [0.0f64; 3];
        for (d, b) in [(sd_d, 0.0), (0.0, sd_b)] {
            let (p, m) = (end(&knots, d, b), end(&knots, -d, -b));
            let half = [
                0.5 * (p.x_m - m.x_m),
                0.5 * (p.y_m - m.y_m),
                0.5 * wrap_angle(p.theta_rad - m.theta_rad),
            ];
            for k in 0..3 {
                v[k] += half[k] * half[k];
            }
        }
        for k in 0..3 {
            var[k] = var[k].max(v[k]);
        }
    }
    var
}

#[test]
fn the_covariance_model_meets_the_exact_arc_and_grows_with_slip() {
    let nominal = Geometry::PAPER_NOMINAL;
    let mut e = Export {
        nominal,
        applied: nominal.with_factors(0.995, 1.01, 1.0),
        method: Some("exact".into()),
        factors: (0.995, 1.01, 1.0),
        sd: Some((1e-4, 2e-4)),
        source: String::new(),
        side_m: 2.0,
        max_accel: 0.3,
        runs: Vec::new(),
        runs_logged_s: None,
        table: Vec::new(),
    };
    // The model's inputs: the log's relative 1σ as they are (no floor, no scale term).
    let inputs = |e: &Export, slip: f64| {
        let (d, b) = e.sd.unwrap();
        crate::covariance::Uncertainty {
            sd_d: d / e.factors.0,
            sd_b: b / e.factors.1,
            sd_s: 0.0,
            slip_m2_per_m: slip,
            scrub_m2_per_rad: 0.0,
        }
    };
    // Without slip: the calibration's 1σ through the exact-arc model, to 1 % (first order
    // against finite differences of ±1σ).
    let model = e.pose_covariance(&inputs(&e, 0.0));
    let exact = exact_arc_variance(&e);
    for (k, m) in [(0, 0), (1, 1), (2, 5)] {
        assert!(
            (model[m] / exact[k] - 1.0).abs() < 0.01,
            "{model:?} vs {exact:?}"
        );
    }
    assert_eq!(model[2], UNOBSERVED_VARIANCE);
    // Twice the 1σ, four times the variance.
    e.sd = Some((2e-4, 4e-4));
    let large = e.pose_covariance(&inputs(&e, 0.0));
    for k in [0, 1, 5] {
        assert!((large[k] / model[k] - 4.0).abs() < 1e-9, "{large:?}");
    }
    // Slip adds to every observed variance.
    let slipping = e.pose_covariance(&inputs(&e, 4e-6));
    for k in [0, 1, 5] {
        assert!(slipping[k] > large[k], "{slipping:?}");
    }
    // The twist: nonzero, unobserved components large.
    let t = e.twist_covariance(100.0, 1);
    assert!(
        t[0] > 0.0 && t[5] > 0.0 && t[1] == UNOBSERVED_VARIANCE,
        "{t:?}"
    );
    // diff_drive_controller's rolling mean over 10 updates: the edge counts' share 100 times
    // smaller, the acceleration's 100 times larger (at 0.3 m/s² it dominates).
    let ten = e.twist_covariance(100.0, 10);
    assert!(ten[0] > t[0] && ten[5] > t[5], "{ten:?} vs {t:?}");
    // The floor: the log's 1σ raised to the between-session drift unless trusted; to the same
    // day's while its runs are less than a day old.
    let (floored, _) = e.uncertainty(None, false, None);
    let (trusted, _) = e.uncertainty(None, true, None);
    assert_eq!(floored.sd_b, 3e-3);
    let logged = 1.7e9;
    let e = Export {
        runs_logged_s: Some(logged),
        ..e
    };
    let (today, why) = e.uncertainty(None, false, Some(logged + 3_600.0));
    assert_eq!(today.sd_b, 1e-3, "{why}");
    assert!(why.contains("same day's drift"), "{why}");
    let (tomorrow, _) = e.uncertainty(None, false, Some(logged + 86_400.0));
    assert_eq!(tomorrow.sd_b, 3e-3);
    assert!((trusted.sd_b - 4e-4 / 1.01).abs() < 1e-15);
    assert_eq!(floored.sd_s, 1e-3);
}
