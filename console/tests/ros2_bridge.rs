//! `ros2_bridge`: the board on a ROS 2 network, checked by an independent DDS implementation.
//!
//! Inside a network namespace of its own that holds only loopback (no DDS packet leaves the
//! machine), the test runs the simulated board on its pseudo-terminal (`host-sim serial --pty`,
//! real time), the bridge (`odocal-console ros2 --port PTY`) and `ros2_peer.py`: Eclipse
//! Cyclone DDS through its Python binding (the DDS behind `rmw_cyclonedds_cpp`), which
//! subscribes `rt/odom` (`nav_msgs::msg::dds_::Odometry_`) and publishes `rt/cmd_vel`.
//! 1. `line 1` typed on the bridge's console: the robot drives a 1 m line; once the odometry
//!    Cyclone receives has stood still, it equals the board's own `pose` reply to the stream's
//!    precision (both print 6 decimals of a metre and 4 of a degree: half a unit of the last
//!    digit each way);
//! 2. Cyclone publishes `cmd_vel` 0.2 m/s at 20 Hz for 2 s: the robot drives about 0.4 m, then,
//!    with no further command, the board's deadman (500 ms) stops it: the distance it drove after
//!    the last command is the deadman's at full speed. Durations are taken in the board's time
//!    (the bridge names the board time of the first and the last command it forwarded), so a
//!    simulator slowed by a loaded machine changes nothing;
//! 3. Cyclone drives a counter-clockwise pivot and a clockwise arc: `odom`'s turn rate has the
//!    turn's sign and sums to the heading change of the board's own `pose`, and the wheels'
//!    joints of `joint_states` (Cyclone subscribes it too) turned by what that heading change
//!    and the board's wheel radii and wheelbase say each wheel travelled (`ros2_bridge/turns.rs`).

use std::io::Write;
use std::path::Path;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

mod support;
use support::{host_sim, lines_of};
#[path = "ros2_bridge/online.rs"]
mod online;
#[path = "ros2_bridge/robust.rs"]
mod robust;
#[path = "ros2_bridge/turns.rs"]
mod turns;

use serde_json::Value;

/// Generous limit for any one wait (only to avoid a hang; nothing is timed by it).
const WAIT: Duration = Duration::from_secs(60);
/// The board's deadman: the motors stop when no `drive` came for this long (docs/protocol.md).
const DEADMAN_S: f64 = odocal::motion::controller::DEFAULT_DEADMAN_MS as f64 / 1000.0;

/// Set (to anything but `0`) where the bridge's test must run: a missing prerequisite then fails
/// the test instead of skipping it. `.ci/run` sets it.
const REQUIRE_VAR: &str = "ODOCAL_REQUIRE_TOOLS";

/// Whether a missing prerequisite fails the test (CI) rather than skipping it (a newcomer's
/// plain `cargo test --workspace`, without root or Cyclone DDS).
fn dds_required() -> bool {
    std::env::var_os(REQUIRE_VAR).is_some_and(|v| v != "0")
}

/// The independent DDS: Cyclone DDS's Python binding. `Err` says what is missing.
fn cyclone_available() -> Result<(), String> {
    let probe = Command::new("python3")
        .args(["-c", "import cyclonedds.domain, cyclonedds.idl"])
        .output()
        .map_err(|e| format!("python3 cannot be started: {e}"))?;
    if probe.status.success() {
        Ok(())
    } else {
        Err(format!(
            "the Python binding of Cyclone DDS is missing (`pip install cyclonedds`): {}",
            String::from_utf8_lossy(&probe.stderr)
                .lines()
                .last()
                .unwrap_or("")
        ))
    }
}

/// Moves this test's thread (and so every process it starts) into a new network namespace and
/// brings up its loopback with multicast, the only interface there. `Err` when this process may
/// not make one (not root and not inside `unshare -rn`) or `ip` (iproute2) is missing; nothing
/// is sent on any network then.
#[allow(unsafe_code)] // the one `unshare` call
fn isolate_network() -> Result<(), String> {
    Command::new("ip")
        .arg("-V")
        .output()
        .map_err(|e| format!("`ip` (iproute2) is needed to set up loopback: {e}"))?;
    // SAFETY: unshare takes a flag word and touches no memory of this process; it moves only
    // the calling thread into the new namespace.
    let rc = unsafe { libc::unshare(libc::CLONE_NEWNET) };
    if rc != 0 {
        return Err(format!(
            "no network namespace of its own, so DDS discovery would leave the machine: \
             unshare(CLONE_NEWNET): {} (run the tests as root, or inside `unshare -rn`)",
            std::io::Error::last_os_error()
        ));
    }
    for args in [
        &["link", "set", "lo", "up"][..],
        &["link", "set", "lo", "multicast", "on"],
        &["route", "add", "224.0.0.0/4", "dev", "lo"],
    ] {
        let status = Command::new("ip")
            .args(args)
            .status()
            .map_err(|e| format!("`ip {}`: {e}", args.join(" ")))?;
        assert!(
            status.success(),
            "ros2_bridge: `ip {}` failed",
            args.join(" ")
        );
    }
    let links = Command::new("ip").args(["-o", "link"]).output().unwrap();
    let links = String::from_utf8_lossy(&links.stdout);
    let names: Vec<&str> = links
        .lines()
        .filter_map(|l| l.split(':').nth(1).map(str::trim))
        .collect();
    assert_eq!(names, ["lo"], "only loopback in the test's namespace");
    Ok(())
}

/// `true` when a prerequisite of the test's world (the independent DDS, a loopback-only network
/// namespace) is there; otherwise the test is skipped with one line on stderr saying what is
/// missing and how to run it, or, with `ODOCAL_REQUIRE_TOOLS` set, fails.
fn ready_or_skip(test: &str, prerequisite: Result<(), String>) -> bool {
    match prerequisite {
        Ok(()) => true,
        Err(why) if dds_required() => panic!("{test}: {why} ({REQUIRE_VAR} is set)"),
        Err(why) => {
            // Straight to the process's stderr: the harness captures `eprintln!` of a passing test.
            let _ = writeln!(
                std::io::stderr(),
                "{test}: skipped: {why}; to run it: `pip install cyclonedds`, then as root or \
                 inside `unshare -rn`: cargo test -p odocal-console --test ros2_bridge"
            );
            false
        }
    }
}

/// Ctrl-C for a child: SIGINT.
#[allow(unsafe_code)] // the one `kill` call
fn interrupt(child: &Child) {
    let pid = libc::pid_t::try_from(child.id()).unwrap();
    // SAFETY: kill takes a process id and a signal number and touches no memory of this process.
    let rc = unsafe { libc::kill(pid, libc::SIGINT) };
    assert_eq!(rc, 0, "SIGINT: {}", std::io::Error::last_os_error());
}

/// A child process whose stdout lines arrive on a channel.
struct Proc {
    child: Child,
    stdin: ChildStdin,
    lines: Receiver<String>,
    name: &'static str,
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Proc {
    fn start(name: &'static str, cmd: &mut Command) -> Proc {
        let mut child = cmd
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("{name} does not start: {e}"));
        let lines = lines_of(child.stdout.take().unwrap());
        let stdin = child.stdin.take().unwrap();
        Proc {
            child,
            stdin,
            lines,
            name,
        }
    }

    fn send(&mut self, line: &str) {
        writeln!(self.stdin, "{line}").unwrap();
        self.stdin.flush().unwrap();
    }

    /// The next stdout line, or a failure naming the process and its exit status.
    fn next(&mut self) -> String {
        match self.lines.recv_timeout(WAIT) {
            Ok(l) => l,
            Err(_) => panic!(
                "{}: no output within {WAIT:?} (exit status {:?})",
                self.name,
                self.child.try_wait()
            ),
        }
    }

    /// Lines until one satisfies `f`; returns it.
    fn until(&mut self, f: impl Fn(&str) -> bool) -> String {
        let deadline = Instant::now() + WAIT;
        while Instant::now() < deadline {
            let l = self.next();
            if f(&l) {
                return l;
            }
        }
        panic!("{}: the line awaited never came", self.name);
    }
}

/// One `rt/odom` sample as Cyclone DDS received it.
#[derive(Clone, Copy, Debug)]
struct Odom {
    t: f64,
    rx: f64,
    x: f64,
    y: f64,
    yaw: f64,
    v: f64,
    w: f64,
    cxx: f64,
    cvv: f64,
}

/// One `rt/joint_states` sample as Cyclone DDS received it: the wheels' joint positions (rad)
/// and rates (rad/s), by the joint names the message gives them.
#[derive(Clone, Copy, Debug)]
struct Joints {
    left: f64,
    right: f64,
    left_rate: f64,
    right_rate: f64,
}

/// The peer's output: odometry and joint samples, and the other messages.
struct Peer {
    proc: Proc,
    samples: Vec<Odom>,
    joints: Vec<Joints>,
    /// `/diagnostics` statuses as received: (receive time, level, message, key-values).
    diags: Vec<Value>,
}

impl Peer {
    /// The next message of the peer; odometry samples are recorded on the way.
    fn next(&mut self) -> Value {
        let l = self.proc.next();
        let v: Value =
            serde_json::from_str(&l).unwrap_or_else(|e| panic!("ros2_peer.py printed `{l}`: {e}"));
        if v["k"] == "odom" {
            assert_eq!(v["frame"], "odom");
            assert_eq!(v["child"], "base_link");
            let f = |k: &str| v[k].as_f64().unwrap();
            self.samples.push(Odom {
                t: f("t"),
                rx: f("rx"),
                x: f("x"),
                y: f("y"),
                yaw: f("yaw"),
                v: f("v"),
                w: f("w"),
                cxx: f("cxx"),
                cvv: f("cvv"),
            });
        } else if v["k"] == "diag" {
            self.diags.push(v.clone());
        } else if v["k"] == "joints" {
            let names: Vec<&str> = v["name"]
                .as_array()
                .unwrap()
                .iter()
                .map(|n| n.as_str().unwrap())
                .collect();
            let at = |key: &str, joint: &str| {
                let i = names.iter().position(|n| *n == joint).unwrap();
                v[key][i].as_f64().unwrap()
            };
            self.joints.push(Joints {
                left: at("position", "left_wheel_joint"),
                right: at("position", "right_wheel_joint"),
                left_rate: at("velocity", "left_wheel_joint"),
                right_rate: at("velocity", "right_wheel_joint"),
            });
        }
        v
    }

    /// The next odometry sample.
    fn odom(&mut self) -> Odom {
        loop {
            if self.next()["k"] == "odom" {
                return *self.samples.last().unwrap();
            }
        }
    }
}

fn number_after(text: &str, key: &str) -> f64 {
    text.split_whitespace()
        .find_map(|w| w.strip_prefix(key)?.strip_prefix('='))
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no {key}= in `{text}`"))
}

fn percentile(v: &[f64], q: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[((s.len() - 1) as f64 * q).round() as usize]
}

/// The processes of the test's world: the simulated board, the bridge and the Cyclone peer
/// (each killed when dropped).
struct World {
    sim: Proc,
    bridge: Proc,
    peer: Peer,
}

/// Starts the simulated board, the bridge and the peer in a network namespace of the test's own,
/// and waits for the first odometry sample (returned); `None` when the test is skipped.
fn start_world() -> Option<(World, Odom)> {
    start_world_on(None)
}

/// [`start_world`], the bridge opening the board's pty through the symlink `link` when given
/// (as a `/dev/serial/by-id/` path points at the adapter's device).
fn start_world_on(link: Option<&Path>) -> Option<(World, Odom)> {
    if !ready_or_skip("ros2_bridge", cyclone_available()) {
        return None;
    }
    let peer_script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/ros2_peer.py");
    host_sim();
    if !ready_or_skip("ros2_bridge", isolate_network()) {
        return None;
    }

    // The simulated board, in real time (the deadman counts board time).
    let (sim, pty) = start_sim();

    let port = match link {
        Some(link) => {
            point(link, &pty);
            link.to_string_lossy().into_owned()
        }
        None => pty,
    };
    let mut bridge = Proc::start(
        "odocal-console ros2",
        Command::new(env!("CARGO_BIN_EXE_odocal-console"))
            .args(["ros2", "--port", &port])
            .env_remove("ROS_AUTOMATIC_DISCOVERY_RANGE")
            .env_remove("ROS_LOCALHOST_ONLY")
            .env("ROS_DOMAIN_ID", "0"),
    );
    let banner = bridge.until(|l| l.starts_with("ros2: "));
    assert!(banner.contains("at 100 Hz"), "{banner}");

    let mut peer = Peer {
        proc: Proc::start(
            "ros2_peer.py",
            Command::new("python3")
                .arg(&peer_script)
                .env("ROS_DOMAIN_ID", "0"),
        ),
        samples: Vec::new(),
        joints: Vec::new(),
        diags: Vec::new(),
    };
    assert_eq!(peer.next()["k"], "ready");
    // Discovery done: Cyclone receives the bridge's odometry.
    let start = peer.odom();
    assert_eq!((start.x, start.y, start.v), (0.0, 0.0, 0.0), "{start:?}");
    Some((World { sim, bridge, peer }, start))
}

/// Points the symlink `link` at `target` (replacing what it pointed at).
fn point(link: &Path, target: &str) {
    let _ = std::fs::remove_file(link);
    std::os::unix::fs::symlink(target, link).unwrap();
}

/// The simulated board on a new pty: the process and the pty's path.
fn start_sim() -> (Proc, String) {
    start_sim_with(&[])
}

/// [`start_sim`] with more options of `host-sim serial`.
fn start_sim_with(args: &[&str]) -> (Proc, String) {
    let mut sim = Proc::start(
        "host-sim",
        Command::new(host_sim())
            .args(["serial", "--pty"])
            .args(args)
            .stderr(Stdio::null()),
    );
    let first = sim.next();
    let pty = first
        .strip_prefix("pty ")
        .unwrap_or_else(|| panic!("no pty line: {first:?}"))
        .to_string();
    (sim, pty)
}

/// Step 1: a 1 m line started on the bridge's console: once at rest, the odometry Cyclone receives is
/// the board's own `pose`. Returns the sample at rest.
fn a_line_ends_at_the_boards_pose(w: &mut World, start: Odom) -> Odom {
    let World { bridge, peer, .. } = w;
    // 1. A 1 m line, started on the bridge's console.
    bridge.send("line 1");
    let started = bridge.until(|l| l.starts_with("ok ") || l.starts_with("err "));
    assert!(started.starts_with("ok run 1 started: line"), "{started}");
    bridge.until(|l| l.starts_with("event run 1 finished"));
    // Stood still: 50 samples in a row (0.5 s) with the same pose and zero speeds.
    let mut still = 0;
    let mut last = peer.odom();
    let deadline = Instant::now() + WAIT;
    while still < 50 {
        assert!(
            Instant::now() < deadline,
            "the robot never stood still: {last:?}"
        );
        let o = peer.odom();
        let same = (o.x, o.y, o.yaw) == (last.x, last.y, last.yaw) && o.v == 0.0 && o.w == 0.0;
        still = if same { still + 1 } else { 0 };
        last = o;
    }
    bridge.send("pose");
    let pose = bridge.until(|l| l.starts_with("ok x="));
    let after = peer.odom();
    let (x, y, theta_deg) = (
        number_after(&pose, "x"),
        number_after(&pose, "y"),
        number_after(&pose, "theta_deg"),
    );
    println!(
        "line 1: board `pose` x={x} y={y} theta_deg={theta_deg}; rt/odom x={} y={} yaw={} deg",
        after.x,
        after.y,
        after.yaw.to_degrees()
    );
    // The stream's precision: 6 decimals of a metre, 4 of a degree, rounded once on each side.
    assert!((after.x - x).abs() <= 1e-6, "x {} vs {x}", after.x);
    assert!((after.y - y).abs() <= 1e-6, "y {} vs {y}", after.y);
    assert!(
        (after.yaw.to_degrees() - theta_deg).abs() <= 1e-4,
        "yaw {} vs {theta_deg}",
        after.yaw.to_degrees()
    );
    // The routine drives 1 m by the odometry (its stop within a millimetre or so).
    assert!((x - 1.0).abs() < 0.005, "{pose}");
    // The pose covariance has grown with the metre driven.
    assert!(
        after.cxx > start.cxx && after.cvv > 0.0,
        "{start:?} {after:?}"
    );

    // The finished line is not measured, and the board moves from an unmeasured end for no
    // command (`err 24`, cmd_vel's drives included) until it is measured or dropped: this test
    // only wanted its pose.
    bridge.send("drop 1");
    let dropped = bridge.until(|l| l.starts_with("ok ") || l.starts_with("err "));
    assert!(dropped.starts_with("ok dropped run 1"), "{dropped}");

    after
}

/// Step 2: `cmd_vel` from Cyclone drives the robot, and the board's deadman stops it.
fn cmd_vel_drives_until_the_deadman(w: &mut World, before: Odom) {
    let World { bridge, peer, .. } = w;
    // 2. cmd_vel from Cyclone: 0.2 m/s for 2 s at 20 Hz. Durations are the board's: the bridge
    // names the board time (and pose) of the stream line current at the first command after a
    // pause and at the last one before a pause of the deadman's length. On a loaded machine the
    // commands may pause that long midway (the publisher or the delivery stalled): the board's
    // deadman then stops the robot and the next command starts it again, a segment each.
    let (v_cmd, seconds, hz) = (0.2, 2.0, 20.0);
    peer.proc.send(&format!("cmd_vel {v_cmd} 0 {seconds} {hz}"));
    let done = loop {
        let m = peer.next();
        if m["k"] == "cmd_vel_done" {
            break m;
        }
    };
    // At rest: 20 samples in a row (0.2 s) with zero speeds, after the motion.
    let mut zero = 0;
    let mut max_speed = 0.0f64;
    let deadline = Instant::now() + WAIT;
    while zero < 20 {
        let o = peer.odom();
        assert!(
            Instant::now() < deadline,
            "the robot never stopped after the last command: {o:?}"
        );
        max_speed = max_speed.max(o.v);
        zero = if max_speed > 0.5 * v_cmd && o.v == 0.0 && o.w == 0.0 {
            zero + 1
        } else {
            0
        };
    }
    let rest = *peer.samples.last().unwrap();
    // The bridge printed every segment's lines before it published those samples at rest; the
    // reply to `params` typed now comes after all of them.
    bridge.send("params");
    let mut segments: Vec<(f64, f64)> = Vec::new();
    let mut at_last = (f64::NAN, f64::NAN);
    let mut accel = f64::NAN;
    loop {
        let l = bridge.next();
        if l.starts_with("ros2: cmd_vel: driving from board") {
            segments.push((number_after(&l, "t"), f64::NAN));
        } else if l.starts_with("ros2: cmd_vel: none since board") {
            let seg = segments.last_mut().expect("a pause before any command");
            seg.1 = number_after(&l, "t");
            at_last = (number_after(&l, "x"), number_after(&l, "y"));
        } else if let Some(a) = l.trim_start().strip_prefix("max_accel ") {
            accel = a.split_whitespace().next().unwrap().parse().unwrap();
        } else if l == "ok" {
            break;
        }
    }
    assert!(
        !segments.is_empty() && segments.iter().all(|s| s.1.is_finite()),
        "{segments:?}"
    );
    let moved = ((rest.x - before.x).powi(2) + (rest.y - before.y).powi(2)).sqrt();
    let after_last = ((rest.x - at_last.0).powi(2) + (rest.y - at_last.1).powi(2)).sqrt();
    // The motion model of a segment: from rest at max_accel (a) up to v_cmd, from its first
    // command until the deadman after its last one (D = t_last - t_first + 0.5 s).
    let segment = |(t0, t1): (f64, f64)| {
        let d = t1 - t0 + DEADMAN_S;
        if d >= v_cmd / accel {
            v_cmd * d - v_cmd * v_cmd / (2.0 * accel)
        } else {
            0.5 * accel * d * d
        }
    };
    let expected: f64 = segments.iter().map(|&s| segment(s)).sum();
    println!(
        "cmd_vel {v_cmd} m/s for {seconds} s ({} commands, board times {segments:?}): moved \
         {moved:.4} m (commanded {:.3} m; expected with the deadman's {DEADMAN_S} s and the \
         {accel:.3} m/s² ramp {expected:.4} m), {after_last:.4} m of it after the last command \
         (the deadman at full speed: {:.4} m), top speed {max_speed} m/s",
        done["n"],
        v_cmd * seconds,
        v_cmd * DEADMAN_S
    );
    assert!((max_speed - v_cmd).abs() < 0.002, "top speed {max_speed}");
    // ±0.015 m a segment: its two board times are those of the stream line before each command
    // (one period, 10 ms, 2 mm each at 0.2 m/s), and the braking after the deadman (under
    // 0.01 m).
    let tolerance = 0.015 * segments.len() as f64;
    assert!(
        (moved - expected).abs() < tolerance,
        "moved {moved} m, expected {expected} m"
    );
    // Stopped by the board's deadman: after the last command the robot kept its speed for the
    // deadman's 0.5 s (when it had reached it: the last segment at least the ramp's v/a long),
    // then braked (under 0.01 m), and moved no further.
    let (t0, t1) = *segments.last().unwrap();
    let low = if t1 - t0 >= v_cmd / accel {
        v_cmd * DEADMAN_S - 0.005
    } else {
        0.0
    };
    assert!(
        after_last > low && after_last < v_cmd * DEADMAN_S + 0.015,
        "{after_last} m after the last command"
    );
    assert!(rest.w.abs() < 1e-9 && rest.y.abs() < 0.01, "{rest:?}");
}

/// Step 5: rate and latency as Cyclone saw them, and the bridge's own summary (Ctrl-C).
fn rates_and_the_bridges_summary(w: &mut World) {
    let World { bridge, peer, .. } = w;
    // Rate and latency seen by Cyclone.
    let s = &peer.samples;
    let rate = (s.len() - 1) as f64 / (s[s.len() - 1].t - s[0].t);
    let latency: Vec<f64> = s.iter().map(|o| o.rx - o.t).collect();
    println!(
        "rt/odom: {} samples at {rate:.2} Hz (stamps); latency stamp -> Cyclone sample: median \
         {:.3} ms, p99 {:.3} ms, max {:.3} ms",
        s.len(),
        1e3 * percentile(&latency, 0.5),
        1e3 * percentile(&latency, 0.99),
        1e3 * percentile(&latency, 1.0)
    );
    // The bridge's own figures (Ctrl-C ends it with its summary): the odometry rate in the
    // board's time, one message per stream line.
    interrupt(&bridge.child);
    let mut summary = Vec::new();
    loop {
        let l = bridge.next();
        let last = l.starts_with("ros2: cmd_vel_forwarded");
        if l.starts_with("ros2: ") {
            summary.push(l);
        }
        if last {
            break;
        }
    }
    println!("{}", summary.join("\n"));
    let figure = |key: &str| -> f64 {
        summary
            .iter()
            .find_map(|l| l.strip_prefix(&format!("ros2: {key} ")))
            .and_then(|v| v.split_whitespace().next()?.parse().ok())
            .unwrap_or_else(|| panic!("no {key} in {summary:?}"))
    };
    let board_rate = figure("rate_board_hz");
    assert!(board_rate >= 50.0, "odometry at {board_rate} Hz");
    assert!(figure("lines") >= s.len() as f64, "{summary:?}");
    peer.proc.send("quit");
}

#[test]
fn ros2_bridge() {
    let Some((mut world, start)) = start_world() else {
        return;
    };
    let after = a_line_ends_at_the_boards_pose(&mut world, start);
    cmd_vel_drives_until_the_deadman(&mut world, after);
    turns::a_ccw_pivot_and_a_cw_arc_match_the_boards_pose(&mut world);
    rates_and_the_bridges_summary(&mut world);
}

#[test]
fn ros2_bridge_survives_board_reset() {
    let Some((mut world, _)) = start_world() else {
        return;
    };
    robust::a_reset_mid_drive_keeps_odom_and_forwards_nothing_blind(&mut world);
}

#[test]
fn ros2_bridge_survives_unplug() {
    let dir = std::env::temp_dir().join(format!("odocal-unplug-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("usb-odocal-if00");
    let Some((mut world, _)) = start_world_on(Some(&link)) else {
        return;
    };
    robust::an_unplugged_board_is_reopened_on_its_path(&mut world, &link);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ros2_bridge_refuses_nan() {
    let Some((mut world, _)) = start_world() else {
        return;
    };
    robust::a_nan_cmd_vel_stops_the_robot_before_the_deadman(&mut world);
}
