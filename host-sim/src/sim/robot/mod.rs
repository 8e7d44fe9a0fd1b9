//! The simulated robot: the library's robot model ([`odocal::plant`]: true geometry, motors,
//! encoders, true pose) with host-sim's layers around it.
//!
//! - **Slip**: optional zero-mean multiplicative noise on each wheel's ground travel (not on its
//!   rotation, so the encoders do not see it), drawn once per control period from a seeded PCG
//!   generator (runs are reproducible) and handed to the model as the period's slip factors;
//!   σ is given per millisecond and scaled by √(rate / 1 kHz) per period, so the slip
//!   accumulated over a path is the same at every control rate.
//! - **Host arithmetic**: the model runs on SSE2 lanes and the platform's `exp`/`sin_cos`
//!   ([`crate::sim::pair::Host`]).
//! - **Closed loop**: [`Sim::run_until_idle`] steps the library's own [`Controller`] against
//!   the robot; nothing of the firmware's logic is repeated here.
//! - **Wear**: the true geometry changed mid-run ([`Sim::apply_wear`], `serial --wear`):
//!   the wheels and the wheelbase change, not the pose.
//! - **Played counts**: the wheels held and the encoders counting recorded motion instead
//!   ([`Sim::play_counts`], `serial --replay`), through the model's own counters.
//! - **Options**: the command line's motors, wiring and wear ([`MotorArgs`], [`WiringOption`],
//!   [`Wear`]).

use core::ops::{Deref, DerefMut};

use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;
use odocal::motion::controller::{Controller, MotorCommand, Status, StepOutput};
use odocal::motion::motor::{MotorDriver, StopMode};
use odocal::motion::path::SegmentKind;
use odocal::plant::{RobotConfig, SimRobot};

use crate::sim::pair::Host;

mod options;
pub use odocal::plant::{BRAKE_TAU_RATIO, COAST_TAU_RATIO, MotorModel};
pub use options::{MotorArgs, Wear, WiringOption, parse_wear};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

/// Configuration of the simulated robot: the model's ([`RobotConfig`], whose fields it
/// dereferences to: `config.rate_hz`, `config.motor`, …) and the slip layer's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimConfig {
    /// The robot model: true geometry, motors, control rate, sub-steps, counters, wiring.
    pub robot: RobotConfig,
    /// Standard deviation of the relative slip of each wheel's travel per 1 ms control period.
    /// At another rate each period draws `slip_sigma · √(rate / 1 kHz)`, so the slip
    /// accumulated over a distance has the same spread at every rate.
    pub slip_sigma: f64,
    /// Seed of the slip noise.
    pub seed: u64,
}

impl SimConfig {
    /// The model's defaults ([`RobotConfig::new`]: 1 m/s motors with a 50 ms lag, the left
    /// motor 2 % weaker, 10 sub-steps, counters starting just below their wrap), no slip.
    pub fn new(true_geometry: Geometry, rate_hz: u32) -> Self {
        SimConfig {
            robot: RobotConfig::new(true_geometry, rate_hz),
            slip_sigma: 0.0,
            seed: 1,
        }
    }
}

impl Deref for SimConfig {
    type Target = RobotConfig;

    fn deref(&self) -> &RobotConfig {
        &self.robot
    }
}

impl DerefMut for SimConfig {
    fn deref_mut(&mut self) -> &mut RobotConfig {
        &mut self.robot
    }
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

/// The simulated robot: the library's model with seeded slip.
#[derive(Clone, Debug)]
pub struct Sim {
    config: SimConfig,
    robot: SimRobot<Host>,
    rng: Pcg64,
    /// True pose when the counters were last read by [`Sim::step`].
    pose_at_read: PoseF64,
    /// The recorded counts the encoders show so far ([`Sim::play_counts`]); `None` while the
    /// wheels drive them.
    played: Option<WheelTicks>,
}

impl Sim {
    /// A robot at rest at the origin, heading +x.
    pub fn new(config: SimConfig) -> Self {
        Sim {
            config,
            robot: SimRobot::new(config.robot),
            rng: Pcg64::seed_from_u64(config.seed),
            pose_at_read: PoseF64::default(),
            played: None,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// Steps one control period of `rate_hz` per [`Sim::advance`] from now on (the board's
    /// controller was retimed).
    pub fn set_rate_hz(&mut self, rate_hz: u32) {
        self.config.robot.rate_hz = rate_hz;
        self.robot.set_rate_hz(rate_hz);
    }

    /// True pose (start frame: origin, heading +x).
    pub fn true_pose(&self) -> PoseF64 {
        self.robot.true_pose()
    }

    /// The robot's true factors become `wear`'s ([`true_geometry`], checked by [`parse_wear`])
    /// from the next period on: its wheel diameters and wheelbase change, its pose, wheel speeds
    /// and encoder counts do not.
    pub fn apply_wear(&mut self, wear: &Wear) {
        self.robot
            .set_true_geometry(true_geometry(wear.ed, wear.eb));
        self.config.robot.true_geometry = self.robot.config().true_geometry;
    }

    /// Recorded wheel motion as the encoders' counts: `total` forward counts per wheel on some
    /// recording's scale. The first call holds the wheels (the motors' commands no longer turn
    /// them, the true pose stays) and takes `total` as what the counters show now; each later
    /// call turns the counters by the difference from the previous `total`, as the model's own
    /// hardware counters count a wheel's rotation (wrapping, the left one counting down, through
    /// the robot's wiring).
    pub fn play_counts(&mut self, total: WheelTicks) {
        let Some(shown) = self.played else {
            self.robot.set_blocked(true, true);
            self.played = Some(total);
            return;
        };
        let d = total - shown;
        let w = self.config.wiring;
        let sign = |reversed: bool, n: i64| if reversed { -n } else { n };
        let (r, l) = (
            sign(w.encoder_right_reversed, d.right),
            sign(w.encoder_left_reversed, d.left),
        );
        // Wrapping casts: the counters are 32 and 16 bits wide; the left one counts down.
        self.robot
            .inject_counter_jump(r as u32, (l as u16).wrapping_neg());
        self.played = Some(total);
    }

    /// True pose at the moment the controller last read the counters (the instant its tick
    /// totals, and so a run record's last knot, refer to).
    pub fn pose_at_last_read(&self) -> PoseF64 {
        self.pose_at_read
    }

    /// Control periods simulated so far.
    pub fn periods(&self) -> u64 {
        self.robot.periods()
    }

    /// True wheel speeds (right, left), m/s.
    pub fn wheel_speeds_mps(&self) -> (f64, f64) {
        self.robot.wheel_speeds_mps()
    }

    /// Quantised wheel rotation since power-up (right, left), counts, forward positive (the
    /// wheels' own: not what [`Sim::play_counts`] makes the counters show).
    pub fn counts(&self) -> (i64, i64) {
        self.robot.counts()
    }

    /// The hardware counter values the board would read now (right 32-bit normal, left 16-bit
    /// inverted), as the `u32`s the controller takes.
    pub fn raw(&self) -> (u32, u32) {
        self.robot.raw()
    }

    /// Blocks (or frees) a wheel: it stops turning at once (a stall).
    pub fn set_blocked(&mut self, right: bool, left: bool) {
        self.robot.set_blocked(right, left);
    }

    /// Makes a counter jump by `right`, `left` counts (electrical noise, a timer reset).
    pub fn inject_counter_jump(&mut self, right: u32, left: u16) {
        self.robot.inject_counter_jump(right, left);
    }

    /// A hand pushes the robot straight forward at `speed_mps` (the wheels roll with it and the
    /// motor commands have no effect), or stops pushing (`None`).
    pub fn set_push(&mut self, speed_mps: Option<f64>) {
        self.robot.set_push(speed_mps);
    }

    /// Sets the motor command held during the following periods.
    pub fn apply(&mut self, command: MotorCommand) {
        self.robot.apply(command);
    }

    /// Standard normal sample (Box–Muller).
    fn normal(&mut self) -> f64 {
        let u1: f64 = 1.0 - self.rng.random::<f64>(); // (0, 1]
        let u2: f64 = self.rng.random::<f64>();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }

    /// Simulates one control period with the current command: this period's slip factors
    /// drawn (when there is slip), then the model's period.
    pub fn advance(&mut self) {
        let c = self.config;
        let (slip_r, slip_l) = if c.slip_sigma > 0.0 {
            let sigma = c.slip_sigma * (f64::from(c.rate_hz) / 1000.0).sqrt();
            (1.0 + sigma * self.normal(), 1.0 + sigma * self.normal())
        } else {
            (1.0, 1.0)
        };
        self.robot.advance_slipping(slip_r, slip_l);
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
        self.pose_at_read = self.robot.true_pose();
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

/// The simulated robot's true geometry: the paper's nominal robot with true factors `ed`, `eb`
/// (its mean wheel diameter unchanged).
pub fn true_geometry(ed: f64, eb: f64) -> Geometry {
    Geometry::PAPER_NOMINAL.with_factors(ed, eb, 1.0)
}

/// The simulated robot's configuration: the paper's nominal robot with true factors `ed`, `eb`.
pub fn sim_config(ed: f64, eb: f64, slip: f64, seed: u64, rate_hz: u32) -> SimConfig {
    let truth = true_geometry(ed, eb);
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
