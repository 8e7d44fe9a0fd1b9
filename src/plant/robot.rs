//! The robot: true geometry, motors, wheels, encoders and the true pose, one control period at a
//! time.

use core::f64::consts::PI;
use core::marker::PhantomData;

use super::motor::{BRAKE_TAU_RATIO, COAST_TAU_RATIO, MotorModel};
use super::numerics::{Lanes, Numerics, Portable};
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::{PoseF64, sinc};
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
    /// Control rate, Hz (one [`Robot::advance`] is one period).
    pub rate_hz: u32,
    /// Integration sub-steps per control period.
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

/// What stays the same in the sub-steps of one control period (lanes: right, left wheel;
/// or x, y).
struct Period<P> {
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
    /// Wheel radii, m.
    rho: P,
    /// This period's slip factors of the wheels' ground travel.
    slip: P,
    /// 1 / wheelbase, 1/m.
    inv_b: f64,
    /// `(cos θ₀, sin θ₀)` and `(−sin θ₀, cos θ₀)`: a step `(cos δ, sin δ)` relative to the
    /// heading θ₀ at the period start, rotated into the world frame, is
    /// `rot_cos · cos δ + rot_sin · sin δ`.
    rot_cos: P,
    rot_sin: P,
}

/// The state the sub-steps integrate.
#[derive(Clone, Copy)]
struct Substep<P> {
    /// Wheel speeds, rad/s.
    omega: P,
    /// Wheel rotation since power-up, counts (continuous).
    counts: P,
    /// Position x, y, m.
    position: P,
    /// Heading change since the period start, rad.
    offset: f64,
}

impl<P: Lanes> Period<P> {
    /// Integrates the period's sub-steps from `s`.
    ///
    /// The wheels follow the exact solution of `τ ω̇ + ω = target` over each sub-step; the
    /// robot moves on the exact arc of the sub-step's wheel travel. Within the period the
    /// sub-steps rotate the heading by small angles δ from θ₀, whose sine and cosine come from
    /// their Taylor series up to δ⁷ and δ⁶ when |δ| < 0.01 rad (truncation error below
    /// δ⁸/8! < 3e-21), so one sincos per period suffices instead of one per sub-step. Both
    /// series are evaluated side by side (lanes: sin δ / δ, cos δ), their coefficients as
    /// multiplications by the reciprocals (a division costs several multiplications; the
    /// results differ by at most an ulp of the correction terms, far below the truncation error
    /// of the position).
    ///
    /// Returns whether it integrated the whole period: with `SMALL_ONLY` it gives up (`false`,
    /// `s` partly advanced) at the first angle beyond the series.
    #[inline(always)]
    fn integrate<N: Numerics<Pair = P>, const SMALL_ONLY: bool>(&self, s: &mut Substep<P>) -> bool {
        let one = P::splat(1.0);
        let (k3, k2, k1) = (
            P::new(1.0 / 42.0, 1.0 / 30.0),
            P::new(1.0 / 20.0, 1.0 / 12.0),
            P::new(1.0 / 6.0, 0.5),
        );
        let rad_per_rev = P::splat(2.0 * PI);
        for _ in 0..self.n {
            let lag = s.omega - self.target;
            let dphi = self.target_h + lag * self.tau * self.one_minus_e;
            s.omega = self.target + lag * self.e;
            s.counts = s.counts + dphi / rad_per_rev * self.cpr;
            let travel = dphi * self.rho * self.slip;
            let (ds_r, ds_l) = (travel.a(), travel.b());
            let ds = 0.5 * (ds_r + ds_l);
            let dtheta = (ds_r - ds_l) * self.inv_b;
            let u = 0.5 * dtheta;
            // `sinc(u)` as the library computes it, its series by reciprocals.
            let chord = if u.abs() < 1e-4 {
                let u2 = u * u;
                ds * (1.0 - u2 * (1.0 / 6.0) + u2 * u2 * (1.0 / 120.0))
            } else if SMALL_ONLY {
                return false;
            } else {
                ds * sinc(u)
            };
            let d = s.offset + u;
            let (sd, cd) = if d.abs() < 0.01 {
                let d2 = P::splat(d * d);
                let t = one - d2 * k3;
                let t = one - d2 * k2 * t;
                let t = one - d2 * k1 * t;
                (d * t.a(), t.b())
            } else if SMALL_ONLY {
                return false;
            } else {
                N::sin_cos(d)
            };
            s.position = s.position
                + P::splat(chord) * (self.rot_cos * P::splat(cd) + self.rot_sin * P::splat(sd));
            s.offset += dtheta;
        }
        true
    }
}

/// The simulated robot: motors, wheels, encoders and the true pose, in `f64` through the
/// arithmetic of `N` ([`Portable`] unless a host build brings faster lanes).
#[derive(Clone, Debug)]
pub struct Robot<N: Numerics = Portable> {
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
    /// The last sub-step decay of each wheel's lag, `(h, τ, exp(−h/τ))`: commands change
    /// rarely, so most periods reuse it.
    decay: [(f64, f64, f64); 2],
    numerics: PhantomData<N>,
}

impl<N: Numerics> Robot<N> {
    /// A robot at rest at the origin, heading +x, motors braked.
    pub fn new(config: RobotConfig) -> Self {
        Robot {
            config,
            right: WheelState::default(),
            left: WheelState::default(),
            pose: PoseF64::default(),
            command: MotorCommand::Stop(StopMode::Brake),
            periods: 0,
            raw_offset: (0, 0),
            push_mps: None,
            decay: [(f64::NAN, f64::NAN, f64::NAN); 2],
            numerics: PhantomData,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &RobotConfig {
        &self.config
    }

    /// Steps one control period of `rate_hz` per [`Robot::advance`] from now on (the board's
    /// controller was retimed).
    pub fn set_rate_hz(&mut self, rate_hz: u32) {
        self.config.rate_hz = rate_hz;
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
        // The lag's decay over one sub-step, `e = exp(−h/τ)`: the same in every sub-step of
        // the period (and in every period until h or τ change). τ = 0 (no lag) gives e = 0:
        // the speed is the target at once.
        let decay = |cache: &mut (f64, f64, f64), tau: f64| {
            if cache.0 != h || cache.1 != tau {
                *cache = (h, tau, if tau > 0.0 { N::exp(-h / tau) } else { 0.0 });
            }
            cache.2
        };
        let [cache_r, cache_l] = &mut self.decay;
        let e = N::Pair::new(decay(cache_r, tau_r), decay(cache_l, tau_l));
        let target = N::Pair::new(target_r, target_l);
        let theta0 = self.pose.theta_rad;
        let (s0, c0) = N::sin_cos(theta0);
        let period = Period {
            n,
            target,
            target_h: target * N::Pair::splat(h),
            tau: N::Pair::new(tau_r, tau_l),
            e,
            one_minus_e: N::Pair::splat(1.0) - e,
            cpr: N::Pair::splat(f64::from(g.counts_per_rev)),
            rho: N::Pair::new(0.5 * g.diameter_right_m, 0.5 * g.diameter_left_m),
            slip: N::Pair::new(slip_right, slip_left),
            inv_b: 1.0 / g.wheelbase_m,
            rot_cos: N::Pair::new(c0, s0),
            rot_sin: N::Pair::new(-s0, c0),
        };
        let start = Substep {
            omega: N::Pair::new(self.right.omega, self.left.omega),
            counts: N::Pair::new(self.right.counts, self.left.counts),
            position: N::Pair::new(self.pose.x_m, self.pose.y_m),
            offset: 0.0,
        };
        // Nearly every period has only small angles: the pass without library calls (whose
        // clobbered registers would cost spills in every sub-step) gives up at the first
        // large one, and the general pass redoes the period from its start.
        let mut end = start;
        if !period.integrate::<N, true>(&mut end) {
            end = start;
            period.integrate::<N, false>(&mut end);
        }
        self.right.omega = end.omega.a();
        self.left.omega = end.omega.b();
        self.right.counts = end.counts.a();
        self.left.counts = end.counts.b();
        self.pose.x_m = end.position.a();
        self.pose.y_m = end.position.b();
        self.pose.theta_rad = theta0 + end.offset;
        self.periods += 1;
    }
}

/// The robot's motors as the board's motor driver: the command is held for the following
/// periods, as PWM registers hold it.
impl<N: Numerics> MotorDriver for Robot<N> {
    fn set_duty(&mut self, right: f32, left: f32) {
        self.apply(MotorCommand::Duty { right, left });
    }

    fn stop(&mut self, mode: StopMode) {
        self.apply(MotorCommand::Stop(mode));
    }
}
