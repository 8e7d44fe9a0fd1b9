//! Why a record is rejected ([`RecordError`]: a value out of range) or cannot be decoded
//! ([`FormatError`]: the layout), and how a format error reaches the storage crate.

use core::fmt;

use sequential_storage::map::SerializationError;

use super::ParamRecord;
use crate::kinematics::geometry::GeometryError;
use crate::motion::speed::TuningError;

/// Why a record was rejected by [`ParamRecord::validate`] or [`MethodName::new`].
///
/// [`MethodName::new`]: super::MethodName::new
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
    /// The declared measuring noise is not finite or outside the ranges `set` accepts.
    MeasuringNoise,
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
            RecordError::MeasuringNoise => f.write_str("measure_sd or heading_sd out of range"),
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
    /// The convention byte names no convention.
    Convention,
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
            FormatError::Convention => f.write_str("stored convention byte unknown"),
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
            FormatError::Length { .. }
            | FormatError::MethodName
            | FormatError::Wiring
            | FormatError::Convention => SerializationError::InvalidFormat,
        }
    }
}
