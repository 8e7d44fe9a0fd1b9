//! The one record the board persists: geometry, calibration result, motion settings, wiring, the
//! speed-loop tuning and the control rate.
//!
//! [`ParamRecord`] is what `save` writes and what boot loads. Its stored form is a hand-written,
//! fixed-length little-endian layout ([`ParamRecord::ENCODED_LEN`] bytes, byte 0 = format
//! version, see `docs/storage.md` for the table). Lengths are metres, speeds m/s, accelerations
//! m/s², turn rates rad/s, turn accelerations rad/s²; calibration factors are dimensionless
//! (`E_d = D_R / D_L`, `E_b = b_actual / b_nominal`, `E_s` = mean-diameter scale).
//!
//! Decoding ([`ParamRecord::decode`]) only checks the layout (version, length, method name);
//! [`ParamRecord::validate`] checks every value (finite, plausible range). A stored record is used
//! only when both pass.

use core::fmt;

use sequential_storage::map::{SerializationError, Value};

use crate::kinematics::geometry::{Geometry, GeometryError};
use crate::motion::controller::{DEFAULT_RATE_HZ, rate_supported};
use crate::motion::speed::{MotorParams, SpeedTuning, TuningError};
use crate::motion::wiring::Wiring;
use crate::util::num::within;

/// Longest calibration method name, bytes of ASCII.
pub const METHOD_NAME_MAX: usize = 12;

/// Name of the method that produced a calibration (`exact`, `lee-x`, `umbmark-x`, `none`, …).
///
/// Short printable ASCII (1 ..= [`METHOD_NAME_MAX`] bytes, no spaces) so the storage format does
/// not depend on the calibration module's types. Unused bytes are always zero.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct MethodName {
    len: u8,
    bytes: [u8; METHOD_NAME_MAX],
}

impl MethodName {
    /// The method name of an uncalibrated robot.
    pub const NONE: MethodName = MethodName {
        len: 4,
        bytes: *b"none\0\0\0\0\0\0\0\0",
    };

    /// A method name from text.
    ///
    /// # Errors
    /// [`RecordError::MethodName`] if `name` is empty, longer than [`METHOD_NAME_MAX`] bytes, or
    /// contains anything but printable ASCII without spaces.
    pub fn new(name: &str) -> Result<Self, RecordError> {
        Self::from_bytes(name.as_bytes())
    }

    fn from_bytes(name: &[u8]) -> Result<Self, RecordError> {
        let printable = name.iter().all(|c| c.is_ascii_graphic());
        if name.is_empty() || name.len() > METHOD_NAME_MAX || !printable {
            return Err(RecordError::MethodName);
        }
        let mut bytes = [0u8; METHOD_NAME_MAX];
        bytes[..name.len()].copy_from_slice(name);
        Ok(MethodName {
            len: name.len() as u8,
            bytes,
        })
    }

    /// The name as text.
    pub fn as_str(&self) -> &str {
        let len = usize::from(self.len).min(METHOD_NAME_MAX);
        core::str::from_utf8(&self.bytes[..len]).unwrap_or("?")
    }
}

impl fmt::Debug for MethodName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:?}", self.as_str())
    }
}

impl fmt::Display for MethodName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(target_os = "none")]
impl defmt::Format for MethodName {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(f, "{=str}", self.as_str())
    }
}

/// A calibration result as stored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Calibration {
    /// Diameter ratio factor `E_d = D_R / D_L` (dimensionless).
    pub e_d: f64,
    /// Wheelbase factor `E_b = b_actual / b_nominal` (dimensionless).
    pub e_b: f64,
    /// Mean-diameter (distance) scale `E_s` (dimensionless).
    pub e_s: f64,
    /// The resulting absolute geometry that odometry and the routine use.
    pub geometry: Geometry,
    /// Which method produced it.
    pub method: MethodName,
    /// Number of square runs used (CW + CCW); 0 for no calibration.
    pub runs: u16,
    /// Predicted worst return-position error `E_max` after the correction, metres.
    pub predicted_e_max_m: f64,
}

impl Calibration {
    /// "No calibration" for a robot with the given nominal geometry: all factors 1.
    pub const fn none(nominal: Geometry) -> Self {
        Calibration {
            e_d: 1.0,
            e_b: 1.0,
            e_s: 1.0,
            geometry: nominal,
            method: MethodName::NONE,
            runs: 0,
            predicted_e_max_m: 0.0,
        }
    }
}

/// Motion settings an operator can `set` and `save`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionSettings {
    /// Maximum straight-line speed, m/s.
    pub max_speed_mps: f32,
    /// Maximum straight-line acceleration, m/s².
    pub max_accel_mps2: f32,
    /// Maximum in-place turn rate, rad/s.
    pub max_turn_rate_radps: f32,
    /// Maximum in-place turn acceleration, rad/s².
    pub max_turn_accel_radps2: f32,
    /// Side length of the calibration square, metres.
    pub square_side_m: f32,
    /// Square runs per direction (CW and CCW each) for a calibration.
    pub runs_per_direction: u8,
}

impl MotionSettings {
    /// Factory settings: 0.3 m/s, 0.3 m/s², 1 rad/s, 2 rad/s², 2 m square, 5 runs per direction.
    pub const DEFAULT: MotionSettings = MotionSettings {
        max_speed_mps: 0.3,
        max_accel_mps2: 0.3,
        max_turn_rate_radps: 1.0,
        max_turn_accel_radps2: 2.0,
        square_side_m: 2.0,
        runs_per_direction: 5,
    };

    /// Checks that every setting is finite and within its plausible range.
    ///
    /// # Errors
    /// The first offending setting, as a [`RecordError`].
    pub fn validate(&self) -> Result<(), RecordError> {
        if !within(self.max_speed_mps, 0.001, 5.0) {
            return Err(RecordError::MaxSpeed);
        }
        if !within(self.max_accel_mps2, 0.001, 20.0) {
            return Err(RecordError::MaxAccel);
        }
        if !within(self.max_turn_rate_radps, 0.001, 20.0) {
            return Err(RecordError::MaxTurnRate);
        }
        if !within(self.max_turn_accel_radps2, 0.001, 100.0) {
            return Err(RecordError::MaxTurnAccel);
        }
        if !within(self.square_side_m, 0.1, 20.0) {
            return Err(RecordError::SquareSide);
        }
        if !(1..=50).contains(&self.runs_per_direction) {
            return Err(RecordError::RunsPerDirection);
        }
        Ok(())
    }
}

impl MotionSettings {
    /// The stored form of the controller's `limits` and the calibration plan.
    pub fn from_limits(
        limits: &crate::motion::profile::MotionLimits,
        square_side_m: f32,
        runs_per_direction: u8,
    ) -> Self {
        MotionSettings {
            max_speed_mps: limits.max_speed_mps,
            max_accel_mps2: limits.max_accel_mps2,
            max_turn_rate_radps: limits.max_turn_rate_radps,
            max_turn_accel_radps2: limits.max_turn_accel_radps2,
            square_side_m,
            runs_per_direction,
        }
    }

    /// The speed and acceleration limits the controller uses.
    pub fn limits(&self) -> crate::motion::profile::MotionLimits {
        crate::motion::profile::MotionLimits {
            max_speed_mps: self.max_speed_mps,
            max_accel_mps2: self.max_accel_mps2,
            max_turn_rate_radps: self.max_turn_rate_radps,
            max_turn_accel_radps2: self.max_turn_accel_radps2,
        }
    }
}

impl Default for MotionSettings {
    fn default() -> Self {
        MotionSettings::DEFAULT
    }
}

/// Everything the board persists, as one stored record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamRecord {
    /// Nominal geometry (design values: D_R = D_L = D, b, counts per revolution).
    pub nominal: Geometry,
    /// Calibration result; [`Calibration::none`] of the nominal geometry when uncalibrated.
    pub calibration: Calibration,
    /// Operator motion settings.
    pub motion: MotionSettings,
    /// Motors and encoders reversed against the standard wiring.
    pub wiring: Wiring,
    /// Speed-loop tuning: both motors' models and the bandwidth (the output limit is not
    /// stored: always full duty).
    pub tuning: SpeedTuning,
    /// Control rate, Hz (one of [`crate::motion::controller::RATES_HZ`]).
    pub control_hz: u32,
}

/// Why a record was rejected by [`ParamRecord::validate`] or [`MethodName::new`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum RecordError {
    /// The nominal geometry is invalid.
    NominalGeometry(GeometryError),
    /// The calibrated geometry is invalid.
    CalibratedGeometry(GeometryError),
    /// The calibrated geometry has another encoder resolution than the nominal one, or a
    /// diameter or wheelbase outside 0.8 ..= 1.25 × nominal.
    CalibrationMismatch,
    /// `E_d`, `E_b` or `E_s` is not finite or outside 0.8 ..= 1.25.
    Factor,
    /// The method name is empty, too long, or not printable ASCII.
    MethodName,
    /// More than 1000 runs.
    Runs,
    /// The predicted `E_max` is not finite or outside 0 ..= 10 m.
    PredictedError,
    /// The maximum speed is not finite or outside 0.001 ..= 5 m/s.
    MaxSpeed,
    /// The maximum acceleration is not finite or outside 0.001 ..= 20 m/s².
    MaxAccel,
    /// The maximum turn rate is not finite or outside 0.001 ..= 20 rad/s.
    MaxTurnRate,
    /// The maximum turn acceleration is not finite or outside 0.001 ..= 100 rad/s².
    MaxTurnAccel,
    /// The square side is not finite or outside 0.1 ..= 20 m.
    SquareSide,
    /// Runs per direction outside 1 ..= 50.
    RunsPerDirection,
    /// The speed-loop tuning is invalid.
    Tuning(TuningError),
    /// The control rate is not one of [`crate::motion::controller::RATES_HZ`].
    ControlRate,
}

impl fmt::Display for RecordError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RecordError::NominalGeometry(e) => write!(f, "nominal geometry: {e}"),
            RecordError::CalibratedGeometry(e) => write!(f, "calibrated geometry: {e}"),
            RecordError::CalibrationMismatch => {
                f.write_str("calibrated geometry must be within 0.8..1.25 x nominal")
            }
            RecordError::Factor => f.write_str("E_d, E_b and E_s must be within 0.8..1.25"),
            RecordError::MethodName => f.write_str("method name must be 1..12 printable ASCII"),
            RecordError::Runs => f.write_str("run count must be at most 1000"),
            RecordError::PredictedError => f.write_str("predicted E_max must be within 0..10 m"),
            RecordError::MaxSpeed => f.write_str("max speed must be within 0.001..5 m/s"),
            RecordError::MaxAccel => f.write_str("max acceleration must be within 0.001..20 m/s2"),
            RecordError::MaxTurnRate => f.write_str("max turn rate must be within 0.001..20 rad/s"),
            RecordError::MaxTurnAccel => {
                f.write_str("max turn acceleration must be within 0.001..100 rad/s2")
            }
            RecordError::SquareSide => f.write_str("square side must be within 0.1..20 m"),
            RecordError::RunsPerDirection => f.write_str("runs per direction must be within 1..50"),
            RecordError::Tuning(e) => write!(f, "speed tuning: {e}"),
            RecordError::ControlRate => f.write_str(crate::motion::controller::RATE_RULE),
        }
    }
}

impl core::error::Error for RecordError {}

/// Why bytes could not be decoded into a [`ParamRecord`] (or a record not encoded).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum FormatError {
    /// The output buffer is shorter than [`ParamRecord::ENCODED_LEN`].
    BufferTooSmall,
    /// The stored bytes have the wrong length for their version.
    Length {
        /// Length the version requires, bytes.
        expected: u16,
        /// Length found, bytes.
        found: u16,
    },
    /// The wiring byte has bits set that no wiring flag uses.
    Wiring,
    /// The stored format version is not one this firmware reads.
    UnsupportedVersion {
        /// Version byte found.
        found: u8,
    },
    /// The stored method name is not printable ASCII.
    MethodName,
}

impl fmt::Display for FormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FormatError::BufferTooSmall => f.write_str("buffer too small for a parameter record"),
            FormatError::Length { expected, found } => {
                // Widened: the replies print unsigned numbers through the `u32` formatter only.
                write!(
                    f,
                    "record is {} bytes, expected {}",
                    u32::from(*found),
                    u32::from(*expected)
                )
            }
            FormatError::UnsupportedVersion { found } => write!(
                f,
                "record format version {} is not supported (this firmware reads {})",
                u32::from(*found),
                u32::from(ParamRecord::FORMAT_VERSION)
            ),
            FormatError::MethodName => f.write_str("stored method name is not printable ASCII"),
            FormatError::Wiring => f.write_str("stored wiring byte has unknown bits"),
        }
    }
}

impl core::error::Error for FormatError {}

/// `SerializationError::Custom` code base for [`FormatError::UnsupportedVersion`] (+ version).
const CUSTOM_VERSION_BASE: i32 = 0x100;

impl From<FormatError> for SerializationError {
    fn from(e: FormatError) -> Self {
        match e {
            FormatError::BufferTooSmall => SerializationError::BufferTooSmall,
            FormatError::UnsupportedVersion { found } => {
                SerializationError::Custom(CUSTOM_VERSION_BASE + i32::from(found))
            }
            FormatError::Length { .. } | FormatError::MethodName | FormatError::Wiring => {
                SerializationError::InvalidFormat
            }
        }
    }
}

/// Little-endian writer over a fixed buffer whose length was checked up front.
pub(super) struct Writer<'a> {
    pub(super) buf: &'a mut [u8],
    pub(super) pos: usize,
}

impl Writer<'_> {
    // Out of line, like `Reader::fill`.
    #[inline(never)]
    pub(super) fn bytes(&mut self, b: &[u8]) {
        if let Some(dst) = self.buf.get_mut(self.pos..self.pos + b.len()) {
            dst.copy_from_slice(b);
        }
        self.pos += b.len();
    }
    pub(super) fn f64(&mut self, v: f64) {
        self.bytes(&v.to_le_bytes());
    }
    pub(super) fn f32(&mut self, v: f32) {
        self.bytes(&v.to_le_bytes());
    }
    pub(super) fn geometry(&mut self, g: &Geometry) {
        self.f64(g.diameter_right_m);
        self.f64(g.diameter_left_m);
        self.f64(g.wheelbase_m);
        self.bytes(&g.counts_per_rev.to_le_bytes());
    }
    fn motor(&mut self, m: &MotorParams) {
        self.f32(m.gain_forward_mps);
        self.f32(m.gain_backward_mps);
        self.f32(m.time_constant_s);
        self.f32(m.deadband);
    }
}

/// Little-endian reader over a buffer whose length was checked up front.
pub(super) struct Reader<'a> {
    pub(super) buf: &'a [u8],
    pub(super) pos: usize,
}

impl Reader<'_> {
    pub(super) fn array<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        self.fill(&mut out);
        out
    }
    /// Copies the next `out.len()` bytes (left zero past the end). Out of line: one copy for
    /// the twenty-odd fields instead of one per field.
    #[inline(never)]
    pub(super) fn fill(&mut self, out: &mut [u8]) {
        if let Some(src) = self.buf.get(self.pos..self.pos + out.len()) {
            out.copy_from_slice(src);
        }
        self.pos += out.len();
    }
    pub(super) fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.array())
    }
    pub(super) fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.array())
    }
    pub(super) fn geometry(&mut self) -> Geometry {
        Geometry {
            diameter_right_m: self.f64(),
            diameter_left_m: self.f64(),
            wheelbase_m: self.f64(),
            counts_per_rev: u32::from_le_bytes(self.array()),
        }
    }
    fn motor(&mut self) -> MotorParams {
        MotorParams {
            gain_forward_mps: self.f32(),
            gain_backward_mps: self.f32(),
            time_constant_s: self.f32(),
            deadband: self.f32(),
        }
    }
}

impl ParamRecord {
    /// Format version written by this firmware (byte 0 of the stored record).
    ///
    /// Version history: 1 = first format; 2 = version 1 + one wiring byte at the end; 3 =
    /// version 2 + the speed-loop tuning (right motor, left motor: forward gain, backward gain,
    /// time constant, dead-band; bandwidth; nine `f32`). A version-1 record is read with the
    /// standard wiring and a version-1 or -2 record with the default tuning
    /// ([`SpeedTuning::DEFAULT`], what those firmwares used); the calibration, geometry and
    /// motion settings carry over unchanged (see [`ParamRecord::decode`]). 4 = version 3 + the
    /// control rate (`u32`, Hz); a version-1..3 record is read with [`DEFAULT_RATE_HZ`], the
    /// fixed rate of those firmwares. Any other version is rejected.
    pub const FORMAT_VERSION: u8 = 4;

    /// Length of a version-1 record, bytes: version 1 + nominal geometry 28 + `E_d, E_b, E_s`
    /// 24 + calibrated geometry 28 + method 1 + 12 + runs 2 + `E_max` 8 + motion 5 × 4 + 1.
    pub const V1_LEN: usize = 1 + 28 + 24 + 28 + 1 + METHOD_NAME_MAX + 2 + 8 + 20 + 1;

    /// Length of a version-2 record, bytes: [`Self::V1_LEN`] + wiring 1.
    pub const V2_LEN: usize = Self::V1_LEN + 1;

    /// Length of a version-3 record, bytes: [`Self::V2_LEN`] + tuning 9 × 4.
    pub const V3_LEN: usize = Self::V2_LEN + 9 * 4;

    /// Length of the stored record, bytes: [`Self::V3_LEN`] + control rate 4.
    pub const ENCODED_LEN: usize = Self::V3_LEN + 4;

    /// The paper's nominal robot (D = 150 mm, b = 385 mm, 200,000 counts/rev), uncalibrated,
    /// factory motion settings.
    pub const DEFAULT: ParamRecord = ParamRecord {
        nominal: Geometry::PAPER_NOMINAL,
        calibration: Calibration::none(Geometry::PAPER_NOMINAL),
        motion: MotionSettings::DEFAULT,
        wiring: Wiring::STANDARD,
        tuning: SpeedTuning::DEFAULT,
        control_hz: DEFAULT_RATE_HZ,
    };

    /// The geometry odometry and the routine use: the calibrated one.
    pub fn active_geometry(&self) -> Geometry {
        self.calibration.geometry
    }

    /// Checks every field: finite, plausible ranges, calibrated geometry consistent with the
    /// nominal one.
    ///
    /// # Errors
    /// The first offending field, as a [`RecordError`].
    pub fn validate(&self) -> Result<(), RecordError> {
        self.nominal
            .validate()
            .map_err(RecordError::NominalGeometry)?;
        let c = &self.calibration;
        c.geometry
            .validate()
            .map_err(RecordError::CalibratedGeometry)?;
        let factor_ok = |e: f64| e.is_finite() && (0.8..=1.25).contains(&e);
        if !(factor_ok(c.e_d) && factor_ok(c.e_b) && factor_ok(c.e_s)) {
            return Err(RecordError::Factor);
        }
        let n = &self.nominal;
        if c.geometry.counts_per_rev != n.counts_per_rev
            || !factor_ok(c.geometry.diameter_right_m / n.diameter_right_m)
            || !factor_ok(c.geometry.diameter_left_m / n.diameter_left_m)
            || !factor_ok(c.geometry.wheelbase_m / n.wheelbase_m)
        {
            return Err(RecordError::CalibrationMismatch);
        }
        MethodName::from_bytes(c.method.as_str().as_bytes())?;
        if c.runs > 1000 {
            return Err(RecordError::Runs);
        }
        if !(c.predicted_e_max_m.is_finite() && (0.0..=10.0).contains(&c.predicted_e_max_m)) {
            return Err(RecordError::PredictedError);
        }
        self.motion.validate()?;
        self.tuning.validate().map_err(RecordError::Tuning)?;
        if !rate_supported(self.control_hz) {
            return Err(RecordError::ControlRate);
        }
        Ok(())
    }

    /// Writes the stored form into `buf`; returns the number of bytes written
    /// ([`Self::ENCODED_LEN`]).
    ///
    /// # Errors
    /// [`FormatError::BufferTooSmall`] if `buf` is shorter than [`Self::ENCODED_LEN`].
    pub fn encode(&self, buf: &mut [u8]) -> Result<usize, FormatError> {
        let Some(buf) = buf.get_mut(..Self::ENCODED_LEN) else {
            return Err(FormatError::BufferTooSmall);
        };
        let mut w = Writer { buf, pos: 0 };
        w.bytes(&[Self::FORMAT_VERSION]);
        w.geometry(&self.nominal);
        let c = &self.calibration;
        w.f64(c.e_d);
        w.f64(c.e_b);
        w.f64(c.e_s);
        w.geometry(&c.geometry);
        w.bytes(&[c.method.len]);
        w.bytes(&c.method.bytes);
        w.bytes(&c.runs.to_le_bytes());
        w.f64(c.predicted_e_max_m);
        let m = &self.motion;
        w.f32(m.max_speed_mps);
        w.f32(m.max_accel_mps2);
        w.f32(m.max_turn_rate_radps);
        w.f32(m.max_turn_accel_radps2);
        w.f32(m.square_side_m);
        w.bytes(&[m.runs_per_direction]);
        w.bytes(&[self.wiring.to_bits()]);
        let t = &self.tuning;
        w.motor(&t.right);
        w.motor(&t.left);
        w.f32(t.bandwidth_radps);
        w.bytes(&self.control_hz.to_le_bytes());
        Ok(w.pos)
    }

    /// Reads a stored record. Checks the layout only; call [`Self::validate`] on the result.
    ///
    /// # Errors
    /// [`FormatError::UnsupportedVersion`] for any version other than
    /// [`Self::FORMAT_VERSION`], [`FormatError::Length`] for a wrong length,
    /// [`FormatError::MethodName`] for a method name that is not printable ASCII.
    pub fn decode(bytes: &[u8]) -> Result<ParamRecord, FormatError> {
        let found_len = u16::try_from(bytes.len()).unwrap_or(u16::MAX);
        let Some(&version) = bytes.first() else {
            return Err(FormatError::Length {
                expected: Self::ENCODED_LEN as u16,
                found: 0,
            });
        };
        // Migration: a version-1 record has no wiring byte and means the standard wiring; a
        // version-1 or -2 record has no tuning and means the default one; a version-1..3
        // record has no control rate and means the 1 kHz those firmwares ran at.
        let expected = match version {
            1 => Self::V1_LEN,
            2 => Self::V2_LEN,
            3 => Self::V3_LEN,
            Self::FORMAT_VERSION => Self::ENCODED_LEN,
            found => return Err(FormatError::UnsupportedVersion { found }),
        };
        if bytes.len() != expected {
            return Err(FormatError::Length {
                expected: expected as u16,
                found: found_len,
            });
        }
        let mut r = Reader { buf: bytes, pos: 1 };
        let nominal = r.geometry();
        let e_d = r.f64();
        let e_b = r.f64();
        let e_s = r.f64();
        let geometry = r.geometry();
        let [name_len] = r.array::<1>();
        let name: [u8; METHOD_NAME_MAX] = r.array();
        let name_len = usize::from(name_len);
        let (used, unused) = name.split_at(name_len.min(METHOD_NAME_MAX));
        if name_len > METHOD_NAME_MAX || unused.iter().any(|&b| b != 0) {
            return Err(FormatError::MethodName);
        }
        let method = MethodName::from_bytes(used).map_err(|_| FormatError::MethodName)?;
        let runs = u16::from_le_bytes(r.array());
        let predicted_e_max_m = r.f64();
        let motion = MotionSettings {
            max_speed_mps: r.f32(),
            max_accel_mps2: r.f32(),
            max_turn_rate_radps: r.f32(),
            max_turn_accel_radps2: r.f32(),
            square_side_m: r.f32(),
            runs_per_direction: r.array::<1>()[0],
        };
        let wiring = if version == 1 {
            Wiring::STANDARD
        } else {
            Wiring::from_bits(r.array::<1>()[0]).ok_or(FormatError::Wiring)?
        };
        let tuning = if version < 3 {
            SpeedTuning::DEFAULT
        } else {
            SpeedTuning {
                right: r.motor(),
                left: r.motor(),
                bandwidth_radps: r.f32(),
                output_limit: SpeedTuning::DEFAULT.output_limit,
            }
        };
        let control_hz = if version < 4 {
            DEFAULT_RATE_HZ
        } else {
            u32::from_le_bytes(r.array())
        };
        Ok(ParamRecord {
            nominal,
            calibration: Calibration {
                e_d,
                e_b,
                e_s,
                geometry,
                method,
                runs,
                predicted_e_max_m,
            },
            motion,
            wiring,
            tuning,
            control_hz,
        })
    }
}

impl Default for ParamRecord {
    fn default() -> Self {
        ParamRecord::DEFAULT
    }
}

impl<'a> Value<'a> for ParamRecord {
    fn serialize_into(&self, buffer: &mut [u8]) -> Result<usize, SerializationError> {
        Ok(self.encode(buffer)?)
    }

    fn deserialize_from(buffer: &'a [u8]) -> Result<(Self, usize), SerializationError> {
        Ok((ParamRecord::decode(buffer)?, buffer.len()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn calibrated() -> ParamRecord {
        let nominal = Geometry::PAPER_NOMINAL;
        ParamRecord {
            nominal,
            calibration: Calibration {
                e_d: 0.998_765_432_1,
                e_b: 1.012_345_678_9,
                e_s: 1.000_5,
                geometry: nominal.with_factors(0.998_765_432_1, 1.012_345_678_9, 1.000_5),
                method: MethodName::new("umbmark-x").unwrap(),
                runs: 10,
                predicted_e_max_m: 0.004_2,
            },
            motion: MotionSettings {
                square_side_m: 4.0,
                runs_per_direction: 7,
                ..MotionSettings::DEFAULT
            },
            wiring: Wiring {
                motor_left_reversed: true,
                encoder_right_reversed: true,
                ..Wiring::STANDARD
            },
            tuning: SpeedTuning {
                right: MotorParams {
                    gain_forward_mps: 0.512,
                    gain_backward_mps: 0.498,
                    time_constant_s: 0.121,
                    deadband: 0.047,
                },
                left: MotorParams {
                    gain_forward_mps: 0.603,
                    gain_backward_mps: 0.611,
                    time_constant_s: 0.149,
                    deadband: 0.052,
                },
                bandwidth_radps: 25.0,
                output_limit: 1.0,
            },
            control_hz: 5_000,
        }
    }

    #[test]
    fn encode_decode_is_bit_exact() {
        let rec = calibrated();
        let mut buf = [0u8; ParamRecord::ENCODED_LEN];
        assert_eq!(rec.encode(&mut buf), Ok(ParamRecord::ENCODED_LEN));
        assert_eq!(buf[0], ParamRecord::FORMAT_VERSION);
        let back = ParamRecord::decode(&buf).unwrap();
        // Exact equality: the layout stores the IEEE bits, so nothing may be lost.
        assert_eq!(back, rec);
        assert_eq!(back.validate(), Ok(()));
    }

    #[test]
    fn default_is_the_uncalibrated_paper_robot() {
        let d = ParamRecord::default();
        assert_eq!(d.nominal, Geometry::PAPER_NOMINAL);
        assert_eq!(d.active_geometry(), Geometry::PAPER_NOMINAL);
        assert_eq!(d.calibration.method.as_str(), "none");
        assert_eq!(d.motion.max_speed_mps, 0.3);
        assert_eq!(d.motion.runs_per_direction, 5);
        assert_eq!(d.validate(), Ok(()));
    }

    #[test]
    fn version_and_length_are_checked() {
        let mut buf = [0u8; ParamRecord::ENCODED_LEN];
        calibrated().encode(&mut buf).unwrap();
        buf[0] = 5;
        assert_eq!(
            ParamRecord::decode(&buf),
            Err(FormatError::UnsupportedVersion { found: 5 })
        );
        buf[0] = 0;
        assert_eq!(
            ParamRecord::decode(&buf),
            Err(FormatError::UnsupportedVersion { found: 0 })
        );
        buf[0] = ParamRecord::FORMAT_VERSION;
        assert!(matches!(
            ParamRecord::decode(&buf[..ParamRecord::ENCODED_LEN - 1]),
            Err(FormatError::Length { .. })
        ));
        let mut short = [0u8; 10];
        assert_eq!(
            calibrated().encode(&mut short),
            Err(FormatError::BufferTooSmall)
        );
    }

    /// Records as the firmware of each format version wrote them (fixed bytes, see the file).
    #[allow(dead_code)]
    mod fixtures {
        use super::*;
        use crate::kinematics::encoder::WheelTicks;
        use crate::kinematics::reference::PoseF64;
        use crate::motion::run::{Direction, Measurement, PathKind, RunRecord};
        use crate::storage::StoredRun;

        include!("../../tests/fixtures/storage_records.rs");
    }

    /// The version-`v` record a firmware of that version stored: fixed bytes from
    /// `tests/fixtures/storage_records.rs`, never made by today's encoder.
    fn old_bytes(v: u8) -> std::vec::Vec<u8> {
        fixtures::fixture_bytes(match v {
            1 => fixtures::PARAM_RECORD_V1,
            2 => fixtures::PARAM_RECORD_V2,
            3 => fixtures::PARAM_RECORD_V3,
            _ => fixtures::PARAM_RECORD_V4,
        })
    }

    /// The stored records of every version have the length and version byte the decoder
    /// expects, and begin with the nominal `D_R` as a little-endian `f64`.
    #[test]
    fn the_old_layouts_start_where_the_old_firmware_started() {
        let lens = [
            ParamRecord::V1_LEN,
            ParamRecord::V2_LEN,
            ParamRecord::V3_LEN,
            ParamRecord::ENCODED_LEN,
        ];
        for (v, len) in (1u8..).zip(lens) {
            let old = old_bytes(v);
            assert_eq!(old.len(), len, "v{v}");
            assert_eq!(old[0], v);
            assert_eq!(&old[1..9], &0.1512f64.to_le_bytes());
        }
        assert_eq!(
            (
                ParamRecord::V1_LEN,
                ParamRecord::V2_LEN,
                ParamRecord::V3_LEN
            ),
            (125, 126, 162)
        );
    }

    #[test]
    fn version_3_records_migrate_with_their_tuning_and_the_1_khz_rate() {
        let rec = fixtures::param_record();
        let migrated = ParamRecord::decode(&old_bytes(3)).unwrap();
        assert_eq!(
            migrated,
            ParamRecord {
                control_hz: 1_000,
                ..rec
            }
        );
        assert_eq!(migrated.validate(), Ok(()));
        let mut buf = [0u8; ParamRecord::ENCODED_LEN];
        migrated.encode(&mut buf).unwrap();
        assert_eq!(buf[0], 4);
        assert_eq!(ParamRecord::decode(&buf).unwrap(), migrated);
        // A version-3 record of the version-4 length is refused, and so is the reverse.
        let mut long = old_bytes(4);
        long[0] = 3;
        assert!(matches!(
            ParamRecord::decode(&long),
            Err(FormatError::Length { .. })
        ));
        let mut short = old_bytes(3);
        short[0] = 4;
        assert!(matches!(
            ParamRecord::decode(&short),
            Err(FormatError::Length { .. })
        ));
    }

    #[test]
    fn version_1_and_2_records_migrate_with_their_calibration_and_the_default_tuning() {
        let rec = fixtures::param_record();
        for v in [1u8, 2] {
            let migrated = ParamRecord::decode(&old_bytes(v)).unwrap();
            assert_eq!(migrated.calibration, rec.calibration, "v{v}");
            assert_eq!(migrated.nominal, rec.nominal);
            assert_eq!(migrated.motion, rec.motion);
            let wiring = if v == 1 { Wiring::STANDARD } else { rec.wiring };
            assert_eq!(migrated.wiring, wiring);
            assert_eq!(migrated.tuning, SpeedTuning::DEFAULT);
            assert_eq!(migrated.control_hz, 1_000);
            assert_eq!(migrated.validate(), Ok(()));
            // Saved again, it is a version-4 record with the calibration intact.
            let mut buf = [0u8; ParamRecord::ENCODED_LEN];
            migrated.encode(&mut buf).unwrap();
            assert_eq!(buf[0], 4);
            assert_eq!(ParamRecord::decode(&buf).unwrap(), migrated);
        }
        // A version-1 record of the new length, or a version-2 record of the old, is refused.
        let mut long = old_bytes(4);
        long[0] = 1;
        assert!(matches!(
            ParamRecord::decode(&long),
            Err(FormatError::Length { .. })
        ));
        let mut short = old_bytes(1);
        short[0] = 2;
        assert!(matches!(
            ParamRecord::decode(&short),
            Err(FormatError::Length { .. })
        ));
        let mut v2 = old_bytes(2);
        v2[0] = 4;
        assert!(matches!(
            ParamRecord::decode(&v2),
            Err(FormatError::Length { .. })
        ));
    }

    #[test]
    fn unknown_wiring_bits_are_a_format_error() {
        let mut buf = [0u8; ParamRecord::ENCODED_LEN];
        calibrated().encode(&mut buf).unwrap();
        buf[ParamRecord::V2_LEN - 1] = 0x80;
        assert_eq!(ParamRecord::decode(&buf), Err(FormatError::Wiring));
    }

    #[test]
    fn validation_rejects_every_bad_field() {
        let good = calibrated();
        type Spoil = fn(&mut ParamRecord);
        let cases: [(Spoil, RecordError); 13] = [
            (|r| r.control_hz = 3_000, RecordError::ControlRate),
            (|r| r.control_hz = 0, RecordError::ControlRate),
            (
                |r| r.tuning.left.time_constant_s = f32::NAN,
                RecordError::Tuning(TuningError::TimeConstant),
            ),
            (
                |r| r.tuning.bandwidth_radps = 0.0,
                RecordError::Tuning(TuningError::Bandwidth),
            ),
            (|r| r.calibration.e_d = f64::NAN, RecordError::Factor),
            (
                |r| r.calibration.geometry.wheelbase_m = f64::INFINITY,
                RecordError::CalibratedGeometry(GeometryError::Wheelbase),
            ),
            (
                |r| r.nominal.diameter_right_m = 0.0,
                RecordError::NominalGeometry(GeometryError::Diameter),
            ),
            (
                |r| r.calibration.geometry.wheelbase_m *= 1.5,
                RecordError::CalibrationMismatch,
            ),
            (
                |r| r.calibration.predicted_e_max_m = -1.0,
                RecordError::PredictedError,
            ),
            (|r| r.calibration.runs = 5000, RecordError::Runs),
            (|r| r.motion.max_speed_mps = f32::NAN, RecordError::MaxSpeed),
            (|r| r.motion.square_side_m = 0.0, RecordError::SquareSide),
            (
                |r| r.motion.runs_per_direction = 0,
                RecordError::RunsPerDirection,
            ),
        ];
        for (spoil, expected) in cases {
            let mut r = good;
            spoil(&mut r);
            assert_eq!(r.validate(), Err(expected));
        }
    }

    #[test]
    fn method_names_are_short_printable_ascii() {
        assert_eq!(MethodName::new("lee-x").unwrap().as_str(), "lee-x");
        assert_eq!(MethodName::new("exactly12chr").unwrap().as_str().len(), 12);
        assert_eq!(MethodName::new(""), Err(RecordError::MethodName));
        assert_eq!(
            MethodName::new("thirteen-char"),
            Err(RecordError::MethodName)
        );
        assert_eq!(MethodName::new("a b"), Err(RecordError::MethodName));
        assert_eq!(MethodName::new("é"), Err(RecordError::MethodName));
        assert_eq!(MethodName::new("none"), Ok(MethodName::NONE));
    }
}
