//! Operator-settable parameters: names, units and accepted ranges of `set <name> <value>`.
//!
//! Geometry values are the *nominal* geometry (metres, counts per wheel revolution); motion limits
//! are magnitudes (always positive). The ranges here are the protocol's hard bounds: a value
//! outside them is rejected by the parser before anything else sees it.

use crate::motion::speed::{MotorParams, SpeedTuning};
use crate::util::text::keyword_eq;

/// An `f32` range (the speed loop's) as the parser's `f64` bounds.
fn f32_range((lo, hi): (f32, f32)) -> (f64, f64) {
    (f64::from(lo), f64::from(hi))
}

/// A parameter an operator may `set`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ParamName {
    /// Nominal right wheel diameter `D_R`, metres.
    DiameterRight,
    /// Nominal left wheel diameter `D_L`, metres.
    DiameterLeft,
    /// Nominal wheelbase `b`, metres.
    Wheelbase,
    /// Encoder counts per wheel revolution (integer).
    CountsPerRev,
    /// Maximum wheel-centre speed on legs, m/s.
    MaxSpeed,
    /// Maximum linear acceleration, m/s².
    MaxAccel,
    /// Maximum turn rate of in-place turns, rad/s.
    MaxTurnRate,
    /// Maximum angular acceleration of in-place turns, rad/s².
    MaxTurnAccel,
    /// Side `L` of the planned calibration squares, metres.
    SquareSide,
    /// Planned square runs per direction (integer).
    RunsPerDirection,
    /// Right motor direction: 1 = standard wiring, −1 = reversed.
    MotorRightSign,
    /// Left motor direction: 1 = standard wiring, −1 = reversed.
    MotorLeftSign,
    /// Right encoder counting direction: 1 = standard wiring, −1 = reversed.
    EncoderRightSign,
    /// Left encoder counting direction: 1 = standard wiring, −1 = reversed.
    EncoderLeftSign,
    /// Right motor gain forward: steady wheel speed per unit duty above the dead-band, m/s.
    MotorRightGainFwd,
    /// Right motor gain backward, m/s per unit duty.
    MotorRightGainBack,
    /// Right motor time constant, s.
    MotorRightTau,
    /// Right motor dead-band (static friction), duty.
    MotorRightDeadband,
    /// Left motor gain forward, m/s per unit duty.
    MotorLeftGainFwd,
    /// Left motor gain backward, m/s per unit duty.
    MotorLeftGainBack,
    /// Left motor time constant, s.
    MotorLeftTau,
    /// Left motor dead-band (static friction), duty.
    MotorLeftDeadband,
    /// Speed-loop bandwidth: the closed-loop poles, rad/s.
    SpeedBandwidth,
    /// Control (and odometry) rate, Hz: one of
    /// [`crate::motion::controller::RATES_HZ`] (1 kHz to 10 kHz).
    ControlHz,
}

impl ParamName {
    /// Every parameter, in the order `params` lists them.
    pub const ALL: [ParamName; 24] = [
        ParamName::DiameterRight,
        ParamName::DiameterLeft,
        ParamName::Wheelbase,
        ParamName::CountsPerRev,
        ParamName::MaxSpeed,
        ParamName::MaxAccel,
        ParamName::MaxTurnRate,
        ParamName::MaxTurnAccel,
        ParamName::SquareSide,
        ParamName::RunsPerDirection,
        ParamName::MotorRightSign,
        ParamName::MotorLeftSign,
        ParamName::EncoderRightSign,
        ParamName::EncoderLeftSign,
        ParamName::MotorRightGainFwd,
        ParamName::MotorRightGainBack,
        ParamName::MotorRightTau,
        ParamName::MotorRightDeadband,
        ParamName::MotorLeftGainFwd,
        ParamName::MotorLeftGainBack,
        ParamName::MotorLeftTau,
        ParamName::MotorLeftDeadband,
        ParamName::SpeedBandwidth,
        ParamName::ControlHz,
    ];

    /// The name used on the wire.
    pub fn as_str(self) -> &'static str {
        match self {
            ParamName::DiameterRight => "d_right",
            ParamName::DiameterLeft => "d_left",
            ParamName::Wheelbase => "wheelbase",
            ParamName::CountsPerRev => "counts_per_rev",
            ParamName::MaxSpeed => "max_speed",
            ParamName::MaxAccel => "max_accel",
            ParamName::MaxTurnRate => "max_turn_rate",
            ParamName::MaxTurnAccel => "max_turn_accel",
            ParamName::SquareSide => "square_side",
            ParamName::RunsPerDirection => "runs_per_direction",
            ParamName::MotorRightSign => "motor_right_sign",
            ParamName::MotorLeftSign => "motor_left_sign",
            ParamName::EncoderRightSign => "encoder_right_sign",
            ParamName::EncoderLeftSign => "encoder_left_sign",
            ParamName::MotorRightGainFwd => "motor_right_gain_fwd",
            ParamName::MotorRightGainBack => "motor_right_gain_back",
            ParamName::MotorRightTau => "motor_right_tau",
            ParamName::MotorRightDeadband => "motor_right_deadband",
            ParamName::MotorLeftGainFwd => "motor_left_gain_fwd",
            ParamName::MotorLeftGainBack => "motor_left_gain_back",
            ParamName::MotorLeftTau => "motor_left_tau",
            ParamName::MotorLeftDeadband => "motor_left_deadband",
            ParamName::SpeedBandwidth => "speed_bandwidth",
            ParamName::ControlHz => "control_hz",
        }
    }

    /// Looks a wire name up (ASCII case-insensitive).
    pub fn from_name(name: &str) -> Option<ParamName> {
        ParamName::ALL
            .iter()
            .copied()
            .find(|p| keyword_eq(p.as_str(), name))
    }

    /// Unit shown after the value.
    pub fn unit(self) -> &'static str {
        match self {
            ParamName::DiameterRight
            | ParamName::DiameterLeft
            | ParamName::Wheelbase
            | ParamName::SquareSide => "m",
            ParamName::CountsPerRev => "counts/rev",
            ParamName::MaxSpeed => "m/s",
            ParamName::MaxAccel => "m/s^2",
            ParamName::MaxTurnRate => "rad/s",
            ParamName::MaxTurnAccel => "rad/s^2",
            ParamName::RunsPerDirection => "runs",
            ParamName::MotorRightSign
            | ParamName::MotorLeftSign
            | ParamName::EncoderRightSign
            | ParamName::EncoderLeftSign => "(1 standard, -1 reversed)",
            ParamName::MotorRightGainFwd
            | ParamName::MotorRightGainBack
            | ParamName::MotorLeftGainFwd
            | ParamName::MotorLeftGainBack => "m/s per duty",
            ParamName::MotorRightTau | ParamName::MotorLeftTau => "s",
            ParamName::MotorRightDeadband | ParamName::MotorLeftDeadband => "duty",
            ParamName::SpeedBandwidth => "rad/s",
            ParamName::ControlHz => "Hz",
        }
    }

    /// Inclusive accepted range `(min, max)`.
    ///
    /// Geometry ranges are those of [`crate::kinematics::geometry::Geometry::validate`]; the run count is
    /// bounded by the run store ([`crate::motion::run::MAX_RUNS`] holds both directions).
    pub fn range(self) -> (f64, f64) {
        match self {
            ParamName::DiameterRight | ParamName::DiameterLeft => (0.001, 2.0),
            ParamName::Wheelbase => (0.01, 5.0),
            ParamName::CountsPerRev => (1.0, 100_000_000.0),
            ParamName::MaxSpeed => (0.01, 2.0),
            ParamName::MaxAccel => (0.01, 5.0),
            ParamName::MaxTurnRate => (0.05, 10.0),
            ParamName::MaxTurnAccel => (0.05, 20.0),
            ParamName::SquareSide => (0.1, 10.0),
            ParamName::RunsPerDirection => (1.0, (crate::motion::run::MAX_RUNS / 2) as f64),
            ParamName::MotorRightSign
            | ParamName::MotorLeftSign
            | ParamName::EncoderRightSign
            | ParamName::EncoderLeftSign => (-1.0, 1.0),
            ParamName::MotorRightGainFwd
            | ParamName::MotorRightGainBack
            | ParamName::MotorLeftGainFwd
            | ParamName::MotorLeftGainBack => f32_range(MotorParams::GAIN_RANGE),
            ParamName::MotorRightTau | ParamName::MotorLeftTau => f32_range(MotorParams::TAU_RANGE),
            ParamName::MotorRightDeadband | ParamName::MotorLeftDeadband => {
                f32_range(MotorParams::DEADBAND_RANGE)
            }
            ParamName::SpeedBandwidth => f32_range(SpeedTuning::BANDWIDTH_RANGE),
            ParamName::ControlHz => (1_000.0, 10_000.0),
        }
    }

    /// Whether this is part of the speed-loop tuning (a motor model or the bandwidth).
    pub fn is_tuning(self) -> bool {
        matches!(
            self,
            ParamName::MotorRightGainFwd
                | ParamName::MotorRightGainBack
                | ParamName::MotorRightTau
                | ParamName::MotorRightDeadband
                | ParamName::MotorLeftGainFwd
                | ParamName::MotorLeftGainBack
                | ParamName::MotorLeftTau
                | ParamName::MotorLeftDeadband
                | ParamName::SpeedBandwidth
        )
    }

    /// Whether the value must be a whole number.
    pub fn is_integer(self) -> bool {
        matches!(
            self,
            ParamName::CountsPerRev | ParamName::RunsPerDirection | ParamName::ControlHz
        ) || self.is_sign()
    }

    /// Whether this is a wiring sign (±1; 0 is refused).
    pub fn is_sign(self) -> bool {
        matches!(
            self,
            ParamName::MotorRightSign
                | ParamName::MotorLeftSign
                | ParamName::EncoderRightSign
                | ParamName::EncoderLeftSign
        )
    }
}
