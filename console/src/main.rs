//! `cargo console`: the guided calibration console for an odocal board.
//!
//! Plug in the board's USB-UART (or start `cargo sim serial --pty`), run `cargo console`, and
//! follow the prompts: the tool checks the board and says whether it holds the factory
//! defaults, takes the nominal geometry, runs the bring-up check and the motor identification
//! (each skippable, and skipped by default when the board holds them), plans the squares,
//! starts each run, shows its progress from the pose stream, forwards the measured end pose as
//! typed (units included) to the board's `measure`, shows `calibrate`'s table, applies and
//! saves the chosen method only on a typed yes, reads `params` back, drives a check square and
//! sums up. `back` at every question returns to the previous one. Everything goes to a
//! JSON-lines session log (`--log`), which `--resume LOG` continues after a crash, a disconnect
//! or a board reset, which `cargo console recalibrate LOG [--method M]` recalibrates on the PC
//! with the same library, and which `cargo console export LOG --format ros2|urdf|json
//! [-o FILE]` turns into files a robot stack loads. An SVG of the runs is written next to the
//! log.

mod covariance;
mod export;
mod guide;
mod link;
mod log;
mod online;
mod plot;
mod ros2;
mod stale;
mod ui;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::{Parser, Subcommand};
use odocal::session::library::LibraryCalibrator;
use odocal::session::{Calibrator, write_calibration};

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Whether Ctrl-C was pressed.
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::Relaxed)
}

extern "C" fn on_sigint(_: libc::c_int) {
    INTERRUPTED.store(true, Ordering::Relaxed);
}

#[allow(unsafe_code)] // the one `libc::signal` call below
fn catch_ctrl_c() {
    // SAFETY: the handler only stores to an atomic, which is async-signal-safe.
    unsafe {
        libc::signal(
            libc::SIGINT,
            on_sigint as extern "C" fn(libc::c_int) as libc::sighandler_t,
        );
    }
}

#[derive(Parser, Debug)]
#[command(
    name = "odocal-console",
    about = "Guided odometry calibration on an odocal board over its serial port",
    after_help = "At every question of the guided session, `back` returns to the previous \
                  question (from a step's first question, to the step before: geometry, \
                  bring-up, identification, plan, runs, calibration, check square); `help` \
                  explains the question; Ctrl-C stops the robot. Nothing done is undone by \
                  `back`, and nothing moves without its Enter or typed yes."
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Cmd>,
    #[command(flatten)]
    session: guide::Options,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Recalibrate a session log on the PC with the library the board runs.
    Recalibrate {
        /// The session log (JSON lines).
        #[arg(required_unless_present = "reference_log")]
        log: Option<PathBuf>,
        /// Redo the online calibration's estimate from the bridge's `--reference-log` instead.
        #[arg(long, conflicts_with_all = ["log", "method"])]
        reference_log: Option<PathBuf>,
        /// Only this method (default: every method, as `calibrate` shows them).
        #[arg(long)]
        method: Option<String>,
    },
    /// Export the board's calibration from a session log (or a terminal capture with the
    /// board's `params` reply) for a robot stack.
    Export {
        /// The session log (JSON lines), or a plain capture of a terminal session.
        log: PathBuf,
        /// ros2: a diff_drive_controller parameter file; urdf: the wheel joints' geometry;
        /// json: the calibration, its uncertainty and the runs.
        #[arg(long, value_enum, default_value = "ros2")]
        format: export::Format,
        /// Write to this file instead of stdout.
        #[arg(short = 'o', long = "output")]
        output: Option<PathBuf>,
        /// ros2: the controller's name (the file's top key).
        #[arg(long, default_value = "diff_drive_controller")]
        controller: String,
        /// ros2: the left wheel's joint.
        #[arg(long, default_value = "left_wheel_joint")]
        left_wheel: String,
        /// ros2: the right wheel's joint.
        #[arg(long, default_value = "right_wheel_joint")]
        right_wheel: String,
        /// ros2: random travel error of each wheel after one metre (1σ, m), in the pose
        /// covariance (default: the scatter of the log's runs, or 2 mm without runs).
        #[arg(long)]
        slip: Option<f64>,
        /// ros2: keep the log's own 1σ of E_d and E_b, even below the drift measured between
        /// sessions.
        #[arg(long)]
        trust_session_sd: bool,
        /// ros2: the controller's update rate, Hz.
        #[arg(long, default_value_t = 100.0)]
        rate_hz: f64,
        /// ros2: the controller's velocity_rolling_window_size (its speeds are the mean over
        /// this many updates: the twist covariance's averaging period).
        #[arg(long, default_value_t = export::ROLLING_WINDOW_DEFAULT)]
        rolling_window: u32,
    },
    /// Bridge the board to a ROS 2 network: odometry, tf, joint states and diagnostics out,
    /// cmd_vel in (docs/operator.md, "Using odocal on a ROS 2 robot").
    Ros2(Box<ros2::Options>),
    /// List candidate serial ports.
    Ports,
}

fn recalibrate(log: &Path, method: Option<&str>) -> Result<(), String> {
    let contents = log::LogContents::read(log)?;
    let runs = contents.live_runs();
    let nominal = contents
        .nominal
        .ok_or_else(|| format!("{}: no `params` of the board in the log", log.display()))?;
    let mut calibrator = LibraryCalibrator::default();
    let method = match method {
        None => None,
        Some(m) => Some(
            calibrator
                .methods()
                .iter()
                .copied()
                .find(|k| k.eq_ignore_ascii_case(m))
                .ok_or_else(|| {
                    format!(
                        "unknown method `{m}`; one of {}",
                        calibrator.methods().join("|")
                    )
                })?,
        ),
    };
    println!(
        "recalibrate {}: {} runs from the log, nominal D_R={} D_L={} b={} m",
        log.display(),
        runs.len(),
        nominal.diameter_right_m,
        nominal.diameter_left_m,
        nominal.wheelbase_m
    );
    let mut out = String::new();
    let numbered = odocal::session::Numbered {
        runs: &runs,
        numbers: &[],
    };
    // Read as the board read them when the log was written.
    write_calibration(
        &mut calibrator,
        numbered,
        &nominal,
        method,
        &contents.reading,
        &mut out,
    )
    .map_err(|e| e.to_string())?;
    print!("{}", out.replace("\r\n", "\n"));
    if out
        .lines()
        .last()
        .and_then(odocal::protocol::FinalLine::parse)
        .is_some_and(|l| !l.is_ok())
    {
        return Err("no calibration from this log".into());
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Some(Cmd::Recalibrate {
            reference_log: Some(path),
            ..
        }) => online::log::recalibrate(path),
        Some(Cmd::Recalibrate {
            log: Some(log),
            method,
            ..
        }) => recalibrate(log, method.as_deref()),
        Some(Cmd::Recalibrate { .. }) => {
            Err("recalibrate: a session log or --reference-log".into())
        }
        Some(Cmd::Export {
            log,
            format,
            output,
            controller,
            left_wheel,
            right_wheel,
            slip,
            trust_session_sd,
            rate_hz,
            rolling_window,
        }) => export::run(
            log,
            *format,
            &export::Target {
                controller: controller.clone(),
                left_wheel: left_wheel.clone(),
                right_wheel: right_wheel.clone(),
                slip_m: *slip,
                trust_session_sd: *trust_session_sd,
                rate_hz: *rate_hz,
                rolling_window: *rolling_window,
            },
            output.as_deref(),
        ),
        Some(Cmd::Ros2(opts)) => {
            catch_ctrl_c();
            ros2::run(opts)
        }
        Some(Cmd::Ports) => {
            let ports = link::candidate_ports();
            if ports.is_empty() {
                println!("no USB serial port found (plug in the board's USB-UART adapter)");
            }
            for p in ports {
                println!("{p}");
            }
            Ok(())
        }
        None => {
            catch_ctrl_c();
            guide::run(&cli.session)
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("console: {e}");
            if interrupted() {
                ExitCode::from(130)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}
