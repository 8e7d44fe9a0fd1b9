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
    session: host_sim::commands::session::SessionArgs,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// The full simulated calibration session through the serial protocol (the default).
    Session(host_sim::commands::session::SessionArgs),
    /// Print the odometry constants derived from a geometry.
    Geometry(host_sim::commands::geometry::GeometryArgs),
    /// Drive 4 CCW laps of a 3.6 m × 8.7 m rectangle exactly (paper §4.3) and report the
    /// odometry's position error with a believed geometry.
    Rectangle(host_sim::commands::rectangle::RectangleArgs),
    /// Drive a scripted velocity profile (line, turn, arc) closed-loop; odometry vs true pose.
    Drive(host_sim::commands::drive::DriveArgs),
    /// Drive UMBmark squares CW and CCW closed-loop; end errors and wheel synchronisation.
    Square(host_sim::commands::square::SquareArgs),
    /// Simulated parameter flash: boots, saves, reboots, wear, damage (see `flash --help`).
    Flash(host_sim::commands::flash::FlashArgs),
    /// Lee, Jung & Chung 2011 §3 simulation: ideal kinematics, every calibration method.
    Paper(host_sim::commands::paper::PaperArgs),
    /// Calibrate on OptiOdom sessions of any kind, evaluate any parameter set on others.
    Replay(host_sim::commands::replay::ReplayArgs),
    /// Paper-mode Monte Carlo with measurement and slip noise.
    Montecarlo(host_sim::commands::montecarlo::MonteCarloArgs),
    /// Track-size advice (paper §2.3) per calibration method.
    Advice(host_sim::commands::advice::AdviceArgs),
    /// Calibration from squares driven closed-loop (motor dynamics), optional noise.
    Closedloop(host_sim::commands::closedloop::ClosedLoopArgs),
    /// The simulated robot speaking the serial protocol on stdin/stdout or a pseudo-terminal.
    Serial(host_sim::commands::serial::SerialArgs),
    /// First power-up of a robot with a reversed motor or encoder: the wiring check over the
    /// serial protocol, its proposed fix, save, reboot, a square.
    Bringup(host_sim::commands::bringup::BringupArgs),
    /// Motor identification on robots whose motors differ from the defaults, and the squares
    /// before and after the identified tuning.
    Motors(host_sim::commands::motors::MotorsArgs),
    /// Host speed: a full simulated 5 + 5 session and a 1,000-trial Monte Carlo.
    Bench(host_sim::commands::bench::BenchArgs),
    /// Monte Carlo over square sides and noise levels: validates the track-size advice.
    Sweep(host_sim::commands::sweep::SweepArgs),
}

/// Runs the command; an error is printed as the message it is (not as a debug string) and the
/// exit status is 1.
#[allow(unsafe_code)] // the one `libc::signal` call below
fn main() -> std::process::ExitCode {
    // Output into a closed pipe (`… | head`) ends the program quietly, as for any Unix tool,
    // instead of a panic in `println!`.
    // SAFETY: restoring the default disposition of SIGPIPE before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    match run(Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("host-sim: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<(), Box<dyn std::error::Error>> {
    let Some(command) = cli.command else {
        return host_sim::commands::session::run(&cli.session);
    };
    match command {
        Command::Session(args) => host_sim::commands::session::run(&args),
        Command::Geometry(args) => host_sim::commands::geometry::run(&args),
        Command::Rectangle(args) => host_sim::commands::rectangle::run_cli(&args),
        Command::Drive(args) => Ok(host_sim::commands::drive::run(&args)?),
        Command::Square(args) => Ok(host_sim::commands::square::run(&args)?),
        Command::Flash(args) => host_sim::commands::flash::run(args),
        Command::Paper(args) => host_sim::commands::paper::run(&args),
        Command::Replay(args) => host_sim::commands::replay::run(&args),
        Command::Montecarlo(args) => host_sim::commands::montecarlo::run(&args),
        Command::Advice(args) => host_sim::commands::advice::run(&args),
        Command::Closedloop(args) => host_sim::commands::closedloop::run(&args),
        Command::Serial(args) => Ok(host_sim::commands::serial::run(&args)?),
        Command::Bringup(args) => Ok(host_sim::commands::bringup::run(&args)?),
        Command::Motors(args) => Ok(host_sim::commands::motors::run(&args)?),
        Command::Bench(args) => host_sim::commands::bench::run(&args),
        Command::Sweep(args) => host_sim::commands::sweep::run(&args),
    }
}
