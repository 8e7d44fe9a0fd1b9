//! The simulated robot's motors and wiring as the command line sets them (`--motor-gain`,
//! `--motor-tau`, `--motor-deadband`, `--wiring`).

use odocal::motion::wiring::Wiring;

use super::{MotorModel, SimConfig};

/// The simulated motors as the command line sets them (`R,L` per wheel, or one value for
/// both): `--motor-gain` (m/s at full duty above the dead-band), `--motor-tau` (s),
/// `--motor-deadband` (duty). Without them the robot has the default motors (1 m/s, 50 ms, the
/// left one 2 % weaker, no dead-band).
#[derive(clap::Args, Debug, Clone, Default, PartialEq)]
pub struct MotorArgs {
    /// Motor gains R,L: wheel speed per unit duty above the dead-band, m/s (default 1.0,0.98).
    #[arg(long, value_delimiter = ',', num_args = 1..=2)]
    pub motor_gain: Vec<f64>,
    /// Motor time constants R,L, s (default 0.05).
    #[arg(long, value_delimiter = ',', num_args = 1..=2)]
    pub motor_tau: Vec<f64>,
    /// Motor dead-bands R,L, duty (default 0).
    #[arg(long, value_delimiter = ',', num_args = 1..=2)]
    pub motor_deadband: Vec<f64>,
}

impl MotorArgs {
    /// Whether any motor option was given (the motors differ from the defaults).
    pub fn any(&self) -> bool {
        !(self.motor_gain.is_empty() && self.motor_tau.is_empty() && self.motor_deadband.is_empty())
    }

    /// `(right, left)` of an `R,L` option (one value: both), or `default`.
    fn pair(v: &[f64], default: (f64, f64)) -> (f64, f64) {
        match v {
            [] => default,
            [x] => (*x, *x),
            [r, l, ..] => (*r, *l),
        }
    }

    /// The motors of `config` with these options applied.
    ///
    /// # Errors
    /// A value out of range, as text.
    pub fn apply(&self, config: &mut SimConfig) -> Result<(), String> {
        if !self.any() {
            return Ok(());
        }
        let d = config.true_geometry.mean_diameter_m();
        let m = config.motor;
        let gain = Self::pair(
            &self.motor_gain,
            (m.gain_right_radps * d / 2.0, m.gain_left_radps * d / 2.0),
        );
        let tau = Self::pair(&self.motor_tau, (m.time_constant_s, m.time_constant_left_s));
        let deadband = Self::pair(&self.motor_deadband, m.deadband);
        let ok = |v: f64, lo: f64, hi: f64| v.is_finite() && (lo..=hi).contains(&v);
        if !(ok(gain.0, 0.01, 20.0) && ok(gain.1, 0.01, 20.0)) {
            return Err("--motor-gain must be within 0.01..20 m/s".into());
        }
        if !(ok(tau.0, 0.001, 2.0) && ok(tau.1, 0.001, 2.0)) {
            return Err("--motor-tau must be within 0.001..2 s".into());
        }
        if !(ok(deadband.0, 0.0, 0.5) && ok(deadband.1, 0.0, 0.5)) {
            return Err("--motor-deadband must be within 0..0.5".into());
        }
        config.motor = MotorModel::per_wheel(gain, d, tau, deadband);
        Ok(())
    }
}

/// A wiring fault of the simulated robot, as the command-line option `--wiring` names it.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WiringOption {
    /// Wired as the board expects.
    #[default]
    Standard,
    /// The right motor's leads are swapped.
    RightMotorReversed,
    /// The left motor's leads are swapped.
    LeftMotorReversed,
    /// The right encoder's A/B channels are swapped.
    RightEncoderReversed,
    /// The left encoder's A/B channels are swapped.
    LeftEncoderReversed,
}

impl WiringOption {
    /// The robot's wiring.
    pub fn wiring(self) -> Wiring {
        let mut w = Wiring::STANDARD;
        match self {
            WiringOption::Standard => {}
            WiringOption::RightMotorReversed => w.motor_right_reversed = true,
            WiringOption::LeftMotorReversed => w.motor_left_reversed = true,
            WiringOption::RightEncoderReversed => w.encoder_right_reversed = true,
            WiringOption::LeftEncoderReversed => w.encoder_left_reversed = true,
        }
        w
    }
}
