//! The bridge under what a robot lives through: the board reset mid-drive, its port unplugged
//! and plugged back, a planner that publishes NaN. Each runs in a world of its own
//! (`ros2_bridge_survives_board_reset`, `ros2_bridge_survives_unplug`, `ros2_bridge_refuses_nan`).

use std::path::Path;
use std::time::{Duration, Instant};

use super::{Odom, Peer, WAIT, World, point, start_sim};

/// `/diagnostics` levels (diagnostic_msgs/msg/DiagnosticStatus).
const OK: u64 = 0;
const ERROR: u64 = 2;

/// Reads the peer's messages until `until` (this machine's clock).
fn read_until(peer: &mut Peer, until: Instant) {
    while Instant::now() < until {
        peer.next();
    }
}

/// The `cmd_vel` commands a `/diagnostics` status counts as refused for want of odometry.
fn refused_no_odometry(d: &serde_json::Value) -> u64 {
    d["values"]["cmd_vel_refused_no_odometry"]
        .as_str()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0)
}

/// Reads until a `/diagnostics` status received since the `from`-th satisfies `f`; returns
/// it.
fn diag_until(
    peer: &mut Peer,
    from: usize,
    what: &str,
    f: impl Fn(&serde_json::Value) -> bool,
) -> serde_json::Value {
    let deadline = Instant::now() + WAIT;
    loop {
        if let Some(d) = peer.diags[from..].iter().find(|d| f(d)) {
            return d.clone();
        }
        assert!(
            Instant::now() < deadline,
            "no /diagnostics with {what}: {:?}",
            peer.diags.last()
        );
        peer.next();
    }
}

/// The robot drives at 0.05 m/s on `cmd_vel` (20 Hz) when the board loses power and comes back
/// (a brown-out reset). While its stream is down no `cmd_vel` reaches the board: the test waits
/// until `/diagnostics` (ERROR) counts a refused one before the power returns, so the outage
/// always holds commands whatever the machine's load. Odometry comes again within 1 s of the
/// reset, `odom` goes on from where it was within 1 mm (the robot moves 0.5 mm in a stream
/// period), the board drives again only from its new odometry, and `/diagnostics` says OK.
pub fn a_reset_mid_drive_keeps_odom_and_forwards_nothing_blind(w: &mut World) {
    let World { sim, bridge, peer } = w;
    peer.proc.send("cmd_vel 0.05 0 10 20");
    // Moving.
    let deadline = Instant::now() + WAIT;
    while peer.odom().v < 0.04 {
        assert!(Instant::now() < deadline, "the robot never drove");
    }
    let diags = peer.diags.len();
    sim.send("power off");
    let refusing = diag_until(
        peer,
        diags,
        "a cmd_vel refused while the stream is down",
        |d| refused_no_odometry(d) > 0,
    );
    assert_eq!(refusing["level"], ERROR, "{refusing}");
    println!("reset mid-drive: /diagnostics {}", refusing["message"]);
    let before: Odom = *peer.samples.last().unwrap();
    // The peer stamps its receive times on this machine's wall clock.
    let wall_s = || {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_secs_f64()
    };
    let powered_at = wall_s();
    sim.send("power on");
    bridge.until(|l| l.starts_with("event boot"));
    // The first sample received after the power came back, within 1 s of it.
    let deadline = Instant::now() + WAIT;
    let resumed = loop {
        let o = peer.odom();
        if o.rx > powered_at {
            break o;
        }
        assert!(Instant::now() < deadline, "no odometry after the reset");
    };
    let gap = resumed.rx - powered_at;
    println!(
        "reset mid-drive: odometry again {gap:.3} s after the power came back; before x={:.6} \
         y={:.6}, after x={:.6} y={:.6}",
        before.x, before.y, resumed.x, resumed.y
    );
    assert!(gap < 1.0, "odometry came again {gap} s after the reset");
    let jump = (resumed.x - before.x).hypot(resumed.y - before.y);
    assert!(jump < 1e-3, "odom jumped {jump} m over the reset");
    // OK once it flows, with the refused commands counted and the reset and the carried pose
    // named.
    let after_error = peer.diags.len();
    let ok = diag_until(peer, after_error, "OK again", |d| d["level"] == OK);
    let values = &ok["values"];
    println!("reset mid-drive: /diagnostics OK again: {values}");
    assert_eq!(values["board_resets"], "1", "{values}");
    assert_ne!(values["odom_carried_over"], "none", "{values}");
    assert!(refused_no_odometry(&ok) > 0, "{values}");
    // The board drove again only on its new odometry: the bridge's first forwarded command
    // after the reset names a stream line of the new board's time (seconds since its boot).
    let driving = bridge.until(|l| l.starts_with("ros2: cmd_vel: driving from board t="));
    let t: f64 = driving["ros2: cmd_vel: driving from board t=".len()..]
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(
        t < 5.0,
        "a command was forwarded on the old board's odometry: {driving}"
    );
}

/// The board's pty closes (the simulated board ends, as a board unplugged) and a new one comes
/// on the same path (the symlink, as `/dev/serial/by-id/` follows the adapter): the bridge
/// reconnects and odometry flows again; while the port was gone it published no odometry and
/// `/diagnostics` said ERROR, `board disconnected: PATH`.
pub fn an_unplugged_board_is_reopened_on_its_path(w: &mut World, link: &Path) {
    let World { sim, peer, .. } = w;
    read_until(peer, Instant::now() + Duration::from_millis(300));
    let before = *peer.samples.last().unwrap();
    // Unplugged: the board's process ends and its pty goes away.
    let diags = peer.diags.len();
    let _ = sim.child.kill();
    let _ = sim.child.wait();
    let unplugged = Instant::now();
    let gone = diag_until(peer, diags, "ERROR board disconnected", |d| {
        d["level"] == ERROR
            && d["message"]
                .as_str()
                .is_some_and(|m| m.starts_with("board disconnected: "))
    });
    println!("unplug: /diagnostics {}", gone["message"]);
    let n = peer.samples.len();
    read_until(peer, Instant::now() + Duration::from_secs(1));
    assert_eq!(
        peer.samples.len(),
        n,
        "odometry published while the board was gone"
    );
    // Plugged back: a new board on a new pty, the same path.
    let (new_sim, pty) = start_sim();
    *sim = new_sim;
    point(link, &pty);
    let deadline = Instant::now() + WAIT;
    let back = loop {
        let o = peer.odom();
        if o.rx > before.rx + 1.0 {
            break o;
        }
        assert!(
            Instant::now() < deadline,
            "no odometry after the port came back"
        );
    };
    println!(
        "unplug: odometry again {:.2} s after the port went away, at x={:.6} y={:.6} (before \
         x={:.6} y={:.6})",
        unplugged.elapsed().as_secs_f64(),
        back.x,
        back.y,
        before.x,
        before.y
    );
    assert!(
        (back.x - before.x).hypot(back.y - before.y) < 1e-3,
        "odom jumped"
    );
    let back_at = peer.diags.len();
    diag_until(peer, back_at, "OK again", |d| d["level"] == OK);
}

/// 0.2 m/s for 1 s, then NaN: the bridge refuses the NaN and stops the robot at once, well
/// before the board's deadman (0.5 s after the last good command) would; `/diagnostics` counts
/// the refused commands.
pub fn a_nan_cmd_vel_stops_the_robot_before_the_deadman(w: &mut World) {
    let World { peer, .. } = w;
    peer.proc.send("cmd_vel 0.2 0 1 20");
    let good = loop {
        let m = peer.next();
        if m["k"] == "cmd_vel_done" {
            break m;
        }
    };
    let last_good = good["last"].as_f64().unwrap();
    peer.proc.send("cmd_vel nan 0 0.6 20");
    // The first sample at rest after the last good command, by its stamp.
    let deadline = Instant::now() + WAIT;
    let stopped = loop {
        let o = peer.odom();
        if o.t > last_good && o.v == 0.0 && o.w == 0.0 {
            break o;
        }
        assert!(Instant::now() < deadline, "the robot never stopped");
    };
    let after = stopped.t - last_good;
    println!("nan: the robot at rest {after:.3} s after the last good command");
    assert!(
        after < 0.4,
        "at rest only {after} s after the last good command (the deadman's 0.5 s)"
    );
    let d = diag_until(peer, 0, "refused NaN commands", |d| {
        d["values"]["cmd_vel_refused_not_finite"]
            .as_str()
            .is_some_and(|n| n != "0")
    });
    println!(
        "nan: /diagnostics {}",
        d["values"]["cmd_vel_refused_not_finite"]
    );
}
