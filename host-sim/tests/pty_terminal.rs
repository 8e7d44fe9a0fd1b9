//! A real terminal program on the simulated board's pseudo-terminal, as the README's operator
//! uses it: `cargo sim serial --pty`, then picocom with its default settings (Enter sends CR, no
//! local echo) inside tmux; keys go in with `tmux send-keys`, the screen comes back with
//! `tmux capture-pane`. Needs `tmux` and `picocom` (`.ci/run` installs them).
//!
//! Sequence: `help`; a square run stopped with Ctrl-C (reported aborted, the pose frozen);
//! `stop` typed after an arrow key; a square run to the end; `measure` in bare millimetres refused
//! naming the units; the correct `measure`; `params`.

use std::io::{BufRead, BufReader, Write};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

struct Terminal {
    session: String,
    sim: Child,
    sim_stderr: Arc<Mutex<String>>,
}

impl Drop for Terminal {
    fn drop(&mut self) {
        let _ = Command::new("tmux")
            .args(["kill-session", "-t", &self.session])
            .status();
        let _ = self.sim.kill();
        let _ = self.sim.wait();
    }
}

impl Terminal {
    fn tmux(&self, args: &[&str]) -> String {
        let out = Command::new("tmux").args(args).output().expect("tmux runs");
        assert!(out.status.success(), "tmux {args:?}: {:?}", out);
        String::from_utf8_lossy(&out.stdout).into_owned()
    }
    fn screen(&self) -> String {
        self.tmux(&[
            "capture-pane",
            "-p",
            "-J",
            "-S",
            "-2000",
            "-t",
            &self.session,
        ])
    }
    /// Types `text` and presses Enter.
    fn line(&self, text: &str) {
        self.tmux(&["send-keys", "-t", &self.session, "-l", text]);
        self.tmux(&["send-keys", "-t", &self.session, "Enter"]);
    }
    fn key(&self, key: &str) {
        self.tmux(&["send-keys", "-t", &self.session, key]);
    }
    /// Waits until the screen satisfies `done` (`what` describes it in the failure message).
    fn wait_until(&self, what: &str, done: impl Fn(&str) -> bool) -> String {
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            let screen = self.screen();
            if done(&screen) {
                return screen;
            }
            assert!(
                Instant::now() < deadline,
                "timed out waiting for {what}; screen:\n{screen}\nsim stderr:\n{}",
                self.sim_stderr.lock().unwrap()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
    /// Waits until the screen shows `what` `count` times.
    fn wait_for(&self, what: &str, count: usize) -> String {
        self.wait_until(&format!("{what:?} ×{count}"), |s| {
            s.matches(what).count() >= count
        })
    }
    fn pose(&self, n: usize) -> String {
        self.line("pose");
        let screen = self.wait_for("ok x=", n);
        screen
            .lines()
            .filter(|l| l.starts_with("ok x="))
            .nth(n - 1)
            .unwrap()
            .to_owned()
    }
}

/// Whether tmux and picocom are there to run this test. Without them the test is skipped with
/// one line on stderr (a newcomer's plain `cargo test --workspace`); with `ODOCAL_REQUIRE_TOOLS`
/// set (`.ci/run`) it fails instead.
fn terminal_tools_or_skip() -> bool {
    let missing: Vec<&str> = ["tmux", "picocom"]
        .into_iter()
        .filter(|tool| Command::new(tool).arg("-h").output().is_err())
        .collect();
    if missing.is_empty() {
        return true;
    }
    let why = format!("{} not installed", missing.join(" and "));
    if std::env::var_os("ODOCAL_REQUIRE_TOOLS").is_some_and(|v| v != "0") {
        panic!("pty_terminal: {why} (ODOCAL_REQUIRE_TOOLS is set)");
    }
    // Straight to the process's stderr: the harness captures `eprintln!` of a passing test.
    let _ = writeln!(
        std::io::stderr(),
        "pty_terminal: skipped: {why}; to run it: apt-get install tmux picocom, then \
         cargo test -p host-sim --test pty_terminal"
    );
    false
}

fn start() -> Terminal {
    let mut sim = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["serial", "--pty"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("host-sim runs");
    let mut first = String::new();
    BufReader::new(sim.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    let path = first
        .trim()
        .strip_prefix("pty ")
        .unwrap_or_else(|| panic!("no pty path: {first:?}"))
        .to_owned();
    let sim_stderr = Arc::new(Mutex::new(String::new()));
    let sink = Arc::clone(&sim_stderr);
    let stderr = sim.stderr.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let mut s = sink.lock().unwrap();
            s.push_str(&line);
            s.push('\n');
        }
    });
    let session = format!("odocal-pty-{}", std::process::id());
    let picocom = format!("picocom {path}; echo '{EXITED}'; sleep 3600");
    let status = Command::new("tmux")
        .args([
            "new-session",
            "-d",
            "-s",
            &session,
            "-x",
            "200",
            "-y",
            "60",
            // The pane outlives picocom, so that a picocom that could not start shows why
            // (instead of tmux reporting a pane it cannot find) and can be started again.
            &picocom,
        ])
        .status()
        .expect("tmux is installed (apt-get install tmux picocom)");
    assert!(status.success());
    let t = Terminal {
        session,
        sim,
        sim_stderr,
    };
    // A picocom that exits before it is ready (once seen on a loaded machine as a pane tmux could
    // not find) is started again, twice at most, in the same pane (respawning clears it).
    for attempt in 1.. {
        let screen = t.wait_until("picocom to start or exit", |s| {
            s.contains("Terminal ready") || s.contains(EXITED)
        });
        if screen.contains("Terminal ready") {
            break;
        }
        assert!(attempt < 3, "picocom did not start:\n{screen}");
        t.tmux(&["respawn-pane", "-k", "-t", &t.session, &picocom]);
    }
    t
}

/// What the pane prints when picocom has exited.
const EXITED: &str = "[picocom exited]";

#[test]
fn picocom_with_default_settings_drives_a_session() {
    if !terminal_tools_or_skip() {
        return;
    }
    let t = start();
    t.line("help");
    let screen = t.wait_for("ok 28 commands", 1);
    // The board echoes what is typed (picocom does not echo locally).
    assert!(screen.contains("help\n"), "{screen}");
    for (set, reply) in [
        ("set max_speed 1", "ok max_speed = 1.000 m/s"),
        ("set max_accel 2", "ok max_accel = 2.000 m/s^2"),
        ("set max_turn_rate 3", "ok max_turn_rate = 3.000 rad/s"),
        (
            "set max_turn_accel 10",
            "ok max_turn_accel = 10.000 rad/s^2",
        ),
    ] {
        t.line(set);
        t.wait_for(reply, 1);
    }
    // Ctrl-C mid-run: stopped at once, reported aborted and not stored.
    t.line("run cw 0.5");
    t.wait_for("ok run 1 started: square cw L=0.500 m", 1);
    std::thread::sleep(Duration::from_millis(700));
    t.key("C-c");
    let screen = t.wait_for("event run 1 aborted, not stored: square cw L=0.500 m", 1);
    assert!(screen.contains("^C"), "{screen}");
    assert!(screen.contains("event stopped (Ctrl-C)"), "{screen}");
    // The motors stopped (the duty is zero from the next control period on, see
    // `tests/console.rs`); once the robot has coasted out its motor lag it stands still: two
    // `pose` replies 0.3 s apart agree. The simulated board runs in real time, and a loaded
    // host may run it late, so the check waits for that (a deadline only bounds a hang); a
    // robot that kept driving never gets there.
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut n = 1;
    let mut last = t.pose(n);
    loop {
        std::thread::sleep(Duration::from_millis(300));
        n += 1;
        let now = t.pose(n);
        if now == last {
            break;
        }
        assert!(Instant::now() < deadline, "still moving: {last} → {now}");
        last = now;
    }
    t.line("status");
    t.wait_for("ok state=idle", 1);
    // An arrow key, then `stop`: the escape sequence never reaches the parser.
    t.key("Up");
    t.key("Left");
    t.line("stop");
    let screen = t.wait_for("ok stopped", 1);
    assert!(!screen.contains("err "), "{screen}");
    // A whole run, then the operator measures it.
    t.line("run cw 0.5");
    t.wait_for("event run 1 finished: square cw L=0.500 m", 1);
    let deadline = Instant::now() + Duration::from_secs(10);
    let measure = loop {
        let stderr = t.sim_stderr.lock().unwrap().clone();
        if let Some(l) = stderr
            .lines()
            .filter_map(|l| l.split_once("start frame: "))
            .map(|(_, m)| m.to_owned())
            .next_back()
        {
            break l;
        }
        assert!(
            Instant::now() < deadline,
            "no true pose on stderr:\n{stderr}"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    let w: Vec<f64> = measure
        .split_whitespace()
        .skip(1)
        .map(|v| v.trim_end_matches(char::is_alphabetic).parse().unwrap())
        .collect();
    // Bare millimetres: no unit is inferred; the reply names the units and nothing is stored.
    t.line(&format!("measure {:.3} {:.3}", w[0] * 1e3, w[1] * 1e3));
    let screen = t.wait_for("has no unit: write mm, cm or m after it", 1);
    let refusal = screen
        .lines()
        .find(|l| l.contains("has no unit"))
        .unwrap_or_default();
    assert!(refusal.starts_with("err 26: <x> "), "{screen}");
    // The same numbers with their unit written are read exactly, and echoed as read.
    t.line(&format!("measure {:.3}mm {:.3}mm", w[0] * 1e3, w[1] * 1e3));
    t.wait_for("ok run 1 square cw L=0.500 m measured: read x=", 1);
    // A finished run is measured or dropped before the next one starts.
    t.line("run cw 0.5");
    t.wait_for("event run 2 finished: square cw L=0.500 m", 1);
    t.line("run cw 0.5");
    t.wait_for(
        "err 24: run 2 (square cw L=0.500 m) is not measured yet: measure it or drop it first",
        1,
    );
    t.line("set max_speed 0.5");
    t.wait_for("ok max_speed = 0.500 m/s (not saved; save to keep)", 1);
    t.line("params");
    let screen = t.wait_for("calibration none", 1);
    let finals: Vec<&str> = screen
        .lines()
        .filter(|l| l.starts_with("ok") || l.starts_with("err"))
        .collect();
    assert_eq!(finals.last(), Some(&"ok"), "{screen}");
    // The only errors of the whole session: the measurement without its unit, and the run
    // started before the last one was measured.
    let errors: Vec<&&str> = finals.iter().filter(|l| l.starts_with("err")).collect();
    assert_eq!(errors.len(), 2, "{screen}");
    assert!(errors[0].starts_with("err 26: "), "{screen}");
    assert!(errors[1].starts_with("err 24: "), "{screen}");
    println!("{screen}");
}
