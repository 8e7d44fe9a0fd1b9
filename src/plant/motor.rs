//! The motors: duty → wheel angular speed through a first-order lag with a dead-band.

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
