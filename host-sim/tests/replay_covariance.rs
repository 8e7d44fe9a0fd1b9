//! The covariance `host-sim replay` predicts for every evaluated run, held against the shared
//! real sessions (the library's `calibration::covariance`, the model the ROS 2 bridge publishes).
//! Without the data the test fails; `ODOCAL_SKIP_DATA=1` skips it on purpose, said on stderr.

#[path = "support/replay_data.rs"]
mod support;

use serde_json::Value;
use support::{json_rows, session_dir, sim};

/// The mean NEES of `rows` (per-run rows of `method` and `kind`), and how many.
fn mean_nees(rows: &[Value], method: &str, kind: &str) -> (f64, usize) {
    let v: Vec<f64> = rows
        .iter()
        .filter(|r| r["method"] == method && r["kind"] == kind && r["run"] != "all")
        .map(|r| r["nees"].as_f64().unwrap())
        .collect();
    (v.iter().sum::<f64>() / v.len() as f64, v.len())
}

/// The covariance the bridge publishes holds on real runs: `replay --format json` gives every
/// evaluated run its predicted final-position covariance (`final_pos_cov_m2`, the library's
/// model with the calibration's 1σ raised to the floor for the calibration's age, a tape's
/// `E_s`, and the slip and scrub of the calibration runs' own scatter) and the NEES of its
/// error against it. Calibrated on the squares, evaluated on the other kinds (the squares of
/// the same evening calibrate the circles and the lines and turns: the same-day floor; the free
/// paths 11 days later: the between-session floor), and on each square session left out of the
/// calibration (calibrated with sessions six months apart: the between-session floor): a mean
/// NEES of 2 is a right covariance. Measured: squares 2.70 (24 runs), circles 1.20 (6), lines
/// and turns 3.42 (9), free paths 3.79 (2); the goal 1..4 on each kind (docs/calibration.md,
/// *Covariance that holds*). With the between-session floor on the circles too they scored
/// 0.56 (conservative); without a floor (`--trust-session-sd`) the squares are at 5.28 and the
/// free paths at 7.44 (over-confident).
#[test]
fn replay_covariance_holds_on_real_runs() {
    let kinds = ["circular", "ivanjko", "free"];
    let ids = ["231220200134", "231220200057", "030120210001"];
    let squares = [
        "230620202042",
        "230620202144",
        "231220200029",
        "231220200040",
    ];
    let Some(square_dirs) = squares
        .iter()
        .map(|id| session_dir("square", id))
        .collect::<Option<Vec<_>>>()
    else {
        return;
    };
    let Some(other_dirs) = kinds
        .iter()
        .zip(ids)
        .map(|(k, id)| session_dir(k, id))
        .collect::<Option<Vec<_>>>()
    else {
        return;
    };
    let mut args: Vec<std::ffi::OsString> = vec!["replay".into(), "--calibrate".into()];
    args.extend(square_dirs.iter().map(|d| d.clone().into_os_string()));
    args.push("--evaluate".into());
    args.extend(other_dirs.iter().map(|d| d.clone().into_os_string()));
    args.extend(["--method", "exact", "--format", "json", "--out"].map(Into::into));
    args.push(
        std::env::temp_dir()
            .join(format!("odocal-replay-nees-{}", std::process::id()))
            .into_os_string(),
    );
    let rows = json_rows(&sim().args(&args).output().unwrap());
    for r in rows.iter().filter(|r| r["run"] != "all") {
        let c = &r["final_pos_cov_m2"];
        assert!(c[0][0].as_f64().unwrap() > 0.0 && c[0][1] == c[1][0], "{r}");
    }
    for (kind, (lo, hi)) in [
        ("circular", (1.0, 4.0)),
        ("ivanjko", (1.0, 4.0)),
        ("free", (1.0, 4.0)),
    ] {
        let (nees, n) = mean_nees(&rows, "exact", kind);
        assert!(
            n > 0 && nees > lo && nees < hi,
            "{kind}: mean NEES {nees} of {n}"
        );
    }
    // Each square session predicted by the others.
    let mut square_rows = Vec::new();
    for (i, d) in square_dirs.iter().enumerate() {
        let mut args: Vec<std::ffi::OsString> = vec!["replay".into(), "--calibrate".into()];
        for (j, o) in square_dirs.iter().enumerate() {
            if j != i {
                args.push(o.clone().into_os_string());
            }
        }
        args.extend(["--evaluate".into(), d.clone().into_os_string()]);
        args.extend(
            [
                "--method",
                "exact",
                "--format",
                "json",
                "--every-date",
                "--out",
            ]
            .map(Into::into),
        );
        args.push(
            std::env::temp_dir()
                .join(format!("odocal-replay-nees-{}", std::process::id()))
                .into_os_string(),
        );
        square_rows.extend(json_rows(&sim().args(&args).output().unwrap()));
    }
    let (nees, n) = mean_nees(&square_rows, "exact", "square");
    assert!(
        n == 24 && nees > 1.0 && nees < 4.0,
        "squares: mean NEES {nees} of {n}"
    );
}
