//! Every parameter end to end on the simulated board: `set` → `params` → `save` → reboot →
//! `params`, and the controller runs with what `params` shows; `reset-params` brings every
//! value back to its default, in `params`, in the running controller (wiring and control rate
//! included) and, after `save`, in flash.

use host_sim::sim::board::Board;
use host_sim::sim::flash::SimParamFlash;
use host_sim::sim::robot::sim_config;
use odocal::protocol::ParamName;
use odocal::session::{MotorsStopped, Settings};

/// Boots at the flash's stored control rate, as a board does after a reset.
fn boot(flash: &mut SimParamFlash) -> Board<'_> {
    let mut out = String::new();
    Board::boot_at_stored_rate(sim_config(1.0, 1.0, 0.0, 1, 1000), flash, &mut out).expect("boot")
}

/// A valid value other than the default for every parameter: a sign reversed, a whole number
/// one up, a rate one step up, anything else 4 % up, or 4 % into its range from a default of 0
/// (inside every range and every whole-set rule from the defaults: diameter ratio 1.04, the
/// tuning's checks).
fn other_value(name: ParamName) -> f64 {
    let default = Settings::default().value(name);
    if name.is_sign() {
        -default
    } else if name == ParamName::ControlHz {
        2_000.0
    } else if name.is_integer() {
        default + 1.0
    } else if default == 0.0 {
        let (lo, hi) = name.range();
        lo + 0.04 * (hi - lo)
    } else {
        default * 1.04
    }
}

/// The `params` line of `name` (its value and unit, as printed).
fn params_line(board: &mut Board, name: ParamName) -> String {
    let reply = board.send("params");
    assert!(reply.ends_with("ok\r\n"), "{reply}");
    let prefix = format!("  {} ", name.as_str());
    reply
        .lines()
        .find(|l| l.starts_with(&prefix))
        .unwrap_or_else(|| panic!("no {} in params:\n{reply}", name.as_str()))
        .to_string()
}

/// `save`, once the controller counts the motors as stopped (a still period after boot or a
/// retiming): the reply.
fn save(board: &mut Board) -> String {
    let mut out = String::new();
    for _ in 0..20_000 {
        if board.controller.motors_stopped().is_ok() {
            break;
        }
        board.step(&mut out);
    }
    board.send("save")
}

/// What the controller runs with equals what the session's settings ask for.
fn assert_controller_follows_settings(board: &Board, context: &str) {
    let wanted = board.session.settings().controller_config();
    let running = *board.controller.config();
    assert_eq!(running.geometry, wanted.geometry, "{context}: geometry");
    assert_eq!(running.limits, wanted.limits, "{context}: limits");
    assert_eq!(running.wiring, wanted.wiring, "{context}: wiring");
    assert_eq!(running.speed, wanted.speed, "{context}: tuning");
    assert_eq!(running.rate_hz, wanted.rate_hz, "{context}: control rate");
}

#[test]
fn every_parameter_survives_set_save_and_a_reboot() {
    for name in ParamName::ALL {
        let mut flash = SimParamFlash::erased();
        let value = other_value(name);
        let line = {
            let mut board = boot(&mut flash);
            let before = params_line(&mut board, name);
            let reply = board.send(&format!("set {} {value}", name.as_str()));
            assert!(reply.starts_with("ok "), "set {}: {reply}", name.as_str());
            assert!(!reply.contains("(unchanged)"), "{reply}");
            let line = params_line(&mut board, name);
            assert_ne!(line, before, "{}", name.as_str());
            assert_controller_follows_settings(&board, name.as_str());
            let reply = save(&mut board);
            assert!(
                reply.starts_with("ok"),
                "save after {}: {reply}",
                name.as_str()
            );
            line
        };
        let mut board = boot(&mut flash);
        assert_eq!(params_line(&mut board, name), line, "after reboot");
        assert_controller_follows_settings(&board, &format!("{} after reboot", name.as_str()));
    }
}

#[test]
fn reset_params_brings_every_value_back_in_params_the_controller_and_flash() {
    let mut flash = SimParamFlash::erased();
    let defaults: Vec<String> = {
        let mut board = boot(&mut flash);
        ParamName::ALL
            .iter()
            .map(|&n| params_line(&mut board, n))
            .collect()
    };
    {
        let mut board = boot(&mut flash);
        for name in ParamName::ALL {
            let reply = board.send(&format!("set {} {}", name.as_str(), other_value(name)));
            assert!(reply.starts_with("ok "), "{reply}");
        }
        assert_eq!(save(&mut board), "ok saved\r\n");
        for (name, default) in ParamName::ALL.iter().zip(&defaults) {
            assert_ne!(&params_line(&mut board, *name), default);
        }
        let reply = board.send("reset-params");
        assert!(reply.starts_with("ok parameters reset"), "{reply}");
        for (name, default) in ParamName::ALL.iter().zip(&defaults) {
            assert_eq!(&params_line(&mut board, *name), default);
        }
        assert_eq!(board.session.settings(), &Settings::default());
        assert_controller_follows_settings(&board, "after reset-params");
        assert_eq!(save(&mut board), "ok saved\r\n");
    }
    let mut board = boot(&mut flash);
    for (name, default) in ParamName::ALL.iter().zip(&defaults) {
        assert_eq!(&params_line(&mut board, *name), default, "after reboot");
    }
    assert_controller_follows_settings(&board, "after reset-params, save and reboot");
}

/// A stored record goes through the rules `set` applies: after a reboot the controller's
/// encoder-glitch limit is derived from the stored speed limit (not the default one), and a
/// stored speed the encoders cannot count is refused at boot, named with its value in the boot
/// line, and replaced by its default while every other stored value is kept.
#[test]
fn stored_limits_are_rederived_at_boot() {
    let mut flash = SimParamFlash::erased();
    // 2,048-count encoders on 100 mm wheels, pivoting at 8 rad/s on a 1 m wheelbase: 4 m/s at
    // the wheels, 4 / (π·0.1 m) · 2,048 counts / 1 kHz, +50 % = 40 counts per period (the
    // default limits' 2 m/s floor gives 20).
    let after_set = {
        let mut board = boot(&mut flash);
        for cmd in [
            "set d_right 0.1",
            "set d_left 0.1",
            "set counts_per_rev 2048",
            "set wheelbase 1",
            "set max_turn_rate 8",
        ] {
            let reply = board.send(cmd);
            assert!(reply.starts_with("ok "), "{cmd}: {reply}");
        }
        save(&mut board);
        let c = board.controller.config();
        (c.right_encoder.max_step, c.left_encoder.max_step)
    };
    assert_eq!(after_set, (40, 40));
    let board = boot(&mut flash);
    let c = board.controller.config();
    assert_eq!(
        (c.right_encoder.max_step, c.left_encoder.max_step),
        after_set
    );
    drop(board);

    // 1.75 m/s (within `set`'s range) on 100 mm wheels with 200,000 counts per revolution: 1.1 M
    // counts/s, beyond the 1 M counts/s the encoder inputs follow (1.57 m/s). `set` refuses it; a
    // stored record that holds it (written by other firmware, or before the rule) is refused at
    // boot.
    let mut stored = Settings::default();
    stored.nominal.diameter_right_m = 0.1;
    stored.nominal.diameter_left_m = 0.1;
    stored.active = stored.nominal;
    stored.motion.max_speed_mps = 1.75;
    stored.motion.max_accel_mps2 = 0.5;
    flash
        .store()
        .save_blocking(&stored, MotorsStopped::without_controller())
        .expect("store the record");
    let mut out = String::new();
    let mut board =
        Board::boot_at_stored_rate(sim_config(1.0, 1.0, 0.0, 1, 1000), &mut flash, &mut out)
            .expect("boot");
    assert!(
        out.contains(
            "max_speed 1.75 refused (the wheels would turn faster than the encoders can count"
        ) && out.contains("), default used"),
        "{out}"
    );
    let c = board.controller.config();
    assert_eq!(
        c.limits.max_speed_mps,
        Settings::default().motion.max_speed_mps
    );
    assert_eq!(
        c.limits.max_accel_mps2, 0.5,
        "the other stored values are kept"
    );
    assert_eq!(c.geometry.diameter_right_m, 0.1);
    assert!(params_line(&mut board, ParamName::MaxSpeed).contains("0.300"));
    assert!(params_line(&mut board, ParamName::MaxAccel).contains("0.500"));
    let reply = board.send("set max_speed 2");
    assert!(
        reply.contains("faster than the encoders can count"),
        "{reply}"
    );
}

/// `save` writes the parameter region only: the run region (its index and every run item)
/// keeps every byte, however many saves there are (no wear for nothing).
#[test]
fn parameter_save_leaves_the_run_region_alone() {
    use host_sim::sim::flash::SIM_RUNS;
    let run_region = |b: &mut Board| -> Vec<Option<u8>> {
        let flash = b.store.flash();
        SIM_RUNS.map(|i| flash.byte(i as usize)).collect()
    };
    let mut flash = SimParamFlash::erased();
    let mut b = boot(&mut flash);
    let mut out = b.send("line 0.2");
    assert!(out.starts_with("ok run "), "{out}");
    assert!(b.run_until_rest(60_000, &mut out) < 60_000, "{out}");
    assert!(out.contains("event run 1 finished"), "{out}");
    let before = run_region(&mut b);
    assert!(before.iter().any(|&x| x != Some(0xFF)), "the run is stored");
    for side in ["1.5", "1.6"] {
        assert!(
            b.send(&format!("set square_side {side}"))
                .starts_with("ok ")
        );
        assert!(save(&mut b).starts_with("ok "));
        let mut out = String::new();
        b.run_until_rest(200, &mut out);
    }
    assert!(
        run_region(&mut b) == before,
        "a parameter save wrote the run region"
    );
}
