//! Small number and text helpers with no domain knowledge: clamping, decimal formatting and
//! keyword comparison. Uses nothing else in the crate.

pub mod decimal;
pub mod num;
pub mod text;
