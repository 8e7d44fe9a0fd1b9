//! `online_calibration`: the bridge keeps the calibration current from the robot's localization.
//!
//! The simulated board (true `E_d` 0.995, `E_b` 1.010, the nominal geometry applied: an erased
//! flash) runs fifteen times faster than real time (`--speed 15`), and the whole chain shares its
//! clock: the bridge stamps with the board's time (`--use-sim-time`), and the robot's side
//! (`online_peer.py`, Cyclone DDS) stamps the reference with the simulator's true pose's board
//! time (`--truth-hz 20`). The robot drives a mixed path by `cmd_vel` (lines, arcs and spins in
//! both directions) while the reference is published at 10 Hz with 20 mm and 1° of noise, 50 ms
//! late (the sample of time t is sent when the truth of t + 50 ms arrives), relocalised once by
//! 0.5 m. Checked on `/diagnostics` (`odocal_bridge: online calibration`):
//! 1. after 10 minutes of driving: both factors within 3σ of the truth, both 1σ below 1e-3, the
//!    jump's window rejected;
//! 2. the tyre wears at 600 s (`--wear 600:0.990:1.010`): one horizon (100 m) of driving later
//!    the estimate of `E_d` is within 3σ of 0.990;
//! 3. the robot stops: `--apply auto` applies and saves the estimate, and the board's `params`
//!    show the calibration's method `online`;
//! 4. `recalibrate --reference-log` finds the bridge's last estimate bit for bit.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

use super::support::host_sim;
use super::{Proc, cyclone_available, isolate_network, ready_or_skip, start_sim_with};

/// The mixed path: (v m/s, ω rad/s, seconds of board time), repeated.
const PATH: [(f64, f64, f64); 7] = [
    (0.3, 0.0, 5.0),
    (0.0, 1.0, 10.0),
    (0.25, 0.5, 6.0),
    (0.0, -1.0, 10.0),
    (0.3, 0.0, 5.0),
    (0.25, -0.5, 6.0),
    (0.2, 0.3, 6.0),
];
/// Reference noise: 1σ of x and y (m) and of the heading (rad).
const SD_XY: f64 = 0.02;
const SD_YAW: f64 = 1.0 * std::f64::consts::PI / 180.0;
/// The relocalisation: at this board time the reference jumps by 0.5 m in x.
const JUMP_S: f64 = 300.0;
/// The tyre wears at this board time.
const WEAR_S: f64 = 600.0;
/// The forgetting horizon, metres (the path rolls about 12 m a minute).
const HORIZON_M: f64 = 100.0;
/// The end of the driving after the wear: the horizon's driving and a margin.
const END_S: f64 = WEAR_S + 540.0;
/// How much faster than real time the simulated board runs.
const SPEED: &str = "15";

/// A small deterministic generator (xorshift64*) with normal draws (Box–Muller).
struct Rng(u64);

impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// The command of the path at board time `t`.
fn command_at(t: f64) -> (f64, f64) {
    let cycle: f64 = PATH.iter().map(|p| p.2).sum();
    let mut at = t % cycle;
    for &(v, w, d) in &PATH {
        if at < d {
            return (v, w);
        }
        at -= d;
    }
    (0.0, 0.0)
}

/// The latest online status the peer printed since the last call.
fn latest_online(peer: &mut Proc) -> Option<Value> {
    let mut last = None;
    while let Ok(l) = peer.lines.try_recv() {
        if let Ok(v) = serde_json::from_str::<Value>(&l)
            && v["k"] == "diag"
            && v["name"] == "odocal_bridge: online calibration"
        {
            last = Some(v);
        }
    }
    last
}

fn value(status: &Value, key: &str) -> f64 {
    status["values"][key]
        .as_str()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no number {key} in {status}"))
}

/// Drives until board time `until`, publishing the reference; returns the last online status
/// seen after the last truth line.
fn drive(sim: &mut Proc, peer: &mut Proc, rng: &mut Rng, until: f64, state: &mut Drive) {
    loop {
        let l = sim.next();
        let Some(rest) = l.strip_prefix("truth ") else {
            continue;
        };
        let v: Vec<f64> = rest
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect();
        let (t, x, y, yaw) = (v[0], v[1], v[2], v[3]);
        let cmd = command_at(t);
        if state.command != Some(cmd) {
            state.command = Some(cmd);
            peer.send(&format!("cmd {} {}", cmd.0, cmd.1));
        }
        // 50 ms late: the previous line's sample (truth at 20 Hz), every other one (10 Hz).
        if let Some((tp, xp, yp, yawp)) = state.previous.take()
            && state.count.is_multiple_of(2)
        {
            let shift = if tp >= JUMP_S { 0.5 } else { 0.0 };
            peer.send(&format!(
                "pose {tp:.6} {:.6} {:.6} {:.6} {SD_XY} {SD_YAW}",
                xp + shift + SD_XY * rng.normal(),
                yp + SD_XY * rng.normal(),
                yawp + SD_YAW * rng.normal()
            ));
        }
        state.count += 1;
        state.previous = Some((t, x, y, yaw));
        if let Some(s) = latest_online(peer) {
            state.status = Some(s);
        }
        if t >= until {
            return;
        }
    }
}

/// What the drive keeps between its legs.
#[derive(Default)]
struct Drive {
    command: Option<(f64, f64)>,
    previous: Option<(f64, f64, f64, f64)>,
    count: u64,
    status: Option<Value>,
}

/// Waits (driving on at rest) for the next online status and returns it.
fn next_status(sim: &mut Proc, peer: &mut Proc, rng: &mut Rng, state: &mut Drive) -> Value {
    state.status = None;
    loop {
        let t = state.previous.map_or(0.0, |p| p.0);
        drive(sim, peer, rng, t + 1.0, state);
        if let Some(s) = state.status.take() {
            return s;
        }
    }
}

#[test]
fn online_calibration() {
    if !ready_or_skip("online_calibration", cyclone_available()) {
        return;
    }
    let peer_script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/online_peer.py");
    host_sim();
    if !ready_or_skip("online_calibration", isolate_network()) {
        return;
    }
    let dir = std::env::temp_dir().join(format!("odocal-online-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("reference.jsonl");

    let wear = format!("{WEAR_S}:0.990:1.010");
    let (mut sim, pty) = start_sim_with(&[
        "--speed",
        SPEED,
        "--truth-hz",
        "20",
        "--ed",
        "0.995",
        "--eb",
        "1.010",
        "--wear",
        &wear,
    ]);
    let mut bridge = Proc::start(
        "odocal-console ros2",
        Command::new(env!("CARGO_BIN_EXE_odocal-console"))
            .args(["ros2", "--port", &pty, "--rate-hz", "50", "--use-sim-time"])
            .args(["--reference", "reference", "--apply", "auto"])
            .args(["--horizon", &HORIZON_M.to_string()])
            .arg("--reference-log")
            .arg(&log)
            .env_remove("ROS_AUTOMATIC_DISCOVERY_RANGE")
            .env_remove("ROS_LOCALHOST_ONLY")
            .env("ROS_DOMAIN_ID", "0"),
    );
    bridge.until(|l| l.starts_with("ros2: online calibration from reference"));
    let mut peer = Proc::start(
        "online_peer.py",
        Command::new("python3")
            .arg(&peer_script)
            .env("ROS_DOMAIN_ID", "0"),
    );
    assert!(peer.next().contains("ready"));

    let started = std::time::Instant::now();
    let mut rng = Rng(0x2545_F491_4F6C_DD1D);
    let mut state = Drive::default();
    // 1. Ten minutes of driving.
    drive(&mut sim, &mut peer, &mut rng, WEAR_S, &mut state);
    let s = next_status(&mut sim, &mut peer, &mut rng, &mut state);
    let (ed, eb) = (value(&s, "online_E_d"), value(&s, "online_E_b"));
    let (sd, sb) = (value(&s, "online_sd_E_d"), value(&s, "online_sd_E_b"));
    eprintln!(
        "online_calibration: after {WEAR_S} s ({:?} of wall clock): {s}",
        started.elapsed()
    );
    assert!(sd < 1e-3 && sb < 1e-3, "1 sigma below 1e-3: {s}");
    assert!((ed - 0.995).abs() < 3.0 * sd, "E_d within 3 sigma: {s}");
    assert!((eb - 1.010).abs() < 3.0 * sb, "E_b within 3 sigma: {s}");
    assert!(
        value(&s, "windows_rejected") >= 1.0,
        "the jump rejected: {s}"
    );

    // 2. The tyre wore at WEAR_S: the estimate follows within the horizon.
    drive(&mut sim, &mut peer, &mut rng, END_S, &mut state);
    let s = next_status(&mut sim, &mut peer, &mut rng, &mut state);
    eprintln!(
        "online_calibration: after {END_S} s ({:?} of wall clock): {s}",
        started.elapsed()
    );
    let (ed, sd) = (value(&s, "online_E_d"), value(&s, "online_sd_E_d"));
    assert!((ed - 0.990).abs() < 3.0 * sd, "E_d follows the wear: {s}");

    // 3. At rest (no more `cmd_vel`): `auto` applies and saves it.
    peer.send("cmd off");
    state.command = Some((0.0, 0.0));
    let applied = loop {
        let t = state.previous.map_or(0.0, |p| p.0);
        drive_at_rest(&mut sim, t + 1.0, &mut state);
        if let Some(l) = bridge
            .lines
            .try_iter()
            .find(|l| l.starts_with("online: applied and saved"))
        {
            break l;
        }
    };
    eprintln!(
        "online_calibration: {applied} ({:?} of wall clock)",
        started.elapsed()
    );
    bridge.send("params");
    let calibration = bridge.until(|l| l.trim_start().starts_with("calibration "));
    assert!(
        calibration.trim_start().starts_with("calibration online"),
        "{calibration}"
    );

    // 4. The offline twin.
    let out = Command::new(env!("CARGO_BIN_EXE_odocal-console"))
        .args(["recalibrate", "--reference-log"])
        .arg(&log)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("the logged estimate, bit for bit"), "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Reads truth lines until board time `until` without publishing anything (the robot at rest).
fn drive_at_rest(sim: &mut Proc, until: f64, state: &mut Drive) {
    loop {
        let l = sim.next();
        if let Some(rest) = l.strip_prefix("truth ") {
            let t: f64 = rest.split_whitespace().next().unwrap().parse().unwrap();
            state.previous = Some((t, 0.0, 0.0, 0.0));
            if t >= until {
                return;
            }
        }
    }
}
