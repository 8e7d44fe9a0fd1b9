//! Small number and text helpers with no domain knowledge: clamping, decimal formatting, keyword
//! comparison, sine/cosine and the floating remainder. Uses nothing else in the crate.

pub mod decimal;
pub mod num;
pub mod text;
pub mod trig;
