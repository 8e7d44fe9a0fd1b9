//! The robot: true geometry, motors, wheels, encoders and the true pose, one control period at a
//! time.

use core::f64::consts::PI;
use core::marker::PhantomData;

use super::motor::{BRAKE_TAU_RATIO, COAST_TAU_RATIO, MotorModel};
use super::numerics::{Lanes, Numerics, Portable};
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::PoseF64;
use crate::motion::controller::MotorCommand;
use crate::motion::motor::{MotorDriver, StopMode, clamp_duty};
use crate::motion::wheel::Wheel;
use crate::motion::wiring::Wiring;

/// Configuration of the simulated robot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobotConfig {
    /// The robot's true geometry.
    pub true_geometry: Geometry,
    /// Motors.
    pub motor: MotorModel,
    /// Control rate, Hz (one [`SimRobot::advance`] is one period).
    pub rate_hz: u32,
    /// Sub-steps per control period of the wheels' lag and the encoder counts (each one exact;
    /// they set the counts' rounding). The true pose moves on one exact arc per period.
    pub substeps: u32,
    /// Hardware counter values at power-up (right 32-bit, left 16-bit).
    pub initial_raw: (u32, u16),
    /// How this robot is really wired, against the board's standard: a reversed motor turns
    /// backward for a forward duty, a reversed encoder counts backward when its wheel rolls
    /// forward.
    pub wiring: Wiring,
}

impl RobotConfig {
    /// Defaults: 1 m/s motors with a 50 ms lag, the left motor 2 % weaker, 10 sub-steps,
    /// counters starting just below their wrap so that both wrap early in a run, standard
    /// wiring.
    pub fn new(true_geometry: Geometry, rate_hz: u32) -> Self {
        RobotConfig {
            true_geometry,
            motor: MotorModel::new(1.0, true_geometry.mean_diameter_m(), 0.05, 0.98),
            rate_hz,
            substeps: 10,
            initial_raw: (u32::MAX - 20_000, 300),
            wiring: Wiring::STANDARD,
        }
    }
}

/// Per-wheel physical state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct WheelState {
    /// Angular speed, rad/s.
    omega: f64,
    /// Rotation since power-up, encoder counts (continuous).
    counts: f64,
    /// Blocked (a stall): does not turn.
    blocked: bool,
}

/// `x.floor() as i64` without a library call (x86-64's baseline has no rounding instruction,
/// and `floor` is not in `core`): truncation toward zero, one less for a negative non-integer.
/// The same value for every `x`: beyond ±2^53 every `f64` is an integer, and out-of-range
/// values saturate as `as` does.
pub fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// The wheels' lag over the sub-steps of one control period (lanes: right, left wheel): what
/// stays the same in all of them.
struct Lag<P> {
    /// Sub-steps.
    n: u32,
    /// Target wheel speeds, rad/s.
    target: P,
    /// Target speeds times the sub-step, rad.
    target_h: P,
    /// Lag time constants, s.
    tau: P,
    /// The lag's decay over a sub-step, `exp(−h/τ)`.
    e: P,
    /// `1 − e`.
    one_minus_e: P,
    /// Encoder counts per revolution.
    cpr: P,
}

impl<P: Lanes> Lag<P> {
    /// Integrates the wheels over the period's sub-steps from the speeds `omega` and the
    /// continuous counts `counts` (both advanced to the period's end); returns each wheel's
    /// rotation over the period, rad.
    ///
    /// Each sub-step is the exact solution of `τ ω̇ + ω = target` over it; the counts add each
    /// sub-step's rotation in counts. Only this recursion is on the way from a command to the
    /// next counts the controller reads, so it is all the loop does (no calls, nothing spilled).
    #[inline(always)]
    fn integrate(&self, omega: &mut P, counts: &mut P) -> P {
        let rad_per_rev = P::splat(2.0 * PI);
        let mut turned = P::splat(0.0);
        for _ in 0..self.n {
            let lag = *omega - self.target;
            let dphi = self.target_h + lag * self.tau * self.one_minus_e;
            *omega = self.target + lag * self.e;
            *counts = *counts + dphi / rad_per_rev * self.cpr;
            turned = turned + dphi;
        }
        turned
    }
}

/// The nodes of the three-point Gauss–Legendre rule on a period, as fractions of it, and their
/// weights: exact for polynomials up to degree 5 in time.
const NODES: [f64; 3] = [
    0.5 - 0.387_298_334_620_741_7, // √(3/5) / 2
    0.5,
    0.5 + 0.387_298_334_620_741_7,
];
const WEIGHTS: [f64; 3] = [5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0];

/// A wheel's lag decays for a sub-step `h` and time constant `τ`: `exp(−h/τ)`, and at each of
/// the quadrature's nodes `t` of the period `n·h` the decay `exp(−t/τ)` and the rotation per
/// unit of initial lag up to it, `τ (1 − exp(−t/τ))` (0 and 0 for τ = 0: no lag).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Decay {
    h: f64,
    tau: f64,
    substep: f64,
    nodes: [(f64, f64); 3],
}

impl Decay {
    /// Nothing computed yet.
    const NONE: Decay = Decay {
        h: f64::NAN,
        tau: f64::NAN,
        substep: f64::NAN,
        nodes: [(f64::NAN, f64::NAN); 3],
    };
}

/// The sine and cosine of the heading at the start of a period, from an anchor heading whose
/// sine and cosine were computed exactly, by the angle-addition formulas for the difference
/// (below 0.01 rad: its series): no error accumulates from period to period, and the library
/// call is needed only when the heading has moved 0.01 rad from the anchor (every ten periods
/// of a 1 rad/s turn at 1 kHz, rarely on a leg).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Heading {
    anchor: f64,
    sin: f64,
    cos: f64,
}

/// `(sin δ, cos δ − 1)` for a heading change δ within a period: their Taylor series to `δ⁷`
/// and `δ⁸` for |δ| < 0.01 rad (truncation below `δ⁹/9! < 3e-24`), side by side in the
/// lanes (`sin δ / δ` and `(1 − cos δ)/(δ²/2)`), by multiplications with the reciprocals of
/// the coefficients; beyond, `sin_cos`.
#[inline(always)]
fn turn<N: Numerics>(d: f64) -> (f64, f64) {
    if libm::fabs(d) < 0.01 {
        let one = N::Pair::splat(1.0);
        let d2 = N::Pair::splat(d * d);
        let t = one - d2 * N::Pair::new(1.0 / 42.0, 1.0 / 56.0);
        let t = one - d2 * N::Pair::new(1.0 / 20.0, 1.0 / 30.0) * t;
        let t = one - d2 * N::Pair::new(1.0 / 6.0, 1.0 / 12.0) * t;
        (d * t.a(), -0.5 * (d * d) * t.b())
    } else {
        let (s, c) = N::sin_cos(d);
        (s, c - 1.0)
    }
}

/// The simulated robot: motors, wheels, encoders and the true pose, in `f64` through the
/// arithmetic of `N` ([`Portable`] unless a host build brings faster lanes).
#[derive(Clone, Debug)]
pub struct SimRobot<N: Numerics = Portable> {
    config: RobotConfig,
    right: WheelState,
    left: WheelState,
    pose: PoseF64,
    command: MotorCommand,
    periods: u64,
    /// Extra counts added to the raw right/left counters (glitch injection).
    raw_offset: (u32, u16),
    /// Speed at which a hand pushes the robot straight forward (motors ignored), m/s.
    push_mps: Option<f64>,
    /// The last decays of each wheel's lag (over a sub-step and to the quadrature's nodes):
    /// commands change rarely, so most periods reuse them.
    decay: [Decay; 2],
    /// The heading's sine and cosine anchor.
    heading: Heading,
    numerics: PhantomData<N>,
}

impl<N: Numerics> SimRobot<N> {
    /// A robot at rest at the origin, heading +x, motors braked.
    pub fn new(config: RobotConfig) -> Self {
        SimRobot {
            config,
            right: WheelState::default(),
            left: WheelState::default(),
            pose: PoseF64::default(),
            command: MotorCommand::Stop(StopMode::Brake),
            periods: 0,
            raw_offset: (0, 0),
            push_mps: None,
            decay: [Decay::NONE; 2],
            heading: Heading {
                anchor: 0.0,
                sin: 0.0,
                cos: 1.0,
            },
            numerics: PhantomData,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &RobotConfig {
        &self.config
    }

    /// Steps one control period of `rate_hz` per [`SimRobot::advance`] from now on (the board's
    /// controller was retimed).
    pub fn set_rate_hz(&mut self, rate_hz: u32) {
        self.config.rate_hz = rate_hz;
    }

    /// Changes the true wheel diameters and wheelbase from the next period on (a tyre worn, a
    /// load added): the pose, the wheels' speeds and the encoder counts stay as they are, and
    /// so do the encoder resolution (`geometry.counts_per_rev` is not used) and the motors
    /// (their gains are wheel turning rates: a smaller wheel rolls slower at the same duty).
    pub fn set_true_geometry(&mut self, geometry: Geometry) {
        self.config.true_geometry = Geometry {
            counts_per_rev: self.config.true_geometry.counts_per_rev,
            ..geometry
        };
    }

    /// True pose (start frame: origin, heading +x).
    pub fn true_pose(&self) -> PoseF64 {
        self.pose
    }

    /// Control periods simulated so far.
    pub fn periods(&self) -> u64 {
        self.periods
    }

    /// True wheel angular speeds (right, left), rad/s.
    pub fn wheel_speeds_radps(&self) -> (f64, f64) {
        (self.right.omega, self.left.omega)
    }

    /// True wheel speeds (right, left), m/s.
    pub fn wheel_speeds_mps(&self) -> (f64, f64) {
        let g = &self.config.true_geometry;
        (
            self.right.omega * 0.5 * g.diameter_right_m,
            self.left.omega * 0.5 * g.diameter_left_m,
        )
    }

    /// Quantised wheel rotation since power-up (right, left), counts, forward positive.
    pub fn counts(&self) -> (i64, i64) {
        (floor_i64(self.right.counts), floor_i64(self.left.counts))
    }

    /// The hardware counter values the board would read now (right 32-bit normal, left 16-bit
    /// inverted), as the `u32`s the controller takes.
    pub fn raw(&self) -> (u32, u32) {
        let (r, l) = self.counts();
        let w = self.config.wiring;
        let r = if w.encoder_right_reversed { -r } else { r };
        let l = if w.encoder_left_reversed { -l } else { l };
        let raw_r = self
            .config
            .initial_raw
            .0
            .wrapping_add(r as u32)
            .wrapping_add(self.raw_offset.0);
        let raw_l = self
            .config
            .initial_raw
            .1
            .wrapping_sub(l as u16)
            .wrapping_add(self.raw_offset.1);
        (raw_r, u32::from(raw_l))
    }

    /// Blocks (or frees) a wheel: it stops turning at once (a stall).
    pub fn set_blocked(&mut self, right: bool, left: bool) {
        self.right.blocked = right;
        self.left.blocked = left;
        if right {
            self.right.omega = 0.0;
        }
        if left {
            self.left.omega = 0.0;
        }
    }

    /// Makes a counter jump by `right`, `left` counts (electrical noise, a timer reset).
    pub fn inject_counter_jump(&mut self, right: u32, left: u16) {
        self.raw_offset.0 = self.raw_offset.0.wrapping_add(right);
        self.raw_offset.1 = self.raw_offset.1.wrapping_add(left);
    }

    /// A hand pushes the robot straight forward at `speed_mps` (the wheels roll with it and the
    /// motor commands have no effect), or stops pushing (`None`).
    pub fn set_push(&mut self, speed_mps: Option<f64>) {
        self.push_mps = speed_mps;
    }

    /// Sets the motor command held during the following periods.
    pub fn apply(&mut self, command: MotorCommand) {
        self.command = command;
    }

    /// The motor command held now.
    pub fn command(&self) -> MotorCommand {
        self.command
    }

    /// `(sin θ, cos θ)` of the heading `theta` ([`Heading`]).
    fn heading_sin_cos(&mut self, theta: f64) -> (f64, f64) {
        let h = &mut self.heading;
        let d = theta - h.anchor;
        if libm::fabs(d) < 0.01 {
            let (sin_d, cos_d_1) = turn::<N>(d);
            (
                h.sin + (h.sin * cos_d_1 + h.cos * sin_d),
                h.cos + (h.cos * cos_d_1 - h.sin * sin_d),
            )
        } else {
            let (sin, cos) = N::sin_cos(theta);
            *h = Heading {
                anchor: theta,
                sin,
                cos,
            };
            (sin, cos)
        }
    }

    /// Simulates one control period with the current command.
    pub fn advance(&mut self) {
        self.advance_slipping(1.0, 1.0);
    }

    /// Simulates one control period with the current command, each wheel's ground travel
    /// scaled by its slip factor (`slip_right`, `slip_left`; 1 = no slip) throughout the
    /// period. The encoders see the wheels' rotation, not their travel.
    pub fn advance_slipping(&mut self, slip_right: f64, slip_left: f64) {
        let c = self.config;
        let g = c.true_geometry;
        let n = c.substeps.max(1);
        let h = 1.0 / (f64::from(c.rate_hz) * f64::from(n));
        let m = c.motor;
        // The drive the dead-band leaves of a duty.
        let drive = |duty: f32, d0: f64| {
            let u = f64::from(clamp_duty(duty));
            if u.abs() > d0 {
                u - d0.copysign(u)
            } else {
                0.0
            }
        };
        let (tr, tl) = (m.time_constant_s, m.time_constant_left_s);
        let (target_r, target_l, tau_r, tau_l) = match self.command {
            MotorCommand::Duty { right, left } => (
                m.gain_right_radps * drive(right, m.deadband.0),
                m.gain_left_radps * drive(left, m.deadband.1),
                tr,
                tl,
            ),
            MotorCommand::Stop(StopMode::Brake) => {
                (0.0, 0.0, BRAKE_TAU_RATIO * tr, BRAKE_TAU_RATIO * tl)
            }
            MotorCommand::Stop(StopMode::Coast) => {
                (0.0, 0.0, COAST_TAU_RATIO * tr, COAST_TAU_RATIO * tl)
            }
        };
        let w = c.wiring;
        let (target_r, target_l, tau_r, tau_l) = match self.push_mps {
            // A push rolls both wheels at the pushed speed within about 20 ms.
            Some(v) => (
                v / (0.5 * g.diameter_right_m),
                v / (0.5 * g.diameter_left_m),
                0.02,
                0.02,
            ),
            None => (
                target_r * f64::from(w.motor_sign(Wheel::Right)),
                target_l * f64::from(w.motor_sign(Wheel::Left)),
                tau_r,
                tau_l,
            ),
        };
        // A blocked wheel does not turn: with ω = 0 and target 0 the lag's solution below
        // keeps it at rest.
        let blocked = (self.right.blocked, self.left.blocked);
        let (target_r, target_l) = (
            if blocked.0 { 0.0 } else { target_r },
            if blocked.1 { 0.0 } else { target_l },
        );
        for (w, b) in [(&mut self.right, blocked.0), (&mut self.left, blocked.1)] {
            if b {
                w.omega = 0.0;
            }
        }
        // The lag's decays, over a sub-step `e = exp(−h/τ)` (the same in every sub-step of the
        // period) and to the quadrature's nodes: the same in every period until h or τ change.
        let period_s = h * f64::from(n);
        let decay = |cache: &mut Decay, tau: f64| {
            if cache.h != h || cache.tau != tau {
                let exp = |t: f64| if tau > 0.0 { N::exp(-t / tau) } else { 0.0 };
                *cache = Decay {
                    h,
                    tau,
                    substep: exp(h),
                    nodes: NODES.map(|f| {
                        let e = exp(f * period_s);
                        (e, tau * (1.0 - e))
                    }),
                };
            }
            *cache
        };
        let [cache_r, cache_l] = &mut self.decay;
        let (decay_r, decay_l) = (decay(cache_r, tau_r), decay(cache_l, tau_l));
        let e = N::Pair::new(decay_r.substep, decay_l.substep);
        let target = N::Pair::new(target_r, target_l);
        let lag = Lag {
            n,
            target,
            target_h: target * N::Pair::splat(h),
            tau: N::Pair::new(tau_r, tau_l),
            e,
            one_minus_e: N::Pair::splat(1.0) - e,
            cpr: N::Pair::splat(f64::from(g.counts_per_rev)),
        };
        let omega0 = N::Pair::new(self.right.omega, self.left.omega);
        let mut omega = omega0;
        let mut counts = N::Pair::new(self.right.counts, self.left.counts);
        let turned = lag.integrate(&mut omega, &mut counts);
        self.right.omega = omega.a();
        self.left.omega = omega.b();
        self.right.counts = counts.a();
        self.left.counts = counts.b();
        // The pose over the period: with δ(t) the heading change and v(t) the speed since the
        // period start, the displacement is `e^{iθ₀} ∫ v e^{iδ} dt = e^{iθ₀} (s + ∫ v (e^{iδ} − 1) dt)`
        // with `s` the exact travel; the small remaining integral by Gauss–Legendre at three
        // nodes, where the lag's solution gives each wheel's speed and rotation exactly. Both
        // are smooth within a period (the duty is held), so the rule's error is far below a
        // nanometre per run (the plant's tests compare it with arcs a thousand times finer).
        let ground = N::Pair::new(0.5 * g.diameter_right_m, 0.5 * g.diameter_left_m)
            * N::Pair::new(slip_right, slip_left);
        let travel = turned * ground;
        let (ds_r, ds_l) = (travel.a(), travel.b());
        let lag0 = omega0 - target;
        let (mut along, mut across) = (0.0, 0.0);
        for ((f, w), (node_r, node_l)) in NODES
            .iter()
            .zip(WEIGHTS)
            .zip(decay_r.nodes.into_iter().zip(decay_l.nodes))
        {
            let speed = (target + lag0 * N::Pair::new(node_r.0, node_l.0)) * ground;
            let rotation = (target * N::Pair::splat(f * period_s)
                + lag0 * N::Pair::new(node_r.1, node_l.1))
                * ground;
            let v = 0.5 * (speed.a() + speed.b());
            let (sin_d, cos_d_1) = turn::<N>((rotation.a() - rotation.b()) / g.wheelbase_m);
            along += w * v * cos_d_1;
            across += w * v * sin_d;
        }
        let along = 0.5 * (ds_r + ds_l) + period_s * along;
        let across = period_s * across;
        let theta0 = self.pose.theta_rad;
        let (s0, c0) = self.heading_sin_cos(theta0);
        self.pose.x_m += c0 * along - s0 * across;
        self.pose.y_m += s0 * along + c0 * across;
        self.pose.theta_rad = theta0 + (ds_r - ds_l) / g.wheelbase_m;
        self.periods += 1;
    }
}

/// The robot's motors as the board's motor driver: the command is held for the following
/// periods, as PWM registers hold it.
impl<N: Numerics> MotorDriver for SimRobot<N> {
    fn set_duty(&mut self, right: f32, left: f32) {
        self.apply(MotorCommand::Duty { right, left });
    }

    fn stop(&mut self, mode: StopMode) {
        self.apply(MotorCommand::Stop(mode));
    }
}
