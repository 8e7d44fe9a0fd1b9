//! The `geometry` subcommand: the odometry constants derived from a geometry.

/// Arguments of the `geometry` subcommand.
#[derive(clap::Args, Debug, Clone, Copy)]
pub struct GeometryArgs {
    /// Wheel diameter, metres.
    #[arg(long, default_value_t = 0.150)]
    pub diameter: f64,
    /// Wheelbase, metres.
    #[arg(long, default_value_t = 0.385)]
    pub wheelbase: f64,
    /// Encoder counts per wheel revolution.
    #[arg(long, default_value_t = odocal::kinematics::geometry::DEFAULT_COUNTS_PER_REV)]
    pub counts_per_rev: u32,
}

/// Prints the per-tick constants of a geometry, or why it is invalid.
pub fn run(args: &GeometryArgs) -> Result<(), Box<dyn std::error::Error>> {
    let GeometryArgs {
        diameter,
        wheelbase,
        counts_per_rev,
    } = *args;
    use odocal::kinematics::encoder::{CounterWidth, max_step_for};
    let g = odocal::kinematics::geometry::Geometry::symmetric(diameter, wheelbase, counts_per_rev);
    g.validate().map_err(|e| format!("invalid geometry: {e}"))?;
    println!(
        "travel per tick      {:.6} um",
        g.meters_per_tick_right() * 1e6
    );
    println!(
        "heading per tick     {:.6e} rad (one wheel)",
        g.meters_per_tick_right() / g.wheelbase_m
    );
    println!(
        "glitch limit @1 kHz  {} counts/period (16-bit timer, 2 m/s)",
        max_step_for(CounterWidth::Bits16, counts_per_rev, diameter, 2.0, 1e-3)
    );
    Ok(())
}
