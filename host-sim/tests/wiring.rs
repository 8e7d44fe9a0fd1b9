//! A motor or encoder wired the other way round: the robot must stop with a following-error
//! fault instead of running away, and the bring-up check must name the fix.

use host_sim::commands::bringup::{BringupArgs, bringup_session};
use host_sim::commands::drive::drive_script;
use host_sim::sim::robot::{Sim, WiringOption, default_controller, sim_config};
use odocal::kinematics::geometry::Geometry;
use odocal::motion::controller::{Fault, Wheel};

const RATE: u32 = 1000;

const REVERSED: [(WiringOption, Wheel, &str); 4] = [
    (
        WiringOption::RightMotorReversed,
        Wheel::Right,
        "set motor_right_sign -1",
    ),
    (
        WiringOption::LeftMotorReversed,
        Wheel::Left,
        "set motor_left_sign -1",
    ),
    (
        WiringOption::RightEncoderReversed,
        Wheel::Right,
        "set encoder_right_sign -1",
    ),
    (
        WiringOption::LeftEncoderReversed,
        Wheel::Left,
        "set encoder_left_sign -1",
    ),
];

/// Within 0.5 s of robot time the reversed wheel latches a following-error fault at full duty;
/// the robot has moved less than the 0.3 m/s command would have taken it in that time plus the
/// distance a wheel at full duty covers while the fault persists (0.1 s at 1 m/s).
#[test]
fn a_reversed_motor_or_encoder_ends_in_a_following_error_not_a_runaway() {
    for (wiring, wheel, _) in REVERSED {
        let mut config = sim_config(1.0, 1.0, 0.0, 1, RATE);
        config.wiring = wiring.wiring();
        let mut sim = Sim::new(config);
        let mut controller = default_controller(Geometry::PAPER_NOMINAL, RATE).unwrap();
        sim.step(&mut controller);
        let fault = drive_script(&mut sim, &mut controller, 0.3, 0.0, 5.0)
            .unwrap()
            .expect_err("a reversed wheel must fault");
        println!(
            "{wiring:?}: {} after {:.3} s, moved {:.3} m",
            fault.fault, fault.after_s, fault.moved_m
        );
        assert!(fault.after_s <= 0.5, "{wiring:?}: {} s", fault.after_s);
        match fault.fault {
            Fault::FollowingError {
                wheel: w,
                peak_duty_pct,
                error_mm,
            } => {
                assert_eq!(w, wheel, "{wiring:?}");
                assert_eq!(peak_duty_pct, 100, "{wiring:?}");
                assert!(error_mm.abs() >= 100, "{wiring:?}: {error_mm} mm");
            }
            other => panic!("{wiring:?}: expected a following error, got {other}"),
        }
        assert!(
            fault.moved_m < 0.25,
            "{wiring:?}: moved {} m",
            fault.moved_m
        );
        assert!(
            controller.motors_stopped().is_ok(),
            "{wiring:?}: motors still running"
        );
    }
}

/// The bring-up check (hand push, then motor pulses) proposes exactly the one `set` that fixes
/// the robot; after `set`, `save` and a reboot the check passes and a 1 m square closes (true
/// geometry = nominal, no slip: it ends within a millimetre of its start).
#[test]
fn bringup_proposes_the_fix_and_the_square_then_runs() {
    for (wiring, _, fix) in REVERSED {
        let o = bringup_session(&BringupArgs {
            wiring,
            side: 1.0,
            rate: RATE,
        })
        .unwrap();
        assert_eq!(
            o.proposals,
            vec![fix.to_string()],
            "{wiring:?}\n{}",
            o.transcript.join("\n")
        );
        assert_eq!(o.recheck, "event bringup done: wiring ok", "{wiring:?}");
        assert!(o.square_ok, "{wiring:?}");
        assert!(o.square_end_m < 1e-3, "{wiring:?}: {} m", o.square_end_m);
    }
    let ok = bringup_session(&BringupArgs {
        wiring: WiringOption::Standard,
        side: 1.0,
        rate: RATE,
    })
    .unwrap();
    assert!(ok.proposals.is_empty(), "{:?}", ok.proposals);
}
