//! Per-wheel speed control: PI with feed-forward and anti-windup.
//!
//! Units: wheel positions and speeds in encoder ticks (forward positive), ticks/s and ticks/s²;
//! output is a motor duty in `[-limit, limit]` (positive forward, see [`crate::motion::motor`]).
//!
//! Control law, per control period of length `dt`, with the reference and the measurement
//! given as the wheel's tick *increments* of the period:
//!
//! ```text
//! e    += Δref − Δmeas                 (integral of the speed error = position error, ticks)
//! E    += e·dt                         (integral of the position error, tick·s)
//! duty  = kff_v·v_ref + kff_a·a_ref    (feed-forward: inverse of the motor model)
//!       + kp·(Δref − Δmeas)/dt + ki·e  (PI on speed)
//!       + kii·E                        (removes the steady error of a wrong motor gain)
//! ```
//!
//! Because the integral of the speed error is exactly the position error, a wheel that follows
//! its reference returns to zero *position* error: two wheels that follow one profile stay
//! synchronised. The second integrator makes the loop type 2, so even a constant-speed leg
//! driven with a feed-forward whose motor gain is off (another motor, a low battery) settles
//! to zero position error instead of a lag proportional to the speed.
//!
//! Anti-windup: while the output saturates, neither integral is advanced in the saturating
//! direction, and each is clamped to the value that alone saturates the output. `f32` is enough
//! here: the integrals stay within a few hundred ticks and every increment is a per-period
//! difference; absolute positions never live in `f32`.
//!
//! [`SpeedTuning`] holds each wheel's plant ([`MotorParams`]: a first-order motor with a
//! dead-band, `τ v̇ + v = K_dir·(duty − sign(duty)·d₀)` for `|duty| > d₀`, `K_dir` the gain of the
//! direction) and the closed-loop bandwidth. [`SpeedTuning::gains`] derives the gains by pole
//! placement, all three closed-loop poles at `−ω_n`:
//! `τ s³ + (1 + kp K) s² + ki K s + kii K = τ (s + ω_n)³`, so `kp = (3 ω_n τ − 1)/K`,
//! `ki = 3 τ ω_n² / K`, `kii = τ ω_n³ / K` with `K` the mean of the two directions' gains, and the
//! feed-forward is the inverse of the plant: `duty_ff = (v + τ a)/K_dir`, and the dead-band is
//! inverted on the whole command (feed-forward plus feedback): `d₀·sign(u)` is added once `|u|`
//! exceeds a small smoothing width ([`DEADBAND_SMOOTHING`]). The gains
//! are derived when the tuning or the geometry changes ([`crate::motion::controller::Controller::set_tuning`]),
//! never per period.

use core::fmt;

use crate::util::num::clamp;
use crate::util::num::within;

/// Gains of one wheel's controller (ticks-based units, see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PiGains {
    /// Proportional gain on the speed error, duty per tick/s.
    pub kp: f32,
    /// Integral gain, duty per tick of position error.
    pub ki: f32,
    /// Second integral gain, duty per tick·s of integrated position error.
    pub kii: f32,
    /// Speed feed-forward forward (reference speed ≥ 0), duty per tick/s (`1/K_fwd`).
    pub kff_v: f32,
    /// Speed feed-forward backward (reference speed < 0), duty per tick/s (`1/K_back`).
    pub kff_v_back: f32,
    /// Motor time constant `τ`, s: the acceleration feed-forward is `kff_v·τ·a`.
    pub tau_s: f32,
    /// Dead-band compensation `d₀`, duty, added in the direction of the command.
    pub deadband: f32,
    /// `d₀ /` [`DEADBAND_SMOOTHING`]: the slope of the compensation's smooth step.
    pub deadband_slope: f32,
    /// Output limit (`0 < limit ≤ 1`), duty.
    pub output_limit: f32,
}

/// One wheel's motor as the speed loop models it (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct MotorParams {
    /// Steady wheel surface speed per unit duty above the dead-band, forward, m/s.
    pub gain_forward_mps: f32,
    /// The same backward (a magnitude), m/s.
    pub gain_backward_mps: f32,
    /// Time constant `τ` of the duty → speed lag, s.
    pub time_constant_s: f32,
    /// Dead-band `d₀`: the |duty| below which the wheel does not turn (static friction), duty.
    pub deadband: f32,
}

impl MotorParams {
    /// 1 m/s at full duty both ways, 50 ms lag, no dead-band.
    pub const DEFAULT: MotorParams = MotorParams {
        gain_forward_mps: 1.0,
        gain_backward_mps: 1.0,
        time_constant_s: 0.05,
        deadband: 0.0,
    };

    /// Accepted gain range, m/s per unit duty.
    pub const GAIN_RANGE: (f32, f32) = (0.01, 20.0);
    /// Accepted time-constant range, s.
    pub const TAU_RANGE: (f32, f32) = (0.001, 2.0);
    /// Accepted dead-band range, duty.
    pub const DEADBAND_RANGE: (f32, f32) = (0.0, 0.5);
    /// Accepted ratio of the forward to the backward gain (one motor's two directions differ by
    /// far less; a value outside is a typing error).
    pub const DIRECTION_RATIO_RANGE: (f32, f32) = (0.5, 2.0);

    /// Checks the parameters.
    ///
    /// # Errors
    /// The first offending field, as a [`TuningError`].
    pub fn validate(&self) -> Result<(), TuningError> {
        let in_range = |v: f32, (lo, hi): (f32, f32)| within(v, lo, hi);
        if !in_range(self.gain_forward_mps, Self::GAIN_RANGE)
            || !in_range(self.gain_backward_mps, Self::GAIN_RANGE)
        {
            return Err(TuningError::MotorGain);
        }
        if !in_range(
            self.gain_forward_mps / self.gain_backward_mps,
            Self::DIRECTION_RATIO_RANGE,
        ) {
            return Err(TuningError::DirectionRatio);
        }
        if !in_range(self.time_constant_s, Self::TAU_RANGE) {
            return Err(TuningError::TimeConstant);
        }
        if !in_range(self.deadband, Self::DEADBAND_RANGE) {
            return Err(TuningError::Deadband);
        }
        Ok(())
    }

    /// Mean of the two directions' gains, m/s per unit duty.
    pub fn mean_gain_mps(&self) -> f32 {
        0.5 * (self.gain_forward_mps + self.gain_backward_mps)
    }
}

impl Default for MotorParams {
    fn default() -> Self {
        MotorParams::DEFAULT
    }
}

/// Tuning of both speed loops, turned into [`PiGains`] per wheel by [`SpeedTuning::gains`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct SpeedTuning {
    /// Right motor.
    pub right: MotorParams,
    /// Left motor.
    pub left: MotorParams,
    /// Closed-loop pole frequency `ω_n` (all three poles at `−ω_n`), rad/s.
    pub bandwidth_radps: f32,
    /// Output limit, duty (`0 < limit ≤ 1`).
    pub output_limit: f32,
}

/// Why a [`SpeedTuning`] was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum TuningError {
    /// A motor gain is not finite or outside 0.01 ..= 20 m/s per unit duty.
    MotorGain,
    /// A motor's forward/backward gain ratio is outside 0.5 ..= 2.
    DirectionRatio,
    /// A time constant is not finite or outside 0.001 ..= 2 s.
    TimeConstant,
    /// A dead-band is not finite or outside 0 ..= 0.5.
    Deadband,
    /// The bandwidth is not finite or outside 1 ..= 200 rad/s.
    Bandwidth,
    /// The output limit is not within (0, 1].
    OutputLimit,
}

impl fmt::Display for TuningError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            TuningError::MotorGain => "motor gain must be within 0.01..20 m/s per unit duty",
            TuningError::DirectionRatio => {
                "a motor's forward/backward gain ratio must be within 0.5..2 (change the other \
                 direction first, or both in steps)"
            }
            TuningError::TimeConstant => "motor time constant must be within 0.001..2 s",
            TuningError::Deadband => "motor dead-band must be within 0..0.5 duty",
            TuningError::Bandwidth => "speed-loop bandwidth must be within 1..200 rad/s",
            TuningError::OutputLimit => "duty limit must be within (0, 1]",
        })
    }
}

impl SpeedTuning {
    /// Both motors [`MotorParams::DEFAULT`]; poles at 30 rad/s; full duty allowed.
    pub const DEFAULT: SpeedTuning = SpeedTuning {
        right: MotorParams::DEFAULT,
        left: MotorParams::DEFAULT,
        bandwidth_radps: 30.0,
        output_limit: 1.0,
    };

    /// Accepted bandwidth range, rad/s (a tenth of the slowest control rate's Nyquist band at
    /// most, so the continuous-time pole placement holds at 1 kHz).
    pub const BANDWIDTH_RANGE: (f32, f32) = (1.0, 200.0);

    /// Checks the tuning.
    ///
    /// # Errors
    /// The first offending field, as a [`TuningError`].
    pub fn validate(&self) -> Result<(), TuningError> {
        self.right.validate()?;
        self.left.validate()?;
        let (lo, hi) = Self::BANDWIDTH_RANGE;
        if !within(self.bandwidth_radps, lo, hi) {
            return Err(TuningError::Bandwidth);
        }
        if !(self.output_limit > 0.0 && self.output_limit <= 1.0) {
            return Err(TuningError::OutputLimit);
        }
        Ok(())
    }

    /// Stiffness of the default design: `3 ω_n τ` for 30 rad/s and 50 ms.
    pub const DEFAULT_STIFFNESS: f32 = 4.5;

    /// The bandwidth for motors whose faster time constant is `tau_min_s`: the default 30 rad/s,
    /// or faster for a fast motor so that `3 ω_n τ` keeps the default design's 4.5 (the
    /// proportional gain `kp·K = 3 ω_n τ − 1` is then never below the default's 3.5: a fast
    /// motor with a dead-band would otherwise get a soft loop that lets the wheels drift apart
    /// at low speed); at most 200 rad/s.
    pub fn bandwidth_for(tau_min_s: f32) -> f32 {
        let stiff = Self::DEFAULT_STIFFNESS / (3.0 * tau_min_s);
        clamp(
            libm::fmaxf(Self::DEFAULT.bandwidth_radps, stiff),
            Self::BANDWIDTH_RANGE.0,
            Self::BANDWIDTH_RANGE.1,
        )
    }

    /// The motor of `wheel`.
    pub fn motor(&self, wheel: crate::motion::wheel::Wheel) -> &MotorParams {
        match wheel {
            crate::motion::wheel::Wheel::Right => &self.right,
            crate::motion::wheel::Wheel::Left => &self.left,
        }
    }

    /// Gains for `motor` on a wheel whose travel per tick is `meters_per_tick` (> 0).
    pub fn gains(&self, motor: &MotorParams, meters_per_tick: f64) -> PiGains {
        // Motor gains in ticks/s per unit duty.
        let ticks = |mps: f32| (f64::from(mps) / meters_per_tick) as f32;
        let k = ticks(motor.mean_gain_mps());
        let tau = motor.time_constant_s;
        let wn = self.bandwidth_radps;
        PiGains {
            kp: libm::fmaxf(3.0 * wn * tau - 1.0, 0.0) / k,
            ki: 3.0 * tau * wn * wn / k,
            kii: tau * wn * wn * wn / k,
            kff_v: 1.0 / ticks(motor.gain_forward_mps),
            kff_v_back: 1.0 / ticks(motor.gain_backward_mps),
            tau_s: tau,
            deadband: motor.deadband,
            deadband_slope: motor.deadband / DEADBAND_SMOOTHING,
            output_limit: self.output_limit,
        }
    }
}

impl Default for SpeedTuning {
    fn default() -> Self {
        SpeedTuning::DEFAULT
    }
}

/// One period's reference for a wheel.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WheelReference {
    /// Reference increment over the period that just ended (the one the measured increment
    /// covers), ticks.
    pub delta_ticks: f32,
    /// Reference speed for the period that starts now (its midpoint), ticks/s.
    pub velocity_tps: f32,
    /// Reference acceleration for the period that starts now, ticks/s².
    pub accel_tps2: f32,
}

/// Evolving state of one wheel's controller.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpeedPiState {
    /// Integral of the speed error = position error, ticks (reference − measured).
    integral_ticks: f32,
    /// Integral of the position error, tick·s.
    integral2: f32,
}

impl SpeedPiState {
    /// Position error (reference − measured) accumulated since the last reset, ticks.
    pub fn position_error_ticks(&self) -> f32 {
        self.integral_ticks
    }
}

/// One wheel's PI speed controller (configuration; the state is [`SpeedPiState`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedPi {
    gains: PiGains,
    rate_hz: f32,
    /// `1 / rate_hz`, s.
    period_s: f32,
    /// The integrals' clamps (`limit / ki`, `limit / kii`; infinite for a zero gain).
    integral_max: (f32, f32),
}

impl SpeedPi {
    /// A controller with `gains` stepped at `rate_hz`.
    pub fn new(gains: PiGains, rate_hz: f32) -> Self {
        let bound = |k: f32| {
            if k > 0.0 {
                gains.output_limit / k
            } else {
                f32::INFINITY
            }
        };
        SpeedPi {
            gains,
            rate_hz,
            period_s: 1.0 / rate_hz,
            integral_max: (bound(gains.ki), bound(gains.kii)),
        }
    }

    /// The gains.
    pub fn gains(&self) -> &PiGains {
        &self.gains
    }

    /// One control period: `reference` for the period, `measured_delta` ticks counted by the
    /// encoder in it. Returns the duty for the next period.
    #[inline]
    pub fn step(
        &self,
        state: &mut SpeedPiState,
        reference: &WheelReference,
        measured_delta: f32,
    ) -> f32 {
        let g = &self.gains;
        let dt = self.period_s;
        let err_step = reference.delta_ticks - measured_delta;
        let v = reference.velocity_tps;
        // Inverse of the plant's gain (of the reference's direction) and lag.
        let kff = if v < 0.0 { g.kff_v_back } else { g.kff_v };
        let ff = kff * (v + g.tau_s * reference.accel_tps2);
        let p = g.kp * err_step * self.rate_hz;
        let i1 = state.integral_ticks + err_step;
        let i2 = state.integral2 + i1 * dt;
        let unsat = deadband_inverse(g, ff + p + g.ki * i1 + g.kii * i2);
        let limit = g.output_limit;
        let (m1, m2) = self.integral_max;
        // Nearly every period: the output within its limit and neither integral at its clamp.
        // Then nothing below changes the integrals' advance to `i1`, `i2`, and the output it
        // computes from them is `unsat` itself (the same expression of the same values), so
        // it is returned as it is, without recomputing it.
        if unsat <= limit && unsat >= -limit && i1 >= -m1 && i1 <= m1 && i2 >= -m2 && i2 <= m2 {
            state.integral_ticks = i1;
            state.integral2 = i2;
            return unsat;
        }
        // Conditional integration: do not wind further into a saturated output.
        // The sign of the saturation (0 when not saturated): an increment winds further into
        // it when their product is positive (one multiply and compare instead of branches).
        let saturation = if unsat > limit {
            1.0
        } else if unsat < -limit {
            -1.0
        } else {
            0.0
        };
        let winds = |inc: f32| inc * saturation > 0.0;
        if !winds(err_step) {
            state.integral_ticks = i1;
        }
        if !winds(state.integral_ticks) {
            state.integral2 += state.integral_ticks * dt;
        }
        // Clamp: an integral alone never needs more than the full output.
        state.integral_ticks = clamp(state.integral_ticks, -m1, m1);
        state.integral2 = clamp(state.integral2, -m2, m2);
        let out = deadband_inverse(
            g,
            ff + p + g.ki * state.integral_ticks + g.kii * state.integral2,
        );
        if out.is_nan() {
            0.0
        } else {
            clamp(out, -limit, limit)
        }
    }
}

/// Width of the smooth step of the dead-band inverse, duty.
pub const DEADBAND_SMOOTHING: f32 = 0.01;

/// The dead-band inverse on the linear command `u`: `u + d₀·sign(u)` once `|u|` exceeds
/// [`DEADBAND_SMOOTHING`], a straight line through zero below (no chatter between ±d₀ at rest).
/// It makes the motor with its dead-band look linear to the loop, also when the feedback alone
/// (a wheel held at rest with a position error) has to move it.
#[inline]
fn deadband_inverse(g: &PiGains, u: f32) -> f32 {
    u + clamp(u * g.deadband_slope, -g.deadband, g.deadband)
}

#[cfg(test)]
mod tests {
    use super::*;

    const M_PER_TICK: f64 = core::f64::consts::PI * 0.15 / 200_000.0;

    /// Exact discretisation of the first-order motor over one period with constant duty.
    fn plant(v: &mut f64, pos: &mut f64, duty: f32, k: f64, tau: f64, dt: f64) {
        let target = f64::from(duty) * k;
        let e = (-dt / tau).exp();
        *pos += target * dt + (*v - target) * tau * (1.0 - e);
        *v = target + (*v - target) * e;
    }

    /// Worst position error (ticks) while `pi` drives a ramp of `accel` m/s² from rest for
    /// `periods` 1 ms periods on a plant with lag `tau`; `motor` maps the commanded duty to the
    /// duty that reaches the motor and its gain (ticks/s per duty).
    fn ramp_error(
        pi: &SpeedPi,
        accel: f64,
        periods: u32,
        tau: f64,
        motor: impl Fn(f32) -> (f32, f64),
    ) -> f64 {
        let mut st = SpeedPiState::default();
        let (mut v, mut pos, mut meas_prev) = (0.0f64, 0.0f64, 0i64);
        let a = accel / M_PER_TICK; // in ticks/s²
        let mut duty = 0.0f32;
        let mut worst = 0.0f64;
        for i in 1..=periods {
            let (eff, k) = motor(duty);
            plant(&mut v, &mut pos, eff, k, tau, 1e-3);
            let t = f64::from(i) * 1e-3;
            let t0 = t - 1e-3;
            let r = WheelReference {
                delta_ticks: (0.5 * a * (t * t - t0 * t0)) as f32,
                velocity_tps: (a * (t + 0.5e-3)) as f32,
                accel_tps2: a as f32,
            };
            let meas = pos.floor() as i64;
            duty = pi.step(&mut st, &r, (meas - meas_prev) as f32);
            meas_prev = meas;
            worst = worst.max((0.5 * a * t * t - pos).abs());
        }
        worst
    }

    #[test]
    fn tracks_a_ramp_with_small_position_error() {
        let tuning = SpeedTuning::DEFAULT;
        let pi = SpeedPi::new(tuning.gains(&tuning.right, M_PER_TICK), 1000.0);
        // 1 m/s at duty 1 and τ = 50 ms, matching the tuning exactly; 0.3 m/s² for 1 s.
        let worst = ramp_error(&pi, 0.3, 1000, 0.05, |duty| (duty, 1.0 / M_PER_TICK));
        // With an exact motor model the feed-forward alone tracks (the duty is held over a
        // period, so the lag sees a step where the ramp is smooth: a·dt²/8-order, 0.02 tick);
        // what is left is the encoder's floor quantisation (< 1 tick) that the PI reacts to.
        // 2 ticks = 4.7 µm over a 0.15 m ramp.
        assert!(worst < 2.0, "worst position error {worst} ticks");
    }

    #[test]
    fn integral_removes_a_motor_gain_error() {
        let tuning = SpeedTuning::DEFAULT;
        let pi = SpeedPi::new(tuning.gains(&tuning.right, M_PER_TICK), 1000.0);
        // The real motor is 10 % weaker than the model.
        let k = 0.9 / M_PER_TICK;
        let mut st = SpeedPiState::default();
        let (mut v, mut pos, mut meas_prev) = (0.0f64, 0.0f64, 0i64);
        let speed = 0.2 / M_PER_TICK;
        let mut duty = 0.0;
        for i in 1..=3000 {
            plant(&mut v, &mut pos, duty, k, 0.05, 1e-3);
            let r = WheelReference {
                delta_ticks: (speed * 1e-3) as f32,
                velocity_tps: speed as f32,
                accel_tps2: 0.0,
            };
            let meas = pos.floor() as i64;
            duty = pi.step(&mut st, &r, (meas - meas_prev) as f32);
            meas_prev = meas;
            let _ = i;
        }
        let reference = speed * 3.0;
        // After 3 s (many closed-loop time constants) the position error is back to the
        // quantisation level: 2 ticks (1 from flooring, 1 from the last period's motion).
        assert!(
            (reference - pos).abs() < 2.0 + speed * 1e-3,
            "error {} ticks",
            reference - pos
        );
    }

    #[test]
    fn anti_windup_limits_the_integral() {
        let tuning = SpeedTuning::DEFAULT;
        let gains = tuning.gains(&tuning.right, M_PER_TICK);
        let pi = SpeedPi::new(gains, 1000.0);
        let mut st = SpeedPiState::default();
        // Blocked wheel: the reference runs away at 0.05 m/s (21 ticks per period) for 2 s.
        // That speed alone does not saturate the output, so only the integrals can wind up.
        let r = WheelReference {
            delta_ticks: (0.05e-3 / M_PER_TICK) as f32,
            velocity_tps: (0.05 / M_PER_TICK) as f32,
            accel_tps2: 0.0,
        };
        let mut duty = 0.0;
        for _ in 0..2000 {
            duty = pi.step(&mut st, &r, 0.0);
        }
        // Conditional integration parks the output at the limit, within one period's increment.
        assert!(duty > 0.99, "{duty}");
        // Without anti-windup the position error would be 2000 × 21.2 = 42,441 ticks and its
        // integral 42,441 tick·s; both are held where each alone saturates the output.
        assert!(st.integral_ticks <= 1.0 / gains.ki * 1.0001, "{st:?}");
        assert!(st.integral2 <= 1.0 / gains.kii * 1.0001, "{st:?}");
        assert!(st.integral_ticks > 0.0 && st.integral2 > 0.0);
        // Released, the wheel catches up at full speed and the duty drops below saturation as
        // soon as the error has been made up (within the 3,144-tick bound: < 8 periods at 1 m/s).
        let stop = WheelReference::default();
        let mut periods = 0;
        while pi.step(&mut st, &stop, 424.0) > 0.99 {
            periods += 1;
            assert!(periods < 8, "{st:?}");
        }
    }

    /// Worst position error (ticks) of a 0.3 m/s² backward ramp over 0.5 s on a motor with
    /// gains `k_fwd`/`k_back` (m/s per duty), lag `tau` and dead-band `d0`, controlled with
    /// `tuning`.
    fn backward_ramp_error(
        tuning: &SpeedTuning,
        k_fwd: f64,
        k_back: f64,
        tau: f64,
        d0: f32,
    ) -> f64 {
        let pi = SpeedPi::new(tuning.gains(&tuning.right, M_PER_TICK), 1000.0);
        ramp_error(&pi, -0.3, 500, tau, |duty| {
            // The dead-band eats d0 of the duty; the direction picks the gain.
            let eff = if duty.abs() > d0 {
                duty - d0.copysign(duty)
            } else {
                0.0
            };
            let k = if eff >= 0.0 { k_fwd } else { k_back } / M_PER_TICK;
            (eff, k)
        })
    }

    #[test]
    fn the_plant_tuning_removes_the_tracking_error_of_an_unusual_motor() {
        // A motor at half the default gain backward (0.6 forward), 3 × the lag, a 5 % dead-band.
        let (k_fwd, k_back, tau, d0) = (0.6, 0.5, 0.15, 0.05);
        let default = backward_ramp_error(&SpeedTuning::DEFAULT, k_fwd, k_back, tau, d0);
        let mut tuned = SpeedTuning::DEFAULT;
        tuned.right = MotorParams {
            gain_forward_mps: k_fwd as f32,
            gain_backward_mps: k_back as f32,
            time_constant_s: tau as f32,
            deadband: d0,
        };
        let matched = backward_ramp_error(&tuned, k_fwd, k_back, tau, d0);
        // With the plant model matching, the feed-forward tracks and only the encoder's floor
        // quantisation and the duty held over a period remain (as in the ramp test above:
        // a few ticks); the default model lags by hundreds of ticks while the integrators
        // catch up with the missing half of the duty and the dead-band.
        assert!(matched < 3.0, "matched model: {matched} ticks");
        assert!(
            default > 30.0 * matched,
            "default {default} vs matched {matched} ticks"
        );
    }

    #[test]
    fn tuning_validates() {
        let mut t = SpeedTuning::DEFAULT;
        t.left.gain_backward_mps = 0.4;
        assert_eq!(t.validate(), Err(TuningError::DirectionRatio));
        let mut t = SpeedTuning::DEFAULT;
        t.right.deadband = -0.1;
        assert_eq!(t.validate(), Err(TuningError::Deadband));
        let mut t = SpeedTuning::DEFAULT;
        t.right.time_constant_s = 3.0;
        assert_eq!(t.validate(), Err(TuningError::TimeConstant));
        assert_eq!(SpeedTuning::DEFAULT.validate(), Ok(()));
        let mut t = SpeedTuning::DEFAULT;
        t.output_limit = 0.0;
        assert_eq!(t.validate(), Err(TuningError::OutputLimit));
        let mut t = SpeedTuning::DEFAULT;
        t.bandwidth_radps = f32::NAN;
        assert_eq!(t.validate(), Err(TuningError::Bandwidth));
    }

    /// The control law as written before its shortcut for an unsaturated output: the
    /// conditional integration, the clamps, the output recomputed from the clamped integrals.
    fn general_law(
        pi: &SpeedPi,
        state: &mut SpeedPiState,
        reference: &WheelReference,
        measured_delta: f32,
    ) -> f32 {
        let g = &pi.gains;
        let dt = pi.period_s;
        let err_step = reference.delta_ticks - measured_delta;
        let v = reference.velocity_tps;
        let kff = if v < 0.0 { g.kff_v_back } else { g.kff_v };
        let ff = kff * (v + g.tau_s * reference.accel_tps2);
        let p = g.kp * err_step * pi.rate_hz;
        let i1 = state.integral_ticks + err_step;
        let i2 = state.integral2 + i1 * dt;
        let unsat = deadband_inverse(g, ff + p + g.ki * i1 + g.kii * i2);
        let limit = g.output_limit;
        let saturation = if unsat > limit {
            1.0
        } else if unsat < -limit {
            -1.0
        } else {
            0.0
        };
        let winds = |inc: f32| inc * saturation > 0.0;
        if !winds(err_step) {
            state.integral_ticks = i1;
        }
        if !winds(state.integral_ticks) {
            state.integral2 += state.integral_ticks * dt;
        }
        let (m1, m2) = pi.integral_max;
        state.integral_ticks = clamp(state.integral_ticks, -m1, m1);
        state.integral2 = clamp(state.integral2, -m2, m2);
        let out = deadband_inverse(
            g,
            ff + p + g.ki * state.integral_ticks + g.kii * state.integral2,
        );
        if out.is_nan() {
            0.0
        } else {
            clamp(out, -limit, limit)
        }
    }

    #[test]
    fn the_unsaturated_shortcut_is_the_general_law_bit_for_bit() {
        // A dead-band, a duty limit below 1 and states from rest to both clamps, references from
        // standstill to beyond saturation either way, and NaN: every output and state the same
        // bits as the general law's.
        let mut tuning = SpeedTuning::DEFAULT;
        tuning.right.deadband = 0.05;
        tuning.output_limit = 0.8;
        let pi = SpeedPi::new(tuning.gains(&tuning.right, M_PER_TICK), 1000.0);
        let (m1, m2) = pi.integral_max;
        let mut shortcut = 0;
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = |scale: f32| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            ((seed >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0) * scale
        };
        for i in 0..20_000 {
            let state = SpeedPiState {
                integral_ticks: next(1.2 * m1),
                integral2: next(1.2 * m2),
            };
            let reference = WheelReference {
                delta_ticks: next(600.0),
                velocity_tps: next(600_000.0),
                accel_tps2: next(2_000_000.0),
            };
            let measured = if i % 1000 == 0 { f32::NAN } else { next(600.0) };
            let (mut a, mut b) = (state, state);
            let fast = pi.step(&mut a, &reference, measured);
            let general = general_law(&pi, &mut b, &reference, measured);
            assert_eq!(
                fast.to_bits(),
                general.to_bits(),
                "{state:?} {reference:?} {measured}"
            );
            assert_eq!(a.integral_ticks.to_bits(), b.integral_ticks.to_bits());
            assert_eq!(a.integral2.to_bits(), b.integral2.to_bits());
            if fast.abs() < 0.8 && a.integral_ticks.abs() < m1 && a.integral2.abs() < m2 {
                shortcut += 1;
            }
        }
        // Both paths were taken many times.
        assert!((2_000..18_000).contains(&shortcut), "{shortcut}");
    }
}
