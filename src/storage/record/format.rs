//! The stored layout of the record: its format version, the length of every version, the encoder,
//! and the decoder that reads every version and migrates the older ones (see `docs/storage.md`
//! for the table).

use super::codec::{Reader, Writer};
use super::{AppliedCalibration, FormatError, METHOD_NAME_MAX, MethodName, ParamRecord};
use crate::motion::controller::DEFAULT_RATE_HZ;
use crate::motion::convention::Convention;
use crate::motion::profile::MotionLimits;
use crate::motion::speed::SpeedTuning;
use crate::motion::wiring::Wiring;

impl ParamRecord {
    /// Format version written by this firmware (byte 0 of the stored record). Every older
    /// version is read and migrated by [`ParamRecord::decode`]; what each version added and how
    /// it migrates: docs/storage.md, *Versions*.
    pub const FORMAT_VERSION: u8 = 5;

    /// Length of a version-1 record, bytes: version 1 + nominal geometry 28 + `E_d, E_b, E_s`
    /// 24 + calibrated geometry 28 + method 1 + 12 + runs 2 + `E_max` 8 + motion 5 × 4 + 1.
    pub const V1_LEN: usize = 1 + 28 + 24 + 28 + 1 + METHOD_NAME_MAX + 2 + 8 + 20 + 1;

    /// Length of a version-2 record, bytes: [`Self::V1_LEN`] + wiring 1.
    pub const V2_LEN: usize = Self::V1_LEN + 1;

    /// Length of a version-3 record, bytes: [`Self::V2_LEN`] + tuning 9 × 4.
    pub const V3_LEN: usize = Self::V2_LEN + 9 * 4;

    /// Length of a version-4 record, bytes: [`Self::V3_LEN`] + control rate 4.
    pub const V4_LEN: usize = Self::V3_LEN + 4;

    /// Length of the stored record, bytes: [`Self::V4_LEN`] + measuring noise 2 × 4 +
    /// convention 1.
    pub const ENCODED_LEN: usize = Self::V4_LEN + 2 * 4 + 1;

    /// Writes the stored form into `buf`; returns the number of bytes written
    /// ([`Self::ENCODED_LEN`]).
    ///
    /// # Errors
    /// [`FormatError::BufferTooSmall`] if `buf` is shorter than [`Self::ENCODED_LEN`].
    pub fn encode(&self, buf: &mut [u8]) -> Result<usize, FormatError> {
        let Some(buf) = buf.get_mut(..Self::ENCODED_LEN) else {
            return Err(FormatError::BufferTooSmall);
        };
        let method = self.stored_method().map_err(|_| FormatError::MethodName)?;
        let mut w = Writer { buf, pos: 0 };
        w.bytes(&[Self::FORMAT_VERSION]);
        w.geometry(&self.nominal);
        let c = self.stored_calibration();
        w.f64(c.e_d);
        w.f64(c.e_b);
        w.f64(c.e_s);
        w.geometry(&c.geometry);
        w.bytes(&[method.len]);
        w.bytes(&method.bytes);
        w.bytes(&c.runs.to_le_bytes());
        w.f64(c.e_max_m);
        let m = &self.motion;
        w.f32(m.max_speed_mps);
        w.f32(m.max_accel_mps2);
        w.f32(m.max_turn_rate_radps);
        w.f32(m.max_turn_accel_radps2);
        w.f32(self.square_side_m);
        w.bytes(&[self.runs_per_direction]);
        w.bytes(&[self.wiring.to_bits()]);
        let t = &self.tuning;
        w.motor(&t.right);
        w.motor(&t.left);
        w.f32(t.bandwidth_radps);
        w.bytes(&self.control_hz.to_le_bytes());
        w.f32(self.measure_sd_m);
        w.f32(self.heading_sd_rad);
        w.bytes(&[self.convention.to_byte()]);
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
        // record has no control rate and means the 1 kHz those firmwares ran at; a version-1..4
        // record has no measuring noise and convention and means the defaults (1 mm, 0.2°,
        // standard).
        let expected = match version {
            1 => Self::V1_LEN,
            2 => Self::V2_LEN,
            3 => Self::V3_LEN,
            4 => Self::V4_LEN,
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
        let motion = MotionLimits {
            max_speed_mps: r.f32(),
            max_accel_mps2: r.f32(),
            max_turn_rate_radps: r.f32(),
            max_turn_accel_radps2: r.f32(),
        };
        let square_side_m = r.f32();
        let runs_per_direction = r.array::<1>()[0];
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
        let (measure_sd_m, heading_sd_rad, convention) = if version < 5 {
            let d = ParamRecord::DEFAULT;
            (d.measure_sd_m, d.heading_sd_rad, d.convention)
        } else {
            let p = r.f32();
            let h = r.f32();
            let c = Convention::from_byte(r.array::<1>()[0]).ok_or(FormatError::Convention)?;
            (p, h, c)
        };
        // `none` is an uncalibrated robot: its stored factors are those of no calibration and
        // are not kept.
        let calibration = if method == MethodName::NONE {
            None
        } else {
            let mut name = heapless::String::new();
            // Cannot fail: a method name is at most METHOD_NAME_MAX bytes, the string's capacity.
            let _ = name.push_str(method.as_str());
            let applied = AppliedCalibration {
                method: name,
                e_d,
                e_b,
                e_s,
                runs_used: runs,
                e_max_m: predicted_e_max_m,
            };
            Some(applied)
        };
        Ok(ParamRecord {
            nominal,
            active: geometry,
            calibration,
            motion,
            square_side_m,
            runs_per_direction,
            wiring,
            tuning,
            control_hz,
            measure_sd_m,
            heading_sd_rad,
            convention,
        })
    }
}
