//! `host-sim paper`: the simulation of Lee, Jung & Chung 2011 §3 in an ideal kinematic mode
//! ([`crate::experiments::paper`]), as a text table or JSON lines.

use clap::Args;
use odocal::kinematics::geometry::Geometry;

pub use crate::experiments::paper::Format;
use crate::experiments::paper::{TruthModel, rows, true_geometry};

/// Arguments of `host-sim paper`.
#[derive(Args, Debug)]
pub struct PaperArgs {
    /// True E_b.
    #[arg(long, default_value_t = 1.010)]
    pub eb: f64,
    /// True E_d.
    #[arg(long, default_value_t = 0.995)]
    pub ed: f64,
    /// Square sides L, metres.
    #[arg(long, value_delimiter = ',', num_args = 1.., default_values_t = [0.2, 1.0, 2.0, 4.0, 16.0])]
    pub sides: Vec<f64>,
    /// How the true diameters follow from E_d.
    #[arg(long, value_enum, default_value_t = TruthModel::Mean)]
    pub truth_model: TruthModel,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Text)]
    pub format: Format,
}

/// Runs the subcommand.
pub fn run(args: &PaperArgs) -> Result<(), Box<dyn std::error::Error>> {
    let nominal = Geometry::PAPER_NOMINAL;
    let truth = true_geometry(&nominal, args.eb, args.ed, args.truth_model);
    truth
        .validate()
        .map_err(|e| format!("invalid true geometry: {e}"))?;
    let t_eb = truth.wheelbase_m / nominal.wheelbase_m;
    let t_ed = truth.diameter_ratio();
    if args.format == Format::Text {
        println!(
            "truth E_b = {t_eb:.6}  E_d = {t_ed:.6}  (D_R = {:.6} mm, D_L = {:.6} mm, b = {:.6} mm)",
            truth.diameter_right_m * 1e3,
            truth.diameter_left_m * 1e3,
            truth.wheelbase_m * 1e3
        );
        println!(
            "{:>5} {:>11} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>11} {:>11} {:>11}",
            "L/m",
            "method",
            "x_cw/mm",
            "y_cw/mm",
            "x_ccw/mm",
            "y_ccw/mm",
            "E_b",
            "E_d",
            "E_b_err",
            "E_d_err",
            "E_max_after/mm"
        );
    }
    for row in rows(&nominal, &truth, &args.sides)? {
        match args.format {
            Format::Json => println!("{}", row.json()),
            Format::Text => {
                let [xc, yc, xa, ya] = row.cg;
                match &row.result {
                    Ok((eb, ed, emax)) => println!(
                        "{:>5} {:>11} {:>10.3} {:>10.3} {:>10.3} {:>10.3} {:>10.6} {:>10.6} {:>11.3e} {:>11.3e} {:>11.4}",
                        row.side,
                        row.method.as_str(),
                        xc * 1e3,
                        yc * 1e3,
                        xa * 1e3,
                        ya * 1e3,
                        eb,
                        ed,
                        eb / t_eb - 1.0,
                        ed / t_ed - 1.0,
                        emax * 1e3
                    ),
                    Err(e) => println!("{:>5} {:>11} error: {e}", row.side, row.method.as_str()),
                }
            }
        }
    }
    Ok(())
}
