//! What the console's integration tests share: the simulated board's binary and a reader that
//! hands a child process's output over line by line.

use std::io::{BufRead, BufReader, Read};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::mpsc::{self, Receiver};

/// The simulated board's binary, built if needed (a no-op when it is up to date). Its path is
/// the one cargo reports for the build, so it is found wherever the build writes it: any
/// `--target`, any target directory.
pub fn host_sim() -> PathBuf {
    let out = Command::new(env!("CARGO"))
        .args(["build", "-q", "-p", "host-sim", "--bin", "host-sim"])
        .args(["--message-format", "json"])
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .stderr(Stdio::inherit())
        .output()
        .expect("cargo runs");
    assert!(out.status.success(), "building host-sim failed");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let path = stdout
        .lines()
        .filter(|l| l.contains(r#""reason":"compiler-artifact""#))
        .find_map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).ok()?;
            v["executable"].as_str().map(PathBuf::from)
        })
        .unwrap_or_else(|| panic!("cargo reported no host-sim executable:\n{stdout}"));
    assert!(path.exists(), "{} missing", path.display());
    path
}

/// The lines of `out` (a child's stdout), read on a thread of their own until it closes or the
/// receiver is dropped.
pub fn lines_of(out: impl Read + Send + 'static) -> Receiver<String> {
    let (tx, lines) = mpsc::channel();
    std::thread::spawn(move || {
        for l in BufReader::new(out).lines().map_while(Result::ok) {
            if tx.send(l).is_err() {
                return;
            }
        }
    });
    lines
}
