//! Result lines printed identically by the host reference run and by the QEMU run.
//!
//! Lines that start with `result ` carry exact bit patterns and must be equal on both sides;
//! `run.sh` compares them. Other lines are informational.

use core::fmt::{self, Write};

use odocal::calibration::{Calibration, CalibrationError};
use odocal::kinematics::odometry::Pose;
use odocal::motion::bringup::CheckReport;
use odocal::motion::identify::MotorFit;
use odocal::motion::run::RunRecord;

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

/// Writes `result <label> <name>=<hex> ...` for raw 64-bit values.
///
/// # Errors
/// Whatever the writer returns.
pub fn bits_line<W: Write>(w: &mut W, label: &str, values: &[(&str, u64)]) -> fmt::Result {
    write!(w, "result {label}")?;
    for (name, v) in values {
        write!(w, " {name}=0x{v:016x}")?;
    }
    writeln!(w)
}

/// Writes the result line of a calibration: the bits of `E_d`, `E_b`, `E_s`, the RMS residual and
/// the iteration count, or the error.
///
/// # Errors
/// Whatever the writer returns.
pub fn calibration_line<W: Write>(
    w: &mut W,
    label: &str,
    result: &Result<Calibration, CalibrationError>,
) -> fmt::Result {
    match result {
        Ok(c) => {
            write!(w, "result {label} iterations={}", c.iterations)?;
            let rms = c.quality.rms_residual_m.unwrap_or(f64::NAN);
            for (name, v) in [("e_d", c.e_d), ("e_b", c.e_b), ("e_s", c.e_s), ("rms", rms)] {
                write!(w, " {name}=0x{:016x}", v.to_bits())?;
            }
            writeln!(w)
        }
        Err(e) => writeln!(w, "result {label} error={e}"),
    }
}

/// Writes the result line of a driven run: periods, knot count, last knot and the bits of the
/// recorded odometry end pose.
///
/// # Errors
/// Whatever the writer returns.
pub fn run_line<W: Write>(w: &mut W, label: &str, periods: u32, record: &RunRecord) -> fmt::Result {
    let last = record.knots.last().copied().unwrap_or_default();
    let end = &record.odometry_end;
    writeln!(
        w,
        "result {label} periods={periods} knots={} last=({},{}) x=0x{:016x} y=0x{:016x} theta=0x{:016x}",
        record.knots.len(),
        last.right,
        last.left,
        end.x_m.to_bits(),
        end.y_m.to_bits(),
        end.theta_rad.to_bits()
    )
}

/// Writes the result line of a motor identification: periods, then per wheel the bits of the
/// fitted parameters (`f32`: gain forward and backward, time constant, dead-band, coasting
/// deceleration and its speed, residual), or the failure.
///
/// # Errors
/// Whatever the writer returns.
pub fn identify_line<W: Write>(
    w: &mut W,
    label: &str,
    periods: u32,
    report: &CheckReport,
) -> fmt::Result {
    write!(w, "result {label} periods={periods}")?;
    match report {
        CheckReport::Identify(r) => {
            for (side, fit) in [("r", &r.right), ("l", &r.left)] {
                write!(w, " {side}=")?;
                fit_bits(w, fit)?;
            }
            writeln!(w)
        }
        CheckReport::IdentifyFailed(f) => writeln!(w, " failed={:?}/{:?}", f.wheel, f.problem),
        other => writeln!(w, " unexpected={other:?}"),
    }
}

fn fit_bits<W: Write>(w: &mut W, fit: &MotorFit) -> fmt::Result {
    let p = &fit.params;
    let values = [
        p.gain_forward_mps,
        p.gain_backward_mps,
        p.time_constant_s,
        p.deadband,
        fit.coast_decel_mps2,
        fit.coast_from_mps,
        fit.residual_mps,
    ];
    for (i, v) in values.iter().enumerate() {
        let sep = if i == 0 { "" } else { "," };
        write!(w, "{sep}{:08x}", v.to_bits())?;
    }
    Ok(())
}
