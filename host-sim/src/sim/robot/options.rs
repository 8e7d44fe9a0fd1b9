//! The simulated robot's motors, wiring and wear as the command line sets them
//! (`--motor-gain`, `--motor-tau`, `--motor-deadband`, `--wiring`, `--wear`).

use odocal::motion::wiring::Wiring;

use super::{MotorModel, SimConfig, true_geometry};

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

/// A change of the robot's true geometry at a board time (`--wear T:ED:EB`): a tyre worn, a
/// load added.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wear {
    /// Board time at which it happens, seconds since boot.
    pub at_s: f64,
    /// The true E_d from then on.
    pub ed: f64,
    /// The true E_b from then on.
    pub eb: f64,
}

impl Wear {
    /// The board time at which it happens, microseconds (the board clock's unit).
    pub fn at_us(&self) -> u64 {
        // In range: `parse_wear` bounds the time.
        (self.at_s * 1e6).round() as u64
    }
}

/// Latest board time a `--wear` may name, seconds (a year: far beyond any session).
const WEAR_MAX_S: f64 = 3.2e7;

/// `--wear T:ED:EB`: board time in seconds, then the true E_d and E_b (a geometry the robot
/// model accepts, with its mean wheel diameter kept).
///
/// # Errors
/// The expected form with an example, or the field or factor that is wrong.
pub fn parse_wear(s: &str) -> Result<Wear, String> {
    const FORM: &str = "expected T:ED:EB, the board time in seconds and the robot's true E_d \
                        and E_b from then on (e.g. --wear 600:0.990:1.010)";
    let fields: Vec<&str> = s.split(':').map(str::trim).collect();
    let [t, ed, eb] = fields[..] else {
        return Err(FORM.into());
    };
    let number = |v: &str, what: &str| -> Result<f64, String> {
        v.parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("{what} {v:?} is not a number; {FORM}"))
    };
    let (at_s, ed, eb) = (number(t, "T")?, number(ed, "ED")?, number(eb, "EB")?);
    if !(0.0..=WEAR_MAX_S).contains(&at_s) {
        return Err(format!("T {t} s is not within 0..{WEAR_MAX_S} s; {FORM}"));
    }
    if !(ed > 0.0 && eb > 0.0) {
        return Err(format!("E_d and E_b must be positive; {FORM}"));
    }
    true_geometry(ed, eb)
        .validate()
        .map_err(|e| format!("E_d {ed}, E_b {eb} make no robot: {e}"))?;
    Ok(Wear { at_s, ed, eb })
}
