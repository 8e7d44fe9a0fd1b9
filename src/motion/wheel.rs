//! The two wheels, named: which motor, encoder or fault a value belongs to. A leaf that every
//! part of [`crate::motion`] may name ([`crate::motion::controller`] re-exports it).

/// Smallest wheel travel that counts as motion, m (1 mm): in a bring-up check's pulse, and in
/// the last quarter of an identification step.
pub const MIN_MOTION_M: f64 = 0.001;

/// A wheel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Wheel {
    /// The right wheel.
    Right,
    /// The left wheel.
    Left,
}
