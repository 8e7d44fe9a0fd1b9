//! The motion-capture heading offset of a session's ground truth, and the truth turned by it
//! into the robot's own start frame.
//!
//! A motion-capture rigid body's heading is whatever direction its creator gave it, never exactly
//! the robot's forward axis. In the shared sessions the recorded heading is 4–9 mrad short of the
//! direction the robot moves in, the same in every run and in both turn directions (so not slip),
//! and the rigid body's origin sits on the axle centre (a lever arm fitted to the in-place turns
//! is under 2 mm). In
//! the recorded start frame a point `d` metres away is then misplaced by `δ·d` across: on squares
//! and circles, whose end lies near the start, a fraction of a millimetre; at the end of a 2 m
//! line 10–20 mm, more than the lateral drift that calibrates `E_d`; along a free path of metres,
//! tens of millimetres. [`truth_heading_offset`] measures `δ` from the ground truth alone: for a
//! robot that does not slip sideways, the chord of a constant-curvature arc points along the
//! mean of its end headings, so `δ` is the median over all rows of a session of
//! `direction(p[k+K] − p[k−K]) − (θ[k−K] + θ[k+K])/2` (`K =` [`OFFSET_HALF_WINDOW`] rows, folded
//! by π for driving backwards), over rows that move at least [`OFFSET_MIN_CHORD_M`] and turn at
//! most [`OFFSET_MAX_TURN_RAD`] across the window. [`OptiRun::aligned`] is the truth turned by
//! `−δ` about the start into the robot's own start frame; the calibration reads it, while the
//! evaluation compares with the truth as recorded (the published protocol, so that its numbers
//! can be reproduced from the files alone).

use odocal::kinematics::reference::PoseF64;

use super::run::OptiRun;

/// Rows on each side of a row in the heading-offset estimate (±0.2 s at 50 ms rows).
pub const OFFSET_HALF_WINDOW: usize = 4;

/// Shortest chord across the window that enters the heading-offset estimate, metres: at 0.1 mm of
/// motion-capture noise its direction is known to about 7 mrad per row, and in-place turns and
/// stops (whose chord direction is noise) stay out.
pub const OFFSET_MIN_CHORD_M: f64 = 0.02;

/// Largest heading change across the window, radians: the chord of a constant-curvature arc points
/// along the mean end heading; where the curvature changes within the window (the start of a turn)
/// it does not, by up to a quarter of the turn.
pub const OFFSET_MAX_TURN_RAD: f64 = 0.2;

/// Fewest rows for a heading-offset estimate (below it the truth is used as recorded).
pub const OFFSET_MIN_SAMPLES: usize = 50;

/// The heading offset of a session's ground truth (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TruthOffset {
    /// Direction of motion minus recorded heading, radians (median over the rows used).
    pub heading_rad: f64,
    /// Rows it was measured on.
    pub samples: usize,
}

/// The heading offset of the ground truth of `runs` (one session: one rigid body), or `None` when
/// fewer than [`OFFSET_MIN_SAMPLES`] rows move along a path (a session of in-place turns only).
pub fn truth_heading_offset(runs: &[OptiRun]) -> Option<TruthOffset> {
    use std::f64::consts::{FRAC_PI_2, PI};
    let k = OFFSET_HALF_WINDOW;
    let mut d: Vec<f64> = runs
        .iter()
        .flat_map(|r| r.truth.windows(2 * k + 1))
        .filter_map(|w| {
            let (a, b) = (w[0], w[2 * k]);
            let (dx, dy) = (b.x_m - a.x_m, b.y_m - a.y_m);
            let turn = b.theta_rad - a.theta_rad;
            (dx.hypot(dy) >= OFFSET_MIN_CHORD_M && turn.abs() <= OFFSET_MAX_TURN_RAD).then(|| {
                let o = odocal::calibration::wrap_angle(
                    dy.atan2(dx) - 0.5 * (a.theta_rad + b.theta_rad),
                );
                // Driving backwards, the chord points against the heading.
                if o > FRAC_PI_2 {
                    o - PI
                } else if o <= -FRAC_PI_2 {
                    o + PI
                } else {
                    o
                }
            })
        })
        .collect();
    if d.len() < OFFSET_MIN_SAMPLES {
        return None;
    }
    d.sort_by(f64::total_cmp);
    let n = d.len();
    let heading_rad = if n % 2 == 1 {
        d[n / 2]
    } else {
        0.5 * (d[n / 2 - 1] + d[n / 2])
    };
    Some(TruthOffset {
        heading_rad,
        samples: n,
    })
}

/// Turns the [aligned](OptiRun::aligned) truth of every run by `−offset` about its start: from
/// the recorded start frame into the robot's own.
pub(super) fn align_truth(runs: &mut [OptiRun], offset: TruthOffset) {
    let (s, c) = offset.heading_rad.sin_cos();
    for r in runs {
        for p in &mut r.aligned {
            *p = PoseF64::new(c * p.x_m + s * p.y_m, c * p.y_m - s * p.x_m, p.theta_rad);
        }
    }
}

#[cfg(test)]
mod tests {
    use std::fs;

    use odocal::kinematics::encoder::WheelTicks;

    use super::super::fixtures::{metadata, session_folder};
    use super::super::{Kind, read_session};
    use super::*;

    /// A run whose truth is a path driven without side slip, recorded with its heading `δ` short of
    /// the direction of motion: forwards along a line, a constant-curvature arc, an in-place
    /// turn, then backwards along a line. 50 ms rows at 0.1 m/s.
    fn run_with_offset(delta: f64) -> OptiRun {
        let (v, dt) = (0.1, 0.05);
        let mut world = vec![PoseF64::new(0.0, 0.0, 0.0)];
        let mut step = |speed: f64, rate: f64, rows: usize| {
            for _ in 0..rows {
                let p = *world.last().unwrap();
                let (th0, th1) = (p.theta_rad, p.theta_rad + rate * dt);
                // Exact chord of the arc: along the mean heading, length 2R·sin(Δθ/2).
                let chord = if rate == 0.0 {
                    speed * dt
                } else {
                    2.0 * speed / rate * (0.5 * rate * dt).sin()
                };
                let mid = 0.5 * (th0 + th1);
                world.push(PoseF64::new(
                    p.x_m + chord * mid.cos(),
                    p.y_m + chord * mid.sin(),
                    th1,
                ));
            }
        };
        step(v, 0.0, 40);
        step(v, 0.3, 60);
        step(0.0, 1.0, 30);
        step(-v, 0.0, 40);
        // The rigid body's heading is δ short of the robot's; positions are the robot's.
        let truth: Vec<PoseF64> = world
            .iter()
            .map(|p| PoseF64::new(p.x_m, p.y_m, p.theta_rad - delta))
            .collect();
        let start = truth[0];
        let truth: Vec<PoseF64> = truth.iter().map(|w| start.relative(w)).collect();
        OptiRun::new(None, vec![WheelTicks::new(0, 0); truth.len()], truth)
    }

    #[test]
    fn the_heading_offset_of_the_truth_is_measured_from_the_direction_of_motion() {
        for delta in [0.0, 0.006, -0.02] {
            let run = run_with_offset(delta);
            let o = truth_heading_offset(std::slice::from_ref(&run)).unwrap();
            // Lines and the constant-curvature arc give δ exactly (to rounding); the windows that
            // straddle a change of curvature lie off it, but they are a minority and the median
            // ignores them. The in-place turn never enters (its chord is zero).
            assert!((o.heading_rad - delta).abs() < 1e-9, "{delta}: {o:?}");
            // 171 rows, 8 at the ends without a full window, 30 turning in place + 4 on each
            // side of it whose chord is under 2 cm.
            assert!(o.samples > 100 && o.samples < 171, "{o:?}");
        }
        // Only in-place turns: nothing to measure.
        let mut turn = run_with_offset(0.006);
        turn.truth.truncate(1);
        assert_eq!(truth_heading_offset(&[turn]), None);
    }

    #[test]
    fn the_heading_offset_survives_motion_capture_noise() {
        // Ten runs with 0.2 mm of position and 1 mrad of heading noise per row (Gaussian, a fixed
        // seed): a row's chord of 4 cm then points to within about 7 mrad, and the median of
        // about 1,300 rows (neighbours share rows, so fewer independent ones) to within about
        // 0.5 mrad. 2 mrad is four times that, and a third of the smallest offset in the
        // shared sessions.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut gauss = move || {
            let mut uniform = || {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (u, v) = (uniform(), uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        };
        let delta = 0.006;
        let runs: Vec<OptiRun> = (0..10)
            .map(|_| {
                let mut r = run_with_offset(delta);
                for p in &mut r.truth {
                    *p = PoseF64::new(
                        p.x_m + 2e-4 * gauss(),
                        p.y_m + 2e-4 * gauss(),
                        p.theta_rad + 1e-3 * gauss(),
                    );
                }
                r
            })
            .collect();
        let o = truth_heading_offset(&runs).unwrap();
        assert!((o.heading_rad - delta).abs() < 2e-3, "{o:?}");
    }

    #[test]
    fn the_aligned_truth_is_the_robot_start_frame() {
        let (root, dir) = session_folder("align", "ivanjko", "77", &metadata("0.084,0.084", 1, ""));
        // A straight line of 2 m along +x in the world, 0.2 m/s, recorded with a heading 10 mrad
        // short of the direction of motion.
        let rows: String = (0..=200)
            .map(|i| {
                format!(
                    "{},{},0,-0.01,10,10\n",
                    f64::from(i) * 0.05,
                    f64::from(i) * 0.01
                )
            })
            .collect();
        fs::write(dir.join("77_run-01.csv"), rows).unwrap();
        let s = read_session(&dir).unwrap();
        fs::remove_dir_all(&root).unwrap();
        let o = s.truth_offset.unwrap();
        assert!((o.heading_rad - 0.01).abs() < 1e-12, "{o:?}");
        let r = &s.runs[0];
        // As recorded, the start frame is turned by −10 mrad: the end is 20 mm to the left.
        assert!(
            (r.truth_end.y_m - 2.0 * 0.01f64.sin()).abs() < 1e-12,
            "{:?}",
            r.truth_end
        );
        // Aligned, the robot drove straight ahead along +x; headings are unchanged.
        let a = *r.aligned.last().unwrap();
        assert!((a.x_m - 2.0).abs() < 1e-12 && a.y_m.abs() < 1e-12, "{a:?}");
        assert_eq!(a.theta_rad, r.truth_end.theta_rad);
        let g = s.nominal;
        let kind = Kind::Ivanjko;
        assert_eq!(
            r.observation(kind, 0.0, &g, false, false, true)
                .measured
                .y_m,
            a.y_m
        );
        assert_eq!(
            r.observation(kind, 0.0, &g, true, true, true).truth_path,
            &r.truth[..]
        );
    }
}
