//! Tests of the whole record: encoding and decoding, every stored version, validation.

use super::*;
use crate::kinematics::geometry::GeometryError;
use crate::motion::profile::LimitsError;
use crate::motion::speed::{MotorParams, TuningError};

fn calibrated() -> ParamRecord {
    let nominal = Geometry::PAPER_NOMINAL;
    ParamRecord {
        nominal,
        active: nominal.with_factors(0.998_765_432_1, 1.012_345_678_9, 1.000_5),
        calibration: Some(AppliedCalibration {
            method: "umbmark-x".try_into().unwrap(),
            e_d: 0.998_765_432_1,
            e_b: 1.012_345_678_9,
            e_s: 1.000_5,
            runs_used: 10,
            e_max_m: 0.004_2,
        }),
        motion: MotionLimits::DEFAULT,
        square_side_m: 4.0,
        runs_per_direction: 6,
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
        measure_sd_m: 0.002,
        heading_sd_rad: 0.006,
        convention: Convention::Swapped,
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
    assert_eq!(d.calibration, None);
    assert_eq!(d.stored_method(), Ok(MethodName::NONE));
    assert_eq!(d.motion.max_speed_mps, 0.3);
    assert_eq!(d.runs_per_direction, 5);
    assert_eq!(d.validate(), Ok(()));
}

#[test]
fn version_and_length_are_checked() {
    let mut buf = [0u8; ParamRecord::ENCODED_LEN];
    calibrated().encode(&mut buf).unwrap();
    buf[0] = 6;
    assert_eq!(
        ParamRecord::decode(&buf),
        Err(FormatError::UnsupportedVersion { found: 6 })
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
    use crate::motion::convention::Convention;
    use crate::motion::run::{Direction, Measurement, PathKind, RunRecord};
    use crate::storage::StoredRun;

    include!("../../../tests/fixtures/storage_records.rs");
}

/// The version-`v` record a firmware of that version stored: fixed bytes from
/// `tests/fixtures/storage_records.rs`, never made by today's encoder.
fn old_bytes(v: u8) -> std::vec::Vec<u8> {
    fixtures::fixture_bytes(match v {
        1 => fixtures::PARAM_RECORD_V1,
        2 => fixtures::PARAM_RECORD_V2,
        3 => fixtures::PARAM_RECORD_V3,
        4 => fixtures::PARAM_RECORD_V4,
        _ => fixtures::PARAM_RECORD_V5,
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
        ParamRecord::V4_LEN,
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
            measure_sd_m: ParamRecord::DEFAULT.measure_sd_m,
            heading_sd_rad: ParamRecord::DEFAULT.heading_sd_rad,
            convention: ParamRecord::DEFAULT.convention,
            ..rec
        }
    );
    assert_eq!(migrated.validate(), Ok(()));
    let mut buf = [0u8; ParamRecord::ENCODED_LEN];
    migrated.encode(&mut buf).unwrap();
    assert_eq!(buf[0], 5);
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
        assert_eq!(migrated.active, rec.active, "v{v}");
        assert_eq!(migrated.nominal, rec.nominal);
        assert_eq!(migrated.motion, rec.motion);
        let wiring = if v == 1 { Wiring::STANDARD } else { rec.wiring };
        assert_eq!(migrated.wiring, wiring);
        assert_eq!(migrated.tuning, SpeedTuning::DEFAULT);
        assert_eq!(migrated.control_hz, 1_000);
        assert_eq!(migrated.validate(), Ok(()));
        // Saved again, it is a version-5 record with the calibration intact.
        let mut buf = [0u8; ParamRecord::ENCODED_LEN];
        migrated.encode(&mut buf).unwrap();
        assert_eq!(buf[0], 5);
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

/// The calibration of a calibrated record.
fn calibration(r: &mut ParamRecord) -> &mut AppliedCalibration {
    r.calibration.as_mut().unwrap()
}

#[test]
fn validation_rejects_every_bad_field() {
    let good = calibrated();
    type Spoil = fn(&mut ParamRecord);
    let cases: [(Spoil, RecordError); 14] = [
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
        (|r| calibration(r).e_d = f64::NAN, RecordError::Factor),
        (
            |r| r.active.wheelbase_m = f64::INFINITY,
            RecordError::CalibratedGeometry(GeometryError::Wheelbase),
        ),
        (
            |r| r.nominal.diameter_right_m = 0.0,
            RecordError::NominalGeometry(GeometryError::Diameter),
        ),
        (
            |r| r.active.wheelbase_m *= 1.5,
            RecordError::CalibrationMismatch,
        ),
        (
            |r| calibration(r).e_max_m = -1.0,
            RecordError::PredictedError,
        ),
        (|r| calibration(r).runs_used = 5000, RecordError::Runs),
        (
            |r| calibration(r).method = "a b".try_into().unwrap(),
            RecordError::MethodName,
        ),
        (
            |r| r.motion.max_speed_mps = f32::NAN,
            RecordError::Limits(LimitsError::Speed),
        ),
        (|r| r.square_side_m = 0.0, RecordError::SquareSide),
        (|r| r.runs_per_direction = 0, RecordError::RunsPerDirection),
    ];
    for (spoil, expected) in cases {
        let mut r = good.clone();
        spoil(&mut r);
        assert_eq!(r.validate(), Err(expected));
    }
}

/// The declared measuring noise at each end of `set`'s range, stored as `set` stores it, is a
/// valid record; a step beyond either end is not.
#[test]
fn measuring_noise_at_its_range_ends_is_stored() {
    use crate::motion::convention::{HEADING_SD_RANGE_DEG, MEASURE_SD_RANGE_M};
    let (p_lo, p_hi) = MEASURE_SD_RANGE_M;
    let (h_lo, h_hi) = HEADING_SD_RANGE_DEG;
    for (p, h) in [(p_lo, h_lo), (p_hi, h_hi)] {
        let rec = ParamRecord {
            measure_sd_m: p as f32,
            heading_sd_rad: h.to_radians() as f32,
            ..ParamRecord::DEFAULT
        };
        assert_eq!(rec.validate(), Ok(()), "{p} m, {h} deg");
    }
    for (p, h) in [
        (p_lo * 0.99, 1.0),
        (p_hi * 1.01, 1.0),
        (0.001, h_lo * 0.99),
        (0.001, h_hi * 1.01),
    ] {
        let rec = ParamRecord {
            measure_sd_m: p as f32,
            heading_sd_rad: f64::to_radians(h) as f32,
            ..ParamRecord::DEFAULT
        };
        assert_eq!(
            rec.validate(),
            Err(RecordError::MeasuringNoise),
            "{p} m, {h} deg"
        );
    }
}
