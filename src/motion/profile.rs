//! Motion limits and the trapezoidal velocity profile.
//!
//! [`MotionLimits`] are the operator-settable speed and acceleration limits of the robot
//! (metres, radians, seconds; the paper drives at 0.3 m/s). [`Trapezoid`] is a time-optimal
//! rest-to-rest profile over a positive distance under a speed and an acceleration limit: it
//! accelerates at `a`, cruises at `v`, decelerates at `a` (or is triangular when the distance is
//! too short to reach `v`). The unit of distance is whatever the caller uses (metres for a leg,
//! radians for an in-place turn); [`crate::motion::routine`] maps it linearly to wheel ticks so that both
//! wheels follow the one profile.
//!
//! Profiles are evaluated in closed form at `t = k / rate` (no integration, no drift). A profile
//! is planned in `f64` when its segment is planned (config time) and sampled in `f32` once per
//! control period: the Cortex-M4F's FPU is single precision, so a sample costs a few
//! instructions instead of soft-float calls. Why `f32` suffices: a sample's relative error is a
//! few units of 2⁻²⁴ of the profile's own distance and duration (each of the ≤ 4 operations
//! rounds once, the phase times are rounded once from `f64`), e.g. ≤ 1 µm on a 2 m leg; the
//! routine maps it to ticks relative to the segment start and ends every segment on an exact
//! integer target, so nothing of it accumulates.

use crate::kinematics::geometry::Geometry;
use crate::util::decimal::Plain;
use crate::util::num::{fmax, fmin, within};
use core::fmt;

/// Speed and acceleration limits of the robot's motion (validated by [`MotionLimits::validate`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct MotionLimits {
    /// Largest speed of the robot's centre (and of either wheel), m/s.
    pub max_speed_mps: f32,
    /// Largest acceleration of the robot's centre (and of either wheel), m/s².
    pub max_accel_mps2: f32,
    /// Largest turn rate, rad/s.
    pub max_turn_rate_radps: f32,
    /// Largest turn acceleration, rad/s².
    pub max_turn_accel_radps2: f32,
}

/// Why a [`MotionLimits`] was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum LimitsError {
    /// The speed is not finite or outside [`MotionLimits::SPEED_RANGE_MPS`].
    Speed,
    /// The acceleration is not finite or outside [`MotionLimits::ACCEL_RANGE_MPS2`].
    Accel,
    /// The turn rate is not finite or outside [`MotionLimits::TURN_RATE_RANGE_RADPS`].
    TurnRate,
    /// The turn acceleration is not finite or outside [`MotionLimits::TURN_ACCEL_RANGE_RADPS2`].
    TurnAccel,
    /// The fastest wheel speed the limits allow is more than the encoders can count
    /// ([`ENCODER_MAX_COUNT_RATE`] on the smaller wheel).
    BeyondEncoders,
}

/// Fastest count rate the board's encoder inputs follow reliably, counts/s: edges 1 µs apart,
/// 3.5 times the timers' input filter (286 ns, docs/hardware.md, Encoders), with room for the
/// rise time of open-collector encoders on their pull-ups. On 150 mm wheels with 200,000
/// counts per revolution that is 2.36 m/s.
pub const ENCODER_MAX_COUNT_RATE: f64 = 1_000_000.0;

impl fmt::Display for LimitsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (what, (lo, hi), unit) = match self {
            LimitsError::Speed => ("max speed", MotionLimits::SPEED_RANGE_MPS, "m/s"),
            LimitsError::Accel => ("max acceleration", MotionLimits::ACCEL_RANGE_MPS2, "m/s^2"),
            LimitsError::TurnRate => (
                "max turn rate",
                MotionLimits::TURN_RATE_RANGE_RADPS,
                "rad/s",
            ),
            LimitsError::TurnAccel => (
                "max turn acceleration",
                MotionLimits::TURN_ACCEL_RANGE_RADPS2,
                "rad/s^2",
            ),
            LimitsError::BeyondEncoders => {
                return f.write_str(
                    "the wheels would turn faster than the encoders can count (1,000,000 \
                     counts/s): lower max_speed or max_turn_rate",
                );
            }
        };
        write!(
            f,
            "{what} must be within {}..{} {unit}",
            Plain(lo),
            Plain(hi)
        )
    }
}

impl MotionLimits {
    /// The defaults: 0.3 m/s (as in the paper), 0.3 m/s², 1 rad/s, 2 rad/s².
    pub const DEFAULT: MotionLimits = MotionLimits {
        max_speed_mps: 0.3,
        max_accel_mps2: 0.3,
        max_turn_rate_radps: 1.0,
        max_turn_accel_radps2: 2.0,
    };

    /// The speeds `set max_speed` accepts and a stored record may hold, m/s.
    pub const SPEED_RANGE_MPS: (f64, f64) = (0.01, 2.0);
    /// The accelerations `set max_accel` accepts and a stored record may hold, m/s².
    pub const ACCEL_RANGE_MPS2: (f64, f64) = (0.01, 5.0);
    /// The turn rates `set max_turn_rate` accepts and a stored record may hold, rad/s.
    pub const TURN_RATE_RANGE_RADPS: (f64, f64) = (0.05, 10.0);
    /// The turn accelerations `set max_turn_accel` accepts and a stored record may hold, rad/s².
    pub const TURN_ACCEL_RANGE_RADPS2: (f64, f64) = (0.05, 20.0);

    /// Checks that every limit is finite and within its range.
    ///
    /// # Errors
    /// The first offending field, as a [`LimitsError`].
    pub fn validate(&self) -> Result<(), LimitsError> {
        // Compared as stored (`f32`): `set` stores a value within the range rounded by the same
        // monotone conversion, so it never falls outside it.
        let ok = |v: f32, (lo, hi): (f64, f64)| within(v, lo as f32, hi as f32);
        if !ok(self.max_speed_mps, Self::SPEED_RANGE_MPS) {
            return Err(LimitsError::Speed);
        }
        if !ok(self.max_accel_mps2, Self::ACCEL_RANGE_MPS2) {
            return Err(LimitsError::Accel);
        }
        if !ok(self.max_turn_rate_radps, Self::TURN_RATE_RANGE_RADPS) {
            return Err(LimitsError::TurnRate);
        }
        if !ok(self.max_turn_accel_radps2, Self::TURN_ACCEL_RANGE_RADPS2) {
            return Err(LimitsError::TurnAccel);
        }
        Ok(())
    }
}

impl MotionLimits {
    /// The fastest a wheel turns under these limits on `geometry`, m/s: the larger of the
    /// speed limit (which bounds either wheel too) and the turn rate's speed at a wheel (`ω·b/2`,
    /// a pivot).
    pub fn wheel_speed_mps(&self, geometry: &Geometry) -> f64 {
        fmax(
            f64::from(self.max_speed_mps),
            f64::from(self.max_turn_rate_radps) * 0.5 * geometry.wheelbase_m,
        )
    }

    /// [`MotionLimits::validate`], and the fastest wheel speed within what the encoders of
    /// `geometry` count ([`ENCODER_MAX_COUNT_RATE`] on the smaller wheel).
    ///
    /// # Errors
    /// As [`MotionLimits::validate`], or [`LimitsError::BeyondEncoders`].
    pub fn validate_for(&self, geometry: &Geometry) -> Result<(), LimitsError> {
        self.validate()?;
        let d = fmin(geometry.diameter_right_m, geometry.diameter_left_m);
        let countable = ENCODER_MAX_COUNT_RATE * core::f64::consts::PI * d
            / f64::from(geometry.counts_per_rev.max(1));
        if self.wheel_speed_mps(geometry) > countable {
            return Err(LimitsError::BeyondEncoders);
        }
        Ok(())
    }
}

impl Default for MotionLimits {
    fn default() -> Self {
        MotionLimits::DEFAULT
    }
}

/// One sample of a profile.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProfileSample {
    /// Distance travelled since the start, profile units.
    pub position: f32,
    /// Speed, units/s (never negative).
    pub velocity: f32,
    /// Acceleration, units/s².
    pub accel: f32,
}

/// A rest-to-rest trapezoidal (or triangular) velocity profile over a non-negative distance:
/// planned in `f64`, sampled in `f32` (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trapezoid {
    distance: f32,
    accel: f32,
    peak: f32,
    /// Phase ends, seconds since the start: acceleration over, profile over (the cruise ends
    /// at `end − t1`).
    t1: f32,
    end: f32,
}

impl Trapezoid {
    /// The profile over `distance ≥ 0` with speed limit `max_speed > 0` and acceleration limit
    /// `max_accel > 0`. Non-finite or non-positive limits, or a negative distance, give the
    /// empty profile (zero duration): a caller that validated its inputs never sees that.
    pub fn new(distance: f64, max_speed: f64, max_accel: f64) -> Self {
        let valid = distance.is_finite()
            && distance > 0.0
            && max_speed.is_finite()
            && max_speed > 0.0
            && max_accel.is_finite()
            && max_accel > 0.0;
        if !valid {
            return Trapezoid {
                distance: 0.0,
                accel: 1.0,
                peak: 0.0,
                t1: 0.0,
                end: 0.0,
            };
        }
        // Triangular when the speed limit cannot be reached: v_peak² / a = distance.
        let peak = fmin(max_speed, libm::sqrt(distance * max_accel));
        let t_accel = peak / max_accel;
        let t_cruise = fmax((distance - peak * t_accel) / peak, 0.0);
        Trapezoid {
            distance: distance as f32,
            accel: max_accel as f32,
            peak: peak as f32,
            t1: t_accel as f32,
            end: (2.0 * t_accel + t_cruise) as f32,
        }
    }

    /// Total distance, units.
    pub fn distance(&self) -> f32 {
        self.distance
    }

    /// Peak speed, units/s.
    pub fn peak_speed(&self) -> f32 {
        self.peak
    }

    /// Duration, seconds (as the samples see it: the planned duration rounded to `f32`).
    pub fn duration(&self) -> f64 {
        f64::from(self.end)
    }

    /// The profile at time `t` seconds since its start (clamped to `[0, duration]`).
    pub fn sample(&self, t: f32) -> ProfileSample {
        let (t1, end) = (self.t1, self.end);
        let t2 = end - t1;
        if t.is_nan() || t <= 0.0 {
            return ProfileSample::default();
        }
        if t >= end {
            return ProfileSample {
                position: self.distance,
                velocity: 0.0,
                accel: 0.0,
            };
        }
        let a = self.accel;
        if t < t1 {
            ProfileSample {
                position: 0.5 * a * t * t,
                velocity: a * t,
                accel: a,
            }
        } else if t < t2 {
            ProfileSample {
                position: self.peak * (t - 0.5 * t1),
                velocity: self.peak,
                accel: 0.0,
            }
        } else {
            // Time left, not time elapsed, so the end is approached without cancellation.
            let r = end - t;
            ProfileSample {
                position: self.distance - 0.5 * a * r * r,
                velocity: a * r,
                accel: -a,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_reaches_its_distance_and_respects_limits() {
        let p = Trapezoid::new(2.0, 0.3, 0.3);
        // 1 s accelerating (0.15 m), 0.15 m decelerating, 1.7 m at 0.3 m/s: 7.667 s in all
        // (held in f32: within 2⁻²⁴ relative, 0.5 µs).
        assert!((p.duration() - (2.0 + 1.7 / 0.3)).abs() < 1e-6);
        let mut prev = p.sample(0.0);
        let rate = 1000.0f32;
        let mut k = 1u32;
        while f64::from(k) / 1000.0 <= p.duration() + 2e-3 {
            let s = p.sample(k as f32 / rate);
            assert!(s.velocity <= 0.3 + 1e-6 && s.velocity >= 0.0);
            assert!(s.accel.abs() <= 0.3 + 1e-6);
            // Finite-difference speed agrees with the sampled speed within a·dt, plus the
            // rounding of two f32 positions near 2 m (2 × 2⁻²² m) over dt.
            let fd = (s.position - prev.position) * rate;
            assert!(
                (fd - s.velocity).abs() <= 0.3e-3 + 2.0 * 2.4e-7 * 1000.0,
                "t={k} ms"
            );
            prev = s;
            k += 1;
        }
        assert_eq!(prev.position, 2.0);
        assert_eq!(prev.velocity, 0.0);
    }

    /// The closed form in `f64`: the reference the `f32` samples are checked against.
    fn exact(d: f64, v: f64, a: f64, t: f64) -> f64 {
        let peak = v.min((d * a).sqrt());
        let t1 = peak / a;
        let t2 = t1 + (d - peak * t1) / peak;
        let end = t2 + t1;
        if t <= 0.0 {
            0.0
        } else if t >= end {
            d
        } else if t < t1 {
            0.5 * a * t * t
        } else if t < t2 {
            0.5 * peak * t1 + peak * (t - t1)
        } else {
            d - 0.5 * a * (end - t) * (end - t)
        }
    }

    #[test]
    fn f32_samples_stay_within_a_few_ulp_of_the_distance() {
        // A 2 m leg, a quarter turn (0.302 m of wheel travel as 1.571 rad) and the longest
        // valid segment (a circle of 100 m radius: 628 m) at 1 kHz and 10 kHz, at the period
        // instants the routine samples (t = k / rate, k an integer count).
        for (d, v, a) in [
            (2.0, 0.3, 0.3),
            (0.5 * core::f64::consts::PI, 1.0, 2.0),
            (628.3, 0.3, 0.3),
        ] {
            let p = Trapezoid::new(d, v, a);
            for rate in [1000u32, 10_000] {
                let periods = (p.duration() * f64::from(rate)).ceil() as u32;
                let stride = (periods / 20_000).max(1);
                let mut worst = 0.0f64;
                let mut k = 0;
                while k <= periods {
                    let t = k as f32 / rate as f32;
                    let s = p.sample(t);
                    let e = exact(d, v, a, f64::from(k) / f64::from(rate));
                    worst = worst.max((f64::from(s.position) - e).abs());
                    k += stride;
                }
                // Stated bound: 8 units of 2⁻²⁴ of the distance (each of the time, the phase
                // times and the ≤ 4 operations of a sample rounds once).
                assert!(
                    worst <= 8.0 * d / 16_777_216.0,
                    "d {d} rate {rate}: worst {worst:e}"
                );
            }
        }
    }

    #[test]
    fn short_distance_is_triangular() {
        let p = Trapezoid::new(0.01, 0.3, 0.3);
        // v_peak = sqrt(d a) = 0.0548 m/s < 0.3.
        assert!((f64::from(p.peak_speed()) - (0.01f64 * 0.3).sqrt()).abs() < 1e-8);
        let mid = p.sample((0.5 * p.duration()) as f32);
        assert!((mid.position - 0.005).abs() < 1e-8);
    }

    #[test]
    fn invalid_inputs_give_an_empty_profile() {
        for p in [
            Trapezoid::new(-1.0, 0.3, 0.3),
            Trapezoid::new(1.0, f64::NAN, 0.3),
            Trapezoid::new(1.0, 0.3, 0.0),
        ] {
            assert_eq!(p.duration(), 0.0);
            assert_eq!(p.sample(1.0).position, 0.0);
        }
    }

    #[test]
    fn limits_validate() {
        assert_eq!(MotionLimits::DEFAULT.validate(), Ok(()));
        let mut l = MotionLimits::DEFAULT;
        l.max_speed_mps = f32::INFINITY;
        assert_eq!(l.validate(), Err(LimitsError::Speed));
        let mut l = MotionLimits::DEFAULT;
        l.max_turn_accel_radps2 = -2.0;
        assert_eq!(l.validate(), Err(LimitsError::TurnAccel));
    }
}
