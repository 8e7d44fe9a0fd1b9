//! `host-sim serial --pty …` as a test drives it: the board's console on the pty, the
//! simulator's own stdin (`button`, `reboot`, `play`), and its stdout and stderr read line by
//! line. Every wait waits for a line (a minute at most, then the test fails with what it saw).

#![allow(dead_code)] // each test binary uses its own subset

use std::fs::File;
use std::io::{BufRead, BufReader, Write};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Longest wait for one line.
const WAIT: Duration = Duration::from_secs(60);

/// A running simulator on a pty.
pub struct PtySim {
    child: Child,
    stdin: ChildStdin,
    stdout: Receiver<String>,
    stderr: Arc<Mutex<String>>,
    stderr_lines: Receiver<String>,
    pty: File,
    console: Receiver<String>,
}

impl Drop for PtySim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Sends each line `read` yields (terminators trimmed) to `tx` until it ends.
fn forward<R: std::io::Read + Send + 'static>(read: R, tx: Sender<String>) {
    std::thread::spawn(move || {
        for line in BufReader::new(read).lines().map_while(Result::ok) {
            if tx.send(line.trim_end_matches('\r').to_owned()).is_err() {
                return;
            }
        }
    });
}

impl PtySim {
    /// Starts `host-sim serial --pty` with `args` and opens its pty.
    pub fn start(args: &[&str]) -> PtySim {
        let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(["serial", "--pty"])
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("host-sim runs");
        let stdin = child.stdin.take().unwrap();
        let (tx, stdout) = channel();
        forward(child.stdout.take().unwrap(), tx);
        let stderr = Arc::new(Mutex::new(String::new()));
        let sink = Arc::clone(&stderr);
        let err = child.stderr.take().unwrap();
        let (tx, stderr_lines) = channel();
        std::thread::spawn(move || {
            for line in BufReader::new(err).lines().map_while(Result::ok) {
                {
                    let mut s = sink.lock().unwrap();
                    s.push_str(&line);
                    s.push('\n');
                }
                if tx.send(line).is_err() {
                    return;
                }
            }
        });
        let first = stdout.recv_timeout(WAIT).expect("host-sim prints its pty");
        let path = first
            .strip_prefix("pty ")
            .unwrap_or_else(|| panic!("no pty line: {first:?}"));
        let pty = File::options()
            .read(true)
            .write(true)
            .open(path)
            .unwrap_or_else(|e| panic!("{path}: {e}"));
        let (tx, console) = channel();
        forward(pty.try_clone().unwrap(), tx);
        PtySim {
            child,
            stdin,
            stdout,
            stderr,
            stderr_lines,
            pty,
            console,
        }
    }

    /// Types `line` on the simulator's own stdin.
    pub fn control(&mut self, line: &str) {
        writeln!(self.stdin, "{line}").unwrap();
        self.stdin.flush().unwrap();
    }

    /// Sends `line` to the board's console (Enter as a terminal sends it).
    pub fn send(&mut self, line: &str) {
        write!(self.pty, "{line}\r").unwrap();
        self.pty.flush().unwrap();
    }

    /// What the simulator has printed on stderr so far.
    pub fn stderr(&self) -> String {
        self.stderr.lock().unwrap().clone()
    }

    /// The stdout lines up to and including the first that satisfies `done`.
    pub fn stdout_until(&mut self, what: &str, done: impl Fn(&str) -> bool) -> Vec<String> {
        let err = Arc::clone(&self.stderr);
        until(&self.stdout, what, done, &|| err.lock().unwrap().clone())
    }

    /// The stderr lines (not yet taken by an earlier wait) up to and including the first that
    /// satisfies `done`.
    pub fn stderr_until(&mut self, what: &str, done: impl Fn(&str) -> bool) -> Vec<String> {
        let err = Arc::clone(&self.stderr);
        until(&self.stderr_lines, what, done, &|| {
            err.lock().unwrap().clone()
        })
    }

    /// The console lines up to and including the first that satisfies `done`.
    pub fn console_until(&mut self, what: &str, done: impl Fn(&str) -> bool) -> Vec<String> {
        let err = Arc::clone(&self.stderr);
        until(&self.console, what, done, &|| err.lock().unwrap().clone())
    }

    /// Sends `line` to the console and returns its final reply line (`ok …` or `err …`).
    pub fn command(&mut self, line: &str) -> String {
        self.reply(line).last().unwrap().clone()
    }

    /// Sends `line` to the console and returns the console lines from its echo (what came
    /// before it, e.g. the boot's events, is skipped) up to its final reply line.
    pub fn reply(&mut self, line: &str) -> Vec<String> {
        self.send(line);
        self.console_until(&format!("the echo of {line:?}"), |l| l == line);
        self.console_until(&format!("the reply to {line:?}"), |l| {
            l.starts_with("ok") || l.starts_with("err ")
        })
    }
}

/// The lines of `rx` up to and including the first that satisfies `done`; fails after [`WAIT`]
/// naming `what`, with the lines seen and the simulator's stderr.
fn until(
    rx: &Receiver<String>,
    what: &str,
    done: impl Fn(&str) -> bool,
    stderr: &dyn Fn() -> String,
) -> Vec<String> {
    let deadline = Instant::now() + WAIT;
    let mut seen = Vec::new();
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(line) => {
                let hit = done(&line);
                seen.push(line);
                if hit {
                    return seen;
                }
            }
            Err(e) => {
                let tail = seen[seen.len().saturating_sub(20)..].join("\n");
                let why = match e {
                    RecvTimeoutError::Timeout => "timed out",
                    RecvTimeoutError::Disconnected => "the stream ended",
                };
                panic!(
                    "{why} waiting for {what}; last lines:\n{tail}\nsim stderr:\n{}",
                    stderr()
                );
            }
        }
    }
}

/// A `truth T X Y THETA` line: T in whole microseconds (exactly as printed), the pose.
pub fn truth(line: &str) -> Option<(u64, f64, f64, f64)> {
    let mut w = line.strip_prefix("truth ")?.split(' ');
    let t = micros(w.next()?)?;
    let mut next = || w.next()?.parse::<f64>().ok();
    Some((t, next()?, next()?, next()?))
}

/// `<s>.<6 digits>` as whole microseconds.
pub fn micros(s: &str) -> Option<u64> {
    let (s, us) = s.split_once('.')?;
    (us.len() == 6).then_some(())?;
    Some(s.parse::<u64>().ok()? * 1_000_000 + us.parse::<u64>().ok()?)
}

/// The number after `key=` in a reply (`ok x=+0.123456 y=…`).
pub fn field(reply: &str, key: &str) -> f64 {
    reply
        .split_whitespace()
        .find_map(|w| w.strip_prefix(key)?.strip_prefix('='))
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no {key}= in {reply:?}"))
}
