//! Track-size advice (Lee, Jung & Chung 2011, §2.3): the side `L` of the square that
//! minimises the expected parameter error of a method for this robot.
//!
//! Two effects pull in opposite directions. A small square makes small end errors, so the
//! measurement error dominates (random error ∝ σ/L). A large square lets non-systematic errors
//! grow and, for the closed-form methods, makes the small-angle approximations fail (bias).
//! For each candidate side the advice computes:
//! - **bias**: the method evaluated on an ideal, noiseless square driven with the belief
//!   geometry by a robot with the estimated true geometry ([`super::synth`]); the exact method
//!   has no model bias;
//! - **random error**: per-coordinate variance of one end position
//!   `σ² = σ_meas² + σ_ns(L)²/2`, with the observed scatter `s` at side `L_obs` grown as
//!   `σ_ns(L) = s·(L/L_obs)^{3/2}` (slip noise: heading variance grows with distance, position
//!   variance with its cube), divided by the number of runs per direction and propagated
//!   through the method (closed form: central differences; exact: `(JᵀJ)⁻¹σ²` of the x, y end
//!   positions). Headings (Jung & Chung) use `σ_θ² = σ_θ,meas² + (σ_ns(L)/L)²`;
//! - **expected error** `sqrt(bias_b² + σ_b² + bias_d² + σ_d²)` of the relative errors of
//!   `E_b` and `E_d`.
//!
//! Limits, against a Monte Carlo whose slip is a random walk in distance (`host-sim sweep`,
//! docs/calibration.md): the closed forms' predictions hold to ~15 %; the exact method's is
//! optimistic by up to ~40 % where slip dominates its error, because the scatter is taken as
//! independent and equal per coordinate while a heading walk correlates the end errors.

// Dense 3×3 linear algebra reads best with explicit indices.
#![allow(clippy::needless_range_loop)]

use super::exact::solve;
use super::quality::propagate;
use super::stats::SquareStats;
use super::synth::{end_poses, square_knots};
use super::{Method, RunObservation, closed_form, wrap_angle};
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::{ArcModel, PoseF64};
use crate::motion::run::{Direction, PathKind};
use crate::util::num::fmax;

/// Sides the advice chooses from, metres.
pub const CANDIDATE_SIDES_M: [f64; 14] = [
    0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 16.0,
];

/// What the advice needs to know about the robot and the measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackAdviceInput {
    /// Geometry the robot will drive with.
    pub belief: Geometry,
    /// Best current estimate of the true geometry (e.g. an earlier calibration).
    pub estimate: Geometry,
    /// 1σ of one measured coordinate, metres.
    pub measurement_sigma_m: f64,
    /// 1σ of a measured heading, radians.
    pub measurement_sigma_rad: f64,
    /// Observed scatter (metres) of the end positions around their centre of gravity and the
    /// side (metres) it was observed at; `None` if unknown (measurement error only). Of the runs
    /// the advice trusts: a run the robust fit flagged is left out ([`observed`]).
    pub observed_scatter: Option<(f64, f64)>,
    /// Runs per direction (the flagged runs left out, as for the scatter).
    pub runs_per_direction: u32,
    /// Largest side that fits the floor, metres.
    pub max_side_m: f64,
}

/// The expected errors of a method at one side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackAdvice {
    /// Method.
    pub method: Method,
    /// Side, metres.
    pub side_m: f64,
    /// Relative bias of `E_b`.
    pub bias_e_b: f64,
    /// Relative bias of `E_d`.
    pub bias_e_d: f64,
    /// Relative 1σ of `E_b`.
    pub sigma_e_b: f64,
    /// Relative 1σ of `E_d`.
    pub sigma_e_d: f64,
    /// `sqrt(bias_b² + σ_b² + bias_d² + σ_d²)`.
    pub expected_error: f64,
}

/// What the advice reads from the measured runs it is given: the scatter of the squares' end
/// errors around each direction's centre of gravity ([`SquareStats::scatter_m`], `None` with
/// fewer than three squares or without one in each direction) and the runs per direction (the
/// fewer of CW and CCW, at least 1). The caller passes only the runs it trusts: a run the
/// robust fit flagged (a typing mistake, a bumped robot) would count as scatter and as a run.
pub fn observed(runs: &[RunObservation<'_>]) -> (Option<f64>, u32) {
    let scatter = SquareStats::from_runs(runs, false)
        .ok()
        .and_then(|s| s.scatter_m());
    let count = |d: Direction| {
        runs.iter()
            .filter(|o| matches!(o.path, PathKind::Square { direction, .. } if direction == d))
            .count()
    };
    let per_direction = count(Direction::Cw).min(count(Direction::Ccw)).max(1);
    (scatter, u32::try_from(per_direction).unwrap_or(u32::MAX))
}

impl TrackAdviceInput {
    fn coordinate_variance(&self, side_m: f64) -> (f64, f64) {
        let ns = self
            .observed_scatter
            .filter(|(_, at)| *at > 0.0)
            .map_or(0.0, |(s, at)| s * pow_1_5(side_m / at));
        let n = f64::from(self.runs_per_direction.max(1));
        let vxy = (self.measurement_sigma_m * self.measurement_sigma_m + 0.5 * ns * ns) / n;
        let vt = (self.measurement_sigma_rad * self.measurement_sigma_rad
            + (ns / side_m) * (ns / side_m))
            / n;
        (vxy, vt)
    }
}

/// Expected errors of `method` on a square of side `side_m`; `None` where the method fails.
pub fn evaluate(input: &TrackAdviceInput, method: Method, side_m: f64) -> Option<TrackAdvice> {
    let belief = &input.belief;
    let truth = &input.estimate;
    let (vxy, vt) = input.coordinate_variance(side_m);
    let cw = square_knots(belief, Direction::Cw, side_m);
    let ccw = square_knots(belief, Direction::Ccw, side_m);
    let err = |k: &[_]| {
        let (o, m) = end_poses(belief, truth, k);
        (
            m.x_m - o.x_m,
            m.y_m - o.y_m,
            wrap_angle(m.theta_rad.unwrap_or(0.0) - o.theta_rad),
        )
    };
    let (xc, yc, tc) = err(&cw);
    let (xa, ya, ta) = err(&ccw);
    let (bias_b, bias_d, sig_b, sig_d) = if method == Method::Exact {
        let [sd, sb] = exact_sigma(truth, &cw, &ccw, vxy)?;
        (0.0, 0.0, sb, sd / truth.diameter_ratio())
    } else {
        let (inputs, var) = if method == Method::JungChung {
            ([tc, 0.0, ta, 0.0], [vt, 0.0, vt, 0.0])
        } else {
            ([xc, yc, xa, ya], [vxy; 4])
        };
        let f = closed_form(method, &inputs, side_m, belief).ok()?;
        let g = belief.corrected(f.e_d, f.e_b, 1.0);
        let [sd, sb] = propagate(method, &inputs, &var, side_m, belief)?;
        (
            g.wheelbase_m / truth.wheelbase_m - 1.0,
            g.diameter_ratio() / truth.diameter_ratio() - 1.0,
            sb * belief.wheelbase_m / truth.wheelbase_m,
            sd * belief.diameter_ratio() / truth.diameter_ratio(),
        )
    };
    let expected = libm::sqrt(bias_b * bias_b + sig_b * sig_b + bias_d * bias_d + sig_d * sig_d);
    Some(TrackAdvice {
        method,
        side_m,
        bias_e_b: bias_b,
        bias_e_d: bias_d,
        sigma_e_b: sig_b,
        sigma_e_d: sig_d,
        expected_error: expected,
    })
}

/// `[σ of D_R/D_L, relative σ of b]` of the exact fit to one CW and one CCW square whose
/// x, y end positions have variance `var` (already divided by the number of runs).
fn exact_sigma(
    truth: &Geometry,
    cw: &[crate::kinematics::encoder::WheelTicks],
    ccw: &[crate::kinematics::encoder::WheelTicks],
    var: f64,
) -> Option<[f64; 2]> {
    let h = 1e-6;
    let p = [truth.diameter_ratio(), 1.0];
    let end = |q: [f64; 2], k: &[crate::kinematics::encoder::WheelTicks]| {
        let g = truth.with_factors(q[0], q[1], 1.0);
        ArcModel::from_geometry(&g).integrate(PoseF64::default(), k)
    };
    let mut a = [[0.0; 3]; 3];
    for k in [cw, ccw] {
        let mut j = [[0.0; 2]; 2];
        for i in 0..2 {
            let mut up = p;
            let mut dn = p;
            up[i] += h;
            dn[i] -= h;
            let (eu, ed) = (end(up, k), end(dn, k));
            j[0][i] = (eu.x_m - ed.x_m) / (2.0 * h);
            j[1][i] = (eu.y_m - ed.y_m) / (2.0 * h);
        }
        for row in j {
            for c in 0..2 {
                for d in 0..2 {
                    a[c][d] += row[c] * row[d];
                }
            }
        }
    }
    let c0 = solve(a, [1.0, 0.0, 0.0], 2)?;
    let c1 = solve(a, [0.0, 1.0, 0.0], 2)?;
    // The second parameter scales truth.b, so its σ is the relative error of b directly.
    Some([
        libm::sqrt(fmax(c0[0], 0.0) * var),
        libm::sqrt(fmax(c1[1], 0.0) * var),
    ])
}

/// The candidate side (≤ `input.max_side_m`) with the smallest expected error of `method`.
pub fn advise(input: &TrackAdviceInput, method: Method) -> Option<TrackAdvice> {
    CANDIDATE_SIDES_M
        .iter()
        .filter(|&&l| l <= input.max_side_m)
        .filter_map(|&l| evaluate(input, method, l))
        .min_by(|a, b| a.expected_error.total_cmp(&b.expected_error))
}

/// `r^1.5` as `r·√r`: within 2 ulp of `libm::pow(r, 1.5)` for `r ≥ 0` (√ and the product are
/// each correctly rounded), without linking `pow` (1.9 KB of flash) for this one use.
fn pow_1_5(r: f64) -> f64 {
    r * libm::sqrt(r)
}

#[cfg(test)]
mod tests {
    use super::pow_1_5;

    #[test]
    fn pow_1_5_matches_libm_pow() {
        // Side ratios from 1e-3 to 1e3 (sides 0.25..16 m against observations at 0.1..20 m
        // lie well inside). Two correctly rounded operations: ≤ 1 ulp each of relative error
        // 2^-53, plus pow's own < 1 ulp, so 4 · 2^-53 bounds the difference.
        let mut r = 1e-3;
        while r < 1e3 {
            let (ours, reference) = (pow_1_5(r), libm::pow(r, 1.5));
            let rel = libm::fabs(ours - reference) / reference;
            assert!(
                rel <= 4.0 * f64::EPSILON / 2.0,
                "{r}: {ours} vs {reference}"
            );
            r *= 1.001_37;
        }
        assert_eq!(pow_1_5(0.0), 0.0);
    }
}
