//! Paper-mode (ideal kinematics) checks of the calibration engine: the exact method recovers
//! the truth at every side, the closed-form methods see our frame with Borenstein's signs,
//! calibrations compose, E_s comes from a straight line, and the track advice behaves.

use odocal::calibration::synth::{end_poses, leg_ticks, square_knots};
use odocal::calibration::track::{TrackAdviceInput, advise};
use odocal::calibration::{Method, RunObservation, calibrate, umbmark};
use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;
use odocal::motion::run::{Direction, Measurement, PathKind, RunRecord};

const NOMINAL: Geometry = Geometry::PAPER_NOMINAL;

struct Run {
    path: PathKind,
    belief: Geometry,
    knots: Vec<WheelTicks>,
    odo: PoseF64,
    measured: Measurement,
}

impl Run {
    fn square(belief: &Geometry, truth: &Geometry, direction: Direction, side_m: f64) -> Self {
        let knots = square_knots(belief, direction, side_m).to_vec();
        let (odo, measured) = end_poses(belief, truth, &knots);
        Run {
            path: PathKind::Square { direction, side_m },
            belief: *belief,
            knots,
            odo,
            measured,
        }
    }

    fn line(belief: &Geometry, truth: &Geometry, length_m: f64) -> Self {
        let knots = vec![WheelTicks::new(0, 0), leg_ticks(belief, length_m)];
        let (odo, measured) = end_poses(belief, truth, &knots);
        Run {
            path: PathKind::Line { length_m },
            belief: *belief,
            knots,
            odo,
            measured,
        }
    }

    fn obs(&self) -> RunObservation<'_> {
        RunObservation {
            path: self.path,
            geometry: self.belief,
            knots: &self.knots,
            odometry_end: self.odo,
            measured: self.measured,
            truth_path: &[],
        }
    }
}

fn pair(belief: &Geometry, truth: &Geometry, side: f64) -> [Run; 2] {
    [
        Run::square(belief, truth, Direction::Cw, side),
        Run::square(belief, truth, Direction::Ccw, side),
    ]
}

#[test]
fn exact_recovers_the_paper_truth_at_every_side() {
    let truth = NOMINAL.with_factors(0.995, 1.010, 1.0);
    for side in [0.2, 1.0, 2.0, 4.0, 16.0] {
        let runs = pair(&NOMINAL, &truth, side);
        let obs: Vec<_> = runs.iter().map(Run::obs).collect();
        let c = calibrate(&obs, &NOMINAL, Method::Exact).unwrap();
        // The requirement is 1e-5; noiseless data fits to rounding (~1e-12).
        assert!(
            (c.e_b / 1.010 - 1.0).abs() <= 1e-5,
            "L={side}: E_b {}",
            c.e_b
        );
        assert!(
            (c.e_d / 0.995 - 1.0).abs() <= 1e-5,
            "L={side}: E_d {}",
            c.e_d
        );
        // No line run: the scale is not fitted and stays at the driving value (1 up to rounding).
        assert!((c.e_s - 1.0).abs() < 1e-15);
        // Re-integrating the recorded ticks with the fit leaves (almost) no systematic error.
        assert!(c.quality.e_max_after_m.unwrap() < 1e-6);
    }
}

#[test]
fn our_frame_has_borensteins_signs() {
    // Small errors, small square: UMBmark's first-order assumptions hold, so a sign slip in x_cw,
    // y_cw, … would show as an error of the size of the effect itself (1e-3), not 1e-5.
    let truth = NOMINAL.with_factors(0.9995, 1.001, 1.0);
    let runs = pair(&NOMINAL, &truth, 0.5);
    let obs: Vec<_> = runs.iter().map(Run::obs).collect();
    for m in [Method::UmbmarkX, Method::UmbmarkY] {
        let c = calibrate(&obs, &NOMINAL, m).unwrap();
        // Second-order terms are ~α² ≈ 2.5e-6 and ~αβ; 2e-5 leaves a margin.
        assert!((c.e_b / 1.001 - 1.0).abs() < 2e-5, "{m}: E_b {}", c.e_b);
        assert!((c.e_d / 0.9995 - 1.0).abs() < 2e-5, "{m}: E_d {}", c.e_d);
    }
    // And the CW square lies at y ≤ 0: the robot under-turns, so the CW end error has y < 0.
    let (_, y_cw) = (runs[0].measured.x_m, runs[0].measured.y_m);
    assert!(y_cw < 0.0);
}

#[test]
fn closed_form_calibrations_compose_iteratively() {
    // Paper Fig. 10: each calibration drives with the previous result and measures a correction
    // relative to it; composed, the error must shrink from one iteration to the next.
    let truth = NOMINAL.with_factors(0.995, 1.010, 1.0);
    let mut belief = NOMINAL;
    let mut last = f64::INFINITY;
    for _ in 0..4 {
        let runs = pair(&belief, &truth, 1.0);
        let obs: Vec<_> = runs.iter().map(Run::obs).collect();
        let c = calibrate(&obs, &NOMINAL, Method::UmbmarkX).unwrap();
        let err = (c.e_b / 1.010 - 1.0).abs() + (c.e_d / 0.995 - 1.0).abs();
        assert!(
            err < last,
            "iteration error {err} did not shrink from {last}"
        );
        last = err;
        belief = c.geometry;
    }
    // Four iterations of a contraction with ratio ≈ α ≈ 1.5e-2 end far below 1e-6.
    assert!(last < 1e-6, "{last}");
}

#[test]
fn exact_from_an_already_calibrated_belief() {
    let truth = NOMINAL.with_factors(0.995, 1.010, 1.0);
    let belief = NOMINAL.corrected(0.997, 1.004, 1.0);
    let runs = pair(&belief, &truth, 2.0);
    let obs: Vec<_> = runs.iter().map(Run::obs).collect();
    let c = calibrate(&obs, &NOMINAL, Method::Exact).unwrap();
    assert!((c.e_b / 1.010 - 1.0).abs() <= 1e-9, "{}", c.e_b);
    assert!((c.e_d / 0.995 - 1.0).abs() <= 1e-9, "{}", c.e_d);
}

#[test]
fn line_run_adds_the_scale() {
    let truth = NOMINAL.with_factors(0.995, 1.010, 1.002);
    let mut runs: Vec<Run> = pair(&NOMINAL, &truth, 2.0).into_iter().collect();
    runs.push(Run::line(&NOMINAL, &truth, 5.0));
    let obs: Vec<_> = runs.iter().map(Run::obs).collect();
    let c = calibrate(&obs, &NOMINAL, Method::Exact).unwrap();
    // Noiseless, so the fit is exact to rounding; 1e-8 is a generous bound.
    assert!((c.e_s - 1.002).abs() < 1e-8, "E_s {}", c.e_s);
    assert!((c.e_b - 1.010).abs() < 1e-8 && (c.e_d - 0.995).abs() < 1e-8);
}

#[test]
fn uncertainty_from_scatter() {
    // Three CW and three CCW runs with end positions displaced by ±1 mm: a non-zero scatter and
    // 1σ figures of the size σ/(√n·4L)·√2 ≈ 1e-4 for E_b.
    let truth = NOMINAL.with_factors(0.995, 1.010, 1.0);
    let mut runs = Vec::new();
    for (i, d) in [-1e-3, 0.0, 1e-3].iter().enumerate() {
        for dir in [Direction::Cw, Direction::Ccw] {
            let mut r = Run::square(&NOMINAL, &truth, dir, 1.0);
            r.measured.x_m += d;
            r.measured.y_m -= if i == 1 { 1e-3 } else { 0.0 };
            runs.push(r);
        }
    }
    let obs: Vec<_> = runs.iter().map(Run::obs).collect();
    for m in [Method::UmbmarkX, Method::LeeY, Method::Exact] {
        let q = calibrate(&obs, &NOMINAL, m).unwrap().quality;
        let s = q.sigma_e_b.unwrap();
        assert!(s > 1e-5 && s < 1e-3, "{m}: σ_E_b {s}");
        assert!(q.scatter_m.unwrap() > 5e-4);
        assert!(q.e_max_before_m.unwrap() > 1e-3);
    }
}

#[test]
fn unmeasured_record_is_not_an_observation() {
    let mut r = RunRecord {
        path: PathKind::Line { length_m: 1.0 },
        geometry: NOMINAL,
        knots: heapless::Vec::new(),
        odometry_end: PoseF64::default(),
        measured: None,
    };
    assert!(RunObservation::from_record(&r).is_none());
    r.measured = Some(Measurement {
        x_m: 1.0,
        y_m: 0.0,
        theta_rad: None,
    });
    assert!(RunObservation::from_record(&r).is_some());
}

#[test]
fn track_advice() {
    let truth = NOMINAL.with_factors(0.995, 1.010, 1.0);
    let mut input = TrackAdviceInput {
        belief: NOMINAL,
        estimate: truth,
        measurement_sigma_m: 0.005,
        measurement_sigma_rad: 0.005,
        observed_scatter: None,
        runs_per_direction: 5,
        max_side_m: 16.0,
    };
    // Without slip scatter the exact method has no bias and its random error falls with L:
    // it asks for the largest floor.
    assert_eq!(advise(&input, Method::Exact).unwrap().side_m, 16.0);
    // UMBmark's small-angle bias grows with L (4 % at 16 m): it stays well below 16 m.
    let u = advise(&input, Method::UmbmarkX).unwrap();
    assert!(u.side_m < 8.0, "{u:?}");
    // With 20 mm scatter observed at 2 m, growing as L^1.5, the exact method backs off too.
    input.observed_scatter = Some((0.02, 2.0));
    let e = advise(&input, Method::Exact).unwrap();
    assert!(e.side_m < 16.0 && e.expected_error < 1e-2, "{e:?}");
}

#[test]
fn umbmark_beta_zero_is_unit_ratio() {
    // A robot with equal wheels: x_cw = x_ccw in the ideal model ⇒ E_d = 1 exactly.
    let f = umbmark::umbmark_x(-0.01, -0.01, 1.0, 0.385).unwrap();
    assert_eq!(f.e_d, 1.0);
}

#[test]
fn one_line_summary() {
    let truth = NOMINAL.with_factors(0.995, 1.010, 1.0);
    let runs = pair(&NOMINAL, &truth, 2.0);
    let obs: Vec<_> = runs.iter().map(Run::obs).collect();
    let c = calibrate(&obs, &NOMINAL, Method::Exact).unwrap();
    let line = format!("{c}");
    // Noiseless runs: the fit residuals, and so the exact method's 1σ, are zero. E_max before
    // is |cg_ccw| at L = 2 m = 238.5 mm (paper table in docs/calibration.md).
    assert!(
        line.starts_with(
            "exact E_b=1.010000+-0.000000 E_d=0.995000+-0.000000 E_s=1.000000 D_R=149.6241mm"
        ),
        "{line}"
    );
    assert!(line.ends_with("E_max=238.5->0.0mm"), "{line}");
}
