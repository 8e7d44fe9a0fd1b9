//! Motor identification on simulated robots whose motors differ from the defaults, through the
//! serial protocol of the simulated board, and what its tuning does to the wheel sync.

use clap::Parser;
use host_sim::commands::drive::{DriveArgs, execute};
use host_sim::experiments::motors::{CASES, identify, squares, worst_relative_error};
use odocal::motion::identify::IdentifyMode;
use odocal::motion::speed::SpeedTuning;

/// Bound on every identified parameter's relative error (see the test below).
const IDENTIFY_TOLERANCE: f64 = 0.01;

/// Gain ×0.5 and ×2, time constant ×0.5 and ×3, each with a dead-band (the cases' table in
/// `commands/motors.rs`): every identified parameter within 1 % of the simulated one.
///
/// The simulated motor is exactly the first-order model with a dead-band that the fit assumes,
/// integrated exactly, so the only noise is the encoder's quantisation (2.4 µm per count,
/// ±1 count per 10 ms block against hundreds of counts per block). Measured worst relative
/// error per wheel: 0.18 / 0.33 %, 0.29 / 0.45 %, 0.08 / 0.03 %, 0.06 / 0.01 % (right / left,
/// cases in table order; `cargo sim motors`). Bound 1 % (2.2× the worst).
#[test]
fn identified_parameters_are_within_1_percent_of_the_simulated_motors() {
    for case in &CASES {
        let tuning = identify(case).expect("identification succeeds");
        for (right, est) in [(true, tuning.right), (false, tuning.left)] {
            let truth = case.truth(right);
            let worst = worst_relative_error(&est, &truth);
            assert!(
                worst < IDENTIFY_TOLERANCE,
                "{} {}: true {truth:?}, identified {est:?}: {:.2} %",
                case.name,
                if right { "right" } else { "left" },
                worst * 100.0
            );
        }
    }
}

/// The squares' peak wheel sync error on the legs with the default tuning and with the
/// identified one (no slip: the control alone). Measured: 299 → 2, 297 → 1, 248 → 28 and
/// 200 → 4 ticks (cases in table order; `cargo sim motors`), at least 8.8 times smaller. Bound:
/// 4 times smaller on every robot.
#[test]
fn the_identified_tuning_reduces_the_squares_sync_error() {
    for case in &CASES {
        let tuned = identify(case).expect("identification succeeds");
        let before = squares(case, SpeedTuning::DEFAULT, 2.0, 0.0).expect("squares");
        let after = squares(case, tuned, 2.0, 0.0).expect("squares");
        assert!(
            after.peak_sync_ticks * 4.0 < before.peak_sync_ticks,
            "{}: {} -> {} ticks",
            case.name,
            before.peak_sync_ticks,
            after.peak_sync_ticks
        );
    }
}

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    drive: DriveArgs,
}

fn peak(args: &[&str]) -> f64 {
    let cli = Cli::parse_from(std::iter::once("drive").chain(args.iter().copied()));
    let outcome = execute(&cli.drive).expect("drive");
    outcome.result.expect("no fault").peak_sync_ticks
}

/// `cargo sim drive line --motor-gain 0.5,0.6 --motor-tau 0.12,0.15` with and without
/// `--identify`: the identified tuning makes the peak sync error at least 3× smaller (measured:
/// 48 → 9 ticks, 5.3×).
#[test]
fn identify_before_the_line_makes_the_sync_error_three_times_smaller() {
    let motors = [
        "line",
        "--motor-gain",
        "0.5,0.6",
        "--motor-tau",
        "0.12,0.15",
    ];
    let default = peak(&motors);
    let mut with = motors.to_vec();
    with.push("--identify");
    let tuned = peak(&with);
    assert!(tuned * 3.0 <= default, "{default} -> {tuned} ticks");
}

/// Through the simulated board: a reversed motor is refused (error event, fault latched, tuning
/// unchanged); a healthy robot's identified tuning survives `save` and a reboot and is what the
/// rebooted controller uses.
#[test]
fn refusal_on_a_miswired_robot_and_the_tuning_survives_a_reboot() {
    use host_sim::sim::board::Board;
    use host_sim::sim::flash::SimParamFlash;
    use host_sim::sim::robot::WiringOption;

    let case = CASES[1];
    let mut cfg = case.sim_config(0.0, 1);
    cfg.wiring = WiringOption::LeftMotorReversed.wiring();
    let mut flash = SimParamFlash::erased();
    let mut out = String::new();
    let mut board = Board::boot(cfg, &mut flash, &mut out).expect("boot");
    let text = board
        .identify(IdentifyMode::Floor)
        .expect_err("a reversed motor is refused");
    assert!(
        text.contains("event identify err 23: left motor: counts run against the duty"),
        "{text}"
    );
    assert_eq!(board.session.settings().tuning, SpeedTuning::DEFAULT);
    assert!(board.send("status").contains("fault=identify"));
    drop(board);

    let cfg = case.sim_config(0.0, 1);
    let mut flash = SimParamFlash::erased();
    let tuned = {
        let mut board = Board::boot(cfg, &mut flash, &mut out).expect("boot");
        board
            .identify(IdentifyMode::Floor)
            .expect("identification succeeds");
        assert_eq!(board.send("save"), "ok saved\r\n");
        board.session.settings().tuning
    };
    let board = Board::boot(cfg, &mut flash, &mut out).expect("reboot");
    assert_eq!(board.session.settings().tuning, tuned);
    assert_eq!(board.controller.config().speed, tuned);
    assert_ne!(tuned, SpeedTuning::DEFAULT);
}

/// Motor identification at 10 kHz (`set control_hz 10000` on the simulated board): its 10 ms
/// blocks are 100 periods instead of 10 and its steps the same seconds, so it identifies the
/// same motors as at 1 kHz, within the same 1 % bound (the reasoning above: only the encoder's
/// quantisation is noise, and a block holds the same counts at either rate; measured: the same
/// worst errors as at 1 kHz, 0.18 / 0.33 % and 0.29 / 0.45 %).
#[test]
fn identification_at_10_khz_finds_the_same_motors() {
    use host_sim::sim::board::Board;
    use host_sim::sim::flash::SimParamFlash;

    for case in &CASES[..2] {
        let mut cfg = case.sim_config(0.0, 1);
        cfg.rate_hz = 10_000;
        let mut flash = SimParamFlash::erased();
        let mut out = String::new();
        let mut board = Board::boot(cfg, &mut flash, &mut out).expect("boot");
        assert_eq!(board.controller.config().rate_hz, 10_000);
        board
            .identify(IdentifyMode::Floor)
            .expect("identification succeeds");
        let tuning = board.session.settings().tuning;
        for (right, est) in [(true, tuning.right), (false, tuning.left)] {
            let truth = case.truth(right);
            let worst = worst_relative_error(&est, &truth);
            println!("{} at 10 kHz: worst {:.3} %", case.name, worst * 100.0);
            assert!(
                worst < IDENTIFY_TOLERANCE,
                "{} {} at 10 kHz: true {truth:?}, identified {est:?}: {:.2} %",
                case.name,
                if right { "right" } else { "left" },
                worst * 100.0
            );
        }
    }
}

/// `identify floor` with weak and strong motors (gain 0.5 and 2 m/s per duty) at `max_speed`
/// 0.3, 1 and 2 m/s: it finishes (or stops with a clear `err`), the robot never goes farther
/// than 1 m from its start (the travel bound, stopping distance included: measured on the true
/// pose at every period) and no wheel goes faster than `max_speed` + 10 % (the routine's own
/// check).
#[test]
fn identify_floor_stays_within_its_travel_at_every_max_speed() {
    use host_sim::sim::board::Board;
    use host_sim::sim::flash::SimParamFlash;
    use host_sim::sim::robot::{MotorArgs, sim_config};
    for gain in [0.5, 2.0] {
        for max_speed in [0.3, 1.0, 2.0] {
            let mut config = sim_config(1.0, 1.0, 0.0, 1, 1000);
            MotorArgs {
                motor_gain: vec![gain],
                ..MotorArgs::default()
            }
            .apply(&mut config)
            .expect("motor options");
            let mut flash = SimParamFlash::erased();
            let mut out = String::new();
            let mut b = Board::boot(config, &mut flash, &mut out).expect("boot");
            assert!(
                b.send(&format!("set max_speed {max_speed}"))
                    .starts_with("ok ")
            );
            let reply = b.send("identify floor");
            assert!(reply.starts_with("ok identify floor"), "{reply}");
            let start = b.sim.true_pose();
            let (mut far, mut fast) = (0.0f64, 0.0f64);
            let mut log = String::new();
            for _ in 0..60_000 {
                b.step(&mut log);
                let p = b.sim.true_pose();
                far = far.max((p.x_m - start.x_m).hypot(p.y_m - start.y_m));
                let (vr, vl) = b.sim.wheel_speeds_mps();
                fast = fast.max(vr.abs()).max(vl.abs());
                if log.contains("event identify done") || log.contains("event identify err") {
                    break;
                }
            }
            let case = format!("gain {gain}, max_speed {max_speed}: {far:.3} m, {fast:.3} m/s");
            assert!(log.contains("event identify done"), "{case}: {log}");
            assert!(far <= 1.0, "{case}");
            assert!(fast <= 1.1 * max_speed, "{case}");
            eprintln!("{case}");
        }
    }
}
