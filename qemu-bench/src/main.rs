//! The benchmark binary.
//!
//! - On thumbv7em-none-eabihf (run under QEMU by `run.sh`): integrates the standard encoder
//!   trace with `odocal::kinematics::odometry`, bracketing every step with marker functions whose addresses
//!   the instruction-counting TCG plugin (`plugin/insnwin.c`) watches, measures a SysTick
//!   cross-check block and the stack high-water mark, and prints the result lines over
//!   semihosting.
//! - On the host: integrates the same trace with the same code and prints the same result lines,
//!   plus the accuracy of the fixed-point odometry against the `f64` exact-arc reference.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(not(target_os = "none"))]
mod host;
#[cfg(target_os = "none")]
mod target;

#[cfg(not(target_os = "none"))]
fn main() -> std::process::ExitCode {
    host::run()
}
