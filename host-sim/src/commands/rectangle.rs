//! `host-sim rectangle`: the rectangle test of a robot with the given true and believed factors
//! (the experiment: [`crate::experiments::rectangle`]); prints the final error, draws the paths.

use crate::experiments::rectangle::{self, RectangleSpec};

/// Arguments of the `rectangle` subcommand.
#[derive(clap::Args, Debug, Clone)]
pub struct RectangleArgs {
    /// True E_b of the simulated robot.
    #[arg(long, default_value_t = 1.010)]
    pub eb: f64,
    /// True E_d of the simulated robot.
    #[arg(long, default_value_t = 0.995)]
    pub ed: f64,
    /// E_b the odometry believes (1 = nominal).
    #[arg(long, default_value_t = 1.0)]
    pub belief_eb: f64,
    /// E_d the odometry believes (1 = nominal).
    #[arg(long, default_value_t = 1.0)]
    pub belief_ed: f64,
    /// Write the paths and the error growth as SVG files with this prefix.
    #[arg(long)]
    pub svg: Option<std::path::PathBuf>,
}

/// The `rectangle` subcommand.
pub fn run_cli(args: &RectangleArgs) -> Result<(), Box<dyn std::error::Error>> {
    let RectangleArgs {
        eb,
        ed,
        belief_eb,
        belief_ed,
        ref svg,
    } = *args;
    use odocal::kinematics::geometry::Geometry;
    let truth = Geometry::PAPER_NOMINAL.with_factors(ed, eb, 1.0);
    let belief = Geometry::PAPER_NOMINAL.with_factors(belief_ed, belief_eb, 1.0);
    let spec = RectangleSpec::default();
    let r = rectangle::run(&spec, &truth, &belief)?;
    println!(
        "rectangle {} m × {} m, {} CCW laps, truth E_b={eb} E_d={ed}, belief E_b={belief_eb} E_d={belief_ed}",
        spec.side_a_m.min(spec.side_b_m),
        spec.side_a_m.max(spec.side_b_m),
        spec.laps
    );
    println!("final position error: {:.4} m", r.final_error_m);
    if let Some(prefix) = svg {
        use crate::sim::plot::{Figure, Series, Style, write_svg};
        let paths = prefix.with_extension("paths.svg");
        write_svg(
            &paths,
            &Figure {
                title: "Rectangle test: true path vs odometry".into(),
                x_label: "x [m]".into(),
                y_label: "y [m]".into(),
                equal_aspect: true,
                series: vec![
                    Series::new("true", r.true_path.clone(), Style::Line, 0),
                    Series::new("odometry", r.odometry_path.clone(), Style::ThinLine, 1),
                    Series::new(
                        "odometry end",
                        r.odometry_path.last().copied().into_iter().collect(),
                        Style::Points,
                        1,
                    ),
                ],
                ..Figure::default()
            },
        )?;
        let growth = prefix.with_extension("growth.svg");
        write_svg(
            &growth,
            &Figure {
                title: "Odometry error over distance".into(),
                x_label: "distance travelled [m]".into(),
                y_label: "position error [m]".into(),
                series: vec![Series::new("odometry", r.growth.clone(), Style::Line, 1)],
                ..Figure::default()
            },
        )?;
        println!("wrote {} and {}", paths.display(), growth.display());
    }
    Ok(())
}
