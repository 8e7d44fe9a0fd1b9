//! The Monte Carlo experiment (`host-sim montecarlo`; its noisy squares also feed `sweep`):
//! repeated paper-mode calibrations with measurement and slip noise.
//!
//! Kinematic model as in [`crate::experiments::paper`] (pulse counts commanded from the belief, no motor
//! dynamics), plus:
//! - **slip**: every segment is split into `substeps` equal parts; in each, the ground travel of
//!   each wheel is its encoder travel × `(1 + slip·N(0,1))`, independently per wheel (the encoder
//!   records the commanded rotation, the ground sees the slipped one);
//! - **measurement noise**: `N(0, σ)` added to the measured x and y; with `--heading` the end
//!   heading is measured too, with `N(0, σ_θ)` (`--meas-sigma-rad`);
//! - **slipping start** (`--slip-start P`): with probability `P` per run the wheels spin in a
//!   jerk before the robot moves: the encoders record an in-place turn of `±slip-start-rad`
//!   (random sign) that the robot never makes, so the odometry's heading is off by that much
//!   from the start on (as in OptiOdom 231220200029 run 2). Only measured headings see it.
//!
//! Besides every method, the `exact-ls` row is the exact fit by plain least squares
//! ([`ExactOptions::plain`]); `exact` is the default, robust fit.
//!
//! Each trial drives `runs` CW and `runs` CCW squares and calibrates with every method; the
//! report is the mean and standard deviation over trials of the relative errors of `E_b`, `E_d`.

use clap::Args;
use odocal::calibration::synth::{square_segments, turn_ticks};
use odocal::calibration::{ExactOptions, Method, RunObservation, calibrate_with};
use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::{ArcModel, PoseF64};
use odocal::motion::run::{Direction, Measurement, PathKind};

use crate::commands::replay::methods::{EXACT_MOCAP, mocap_options};
use crate::experiments::paper::{Format, TruthModel, true_geometry};

/// Arguments of `host-sim montecarlo`.
#[derive(Args, Debug)]
pub struct MonteCarloArgs {
    /// Trials.
    #[arg(long, default_value_t = 200)]
    pub trials: u32,
    /// Square side L, metres.
    #[arg(long, default_value_t = 2.0)]
    pub side: f64,
    /// Runs per direction.
    #[arg(long, default_value_t = 5)]
    pub runs: u32,
    /// 1σ of a measured coordinate, metres.
    #[arg(long, default_value_t = 0.005)]
    pub meas_sigma: f64,
    /// 1σ of the relative slip of a wheel per substep.
    #[arg(long, default_value_t = 0.002)]
    pub slip: f64,
    /// Substeps per segment (slip is drawn per substep).
    #[arg(long, default_value_t = 20)]
    pub substeps: u32,
    /// True E_b.
    #[arg(long, default_value_t = 1.010)]
    pub eb: f64,
    /// True E_d.
    #[arg(long, default_value_t = 0.995)]
    pub ed: f64,
    /// Probability per run of a slipping start (a phantom in-place turn in the encoders).
    #[arg(long, default_value_t = 0.0)]
    pub slip_start: f64,
    /// Size of the phantom turn of a slipping start, radians (random sign).
    #[arg(long, default_value_t = 0.075)]
    pub slip_start_rad: f64,
    /// Measure the end heading too.
    #[arg(long)]
    pub heading: bool,
    /// 1σ of a measured heading, radians (with `--heading`).
    #[arg(long, default_value_t = 0.001)]
    pub meas_sigma_rad: f64,
    /// A bias of every measured end position, `x,y` in millimetres in the run's start frame (the
    /// start read off the axle by the same vector every time): what the exact fit's end offset
    /// models (the exact fits fit it with `--heading`; the closed forms read it as geometry). A
    /// lone value is x.
    #[arg(long, value_delimiter = ',', num_args = 1..=2)]
    pub end_offset_mm: Vec<f64>,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Text)]
    pub format: Format,
}

/// SplitMix64 with Box–Muller normals: small, seedable, reproducible.
pub struct Rng(u64);

impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }

    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in (0, 1].
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 1.0) / (1u64 << 53) as f64
    }

    /// Standard normal.
    pub fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// One noisy square with its direction: (direction, recorded knots, odometry end, measurement).
pub type NoisyRun = (Direction, Vec<WheelTicks>, PoseF64, Measurement);

/// `per_direction` noisy squares CW, then as many CCW ([`noisy_square`], drawn in that order).
pub fn noisy_squares(
    belief: &Geometry,
    truth: &Geometry,
    side_m: f64,
    per_direction: u32,
    args: &MonteCarloArgs,
    rng: &mut Rng,
) -> Vec<NoisyRun> {
    let mut runs = Vec::with_capacity(2 * per_direction as usize);
    for d in [Direction::Cw, Direction::Ccw] {
        for _ in 0..per_direction {
            let (k, o, m) = noisy_square(belief, truth, d, side_m, args, rng);
            runs.push((d, k, o, m));
        }
    }
    runs
}

/// Noisy squares of side `side_m` as the calibration reads them, driven believing `belief`.
pub fn observations<'a>(
    runs: &'a [NoisyRun],
    side_m: f64,
    belief: &Geometry,
) -> Vec<RunObservation<'a>> {
    runs.iter()
        .map(|(d, k, o, m)| RunObservation {
            path: PathKind::Square {
                direction: *d,
                side_m,
            },
            geometry: *belief,
            knots: k,
            odometry_end: *o,
            measured: *m,
            truth_path: &[],
        })
        .collect()
}

/// One noisy square: (recorded knots, odometry end, measurement).
pub fn noisy_square(
    belief: &Geometry,
    truth: &Geometry,
    direction: Direction,
    side_m: f64,
    args: &MonteCarloArgs,
    rng: &mut Rng,
) -> (Vec<WheelTicks>, PoseF64, Measurement) {
    let sub = args.substeps.max(1) as i64;
    let mut knots = vec![WheelTicks::new(0, 0)];
    let mut true_knots = vec![WheelTicks::new(0, 0)];
    // A slipping start: the encoders count a turn the robot does not make.
    if args.slip_start > 0.0 && rng.uniform() <= args.slip_start {
        let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
        knots.push(turn_ticks(belief, sign * args.slip_start_rad));
        true_knots.push(WheelTicks::new(0, 0));
    }
    for seg in square_segments(belief, direction, side_m) {
        for i in 0..sub {
            // Split the segment's ticks into `sub` integer parts that add up exactly.
            let part = |t: i64| t * (i + 1) / sub - t * i / sub;
            let (dr, dl) = (part(seg.right), part(seg.left));
            let k = *knots.last().unwrap_or(&WheelTicks::new(0, 0));
            knots.push(WheelTicks::new(k.right + dr, k.left + dl));
            let slip = |d: i64, rng: &mut Rng| {
                (d as f64 * (1.0 + args.slip * rng.normal())).round() as i64
            };
            let t = *true_knots.last().unwrap_or(&WheelTicks::new(0, 0));
            let (sr, sl) = (slip(dr, rng), slip(dl, rng));
            true_knots.push(WheelTicks::new(t.right + sr, t.left + sl));
        }
    }
    let odo = ArcModel::from_geometry(belief).integrate(PoseF64::default(), &knots);
    let t = ArcModel::from_geometry(truth).integrate(PoseF64::default(), &true_knots);
    // `x,y`; a missing y (or both) is zero.
    let offset = |i: usize| args.end_offset_mm.get(i).copied().unwrap_or(0.0) * 1e-3;
    let x_m = t.x_m + args.meas_sigma * rng.normal() + offset(0);
    let y_m = t.y_m + args.meas_sigma * rng.normal() + offset(1);
    let theta_rad = args
        .heading
        .then(|| t.theta_rad + args.meas_sigma_rad * rng.normal());
    let measured = Measurement {
        x_m,
        y_m,
        theta_rad,
    };
    (knots, odo, measured)
}

/// Mean and standard deviation of the relative E_b and E_d errors of one method over trials.
#[derive(Default, Clone, Copy)]
pub struct Acc {
    n: u32,
    sum: [f64; 2],
    sum2: [f64; 2],
    failed: u32,
}

impl Acc {
    /// Adds one trial's relative errors.
    pub fn push(&mut self, eb: f64, ed: f64) {
        self.n += 1;
        for (i, v) in [eb, ed].into_iter().enumerate() {
            self.sum[i] += v;
            self.sum2[i] += v * v;
        }
    }

    /// Trials that gave a result.
    pub fn trials(&self) -> u32 {
        self.n
    }

    /// Trials that failed.
    pub fn failed(&self) -> u32 {
        self.failed
    }

    /// Records a failed trial.
    pub fn fail(&mut self) {
        self.failed += 1;
    }

    /// Mean and sample standard deviation of component `i` (0 = E_b, 1 = E_d).
    pub fn mean_std(&self, i: usize) -> (f64, f64) {
        let n = f64::from(self.n.max(1));
        let mean = self.sum[i] / n;
        let var = (self.sum2[i] - n * mean * mean) / (n - 1.0).max(1.0);
        (mean, var.max(0.0).sqrt())
    }
}

/// The experiment: `args.trials` calibrations of `args.runs` noisy CW and CCW squares each,
/// with every method (and `exact-ls`, the exact fit by plain least squares); the statistics of
/// the relative E_b and E_d errors per method, labelled.
///
/// # Errors
/// An invalid truth, side, run count or trial count.
pub fn simulate(args: &MonteCarloArgs) -> Result<Vec<(String, Acc)>, String> {
    let nominal = Geometry::PAPER_NOMINAL;
    let truth = true_geometry(&nominal, args.eb, args.ed, TruthModel::Mean);
    truth
        .validate()
        .map_err(|e| format!("invalid truth: {e}"))?;
    if !(args.side > 0.0 && args.runs > 0 && args.trials > 1) {
        return Err("need side > 0, runs ≥ 1, trials ≥ 2".into());
    }
    if !args.end_offset_mm.iter().all(|v| v.is_finite()) {
        return Err("--end-offset-mm must be finite millimetres x,y".into());
    }
    let mut methods: Vec<(String, Method, ExactOptions)> = [
        Method::UmbmarkX,
        Method::UmbmarkY,
        Method::LeeX,
        Method::LeeY,
    ]
    .into_iter()
    .chain(args.heading.then_some(Method::JungChung))
    .chain([Method::Exact])
    .map(|m| (m.as_str().to_string(), m, ExactOptions::default()))
    .collect();
    methods.push(("exact-ls".into(), Method::Exact, ExactOptions::plain()));
    if args.heading {
        // `replay`'s default for motion-capture end poses: the end offset, the heading at 3 L.
        methods.push((EXACT_MOCAP.into(), Method::Exact, mocap_options()));
    }
    let mut acc = vec![Acc::default(); methods.len()];
    let mut rng = Rng::new(args.seed);
    for _ in 0..args.trials {
        let recs = noisy_squares(&nominal, &truth, args.side, args.runs, args, &mut rng);
        let obs = observations(&recs, args.side, &nominal);
        for (i, (_, m, options)) in methods.iter().enumerate() {
            match calibrate_with(&obs, &nominal, *m, options) {
                Ok(c) => acc[i].push(c.e_b / args.eb - 1.0, c.e_d / truth.diameter_ratio() - 1.0),
                Err(_) => acc[i].failed += 1,
            }
        }
    }
    Ok(methods
        .into_iter()
        .zip(acc)
        .map(|((label, _, _), a)| (label, a))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(slip_start: f64) -> MonteCarloArgs {
        MonteCarloArgs {
            trials: 2,
            side: 2.0,
            runs: 5,
            meas_sigma: 0.0,
            slip: 0.0,
            substeps: 1,
            eb: 1.0,
            ed: 1.0,
            slip_start,
            slip_start_rad: 0.075,
            heading: true,
            meas_sigma_rad: 0.0,
            end_offset_mm: Vec::new(),
            seed: 1,
            format: Format::Text,
        }
    }

    #[test]
    fn a_slipping_start_turns_the_odometry_and_not_the_robot() {
        let g = Geometry::PAPER_NOMINAL;
        let mut rng = Rng::new(3);
        let (_, odo, m) = noisy_square(&g, &g, Direction::Cw, 2.0, &args(1.0), &mut rng);
        // Truth = belief and no noise: the only heading error is the phantom turn, ±75 mrad to
        // the tick quantisation of the turn (1e-5 rad here).
        let d = odocal::calibration::wrap_angle(m.theta_rad.unwrap() - odo.theta_rad);
        assert!((d.abs() - 0.075).abs() < 1e-4, "{d}");
        let (_, odo, m) = noisy_square(&g, &g, Direction::Cw, 2.0, &args(0.0), &mut rng);
        let d = odocal::calibration::wrap_angle(m.theta_rad.unwrap() - odo.theta_rad);
        assert!(d.abs() < 1e-9, "{d}");
    }

    #[test]
    fn an_end_offset_biases_the_closed_forms_and_not_the_exact_fits() {
        // E_b = 1.010, E_d = 0.995, 2 m squares, 1 mm / 1 mrad measurements, 0.2 % slip per
        // substep, every measured end shifted by (15, 5) mm; 40 trials. Measured with 200
        // trials: UMBmark-x E_b mean −3.3e-3 (−8.8e-4 without the offset), `exact` and
        // `exact-mocap`, which fit the offset, the same as without it to the last digit (the
        // fit without it, the heading at L: −3.7e-4, about its σ of 3.6e-4).
        let mut a = args(0.0);
        (a.trials, a.eb, a.ed, a.meas_sigma, a.meas_sigma_rad) = (40, 1.010, 0.995, 1e-3, 1e-3);
        (a.slip, a.substeps) = (0.002, 20);
        a.end_offset_mm = vec![15.0, 5.0];
        let shifted = simulate(&a).unwrap();
        a.end_offset_mm = Vec::new();
        let clean = simulate(&a).unwrap();
        let mean_eb = |rows: &[(String, Acc)], m: &str| {
            let (_, acc) = rows.iter().find(|(l, _)| l == m).unwrap();
            acc.mean_std(0).0
        };
        // The offset is projected out: the exact fits' estimates do not move (the standard
        // error of the mean over 40 trials is about 6e-5; the bound is far below it).
        for m in ["exact", EXACT_MOCAP] {
            let moved = (mean_eb(&shifted, m) - mean_eb(&clean, m)).abs();
            assert!(moved < 1e-9, "{m}: {moved}");
        }
        // UMBmark reads it as geometry: x shifted by 15 mm in both directions is, to it, a
        // wheelbase error (about 2.4e-3 of E_b on 2 m squares).
        let bias = mean_eb(&shifted, "umbmark-x") - mean_eb(&clean, "umbmark-x");
        assert!(bias < -1e-3, "{bias}");
    }
}
