//! The simulated robot: true kinematics, motors, encoders and (optional) wheel slip.
//!
//! - **True geometry** `D_R`, `D_L`, `b` (generally not the nominal ones the firmware believes).
//! - **Motors**: first-order lag from duty to wheel angular speed, `τ ω̇ + ω = K·duty`, integrated
//!   exactly over each sub-step (the duty is held for a control period, as the PWM does).
//!   A stop brakes (or coasts) with its own time constant.
//! - **Encoders**: the wheel angle is quantised to `counts_per_rev` counts per revolution (floor)
//!   and presented as wrapping hardware counters like the board's: right on a 32-bit timer, left
//!   on a 16-bit timer counting *down* when the wheel rolls forward.
//! - **Slip**: optional zero-mean multiplicative noise on each wheel's ground travel (not on its
//!   rotation, so the encoders do not see it), drawn once per control period from a seeded PCG
//!   generator (runs are reproducible); σ is given per millisecond and scaled by √(rate / 1 kHz)
//!   per period, so the slip accumulated over a path is the same at every control rate.
//! - **True pose** in `f64`, integrated as exact arcs per sub-step.
//!
//! [`Sim::run_until_idle`] steps the library's own [`Controller`] against this robot; nothing of
//! the firmware's logic is repeated here.

use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::{PoseF64, sinc};
use odocal::motion::controller::Wheel;
use odocal::motion::controller::{Controller, MotorCommand, Status, StepOutput};
use odocal::motion::motor::{MotorDriver, StopMode};
use odocal::motion::routine::SegmentKind;
use odocal::motion::wiring::Wiring;

use crate::sim::pair::Pair;

mod options;
pub use options::{MotorArgs, WiringOption};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

/// Motor model of both wheels: `τ ω̇ + ω = K·(duty − sign(duty)·d₀)` above the dead-band `d₀`
/// (the wheel gets no drive below it), a braked stop with `τ/2`, a coasting one with `4τ`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorModel {
    /// Right wheel angular speed per unit duty above the dead-band in steady state, rad/s.
    pub gain_right_radps: f64,
    /// Left wheel angular speed per unit duty above the dead-band in steady state, rad/s.
    pub gain_left_radps: f64,
    /// Time constant of the right motor's duty → speed lag, s.
    pub time_constant_s: f64,
    /// Time constant of the left motor's lag, s.
    pub time_constant_left_s: f64,
    /// Dead-band of the right and left motor, duty.
    pub deadband: (f64, f64),
}

/// A braked stop's time constant against the motor's.
pub const BRAKE_TAU_RATIO: f64 = 0.5;
/// A coasting stop's time constant against the motor's.
pub const COAST_TAU_RATIO: f64 = 4.0;

impl MotorModel {
    /// Motors reaching `speed_mps` at full duty on wheels of `diameter_m`, lag `tau_s`; the left
    /// motor is `left_ratio` times as strong as the right one; no dead-band.
    pub fn new(speed_mps: f64, diameter_m: f64, tau_s: f64, left_ratio: f64) -> Self {
        let w = 2.0 * speed_mps / diameter_m;
        MotorModel {
            gain_right_radps: w,
            gain_left_radps: w * left_ratio,
            time_constant_s: tau_s,
            time_constant_left_s: tau_s,
            deadband: (0.0, 0.0),
        }
    }

    /// Motors per wheel (right, left): full-duty surface speeds `speed_mps` (above the
    /// dead-band, m/s per unit duty) on wheels of `diameter_m`, lags `tau_s`, dead-bands
    /// `deadband`.
    pub fn per_wheel(
        speed_mps: (f64, f64),
        diameter_m: f64,
        tau_s: (f64, f64),
        deadband: (f64, f64),
    ) -> Self {
        MotorModel {
            gain_right_radps: 2.0 * speed_mps.0 / diameter_m,
            gain_left_radps: 2.0 * speed_mps.1 / diameter_m,
            time_constant_s: tau_s.0,
            time_constant_left_s: tau_s.1,
            deadband,
        }
    }
}

/// Configuration of the simulated robot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimConfig {
    /// The robot's true geometry.
    pub true_geometry: Geometry,
    /// Motors.
    pub motor: MotorModel,
    /// Control rate, Hz (one [`Sim::advance`] is one period).
    pub rate_hz: u32,
    /// Integration sub-steps per control period.
    pub substeps: u32,
    /// Standard deviation of the relative slip of each wheel's travel per 1 ms control period.
    /// At another rate each period draws `slip_sigma · √(rate / 1 kHz)`, so the slip
    /// accumulated over a distance has the same spread at every rate.
    pub slip_sigma: f64,
    /// Seed of the slip noise.
    pub seed: u64,
    /// Hardware counter values at power-up (right 32-bit, left 16-bit).
    pub initial_raw: (u32, u16),
    /// How this robot is really wired, against the board's standard: a reversed motor turns
    /// backward for a forward duty, a reversed encoder counts backward when its wheel rolls
    /// forward.
    pub wiring: Wiring,
}

impl SimConfig {
    /// Defaults: 1 m/s motors with a 50 ms lag, the left motor 2 % weaker, 10 sub-steps, no
    /// slip, counters starting just below their wrap so that both wrap early in a run.
    pub fn new(true_geometry: Geometry, rate_hz: u32) -> Self {
        SimConfig {
            true_geometry,
            motor: MotorModel::new(1.0, true_geometry.mean_diameter_m(), 0.05, 0.98),
            rate_hz,
            substeps: 10,
            slip_sigma: 0.0,
            seed: 1,
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
    /// Blocked (for stall tests): does not turn.
    blocked: bool,
}

/// What a closed-loop run produced.
#[derive(Clone, Debug, PartialEq)]
pub struct RunStats {
    /// Control periods stepped.
    pub periods: u64,
    /// Largest |wheel synchronisation error| during straight legs, ticks.
    pub peak_leg_sync_ticks: f64,
    /// Largest |tracking error| of either wheel, ticks.
    pub peak_tracking_ticks: f64,
    /// The last step's output.
    pub last: Option<StepOutput>,
    /// Whether the controller became idle (or faulted) within the step budget.
    pub completed: bool,
}

/// `x.floor() as i64`, without the library call `floor` is on x86-64's baseline (which has
/// no rounding instruction): truncation toward zero, one less for a negative non-integer.
/// The same value for every `x`: beyond ±2^53 every `f64` is an integer, and out-of-range
/// values saturate as `as` does.
fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// What stays the same in the sub-steps of one control period (lanes: right, left wheel;
/// or x, y).
struct Period {
    /// Sub-steps.
    n: u32,
    /// Target wheel speeds, rad/s.
    target: Pair,
    /// Target speeds times the sub-step, rad.
    target_h: Pair,
    /// Lag time constants, s.
    tau: Pair,
    /// The lag's decay over a sub-step, `exp(−h/τ)`.
    e: Pair,
    /// `1 − e`.
    one_minus_e: Pair,
    /// Encoder counts per revolution.
    cpr: Pair,
    /// Wheel radii, m.
    rho: Pair,
    /// This period's slip factors of the wheels' ground travel.
    slip: Pair,
    /// 1 / wheelbase, 1/m.
    inv_b: f64,
    /// `(cos θ₀, sin θ₀)` and `(−sin θ₀, cos θ₀)`: a step `(cos δ, sin δ)` relative to the
    /// heading θ₀ at the period start, rotated into the world frame, is
    /// `rot_cos · cos δ + rot_sin · sin δ`.
    rot_cos: Pair,
    rot_sin: Pair,
}

/// The state the sub-steps integrate.
#[derive(Clone, Copy)]
struct Substep {
    /// Wheel speeds, rad/s.
    omega: Pair,
    /// Wheel rotation since power-up, counts (continuous).
    counts: Pair,
    /// Position x, y, m.
    position: Pair,
    /// Heading change since the period start, rad.
    offset: f64,
}

impl Period {
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
    fn integrate<const SMALL_ONLY: bool>(&self, s: &mut Substep) -> bool {
        let one = Pair::splat(1.0);
        let (k3, k2, k1) = (
            Pair::new(1.0 / 42.0, 1.0 / 30.0),
            Pair::new(1.0 / 20.0, 1.0 / 12.0),
            Pair::new(1.0 / 6.0, 0.5),
        );
        let rad_per_rev = Pair::splat(2.0 * std::f64::consts::PI);
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
                let d2 = Pair::splat(d * d);
                let t = one - d2 * k3;
                let t = one - d2 * k2 * t;
                let t = one - d2 * k1 * t;
                (d * t.a(), t.b())
            } else if SMALL_ONLY {
                return false;
            } else {
                d.sin_cos()
            };
            s.position = s.position
                + Pair::splat(chord)
                    * (self.rot_cos * Pair::splat(cd) + self.rot_sin * Pair::splat(sd));
            s.offset += dtheta;
        }
        true
    }
}

/// The simulated robot.
#[derive(Clone, Debug)]
pub struct Sim {
    config: SimConfig,
    right: WheelState,
    left: WheelState,
    pose: PoseF64,
    command: MotorCommand,
    rng: Pcg64,
    periods: u64,
    /// Extra counts added to the raw right/left counters (glitch injection).
    raw_offset: (u32, u16),
    /// True pose when the counters were last read by [`Sim::step`].
    pose_at_read: PoseF64,
    /// Speed at which a hand pushes the robot straight forward (motors ignored), m/s.
    push_mps: Option<f64>,
    /// The last sub-step decay of each wheel's lag, `(h, τ, exp(−h/τ))`: commands change
    /// rarely, so most periods reuse it.
    decay: [(f64, f64, f64); 2],
}

impl Sim {
    /// A robot at rest at the origin, heading +x.
    pub fn new(config: SimConfig) -> Self {
        Sim {
            config,
            right: WheelState::default(),
            left: WheelState::default(),
            pose: PoseF64::default(),
            command: MotorCommand::Stop(StopMode::Brake),
            rng: Pcg64::seed_from_u64(config.seed),
            periods: 0,
            raw_offset: (0, 0),
            pose_at_read: PoseF64::default(),
            push_mps: None,
            decay: [(f64::NAN, f64::NAN, f64::NAN); 2],
        }
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// Steps one control period of `rate_hz` per [`Sim::advance`] from now on (the board's
    /// controller was retimed).
    pub fn set_rate_hz(&mut self, rate_hz: u32) {
        self.config.rate_hz = rate_hz;
    }

    /// True pose (start frame: origin, heading +x).
    pub fn true_pose(&self) -> PoseF64 {
        self.pose
    }

    /// True pose at the moment the controller last read the counters (the instant its tick
    /// totals, and so a run record's last knot, refer to).
    pub fn pose_at_last_read(&self) -> PoseF64 {
        self.pose_at_read
    }

    /// Control periods simulated so far.
    pub fn periods(&self) -> u64 {
        self.periods
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

    /// Standard normal sample (Box–Muller).
    fn normal(&mut self) -> f64 {
        let u1: f64 = 1.0 - self.rng.random::<f64>(); // (0, 1]
        let u2: f64 = self.rng.random::<f64>();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }

    /// Simulates one control period with the current command.
    pub fn advance(&mut self) {
        let c = self.config;
        let g = c.true_geometry;
        let n = c.substeps.max(1);
        let h = 1.0 / (f64::from(c.rate_hz) * f64::from(n));
        let (slip_r, slip_l) = if c.slip_sigma > 0.0 {
            let sigma = c.slip_sigma * (f64::from(c.rate_hz) / 1000.0).sqrt();
            (1.0 + sigma * self.normal(), 1.0 + sigma * self.normal())
        } else {
            (1.0, 1.0)
        };
        let m = c.motor;
        // The drive the dead-band leaves of a duty.
        let drive = |duty: f32, d0: f64| {
            let u = f64::from(odocal::motion::motor::clamp_duty(duty));
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
        // Both wheels side by side (lanes: right, left). A blocked wheel does not turn: with
        // ω = 0 and target 0 the lag's solution below keeps it at rest.
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
                *cache = (h, tau, if tau > 0.0 { (-h / tau).exp() } else { 0.0 });
            }
            cache.2
        };
        let [cache_r, cache_l] = &mut self.decay;
        let e = Pair::new(decay(cache_r, tau_r), decay(cache_l, tau_l));
        let target = Pair::new(target_r, target_l);
        let theta0 = self.pose.theta_rad;
        let (s0, c0) = theta0.sin_cos();
        let period = Period {
            n,
            target,
            target_h: target * Pair::splat(h),
            tau: Pair::new(tau_r, tau_l),
            e,
            one_minus_e: Pair::splat(1.0) - e,
            cpr: Pair::splat(f64::from(g.counts_per_rev)),
            rho: Pair::new(0.5 * g.diameter_right_m, 0.5 * g.diameter_left_m),
            slip: Pair::new(slip_r, slip_l),
            inv_b: 1.0 / g.wheelbase_m,
            rot_cos: Pair::new(c0, s0),
            rot_sin: Pair::new(-s0, c0),
        };
        let start = Substep {
            omega: Pair::new(self.right.omega, self.left.omega),
            counts: Pair::new(self.right.counts, self.left.counts),
            position: Pair::new(self.pose.x_m, self.pose.y_m),
            offset: 0.0,
        };
        // Nearly every period has only small angles: the pass without library calls (whose
        // clobbered registers would cost spills in every sub-step) gives up at the first
        // large one, and the general pass redoes the period from its start.
        let mut end = start;
        if !period.integrate::<true>(&mut end) {
            end = start;
            period.integrate::<false>(&mut end);
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

    /// One closed-loop period: the controller reads the counters, its command is applied and
    /// the robot moves for one period. Returns the controller's output.
    pub fn step(&mut self, controller: &mut Controller) -> StepOutput {
        self.step_with(|r, l, sim| {
            let out = controller.step(r, l);
            sim.apply(out.command);
            out
        })
    }

    /// One control period run by `control`: it gets the raw encoder counts read at the start
    /// of the period and the robot as the motor driver; then the robot moves for the period
    /// with the last command it was given.
    pub fn step_with(
        &mut self,
        control: impl FnOnce(u32, u32, &mut Sim) -> StepOutput,
    ) -> StepOutput {
        let (r, l) = self.raw();
        self.pose_at_read = self.pose;
        let out = control(r, l, self);
        self.advance();
        out
    }

    /// Steps `controller` until it is idle or faulted with its motors stopped (or `max_periods`
    /// have passed), calling `observe` after every period; it may act on the controller (abort,
    /// drive) or the robot (block a wheel).
    pub fn run_with<F>(
        &mut self,
        controller: &mut Controller,
        max_periods: u64,
        mut observe: F,
    ) -> RunStats
    where
        F: FnMut(&mut Sim, &mut Controller, &StepOutput),
    {
        let mut stats = RunStats {
            periods: 0,
            peak_leg_sync_ticks: 0.0,
            peak_tracking_ticks: 0.0,
            last: None,
            completed: false,
        };
        while stats.periods < max_periods {
            let out = self.step(controller);
            stats.periods += 1;
            if let Some(t) = out.tracking {
                if let SegmentKind::Straight { .. } = t.kind {
                    stats.peak_leg_sync_ticks = stats
                        .peak_leg_sync_ticks
                        .max(f64::from(t.sync_error_ticks().abs()));
                }
                stats.peak_tracking_ticks = stats
                    .peak_tracking_ticks
                    .max(f64::from(t.error_right_ticks.abs()))
                    .max(f64::from(t.error_left_ticks.abs()));
            }
            observe(self, controller, &out);
            stats.last = Some(out);
            let idle = matches!(controller.status(), Status::Idle | Status::Faulted(_));
            if idle && out.command.is_stop() {
                stats.completed = true;
                break;
            }
        }
        stats
    }

    /// [`Sim::run_with`] without an observer.
    pub fn run_until_idle(&mut self, controller: &mut Controller, max_periods: u64) -> RunStats {
        self.run_with(controller, max_periods, |_, _, _| {})
    }

    /// Keeps stepping an idle controller for `periods` (the robot comes to rest).
    pub fn rest(&mut self, controller: &mut Controller, periods: u64) {
        for _ in 0..periods {
            self.step(controller);
        }
    }
}

/// A controller with the board's default configuration at `rate_hz`, believing `belief`.
///
/// # Errors
/// The configuration error, as text (an invalid belief or rate).
pub fn default_controller(belief: Geometry, rate_hz: u32) -> Result<Controller, String> {
    let cfg = odocal::motion::controller::ControllerConfig::new(belief, rate_hz);
    Controller::new(cfg).map_err(|e| format!("controller config: {e}"))
}

/// The simulated robot's configuration: the paper's nominal robot with true factors `ed`, `eb`.
pub fn sim_config(ed: f64, eb: f64, slip: f64, seed: u64, rate_hz: u32) -> SimConfig {
    let truth = Geometry::PAPER_NOMINAL.with_factors(ed, eb, 1.0);
    let mut c = SimConfig::new(truth, rate_hz);
    c.slip_sigma = slip;
    c.seed = seed;
    c
}

/// The robot's motors as the board's motor driver: the command is held for the following
/// periods, as PWM registers hold it.
impl MotorDriver for Sim {
    fn set_duty(&mut self, right: f32, left: f32) {
        self.apply(MotorCommand::Duty { right, left });
    }

    fn stop(&mut self, mode: StopMode) {
        self.apply(MotorCommand::Stop(mode));
    }
}

#[cfg(test)]
mod tests;
