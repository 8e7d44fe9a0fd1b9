//! The `bringup` subcommand: a first power-up of a robot whose motor or encoder may be wired
//! the other way round, through the board's serial protocol.
//!
//! The simulated board boots on an erased flash with the robot's `--wiring`; then, as the README's
//! bring-up procedure says: `bringup push` (the simulated hand pushes the robot forward),
//! `bringup` (motor pulses), the `set` commands the board proposes, `save`, a reboot on the same
//! flash, `bringup` again, and a square. Every line sent and received is printed.

use odocal::motion::controller::Status;
use odocal::motion::run::Direction;
use odocal::protocol::Command;

use crate::sim::board::{Board, accepted, measure_line};
use crate::sim::flash::SimParamFlash;
use crate::sim::robot::{WiringOption, sim_config};

/// Command-line arguments of the `bringup` subcommand.
#[derive(clap::Args, Debug, Clone)]
pub struct BringupArgs {
    /// How the simulated robot is wired.
    #[arg(long, value_enum, default_value_t = WiringOption::Standard)]
    pub wiring: WiringOption,
    /// Side of the square driven after the fix, metres.
    #[arg(long, default_value_t = 1.0)]
    pub side: f64,
    /// Control rate, Hz: 1000, 2000, 4000, 5000, 8000 or 10000 (the board's `control_hz`).
    #[arg(long = "rate-hz", visible_alias = "rate", default_value_t = odocal::motion::controller::DEFAULT_RATE_HZ, value_parser = crate::commands::parse_rate_hz)]
    pub rate: u32,
}

/// What a bring-up session found and did.
#[derive(Clone, Debug, PartialEq)]
pub struct BringupOutcome {
    /// The `set` commands the board proposed (and that were applied), in order.
    pub proposals: Vec<String>,
    /// The second check's verdict line after the fix (`event bringup done: …`).
    pub recheck: String,
    /// Whether the square after the fix ended without a fault.
    pub square_ok: bool,
    /// True end position error of that square against the start (a closed square ends near
    /// its start), m.
    pub square_end_m: f64,
    /// Every line exchanged, for printing.
    pub transcript: Vec<String>,
}

fn exchange(board: &mut Board, line: &str, transcript: &mut Vec<String>) -> String {
    transcript.push(format!("> {line}"));
    let reply = board.send(line);
    transcript.extend(reply.lines().map(|l| format!("< {l}")));
    reply
}

fn settle(board: &mut Board, seconds: u64, rate: u32, transcript: &mut Vec<String>) -> String {
    let mut out = String::new();
    board.run_until_rest(seconds * u64::from(rate), &mut out);
    transcript.extend(out.lines().map(|l| format!("< {l}")));
    out
}

/// Runs the bring-up session.
///
/// # Errors
/// A board that does not boot, or a reply that is not what the procedure expects.
pub fn bringup_session(args: &BringupArgs) -> Result<BringupOutcome, String> {
    let mut config = sim_config(1.0, 1.0, 0.0, 1, args.rate);
    config.wiring = args.wiring.wiring();
    let mut flash = SimParamFlash::erased();
    let mut t = Vec::new();
    let mut proposals = Vec::new();
    {
        let mut boot = String::new();
        let mut board = Board::boot(config, &mut flash, &mut boot)?;
        t.extend(boot.lines().map(|l| format!("< {l}")));
        for check in ["bringup push", "bringup"] {
            let reply = exchange(&mut board, check, &mut t);
            if !accepted(&reply) {
                return Err(format!("`{check}` refused: {reply}"));
            }
            let events = settle(&mut board, 10, args.rate, &mut t);
            for line in events.lines() {
                if let Some(set) = line.strip_prefix("event bringup propose: ")
                    && !proposals.iter().any(|p| p == set)
                {
                    proposals.push(set.to_string());
                }
            }
        }
        for set in &proposals {
            let reply = exchange(&mut board, set, &mut t);
            if !accepted(&reply) {
                return Err(format!("`{set}` refused: {reply}"));
            }
        }
        let reply = exchange(&mut board, "save", &mut t);
        if !accepted(&reply) {
            return Err(format!("save refused: {reply}"));
        }
    }
    t.push("(reboot on the same flash)".into());
    let mut boot = String::new();
    let mut board = Board::boot(config, &mut flash, &mut boot)?;
    t.extend(boot.lines().map(|l| format!("< {l}")));
    exchange(&mut board, "bringup", &mut t);
    let events = settle(&mut board, 10, args.rate, &mut t);
    let recheck = events
        .lines()
        .find(|l| l.starts_with("event bringup done"))
        .unwrap_or("no verdict")
        .to_string();
    let start = board.sim.true_pose();
    let run = Command::Run {
        direction: Direction::Cw,
        side_m: Some(args.side),
    };
    exchange(&mut board, &run.to_string(), &mut t);
    settle(&mut board, 120, args.rate, &mut t);
    let square_ok = !matches!(board.controller.status(), Status::Faulted(_));
    let square_end_m = board.sim.true_pose().distance_to(&start);
    if let Some(m) = measure_line(&board) {
        t.push(format!("(true end pose: {m})"));
    }
    Ok(BringupOutcome {
        proposals,
        recheck,
        square_ok,
        square_end_m,
        transcript: t,
    })
}

/// Runs the `bringup` subcommand.
///
/// # Errors
/// As [`bringup_session`].
pub fn run(args: &BringupArgs) -> Result<(), String> {
    let o = bringup_session(args)?;
    for line in &o.transcript {
        println!("{line}");
    }
    println!();
    if o.proposals.is_empty() {
        println!("proposed fix: none (wiring ok)");
    } else {
        println!("proposed fix: {}", o.proposals.join("; "));
    }
    println!("after the fix: {}", o.recheck);
    println!(
        "square of {} m after the fix: {}, true end {:.1} mm from the start",
        args.side,
        if o.square_ok { "no fault" } else { "FAULT" },
        o.square_end_m * 1e3
    );
    Ok(())
}
