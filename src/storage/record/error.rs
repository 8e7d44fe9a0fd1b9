//! Why a record is rejected ([`RecordError`]: a value out of range) or cannot be decoded
//! ([`FormatError`]: the layout), and how a format error reaches the storage crate.

use core::fmt;

use sequential_storage::map::SerializationError;

use super::{ParamRecord, STORED_FACTOR_RANGE};
use crate::kinematics::geometry::GeometryError;
use crate::motion::profile::LimitsError;
use crate::motion::routine::RunPlan;
use crate::motion::speed::TuningError;
use crate::util::decimal::Plain;

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
    /// diameter or wheelbase outside [`STORED_FACTOR_RANGE`] × nominal.
    CalibrationMismatch,
    /// `E_d`, `E_b` or `E_s` is not finite or outside [`STORED_FACTOR_RANGE`].
    Factor,
    /// The method name is empty, too long, or not printable ASCII.
    MethodName,
    /// More than 1000 runs.
    Runs,
    /// The predicted `E_max` is not finite or outside 0 ..= 10 m.
    PredictedError,
    /// A motion limit is not finite or outside its range.
    Limits(LimitsError),
    /// The square side is not finite or outside [`RunPlan::SIDE_RANGE_M`].
    SquareSide,
    /// Runs per direction outside [`RunPlan::RUNS_PER_DIRECTION_RANGE`].
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
            RecordError::CalibrationMismatch => write!(
                f,
                "calibrated geometry must be within {}..{} x nominal",
                Plain(*STORED_FACTOR_RANGE.start()),
                Plain(*STORED_FACTOR_RANGE.end())
            ),
            RecordError::Factor => write!(
                f,
                "E_d, E_b and E_s must be within {}..{}",
                Plain(*STORED_FACTOR_RANGE.start()),
                Plain(*STORED_FACTOR_RANGE.end())
            ),
            RecordError::MethodName => f.write_str("method name must be 1..12 printable ASCII"),
            RecordError::Runs => f.write_str("run count must be at most 1000"),
            RecordError::PredictedError => f.write_str("predicted E_max must be within 0..10 m"),
            RecordError::Limits(e) => write!(f, "motion limits: {e}"),
            RecordError::SquareSide => {
                let (lo, hi) = RunPlan::SIDE_RANGE_M;
                write!(
                    f,
                    "square side must be within {}..{} m",
                    Plain(lo),
                    Plain(hi)
                )
            }
            RecordError::RunsPerDirection => {
                let (lo, hi) = RunPlan::RUNS_PER_DIRECTION_RANGE;
                write!(f, "runs per direction must be within {lo}..{hi}")
            }
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
