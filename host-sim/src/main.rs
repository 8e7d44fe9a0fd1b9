//! host-sim: runs the odocal library against a simulated robot.
//!
//! Every subcommand drives the library's own state machines; nothing here re-implements
//! firmware logic. The simulated hardware (wheels, motors, encoders, flash, serial line) lives in
//! this crate.

use clap::{Parser, Subcommand};

/// Simulated odocal robot.
#[derive(Parser, Debug)]
#[command(name = "host-sim", version, about)]
#[command(args_conflicts_with_subcommands = true)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Without a subcommand: the full simulated calibration session (as `session`).
    #[command(flatten)]
    session: host_sim::session::SessionArgs,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// The full simulated calibration session through the serial protocol (the default).
    Session(host_sim::session::SessionArgs),
    /// Print the odometry constants derived from a geometry.
    Geometry {
        /// Wheel diameter, metres.
        #[arg(long, default_value_t = 0.150)]
        diameter: f64,
        /// Wheelbase, metres.
        #[arg(long, default_value_t = 0.385)]
        wheelbase: f64,
        /// Encoder counts per wheel revolution.
        #[arg(long, default_value_t = odocal::geometry::DEFAULT_COUNTS_PER_REV)]
        counts_per_rev: u32,
    },
    /// Drive 4 CCW laps of a 3.6 m × 8.7 m rectangle exactly (paper §4.3) and report the
    /// odometry's position error with a believed geometry.
    Rectangle {
        /// True E_b of the simulated robot.
        #[arg(long, default_value_t = 1.010)]
        eb: f64,
        /// True E_d of the simulated robot.
        #[arg(long, default_value_t = 0.995)]
        ed: f64,
        /// E_b the odometry believes (1 = nominal).
        #[arg(long, default_value_t = 1.0)]
        belief_eb: f64,
        /// E_d the odometry believes (1 = nominal).
        #[arg(long, default_value_t = 1.0)]
        belief_ed: f64,
        /// Write the paths and the error growth as SVG files with this prefix.
        #[arg(long)]
        svg: Option<std::path::PathBuf>,
    },
    /// Drive a scripted velocity profile (line, turn, arc) closed-loop; odometry vs true pose.
    Drive(host_sim::drive::DriveArgs),
    /// Drive UMBmark squares CW and CCW closed-loop; end errors and wheel synchronisation.
    Square(host_sim::square::SquareArgs),
    /// Simulated parameter flash: boots, saves, reboots, wear, damage (see `flash --help`).
    Flash(host_sim::flash::FlashArgs),
    /// Lee, Jung & Chung 2011 §3 simulation: ideal kinematics, every calibration method.
    Paper(host_sim::paper::PaperArgs),
    /// Calibrate on one OptiOdom session, evaluate on others.
    Replay(host_sim::replay::ReplayArgs),
    /// Paper-mode Monte Carlo with measurement and slip noise.
    Montecarlo(host_sim::montecarlo::MonteCarloArgs),
    /// Track-size advice (paper §2.3) per calibration method.
    Advice(host_sim::advice::AdviceArgs),
    /// Calibration from squares driven closed-loop (motor dynamics), optional noise.
    Closedloop(host_sim::closedloop::ClosedLoopArgs),
    /// The simulated robot speaking the serial protocol on stdin/stdout or a pseudo-terminal.
    Serial(host_sim::serial::SerialArgs),
    /// Host speed: a full simulated 5 + 5 session and a 1,000-trial Monte Carlo.
    Bench(host_sim::bench::BenchArgs),
    /// Monte Carlo over square sides and noise levels: validates the track-size advice.
    Sweep(host_sim::sweep::SweepArgs),
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cli = Cli::parse();
    let Some(command) = cli.command else {
        return host_sim::session::run(&cli.session);
    };
    match command {
        Command::Session(args) => host_sim::session::run(&args),
        Command::Geometry {
            diameter,
            wheelbase,
            counts_per_rev,
        } => print_geometry(diameter, wheelbase, counts_per_rev),
        Command::Rectangle {
            eb,
            ed,
            belief_eb,
            belief_ed,
            svg,
        } => run_rectangle(eb, ed, belief_eb, belief_ed, svg),
        Command::Drive(args) => Ok(host_sim::drive::run(&args)?),
        Command::Square(args) => Ok(host_sim::square::run(&args)?),
        Command::Flash(args) => host_sim::flash::run(args),
        Command::Paper(args) => host_sim::paper::run(&args),
        Command::Replay(args) => host_sim::replay::run(&args),
        Command::Montecarlo(args) => host_sim::montecarlo::run(&args),
        Command::Advice(args) => host_sim::advice::run(&args),
        Command::Closedloop(args) => host_sim::closedloop::run(&args),
        Command::Serial(args) => Ok(host_sim::serial::run(&args)?),
        Command::Bench(args) => host_sim::bench::run(&args),
        Command::Sweep(args) => host_sim::sweep::run(&args),
    }
}

/// Prints the per-tick constants of a geometry, or why it is invalid.
fn print_geometry(
    diameter: f64,
    wheelbase: f64,
    counts_per_rev: u32,
) -> Result<(), Box<dyn std::error::Error>> {
    use odocal::encoder::{CounterWidth, max_step_for};
    let g = odocal::geometry::Geometry::symmetric(diameter, wheelbase, counts_per_rev);
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

/// The rectangle subcommand.
fn run_rectangle(
    eb: f64,
    ed: f64,
    belief_eb: f64,
    belief_ed: f64,
    svg: Option<std::path::PathBuf>,
) -> Result<(), Box<dyn std::error::Error>> {
    use odocal::geometry::Geometry;
    let truth = Geometry::PAPER_NOMINAL.with_factors(ed, eb, 1.0);
    let belief = Geometry::PAPER_NOMINAL.with_factors(belief_ed, belief_eb, 1.0);
    let spec = host_sim::rectangle::RectangleSpec::default();
    let r = host_sim::rectangle::run(&spec, &truth, &belief)?;
    println!(
        "rectangle {} x {} m, {} CCW laps, truth E_b={eb} E_d={ed}, belief E_b={belief_eb} E_d={belief_ed}",
        spec.side_a_m, spec.side_b_m, spec.laps
    );
    println!("final position error: {:.4} m", r.final_error_m);
    if let Some(prefix) = svg {
        use host_sim::plot::{Figure, Series, Style, write_svg};
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
