//! Operator-settable parameters: one table row per parameter ([`PARAMS`]) with its wire name,
//! unit, accepted range, how its value is written and which part of the settings it belongs to;
//! `set`, `params`, the parser's checks and the console tool read them from there.
//!
//! Geometry values are the *nominal* geometry (metres, counts per wheel revolution); motion limits
//! are magnitudes (always positive). Each range is its owner's (`Geometry`, `MotionLimits`,
//! `RunPlan`, `MotorParams`, the measuring convention), the one a stored record is checked
//! against too: a value outside it is rejected by the parser before anything else sees it.

use crate::kinematics::geometry::Geometry;
use crate::motion::convention::{HEADING_SD_RANGE_DEG, MEASURE_SD_RANGE_M};
use crate::motion::profile::MotionLimits;
use crate::motion::routine::RunPlan;
use crate::motion::speed::{MotorParams, SpeedTuning};
use crate::storage::record::ParamRecord;
use crate::util::text::keyword_eq;

/// An `f32` range (the speed loop's) as the parser's `f64` bounds (exact: every `f32` is an
/// `f64`).
const fn f32_range((lo, hi): (f32, f32)) -> (f64, f64) {
    (lo as f64, hi as f64)
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
    /// 1σ of a measured end position (each of x, y) that `calibrate`'s fit check assumes, metres.
    MeasureSd,
    /// 1σ of a measured end heading that the fit check assumes, degrees.
    HeadingSd,
}

impl ParamName {
    /// Every parameter, in the order `params` lists them.
    pub const ALL: [ParamName; 26] = [
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
        ParamName::MeasureSd,
        ParamName::HeadingSd,
    ];

    /// This parameter's row of [`PARAMS`].
    pub fn spec(self) -> &'static ParamSpec {
        // `PARAMS` lists the parameters in declaration order (checked by a test).
        &PARAMS[self as usize]
    }

    /// The name used on the wire.
    pub fn as_str(self) -> &'static str {
        self.spec().wire
    }

    /// Looks a wire name up (ASCII case-insensitive).
    pub fn from_name(name: &str) -> Option<ParamName> {
        ParamName::ALL
            .iter()
            .copied()
            .find(|p| keyword_eq(p.as_str(), name))
    }

    /// The parameter whose name is nearest `name` (edit distance, ASCII case-insensitive), if
    /// one is near enough to be what was meant: at most 2 edits, and fewer than a third of the
    /// name's length (`squareside` → `square_side`).
    pub fn nearest(name: &str) -> Option<ParamName> {
        let mut best: Option<(usize, ParamName)> = None;
        for p in ParamName::ALL {
            let d = edit_distance(name.as_bytes(), p.as_str().as_bytes());
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, p));
            }
        }
        best.filter(|&(d, p)| d <= 2 && 3 * d < p.as_str().len())
            .map(|(_, p)| p)
    }

    /// Unit shown after the value.
    pub fn unit(self) -> &'static str {
        self.spec().unit
    }

    /// Inclusive accepted range `(min, max)`.
    ///
    /// Geometry ranges are those of [`crate::kinematics::geometry::Geometry::validate`]; the run count is
    /// bounded by the run store ([`crate::motion::run::MAX_RUNS`] holds both directions).
    pub fn range(self) -> (f64, f64) {
        self.spec().range
    }

    /// Whether this is part of the speed-loop tuning (a motor model or the bandwidth).
    pub fn is_tuning(self) -> bool {
        self.spec().group == ParamGroup::Tuning
    }

    /// Whether the value must be a whole number.
    pub fn is_integer(self) -> bool {
        !matches!(self.spec().value, ValueKind::Real { .. })
    }

    /// Whether this is a wiring sign (±1; 0 is refused).
    pub fn is_sign(self) -> bool {
        self.spec().value == ValueKind::Sign
    }

    /// Decimal places `params` and `set` print the value with.
    pub fn places(self) -> u8 {
        match self.spec().value {
            ValueKind::Real { places } => places,
            ValueKind::Whole | ValueKind::Sign => 0,
        }
    }
}

/// Levenshtein distance of two ASCII words, case-insensitive; words longer than 32 bytes count
/// only their first 32.
fn edit_distance(a: &[u8], b: &[u8]) -> usize {
    const N: usize = 32;
    let (a, b) = (a.get(..N).unwrap_or(a), b.get(..N).unwrap_or(b));
    let mut row = [0usize; N + 1];
    for (j, slot) in row.iter_mut().enumerate() {
        *slot = j;
    }
    for (i, &ca) in a.iter().enumerate() {
        let mut diagonal = i;
        let mut left = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let up = row.get(j + 1).copied().unwrap_or(N);
            let cost = usize::from(!ca.eq_ignore_ascii_case(&cb));
            let d = (diagonal + cost).min(up + 1).min(left + 1);
            diagonal = up;
            if let Some(slot) = row.get_mut(j + 1) {
                *slot = d;
            }
            left = d;
        }
    }
    row.get(b.len()).copied().unwrap_or(N)
}

/// How a parameter's value is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValueKind {
    /// A real number, printed with `places` decimals.
    Real {
        /// Decimal places.
        places: u8,
    },
    /// A whole number.
    Whole,
    /// A wiring sign: 1 standard, −1 reversed.
    Sign,
}

/// The part of the settings (and of the running controller) a parameter belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamGroup {
    /// The nominal geometry (a change drops the calibration computed against it).
    Geometry,
    /// The motion limits.
    Motion,
    /// The calibration plan.
    Plan,
    /// The motor and encoder wiring.
    Wiring,
    /// The speed-loop tuning.
    Tuning,
    /// The control rate.
    Rate,
}

/// One parameter: everything the protocol knows of it, and where it lives in the settings
/// record ([`ParamRecord`]): the one place a parameter is defined.
#[derive(Clone, Copy, Debug)]
pub struct ParamSpec {
    /// The parameter.
    pub name: ParamName,
    /// Its name on the wire.
    pub wire: &'static str,
    /// The unit shown after its value.
    pub unit: &'static str,
    /// Inclusive accepted range `(min, max)`.
    pub range: (f64, f64),
    /// How its value is written.
    pub value: ValueKind,
    /// The part of the settings it belongs to.
    pub group: ParamGroup,
    /// Its value in a record, as the `f64` the protocol shows (exact for every field type).
    pub get: fn(&ParamRecord) -> f64,
    /// Writes a value into a record: already within `range`, whole for [`ValueKind::Whole`],
    /// ±1 for [`ValueKind::Sign`] (the caller checks; see `session::settings`). Limits and
    /// tuning are stored as `f32`.
    pub set: fn(&mut ParamRecord, f64),
}

/// A table row.
const fn row(
    name: ParamName,
    wire: &'static str,
    unit: &'static str,
    range: (f64, f64),
    value: ValueKind,
    group: ParamGroup,
    (get, set): Access,
) -> ParamSpec {
    ParamSpec {
        name,
        wire,
        unit,
        range,
        value,
        group,
        get,
        set,
    }
}

/// How a row reads and writes its field of the record.
type Access = (fn(&ParamRecord) -> f64, fn(&mut ParamRecord, f64));

/// A wiring flag as the protocol's sign: 1 standard, −1 reversed.
const fn sign(reversed: bool) -> f64 {
    if reversed { -1.0 } else { 1.0 }
}

const METRES_9: ValueKind = ValueKind::Real { places: 9 };
const LIMIT_3: ValueKind = ValueKind::Real { places: 3 };
const TUNING_4: ValueKind = ValueKind::Real { places: 4 };
const SIGN_UNIT: &str = "(1 standard, -1 reversed)";
const GAIN: (f64, f64) = f32_range(MotorParams::GAIN_RANGE);
const COUNTS: (f64, f64) = {
    let (lo, hi) = Geometry::COUNTS_PER_REV_RANGE;
    (lo as f64, hi as f64)
};
const RUNS: (f64, f64) = {
    let (lo, hi) = RunPlan::RUNS_PER_DIRECTION_RANGE;
    (lo as f64, hi as f64)
};
const TAU: (f64, f64) = f32_range(MotorParams::TAU_RANGE);
const DEADBAND: (f64, f64) = f32_range(MotorParams::DEADBAND_RANGE);

/// Every parameter, in [`ParamName`]'s order (the order `params` lists them).
pub const PARAMS: [ParamSpec; 26] = {
    use ParamGroup as G;
    use ParamName as P;
    use ValueKind::{Sign, Whole};
    [
        row(
            P::DiameterRight,
            "d_right",
            "m",
            Geometry::DIAMETER_RANGE_M,
            METRES_9,
            G::Geometry,
            (
                |r| r.nominal.diameter_right_m,
                |r, v| r.nominal.diameter_right_m = v,
            ),
        ),
        row(
            P::DiameterLeft,
            "d_left",
            "m",
            Geometry::DIAMETER_RANGE_M,
            METRES_9,
            G::Geometry,
            (
                |r| r.nominal.diameter_left_m,
                |r, v| r.nominal.diameter_left_m = v,
            ),
        ),
        row(
            P::Wheelbase,
            "wheelbase",
            "m",
            Geometry::WHEELBASE_RANGE_M,
            METRES_9,
            G::Geometry,
            (|r| r.nominal.wheelbase_m, |r, v| r.nominal.wheelbase_m = v),
        ),
        row(
            P::CountsPerRev,
            "counts_per_rev",
            "counts/rev",
            COUNTS,
            Whole,
            G::Geometry,
            (
                |r| f64::from(r.nominal.counts_per_rev),
                |r, v| r.nominal.counts_per_rev = v as u32,
            ),
        ),
        row(
            P::MaxSpeed,
            "max_speed",
            "m/s",
            MotionLimits::SPEED_RANGE_MPS,
            LIMIT_3,
            G::Motion,
            (
                |r| f64::from(r.motion.max_speed_mps),
                |r, v| r.motion.max_speed_mps = v as f32,
            ),
        ),
        row(
            P::MaxAccel,
            "max_accel",
            "m/s^2",
            MotionLimits::ACCEL_RANGE_MPS2,
            LIMIT_3,
            G::Motion,
            (
                |r| f64::from(r.motion.max_accel_mps2),
                |r, v| r.motion.max_accel_mps2 = v as f32,
            ),
        ),
        row(
            P::MaxTurnRate,
            "max_turn_rate",
            "rad/s",
            MotionLimits::TURN_RATE_RANGE_RADPS,
            LIMIT_3,
            G::Motion,
            (
                |r| f64::from(r.motion.max_turn_rate_radps),
                |r, v| r.motion.max_turn_rate_radps = v as f32,
            ),
        ),
        row(
            P::MaxTurnAccel,
            "max_turn_accel",
            "rad/s^2",
            MotionLimits::TURN_ACCEL_RANGE_RADPS2,
            LIMIT_3,
            G::Motion,
            (
                |r| f64::from(r.motion.max_turn_accel_radps2),
                |r, v| r.motion.max_turn_accel_radps2 = v as f32,
            ),
        ),
        row(
            P::SquareSide,
            "square_side",
            "m",
            RunPlan::SIDE_RANGE_M,
            LIMIT_3,
            G::Plan,
            (
                |r| f64::from(r.square_side_m),
                |r, v| r.square_side_m = v as f32,
            ),
        ),
        row(
            P::RunsPerDirection,
            "runs_per_direction",
            "runs",
            RUNS,
            Whole,
            G::Plan,
            (
                |r| f64::from(r.runs_per_direction),
                |r, v| r.runs_per_direction = v as u8,
            ),
        ),
        row(
            P::MotorRightSign,
            "motor_right_sign",
            SIGN_UNIT,
            (-1.0, 1.0),
            Sign,
            G::Wiring,
            (
                |r| sign(r.wiring.motor_right_reversed),
                |r, v| r.wiring.motor_right_reversed = v < 0.0,
            ),
        ),
        row(
            P::MotorLeftSign,
            "motor_left_sign",
            SIGN_UNIT,
            (-1.0, 1.0),
            Sign,
            G::Wiring,
            (
                |r| sign(r.wiring.motor_left_reversed),
                |r, v| r.wiring.motor_left_reversed = v < 0.0,
            ),
        ),
        row(
            P::EncoderRightSign,
            "encoder_right_sign",
            SIGN_UNIT,
            (-1.0, 1.0),
            Sign,
            G::Wiring,
            (
                |r| sign(r.wiring.encoder_right_reversed),
                |r, v| r.wiring.encoder_right_reversed = v < 0.0,
            ),
        ),
        row(
            P::EncoderLeftSign,
            "encoder_left_sign",
            SIGN_UNIT,
            (-1.0, 1.0),
            Sign,
            G::Wiring,
            (
                |r| sign(r.wiring.encoder_left_reversed),
                |r, v| r.wiring.encoder_left_reversed = v < 0.0,
            ),
        ),
        row(
            P::MotorRightGainFwd,
            "motor_right_gain_fwd",
            "m/s per duty",
            GAIN,
            TUNING_4,
            G::Tuning,
            (
                |r| f64::from(r.tuning.right.gain_forward_mps),
                |r, v| r.tuning.right.gain_forward_mps = v as f32,
            ),
        ),
        row(
            P::MotorRightGainBack,
            "motor_right_gain_back",
            "m/s per duty",
            GAIN,
            TUNING_4,
            G::Tuning,
            (
                |r| f64::from(r.tuning.right.gain_backward_mps),
                |r, v| r.tuning.right.gain_backward_mps = v as f32,
            ),
        ),
        row(
            P::MotorRightTau,
            "motor_right_tau",
            "s",
            TAU,
            TUNING_4,
            G::Tuning,
            (
                |r| f64::from(r.tuning.right.time_constant_s),
                |r, v| r.tuning.right.time_constant_s = v as f32,
            ),
        ),
        row(
            P::MotorRightDeadband,
            "motor_right_deadband",
            "duty",
            DEADBAND,
            TUNING_4,
            G::Tuning,
            (
                |r| f64::from(r.tuning.right.deadband),
                |r, v| r.tuning.right.deadband = v as f32,
            ),
        ),
        row(
            P::MotorLeftGainFwd,
            "motor_left_gain_fwd",
            "m/s per duty",
            GAIN,
            TUNING_4,
            G::Tuning,
            (
                |r| f64::from(r.tuning.left.gain_forward_mps),
                |r, v| r.tuning.left.gain_forward_mps = v as f32,
            ),
        ),
        row(
            P::MotorLeftGainBack,
            "motor_left_gain_back",
            "m/s per duty",
            GAIN,
            TUNING_4,
            G::Tuning,
            (
                |r| f64::from(r.tuning.left.gain_backward_mps),
                |r, v| r.tuning.left.gain_backward_mps = v as f32,
            ),
        ),
        row(
            P::MotorLeftTau,
            "motor_left_tau",
            "s",
            TAU,
            TUNING_4,
            G::Tuning,
            (
                |r| f64::from(r.tuning.left.time_constant_s),
                |r, v| r.tuning.left.time_constant_s = v as f32,
            ),
        ),
        row(
            P::MotorLeftDeadband,
            "motor_left_deadband",
            "duty",
            DEADBAND,
            TUNING_4,
            G::Tuning,
            (
                |r| f64::from(r.tuning.left.deadband),
                |r, v| r.tuning.left.deadband = v as f32,
            ),
        ),
        row(
            P::SpeedBandwidth,
            "speed_bandwidth",
            "rad/s",
            f32_range(SpeedTuning::BANDWIDTH_RANGE),
            TUNING_4,
            G::Tuning,
            (
                |r| f64::from(r.tuning.bandwidth_radps),
                |r, v| r.tuning.bandwidth_radps = v as f32,
            ),
        ),
        row(
            P::ControlHz,
            "control_hz",
            "Hz",
            (1_000.0, 10_000.0),
            Whole,
            G::Rate,
            (|r| f64::from(r.control_hz), |r, v| r.control_hz = v as u32),
        ),
        row(
            P::MeasureSd,
            "measure_sd",
            "m",
            MEASURE_SD_RANGE_M,
            ValueKind::Real { places: 6 },
            G::Plan,
            (
                |r| f64::from(r.measure_sd_m),
                |r, v| r.measure_sd_m = v as f32,
            ),
        ),
        row(
            P::HeadingSd,
            "heading_sd",
            "deg",
            HEADING_SD_RANGE_DEG,
            ValueKind::Real { places: 3 },
            G::Plan,
            (
                |r| f64::from(r.heading_sd_rad).to_degrees(),
                |r, v| r.heading_sd_rad = v.to_radians() as f32,
            ),
        ),
    ]
};

#[cfg(test)]
mod tests {
    #[test]
    fn a_near_name_is_suggested_and_a_far_one_is_not() {
        use super::{ParamName, edit_distance};
        assert_eq!(edit_distance(b"squareside", b"square_side"), 1);
        assert_eq!(edit_distance(b"", b"abc"), 3);
        assert_eq!(edit_distance(b"kitten", b"sitting"), 3);
        assert_eq!(
            ParamName::nearest("squareside"),
            Some(ParamName::SquareSide)
        );
        assert_eq!(ParamName::nearest("MAX_SPED"), Some(ParamName::MaxSpeed));
        assert_eq!(ParamName::nearest("speed"), None);
        assert_eq!(ParamName::nearest("xyz"), None);
    }

    use super::*;

    #[test]
    fn the_table_lists_every_parameter_in_declaration_order() {
        for (i, name) in ParamName::ALL.iter().enumerate() {
            assert_eq!(*name as usize, i);
            assert_eq!(PARAMS[i].name, *name);
            let (lo, hi) = PARAMS[i].range;
            assert!(lo < hi, "{}", PARAMS[i].wire);
        }
    }
}
