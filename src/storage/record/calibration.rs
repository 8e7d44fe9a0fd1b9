//! The calibration result the record holds, and the short ASCII name its method is stored
//! under.

use core::fmt;

use super::RecordError;

/// Longest calibration method name, bytes of ASCII.
pub const METHOD_NAME_MAX: usize = 12;

/// Name of the method that produced a calibration (`exact`, `lee-x`, `umbmark-x`, `none`, …).
///
/// Short printable ASCII (1 ..= [`METHOD_NAME_MAX`] bytes, no spaces) so the storage format does
/// not depend on the calibration module's types. Unused bytes are always zero.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct MethodName {
    pub(super) len: u8,
    pub(super) bytes: [u8; METHOD_NAME_MAX],
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

    pub(super) fn from_bytes(name: &[u8]) -> Result<Self, RecordError> {
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

/// A calibration result in use: the factors relative to the nominal geometry (the geometry they
/// give is the record's `active` one), the method and what it was computed from.
#[derive(Clone, Debug, PartialEq)]
pub struct AppliedCalibration {
    /// Method name (e.g. `exact`): stored as a [`MethodName`], so 1..=[`METHOD_NAME_MAX`]
    /// printable ASCII bytes ([`super::ParamRecord::validate`] checks it).
    pub method: heapless::String<METHOD_NAME_MAX>,
    /// Diameter ratio factor `E_d = D_R / D_L` (dimensionless).
    pub e_d: f64,
    /// Wheelbase factor `E_b = b_actual / b_nominal` (dimensionless).
    pub e_b: f64,
    /// Mean-diameter (distance) scale `E_s = D_a / D_a,nominal` (dimensionless).
    pub e_s: f64,
    /// Number of square runs it was computed from (CW + CCW).
    pub runs_used: u16,
    /// Predicted worst square end error `E_max` with it, metres (0 when unknown).
    pub e_max_m: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

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
