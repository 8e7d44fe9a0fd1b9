//! The uncertainty of the board's odometry, one model for the ROS 2 bridge (published with every
//! `nav_msgs/Odometry`) and for the `diff_drive_controller` export.
//!
//! **Pose.** Two kinds of error, propagated along the path the wheels actually drove:
//! - *systematic*, from the calibration: the true `E_d` and `E_b` differ from the applied ones by
//!   their 1σ (relative `σ_d = sd(E_d)/E_d`, `σ_b = sd(E_b)/E_b`). A relative change `δ_d` of
//!   `E_d` at a constant mean diameter moves each right step by `+δ_d/2` and each left step by
//!   `−δ_d/2`; a relative change `δ_b` of the wheelbase scales each heading step by `1 − δ_b`.
//!   The pose's first-order sensitivities `S_d = ∂pose/∂δ_d` and `S_b = ∂pose/∂δ_b` are
//!   integrated step by step (the exact derivative of the midpoint update, so a heading error
//!   turns into a lateral error with the distance driven after it), and contribute
//!   `σ_d² S_d S_dᵀ + σ_b² S_b S_bᵀ`: this grows linearly in 1σ with the rotation driven (E_b)
//!   and with distance (E_d, quadratically in the lateral direction);
//! - *random*, the per-metre slip term: each wheel's travel is off by an independent error of
//!   variance `k·|Δ|` (`k` in m²/m: the σ after one metre, squared), propagated as in any
//!   odometry filter (`P ← F P Fᵀ + G Q Gᵀ`): a random walk in distance and heading.
//!
//! The pose covariance is the sum, in the odometry frame (x, y, yaw; z, roll and pitch are
//! unobserved by a planar robot and get [`UNOBSERVED_VARIANCE`]).
//!
//! **Twist.** The board's wheel speeds are means over the stream period `T` of counted encoder
//! edges: an edge count is off by up to one count at each end (a triangular error of variance
//! `q²/6`, `q = πD/counts_per_rev`), so a wheel speed has variance `q²/(6T²)`; and the speed
//! loop changes the speed during the period by up to `a·T` (`a` the board's `max_accel`), so the
//! mean departs from the speed at the period's end by up to `a·T/2` (variance `(a·T/2)²/3`,
//! uniform). The robot's `v = (v_R + v_L)/2` and `ω = (v_R − v_L)/b` carry these.

/// Variance written for the components a planar robot's odometry does not observe (z, roll,
/// pitch; linear y and z, angular x and y of the twist), as ROS configurations of
/// `diff_drive_controller` commonly do.
pub const UNOBSERVED_VARIANCE: f64 = 1.0e6;

/// The slip term used when none is given: 2 mm of random travel error (1σ) per wheel after one
/// metre (σ² = 4e-6 m²/m), a robot with rubber tyres on a hard indoor floor.
pub const DEFAULT_SLIP_M: f64 = 0.002;

/// The relative 1σ of `E_d` and `E_b` assumed for a calibrated board when no session log gives
/// the calibration's own: `E_b`'s is the drift between sessions of one robot on one floor
/// (docs/calibration.md: 2.9e-3, 5–10 times a single session's 1σ), `E_d`'s a single session's.
pub const DEFAULT_SD_CALIBRATED: (f64, f64) = (5.0e-4, 3.0e-3);

/// The relative 1σ assumed for an uncalibrated board (nominal, tape-measured geometry): 1 %.
pub const DEFAULT_SD_NOMINAL: (f64, f64) = (1.0e-2, 1.0e-2);

/// The inputs of the pose model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Uncertainty {
    /// Relative 1σ of `E_d` (sd(E_d)/E_d).
    pub sd_d: f64,
    /// Relative 1σ of `E_b` (sd(E_b)/E_b).
    pub sd_b: f64,
    /// Random travel error variance per metre of each wheel, m²/m.
    pub slip_m2_per_m: f64,
}

/// The pose covariance along a path, step by step.
#[derive(Clone, Debug)]
pub struct PoseCovariance {
    wheelbase_m: f64,
    u: Uncertainty,
    theta: f64,
    s_d: [f64; 3],
    s_b: [f64; 3],
    p: [[f64; 3]; 3],
    /// Distance driven (mean of the wheels' absolute travel), m.
    pub distance_m: f64,
    /// Rotation driven (absolute), rad.
    pub rotation_rad: f64,
}

impl PoseCovariance {
    /// A model at the start of a path (zero covariance), for a robot of wheelbase `b`.
    pub fn new(wheelbase_m: f64, u: Uncertainty) -> PoseCovariance {
        PoseCovariance {
            wheelbase_m,
            u,
            theta: 0.0,
            s_d: [0.0; 3],
            s_b: [0.0; 3],
            p: [[0.0; 3]; 3],
            distance_m: 0.0,
            rotation_rad: 0.0,
        }
    }

    /// One step: the right and left wheels travelled `dr` and `dl` metres.
    pub fn step(&mut self, dr: f64, dl: f64) {
        let b = self.wheelbase_m;
        let ds = 0.5 * (dr + dl);
        let dth = (dr - dl) / b;
        let tm = self.theta + 0.5 * dth;
        let (s, c) = tm.sin_cos();
        // Systematic sensitivities (midpoint update differentiated).
        let ds_d = 0.25 * (dr - dl);
        let dth_d = ds / b;
        let dth_b = -dth;
        for (sens, d_ds, d_dth) in [(&mut self.s_d, ds_d, dth_d), (&mut self.s_b, 0.0, dth_b)] {
            let tm_sens = sens[2] + 0.5 * d_dth;
            sens[0] += d_ds * c - ds * s * tm_sens;
            sens[1] += d_ds * s + ds * c * tm_sens;
            sens[2] += d_dth;
        }
        // Random slip: P = F P Fᵀ + G Q Gᵀ.
        let f = [[1.0, 0.0, -ds * s], [0.0, 1.0, ds * c], [0.0, 0.0, 1.0]];
        let g = [
            [0.5 * c - ds * s / (2.0 * b), 0.5 * c + ds * s / (2.0 * b)],
            [0.5 * s + ds * c / (2.0 * b), 0.5 * s - ds * c / (2.0 * b)],
            [1.0 / b, -1.0 / b],
        ];
        let q = [
            self.u.slip_m2_per_m * dr.abs(),
            self.u.slip_m2_per_m * dl.abs(),
        ];
        let mut next = [[0.0; 3]; 3];
        for (i, row) in next.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                let mut fpf = 0.0;
                for k in 0..3 {
                    for l in 0..3 {
                        fpf += f[i][k] * self.p[k][l] * f[j][l];
                    }
                }
                *v = fpf + g[i][0] * q[0] * g[j][0] + g[i][1] * q[1] * g[j][1];
            }
        }
        self.p = next;
        self.theta += dth;
        self.distance_m += 0.5 * (dr.abs() + dl.abs());
        self.rotation_rad += dth.abs();
    }

    /// The 3×3 covariance of (x, y, yaw) now.
    pub fn xy_yaw(&self) -> [[f64; 3]; 3] {
        let mut m = self.p;
        for (i, row) in m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v += self.u.sd_d * self.u.sd_d * self.s_d[i] * self.s_d[j]
                    + self.u.sd_b * self.u.sd_b * self.s_b[i] * self.s_b[j];
            }
        }
        m
    }

    /// The row-major 6×6 covariance of (x, y, z, roll, pitch, yaw) as ROS writes it.
    pub fn ros(&self) -> [f64; 36] {
        let m = self.xy_yaw();
        let mut c = [0.0; 36];
        let idx = [0usize, 1, 5];
        for (a, &i) in idx.iter().enumerate() {
            for (b, &j) in idx.iter().enumerate() {
                c[i * 6 + j] = m[a][b];
            }
        }
        for k in [2usize, 3, 4] {
            c[k * 6 + k] = UNOBSERVED_VARIANCE;
        }
        c
    }
}

/// Variances of the forward speed (m²/s²) and the turn rate (rad²/s²) measured as the means of
/// the wheel speeds over `period_s` (see the module's text).
pub fn twist_variance(
    diameter_m: f64,
    counts_per_rev: u32,
    wheelbase_m: f64,
    period_s: f64,
    max_accel: f64,
) -> (f64, f64) {
    let q = std::f64::consts::PI * diameter_m / f64::from(counts_per_rev.max(1));
    let wheel = q * q / (6.0 * period_s * period_s) + (max_accel * period_s * 0.5).powi(2) / 3.0;
    // Independent wheels: v = (v_R + v_L)/2, ω = (v_R − v_L)/b.
    (0.5 * wheel, 2.0 * wheel / (wheelbase_m * wheelbase_m))
}

/// The row-major 6×6 twist covariance (vx, vy, vz, wx, wy, wz) of [`twist_variance`].
pub fn twist_ros(var_v: f64, var_w: f64) -> [f64; 36] {
    let mut c = [0.0; 36];
    c[0] = var_v;
    c[35] = var_w;
    for k in [1usize, 2, 3, 4] {
        c[k * 6 + k] = UNOBSERVED_VARIANCE;
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(u: Uncertainty, metres: f64) -> PoseCovariance {
        let mut m = PoseCovariance::new(0.4, u);
        for _ in 0..(metres * 1000.0) as usize {
            m.step(0.001, 0.001);
        }
        m
    }

    #[test]
    fn a_straight_line_bends_with_sd_e_d_and_walks_with_slip() {
        // E_d off by δ: heading error δ·s/b, lateral error δ·s²/(2b).
        let u = Uncertainty {
            sd_d: 1e-3,
            sd_b: 0.0,
            slip_m2_per_m: 0.0,
        };
        let c = straight(u, 2.0).xy_yaw();
        assert!((c[2][2].sqrt() - 1e-3 * 2.0 / 0.4).abs() < 1e-9, "{c:?}");
        assert!((c[1][1].sqrt() - 1e-3 * 4.0 / 0.8).abs() < 1e-6, "{c:?}");
        // Slip alone: along-track variance k·s/2 (mean of two independent wheels), heading
        // variance 2k·s/b².
        let u = Uncertainty {
            sd_d: 0.0,
            sd_b: 0.0,
            slip_m2_per_m: 4e-6,
        };
        let c = straight(u, 2.0).xy_yaw();
        assert!((c[0][0] - 4e-6).abs() < 1e-12, "{c:?}");
        assert!((c[2][2] - 2.0 * 4e-6 * 2.0 / 0.16).abs() < 1e-12, "{c:?}");
    }

    #[test]
    fn a_turn_in_place_errs_with_sd_e_b() {
        let u = Uncertainty {
            sd_d: 0.0,
            sd_b: 2e-3,
            slip_m2_per_m: 0.0,
        };
        let mut m = PoseCovariance::new(0.4, u);
        // A full turn: 2π·b/2 per wheel.
        let n = 1000;
        let arc = std::f64::consts::PI * 0.4 / f64::from(n);
        for _ in 0..n {
            m.step(arc, -arc);
        }
        let c = m.xy_yaw();
        let expected = 2.0 * std::f64::consts::PI * 2e-3;
        assert!((c[2][2].sqrt() / expected - 1.0).abs() < 1e-9, "{c:?}");
        assert!(c[0][0] < 1e-20 && c[1][1] < 1e-20, "no translation: {c:?}");
        assert!((m.rotation_rad - 2.0 * std::f64::consts::PI).abs() < 1e-9);
    }

    #[test]
    fn twist_variance_from_counts_and_acceleration() {
        // 1000 counts/rev on 0.1 m wheels, 10 ms: q = 0.314 mm, wheel σ² = q²/(6T²) + (aT/2)²/3.
        let (v, w) = twist_variance(0.1, 1000, 0.4, 0.01, 1.0);
        let q = std::f64::consts::PI * 0.1 / 1000.0;
        let wheel = q * q / 6e-4 + (0.005f64).powi(2) / 3.0;
        assert!((v - wheel / 2.0).abs() < 1e-15);
        assert!((w - 2.0 * wheel / 0.16).abs() < 1e-12);
    }
}
