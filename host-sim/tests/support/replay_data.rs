//! The shared OptiOdom sessions for the replay tests (`../shared/data` beside the checkout, or
//! `ODOCAL_DATA`) and the `host-sim` binary's JSON output, read the same way by each.

#![allow(dead_code)] // each test binary uses its own subset

use std::path::PathBuf;
use std::process::Command;

use host_sim::sim::optiodom::{Session, read_session};
use serde_json::Value;

/// The shared data folder: `ODOCAL_DATA`, or `../shared/data` beside the checkout.
pub fn data_dir() -> PathBuf {
    std::env::var_os("ODOCAL_DATA").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"),
        PathBuf::from,
    )
}

/// The folder of a shared session. An absent folder fails the test, unless `ODOCAL_SKIP_DATA`
/// is set: then the test is skipped and says so on stderr (`None`). A missing data folder must
/// never pass for a green run.
pub fn session_dir(kind: &str, id: &str) -> Option<PathBuf> {
    let d = data_dir().join("optiodom/diff").join(kind).join(id);
    if d.is_dir() {
        Some(d)
    } else if std::env::var_os("ODOCAL_SKIP_DATA").is_some() {
        eprintln!("skipped (ODOCAL_SKIP_DATA is set): {} absent", d.display());
        None
    } else {
        panic!(
            "{} absent: put the shared data beside the checkout (../shared/data) or set \
             ODOCAL_DATA to its folder; ODOCAL_SKIP_DATA=1 skips these tests on purpose",
            d.display()
        )
    }
}

pub fn session(kind: &str, id: &str) -> Option<Session> {
    session_dir(kind, id).map(|d| read_session(&d).unwrap())
}

/// The `host-sim` binary of this build.
pub fn sim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
}

/// The JSON lines of a successful `replay --format json`, parsed; a failure shows its stderr.
pub fn json_rows(out: &std::process::Output) -> Vec<Value> {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}
