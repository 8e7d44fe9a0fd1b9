//! Step 4 of `ros2_bridge`: the simulated board is reset (`reboot`: a new board over the same
//! flash, its stream off and its pose at its origin). The bridge sees the boot event, turns the
//! stream on again, and `odom` goes on from where it was (REP 105); a `cmd_vel` then drives the
//! robot on from there.

use std::time::Instant;

use super::{WAIT, World};

pub fn a_board_reset_keeps_odom_continuous_and_driving_resumes(w: &mut World) {
    let World { sim, bridge, peer } = w;
    let before = *peer.samples.last().expect("samples before the reset");
    sim.send("reboot");
    let boot = bridge.until(|l| l.starts_with("event boot"));
    println!("reset: the bridge printed `{boot}`");
    // Odometry flows again: 50 samples after the boot event, the robot at rest where `odom`
    // was (the board's new pose, its origin, composed onto it).
    let resumed = peer.samples.len();
    let deadline = Instant::now() + WAIT;
    while peer.samples.len() < resumed + 50 {
        assert!(Instant::now() < deadline, "no odometry after the reset");
        peer.odom();
    }
    let after = *peer.samples.last().unwrap();
    println!(
        "reset: odom before x={:.6} y={:.6} yaw={:.6}, after x={:.6} y={:.6} yaw={:.6}",
        before.x, before.y, before.yaw, after.x, after.y, after.yaw
    );
    // Both are the stream's rounding of the same pose (6 decimals of a metre, 4 of a degree).
    assert!((after.x - before.x).abs() <= 2e-6, "{before:?} {after:?}");
    assert!((after.y - before.y).abs() <= 2e-6, "{before:?} {after:?}");
    assert!(
        (after.yaw - before.yaw).abs() <= 2e-4_f64.to_radians(),
        "{before:?} {after:?}"
    );
    // A cmd_vel drives again, from there: 0.2 m/s for 1 s moves the robot about 0.2 m along
    // its heading in `odom` (at least 0.1 m: the ramp and the deadman's end included).
    peer.proc.send("cmd_vel 0.2 0 1 20");
    loop {
        if peer.next()["k"] == "cmd_vel_done" {
            break;
        }
    }
    let deadline = Instant::now() + WAIT;
    let moved = loop {
        let o = peer.odom();
        let along = (o.x - before.x) * before.yaw.cos() + (o.y - before.y) * before.yaw.sin();
        if along > 0.1 {
            break along;
        }
        assert!(
            Instant::now() < deadline,
            "the robot did not drive after the reset: {o:?}"
        );
    };
    println!("reset: cmd_vel drove {moved:.3} m along the heading after the reset");
}
