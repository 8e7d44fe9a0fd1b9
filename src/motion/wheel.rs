//! The two wheels, named: which motor, encoder or fault a value belongs to. A leaf that every
//! part of [`crate::motion`] may name ([`crate::motion::controller`] re-exports it).

/// A wheel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Wheel {
    /// The right wheel.
    Right,
    /// The left wheel.
    Left,
}
