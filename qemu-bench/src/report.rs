//! Result lines printed identically by the host reference run and by the QEMU run.
//!
//! Lines that start with `result ` carry exact bit patterns and must be equal on both sides;
//! `run.sh` compares them. Other lines are informational.

use core::fmt::{self, Write};

use odocal::odometry::Pose;

/// Writes `result <label> x=<bits> y=<bits> heading=<bits>`: the raw `i64` bits of the Q40
/// position and the `u64` binary heading, in hex.
///
/// # Errors
/// Whatever the writer returns.
pub fn pose_line<W: Write>(w: &mut W, label: &str, pose: &Pose) -> fmt::Result {
    writeln!(
        w,
        "result {label} x=0x{:016x} y=0x{:016x} heading=0x{:016x}",
        pose.x.to_bits(),
        pose.y.to_bits(),
        pose.heading.0
    )
}

/// Writes `result <label> <name>=<bits> ...` for `f64` values (raw IEEE-754 bits in hex).
///
/// # Errors
/// Whatever the writer returns.
pub fn f64_line<W: Write>(w: &mut W, label: &str, values: &[(&str, f64)]) -> fmt::Result {
    write!(w, "result {label}")?;
    for (name, v) in values {
        write!(w, " {name}=0x{:016x}", v.to_bits())?;
    }
    writeln!(w)
}
