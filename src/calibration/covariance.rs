//! The uncertainty of odometry integrated with a calibrated geometry, one model for the ROS 2
//! bridge (published with every `nav_msgs/Odometry`), the `diff_drive_controller` export and
//! `host-sim replay`'s evaluation (its `final_pos_cov_m2` and NEES).
//!
//! Two kinds of error, propagated along the path the wheels actually drove:
//! - *systematic*, from the calibration: the true `E_d`, `E_b` and mean-diameter scale `E_s`
//!   differ from the applied ones by their relative 1σ (`σ_d`, `σ_b`, `σ_s`). A relative change
//!   `δ_d` of `E_d` at a constant mean diameter moves each right step by `+δ_d/2` and each left
//!   step by `−δ_d/2`; `δ_b` of the wheelbase scales each heading step by `1 − δ_b`; `δ_s` of
//!   the mean diameter scales both wheels' steps by `1 + δ_s`. The pose's first-order
//!   sensitivities are integrated step by step (the exact derivative of the midpoint update, so a
//!   heading error turns into a lateral error with the distance driven after it);
//! - *random*: each wheel's travel is off by an independent error of variance `k·|Δ|` (slip,
//!   `k` in m²/m), propagated as in any odometry filter (`P ← F P Fᵀ + G Q Gᵀ`); and the axle's
//!   midpoint moves by an independent error of variance `s·|Δθ|` in each of x and y (scrub, `s`
//!   in m²/rad: the contact points slide when the robot turns, in place above all, which wheel
//!   travel does not see).
//!
//! Which numbers: a session's own 1σ of `E_d`, `E_b` is far below what the next session finds
//! (docs/calibration.md: `E_b` drifts by 5–10 times a session's 1σ between sessions of one
//! robot on different days, by about 1e-3 between sessions of one evening), so the model never
//! takes them below a floor ([`Floor`]): [`SAME_DAY_FLOOR`] for a calibration less than a day
//! old, [`BETWEEN_SESSION_FLOOR`] for an older one or one of unknown age, none when told to
//! trust the session; `E_s` is a tape's [`TAPE_SCALE_SD`] unless a fit measured it; slip and
//! scrub are estimated from the calibration's own runs ([`RandomEstimate`]).

use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::reference::{ArcModel, PoseF64};
use crate::util::trig::sincos;

/// The slip term used when none is known: 2 mm of random travel error (1σ) per wheel after one
/// metre (σ² = 4e-6 m²/m), a robot with rubber tyres on a hard indoor floor.
pub const DEFAULT_SLIP_M: f64 = 0.002;

/// The least relative 1σ of `(E_d, E_b)` for a calibrated robot: `E_b`'s is the drift between
/// sessions of one robot on one floor (docs/calibration.md: 2.9e-3, 5–10 times a single
/// session's 1σ), `E_d`'s a single session's at its largest.
pub const BETWEEN_SESSION_FLOOR: (f64, f64) = (5.0e-4, 3.0e-3);

/// The least relative 1σ of `(E_d, E_b)` for a calibration less than [`SAME_DAY_S`] old: the
/// spread of sessions recorded within an hour of each other, rounded up (docs/calibration.md:
/// the two pairs of shared sessions of one evening scatter by 1.3e-4 and 1.5e-4 in `E_d`, 0.8e-3
/// and 1.0e-3 in `E_b`, 1σ).
pub const SAME_DAY_FLOOR: (f64, f64) = (2.0e-4, 1.0e-3);

/// How long a calibration counts as the day's own, seconds: a day.
pub const SAME_DAY_S: f64 = 86_400.0;

/// The least relative 1σ the model takes for `E_d`, `E_b` (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Floor {
    /// [`BETWEEN_SESSION_FLOOR`]: a calibration a day old or older, or of unknown age.
    BetweenSessions,
    /// [`SAME_DAY_FLOOR`]: a calibration from runs less than [`SAME_DAY_S`] old.
    SameDay,
    /// None: the calibration's own 1σ (`--trust-session-sd`).
    TrustSession,
}

impl Floor {
    /// The floor for a calibration whose oldest run is `age_s` seconds from the odometry it
    /// corrects (`None`: unknown), or none with `trust_session`.
    pub fn for_age(age_s: Option<f64>, trust_session: bool) -> Floor {
        match age_s {
            _ if trust_session => Floor::TrustSession,
            Some(a) if libm::fabs(a) < SAME_DAY_S => Floor::SameDay,
            _ => Floor::BetweenSessions,
        }
    }

    /// The floor's relative 1σ of `(E_d, E_b)`.
    pub fn sd(self) -> (f64, f64) {
        match self {
            Floor::BetweenSessions => BETWEEN_SESSION_FLOOR,
            Floor::SameDay => SAME_DAY_FLOOR,
            Floor::TrustSession => (0.0, 0.0),
        }
    }
}

/// The relative 1σ of `(E_d, E_b)` for an uncalibrated robot (nominal, tape-measured
/// geometry): 1 %.
pub const NOMINAL_SD: (f64, f64) = (1.0e-2, 1.0e-2);

/// The relative 1σ of the mean wheel diameter measured with a tape (10 revolutions rolled out,
/// 1 mm on 4.7 m): squares do not correct it, so it stays in every calibration that did not fit
/// `E_s` (100 mm after 100 m).
pub const TAPE_SCALE_SD: f64 = 1.0e-3;

/// The inputs of the pose model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Uncertainty {
    /// Relative 1σ of `E_d` (sd(E_d)/E_d).
    pub sd_d: f64,
    /// Relative 1σ of `E_b` (sd(E_b)/E_b).
    pub sd_b: f64,
    /// Relative 1σ of the mean wheel diameter (sd(E_s)/E_s).
    pub sd_s: f64,
    /// Random travel error variance per metre of each wheel, m²/m.
    pub slip_m2_per_m: f64,
    /// Random position error variance per radian turned, in each of x and y, m²/rad: the
    /// scrub of the contact points when the robot turns (in place above all), which moves the
    /// axle's midpoint across as well as along.
    pub scrub_m2_per_rad: f64,
}

impl Uncertainty {
    /// A calibrated robot: the calibration's relative 1σ `(sd_d, sd_b)`, raised to `floor`
    /// (`None`, a calibration whose 1σ is not known: at least the between-session floor when
    /// told to trust it); the fitted relative 1σ of `E_s`, or [`TAPE_SCALE_SD`] when `E_s` was
    /// not fitted; `random` the slip and scrub ([`RandomError`]).
    pub fn calibrated(
        relative_sd: Option<(f64, f64)>,
        fitted_sd_s: Option<f64>,
        random: RandomError,
        floor: Floor,
    ) -> Uncertainty {
        let (sd_d, sd_b) = relative_sd.unwrap_or((0.0, 0.0));
        let floor = match floor {
            Floor::TrustSession if relative_sd.is_none() => Floor::BetweenSessions,
            f => f,
        };
        let (floor_d, floor_b) = floor.sd();
        Uncertainty {
            sd_d: crate::util::num::fmax(sd_d, floor_d),
            sd_b: crate::util::num::fmax(sd_b, floor_b),
            sd_s: fitted_sd_s.unwrap_or(TAPE_SCALE_SD),
            slip_m2_per_m: random.slip_m2_per_m,
            scrub_m2_per_rad: random.scrub_m2_per_rad,
        }
    }

    /// An uncalibrated robot: [`NOMINAL_SD`], a tape's scale, `random` slip and scrub.
    pub fn nominal(random: RandomError) -> Uncertainty {
        Uncertainty {
            sd_d: NOMINAL_SD.0,
            sd_b: NOMINAL_SD.1,
            sd_s: TAPE_SCALE_SD,
            slip_m2_per_m: random.slip_m2_per_m,
            scrub_m2_per_rad: random.scrub_m2_per_rad,
        }
    }
}

/// The random part of the model: slip per metre of wheel travel, scrub per radian turned.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RandomError {
    /// Each wheel's travel error variance per metre, m²/m.
    pub slip_m2_per_m: f64,
    /// The position error variance per radian turned, in each of x and y, m²/rad.
    pub scrub_m2_per_rad: f64,
}

impl RandomError {
    /// No random error.
    pub const NONE: RandomError = RandomError {
        slip_m2_per_m: 0.0,
        scrub_m2_per_rad: 0.0,
    };

    /// What is assumed without a calibration's runs to estimate it from: [`DEFAULT_SLIP_M`] of
    /// slip per metre, and the scrub of 1 mm (1σ, each axis) per radian turned.
    pub const DEFAULT: RandomError = RandomError {
        slip_m2_per_m: DEFAULT_SLIP_M * DEFAULT_SLIP_M,
        scrub_m2_per_rad: DEFAULT_SCRUB_M * DEFAULT_SCRUB_M,
    };
}

/// The scrub used when none is known: 1 mm (1σ, each axis) per radian turned.
pub const DEFAULT_SCRUB_M: f64 = 0.001;

/// The pose covariance along a path, step by step.
#[derive(Clone, Debug)]
pub struct PoseCovariance {
    wheelbase_m: f64,
    u: Uncertainty,
    theta: f64,
    s_d: [f64; 3],
    s_b: [f64; 3],
    s_s: [f64; 3],
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
            s_s: [0.0; 3],
            p: [[0.0; 3]; 3],
            distance_m: 0.0,
            rotation_rad: 0.0,
        }
    }

    /// The model at the end of the path of `knots` (cumulative wheel ticks) driven with `model`'s
    /// geometry.
    pub fn along(model: &ArcModel, u: Uncertainty, knots: &[WheelTicks]) -> PoseCovariance {
        let mut c = PoseCovariance::new(model.wheelbase_m, u);
        for w in knots.windows(2) {
            let dr = (w[1].right - w[0].right) as f64 * model.right_m_per_tick;
            let dl = (w[1].left - w[0].left) as f64 * model.left_m_per_tick;
            c.step(dr, dl);
        }
        c
    }

    /// The model's inputs from now on: the calibration's 1σ applies to the whole path driven
    /// (it is read when the covariance is), the random part to the steps still to come.
    pub fn set_uncertainty(&mut self, u: Uncertainty) {
        self.u = u;
    }

    /// The same model from the start of a new path (the pose reset to the origin).
    pub fn restart(&mut self) {
        *self = PoseCovariance::new(self.wheelbase_m, self.u);
    }

    /// One step: the right and left wheels travelled `dr` and `dl` metres.
    pub fn step(&mut self, dr: f64, dl: f64) {
        let b = self.wheelbase_m;
        let ds = 0.5 * (dr + dl);
        let dth = (dr - dl) / b;
        let tm = self.theta + 0.5 * dth;
        let (s, c) = sincos(tm);
        // Systematic sensitivities (midpoint update differentiated): (∂ds, ∂dθ) per factor.
        let factors = [
            (&mut self.s_d, 0.25 * (dr - dl), ds / b),
            (&mut self.s_b, 0.0, -dth),
            (&mut self.s_s, ds, dth),
        ];
        for (sens, d_ds, d_dth) in factors {
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
                for (k, fk) in f[i].iter().enumerate() {
                    for (l, fl) in f[j].iter().enumerate() {
                        fpf += fk * self.p[k][l] * fl;
                    }
                }
                *v = fpf + g[i][0] * q[0] * g[j][0] + g[i][1] * q[1] * g[j][1];
            }
        }
        let scrub = self.u.scrub_m2_per_rad * dth.abs();
        next[0][0] += scrub;
        next[1][1] += scrub;
        self.p = next;
        self.theta += dth;
        self.distance_m += 0.5 * (dr.abs() + dl.abs());
        self.rotation_rad += dth.abs();
    }

    /// The 3×3 covariance of (x, y, yaw) now.
    pub fn xy_yaw(&self) -> [[f64; 3]; 3] {
        let u = &self.u;
        let mut m = self.p;
        for (i, row) in m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v += u.sd_d * u.sd_d * self.s_d[i] * self.s_d[j]
                    + u.sd_b * u.sd_b * self.s_b[i] * self.s_b[j]
                    + u.sd_s * u.sd_s * self.s_s[i] * self.s_s[j];
            }
        }
        m
    }

    /// The 2×2 covariance of the position (x, y), m² (symmetric to the bit).
    pub fn xy(&self) -> [[f64; 2]; 2] {
        let m = self.xy_yaw();
        let off = 0.5 * (m[0][1] + m[1][0]);
        [[m[0][0], off], [off, m[1][1]]]
    }
}

/// The normalised estimation error squared of a position error `e` (truth − odometry, m)
/// against its predicted covariance `p`: `eᵀ P⁻¹ e`, 2 on average when `p` is right; `None`
/// for a singular `p`.
pub fn nees(e: [f64; 2], p: [[f64; 2]; 2]) -> Option<f64> {
    let det = p[0][0] * p[1][1] - p[0][1] * p[1][0];
    if !(det > 0.0 && det.is_finite()) {
        return None;
    }
    let (a, b, c) = (p[1][1] / det, -p[0][1] / det, p[0][0] / det);
    Some(e[0] * e[0] * a + 2.0 * e[0] * e[1] * b + e[1] * e[1] * c)
}

/// The slip and scrub a calibration's own runs show: their run-to-run scatter. The runs of one
/// path (kind, size, direction; one session) share their systematic error, so each run's end
/// residual against the calibrated geometry is taken from the mean of its group's
/// (`d_i = e_i − ē`, scaled by `n/(n − 1)`), which leaves the random part alone; then least
/// squares on `|d_i|² ≈ k t_i + s u_i` over the runs, `t_i` the run's position variance trace at
/// `k` = 1 along its own wheel travel, `u_i = 2 R_i` its scrub trace at `s` = 1 (`R_i` the
/// radians it turned). Runs of one shape (squares of one side) cannot tell slip from scrub: then
/// the scrub is [`DEFAULT_SCRUB_M`]'s and the slip takes the rest. Neither is taken below 0.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RandomEstimate {
    // Sums of the normal equations of the two-parameter fit.
    tt: f64,
    tu: f64,
    uu: f64,
    te: f64,
    ue: f64,
    /// Runs added.
    pub runs: usize,
}

impl RandomEstimate {
    /// Adds one group of runs of one path (cumulative wheel ticks, and the end measured at
    /// `(x, y)` in the run's start frame) driven with `model`'s geometry; a group of fewer than
    /// two runs has no scatter and adds nothing.
    pub fn add_group<'a>(
        &mut self,
        model: &ArcModel,
        runs: impl IntoIterator<Item = (&'a [WheelTicks], (f64, f64))> + Clone,
    ) {
        let unit = Uncertainty {
            sd_d: 0.0,
            sd_b: 0.0,
            sd_s: 0.0,
            slip_m2_per_m: 1.0,
            scrub_m2_per_rad: 0.0,
        };
        // The residuals' mean (the group's systematic error).
        let (mut n, mut mx, mut my) = (0usize, 0.0, 0.0);
        for (knots, (x, y)) in runs.clone() {
            let end = model.integrate(PoseF64::default(), knots);
            mx += x - end.x_m;
            my += y - end.y_m;
            n += 1;
        }
        if n < 2 {
            return;
        }
        let nf = n as f64;
        let (mx, my) = (mx / nf, my / nf);
        for (knots, (x, y)) in runs {
            let end = model.integrate(PoseF64::default(), knots);
            let (dx, dy) = (x - end.x_m - mx, y - end.y_m - my);
            let e = (dx * dx + dy * dy) * nf / (nf - 1.0);
            let c = PoseCovariance::along(model, unit, knots);
            let (t, u) = (c.p[0][0] + c.p[1][1], 2.0 * c.rotation_rad);
            if !(e.is_finite() && t.is_finite() && u.is_finite() && t + u > 0.0) {
                continue;
            }
            self.tt += t * t;
            self.tu += t * u;
            self.uu += u * u;
            self.te += t * e;
            self.ue += u * e;
            self.runs += 1;
        }
    }

    /// The estimate; `None` without a run.
    pub fn random_error(&self) -> Option<RandomError> {
        if self.runs == 0 {
            return None;
        }
        let det = self.tt * self.uu - self.tu * self.tu;
        // Separable: the runs' shapes differ by more than rounding.
        if det > 1e-6 * self.tt * self.uu {
            let k = (self.uu * self.te - self.tu * self.ue) / det;
            let s = (self.tt * self.ue - self.tu * self.te) / det;
            if k >= 0.0 && s >= 0.0 {
                return Some(RandomError {
                    slip_m2_per_m: k,
                    scrub_m2_per_rad: s,
                });
            }
        }
        // One shape, or a negative share: the default scrub, the slip from the rest.
        let s = match self.ue > 0.0 && self.uu > 0.0 {
            true => DEFAULT_SCRUB_M * DEFAULT_SCRUB_M,
            false => 0.0,
        };
        let k = match self.tt > 0.0 {
            true => crate::util::num::fmax((self.te - s * self.tu) / self.tt, 0.0),
            false => 0.0,
        };
        Some(RandomError {
            slip_m2_per_m: k,
            scrub_m2_per_rad: s,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const NONE: Uncertainty = Uncertainty {
        sd_d: 0.0,
        sd_b: 0.0,
        sd_s: 0.0,
        slip_m2_per_m: 0.0,
        scrub_m2_per_rad: 0.0,
    };

    fn straight(u: Uncertainty, metres: f64) -> PoseCovariance {
        let mut m = PoseCovariance::new(0.4, u);
        for _ in 0..(metres * 1000.0) as usize {
            m.step(0.001, 0.001);
        }
        m
    }

    #[test]
    fn a_straight_line_bends_with_sd_e_d_stretches_with_sd_e_s_and_walks_with_slip() {
        // E_d off by δ: heading error δ·s/b, lateral error δ·s²/(2b).
        let c = straight(Uncertainty { sd_d: 1e-3, ..NONE }, 2.0).xy_yaw();
        assert!((c[2][2].sqrt() - 1e-3 * 2.0 / 0.4).abs() < 1e-9, "{c:?}");
        assert!((c[1][1].sqrt() - 1e-3 * 4.0 / 0.8).abs() < 1e-6, "{c:?}");
        // The scale: along-track 1σ = σ_s·s, nothing across.
        let c = straight(Uncertainty { sd_s: 1e-3, ..NONE }, 2.0).xy_yaw();
        assert!((c[0][0].sqrt() - 2e-3).abs() < 1e-12, "{c:?}");
        assert!(c[1][1] < 1e-24 && c[2][2] < 1e-24, "{c:?}");
        // Slip alone: along-track variance k·s/2, heading variance 2k·s/b².
        let m = straight(
            Uncertainty {
                slip_m2_per_m: 4e-6,
                ..NONE
            },
            2.0,
        );
        let c = m.xy_yaw();
        assert!((c[0][0] - 4e-6).abs() < 1e-12, "{c:?}");
        assert!((c[2][2] - 2.0 * 4e-6 * 2.0 / 0.16).abs() < 1e-12, "{c:?}");
    }

    #[test]
    fn a_turn_in_place_errs_with_sd_e_b_only() {
        let u = Uncertainty {
            sd_b: 2e-3,
            sd_s: 1e-3,
            ..NONE
        };
        let mut m = PoseCovariance::new(0.4, u);
        let n = 1000;
        let arc = core::f64::consts::PI * 0.4 / f64::from(n);
        for _ in 0..n {
            m.step(arc, -arc);
        }
        let c = m.xy_yaw();
        // Both wheels' scale moves the heading like the wheelbase, the other way: in quadrature.
        let per_rad = libm::sqrt(2e-3f64 * 2e-3 + 1e-3 * 1e-3);
        let expected = 2.0 * core::f64::consts::PI * per_rad;
        assert!((c[2][2].sqrt() / expected - 1.0).abs() < 1e-9, "{c:?}");
        assert!(c[0][0] < 1e-20 && c[1][1] < 1e-20, "no translation: {c:?}");
        m.restart();
        assert_eq!(m.xy_yaw(), [[0.0; 3]; 3]);
    }

    #[test]
    fn the_session_sd_is_floored_unless_trusted() {
        let r = RandomError::DEFAULT;
        let sd = Some((1e-5, 3.5e-8));
        let u = Uncertainty::calibrated(sd, None, r, Floor::BetweenSessions);
        assert_eq!((u.sd_d, u.sd_b, u.sd_s), (5e-4, 3e-3, TAPE_SCALE_SD));
        let d = Uncertainty::calibrated(sd, None, r, Floor::SameDay);
        assert_eq!((d.sd_d, d.sd_b), SAME_DAY_FLOOR);
        // A session 1σ above the floor is kept.
        let wide = Uncertainty::calibrated(Some((1e-5, 2e-3)), None, r, Floor::SameDay);
        assert_eq!(wide.sd_b, 2e-3);
        let t = Uncertainty::calibrated(sd, Some(2e-4), r, Floor::TrustSession);
        assert_eq!((t.sd_d, t.sd_b, t.sd_s), (1e-5, 3.5e-8, 2e-4));
        // No 1σ known: the between-session floor, trusted or not.
        let f = Uncertainty::calibrated(None, None, r, Floor::TrustSession);
        assert_eq!((f.sd_d, f.sd_b), BETWEEN_SESSION_FLOOR);
    }

    /// A calibration counts as the day's own for a day, before or after the odometry; of
    /// unknown age it is an old one.
    #[test]
    fn the_floor_follows_the_calibrations_age() {
        assert_eq!(Floor::for_age(Some(3_900.0), false), Floor::SameDay);
        assert_eq!(Floor::for_age(Some(-3_900.0), false), Floor::SameDay);
        assert_eq!(
            Floor::for_age(Some(SAME_DAY_S), false),
            Floor::BetweenSessions
        );
        assert_eq!(
            Floor::for_age(Some(11.0 * SAME_DAY_S), false),
            Floor::BetweenSessions
        );
        assert_eq!(Floor::for_age(None, false), Floor::BetweenSessions);
        assert_eq!(Floor::for_age(None, true), Floor::TrustSession);
        assert_eq!(Floor::for_age(Some(0.0), true), Floor::TrustSession);
    }

    /// A turn in place scrubs: the midpoint's variance grows by `s` per radian on each axis.
    #[test]
    fn a_turn_in_place_scrubs() {
        let u = Uncertainty {
            scrub_m2_per_rad: 1e-6,
            ..NONE
        };
        let mut m = PoseCovariance::new(0.4, u);
        let arc = core::f64::consts::PI * 0.2 / 1000.0;
        for _ in 0..1000 {
            m.step(arc, -arc);
        }
        let c = m.xy();
        assert!(
            (c[0][0] - 1e-6 * core::f64::consts::PI).abs() < 1e-15,
            "{c:?}"
        );
        assert!((c[1][1] - c[0][0]).abs() < 1e-18 && c[0][1] == 0.0, "{c:?}");
    }

    /// Squares of two sides whose ends miss by exactly the model's variance give the slip and
    /// scrub back; squares of one side give the default scrub and the slip from the rest.
    #[test]
    fn slip_and_scrub_come_back_from_the_runs() {
        let model = ArcModel {
            right_m_per_tick: 1e-4,
            left_m_per_tick: 1e-4,
            wheelbase_m: 0.4,
        };
        let truth = RandomError {
            slip_m2_per_m: 2e-6,
            scrub_m2_per_rad: 4e-7,
        };
        // A square: 4 × (L straight, 90° in place).
        let square = |side_m: f64| {
            let mut knots = std::vec![WheelTicks::new(0, 0)];
            let (mut r, mut l) = (0i64, 0i64);
            let leg = (side_m / 1e-4 / 20.0).round() as i64;
            let turn = (core::f64::consts::FRAC_PI_2 * 0.2 / 1e-4 / 10.0).round() as i64;
            for _ in 0..4 {
                for _ in 0..20 {
                    (r, l) = (r + leg, l + leg);
                    knots.push(WheelTicks::new(r, l));
                }
                for _ in 0..10 {
                    (r, l) = (r + turn, l - turn);
                    knots.push(WheelTicks::new(r, l));
                }
            }
            knots
        };
        let u = Uncertainty {
            slip_m2_per_m: truth.slip_m2_per_m,
            scrub_m2_per_rad: truth.scrub_m2_per_rad,
            ..NONE
        };
        // Two runs of one path, ends at a common offset ± the scatter: the offset (the group's
        // systematic error) drops out, and |d|²·n/(n−1) = the variance trace exactly.
        let run = |est: &mut RandomEstimate, knots: &[WheelTicks]| {
            let p = PoseCovariance::along(&model, u, knots).xy();
            let end = model.integrate(PoseF64::default(), knots);
            let miss = ((p[0][0] + p[1][1]) / 2.0).sqrt();
            let (ox, oy) = (0.01, -0.02);
            let ends = [
                (end.x_m + ox + miss, end.y_m + oy),
                (end.x_m + ox - miss, end.y_m + oy),
            ];
            est.add_group(&model, ends.map(|m| (knots, m)));
        };
        let mut est = RandomEstimate::default();
        for side in [0.75, 1.7] {
            run(&mut est, &square(side));
        }
        let got = est.random_error().unwrap();
        assert!(
            (got.slip_m2_per_m / truth.slip_m2_per_m - 1.0).abs() < 1e-6,
            "{got:?}"
        );
        assert!(
            (got.scrub_m2_per_rad / truth.scrub_m2_per_rad - 1.0).abs() < 1e-6,
            "{got:?}"
        );
        let mut one = RandomEstimate::default();
        run(&mut one, &square(1.0));
        let got = one.random_error().unwrap();
        assert_eq!(got.scrub_m2_per_rad, DEFAULT_SCRUB_M * DEFAULT_SCRUB_M);
        assert!(got.slip_m2_per_m > 0.0, "{got:?}");
        assert_eq!(RandomEstimate::default().random_error(), None);
    }

    #[test]
    fn nees_is_2_on_average_for_a_right_covariance() {
        let p = [[4e-6, 0.0], [0.0, 1e-6]];
        assert!((nees([2e-3, 1e-3], p).unwrap() - 2.0).abs() < 1e-12);
        assert_eq!(nees([1.0, 1.0], [[0.0; 2]; 2]), None);
    }
}
