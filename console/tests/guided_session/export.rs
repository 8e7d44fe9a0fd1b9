//! `guided_session`: the exports for a robot stack and the factory-default board's full procedure.

use super::*;

/// The flat `key: value` entries of a `diff_drive_controller` parameter file (comments and the
/// two header keys skipped; a `[a, b, …]` list kept as its text).
fn yaml_entries(yaml: &str) -> Vec<(String, String)> {
    yaml.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .filter_map(|l| {
            let (k, v) = l.split_once(':')?;
            let v = v.trim();
            (!v.is_empty()).then(|| (k.trim().to_string(), v.to_string()))
        })
        .collect()
}

fn yaml_number(entries: &[(String, String)], key: &str) -> f64 {
    entries
        .iter()
        .find(|(k, _)| k == key)
        .unwrap_or_else(|| panic!("no {key} in {entries:#?}"))
        .1
        .parse()
        .unwrap_or_else(|e| panic!("{key}: {e}"))
}

/// `odocal-console export LOG --format F -o OUT`: the file written.
fn export(log: &Path, format: &str, out: &Path) -> String {
    let status = Command::new(env!("CARGO_BIN_EXE_odocal-console"))
        .arg("export")
        .arg(log)
        .args(["--format", format, "-o"])
        .arg(out)
        .status()
        .unwrap();
    assert!(status.success(), "export {format} of {}", log.display());
    std::fs::read_to_string(out).unwrap()
}

/// The geometry the board applied, `(D_R, D_L, b)`: the `active` line of its last `params` reply.
fn applied_geometry(rx: &[String]) -> (f64, f64, f64) {
    let active = rx
        .iter()
        .rev()
        .find_map(|l| l.trim().strip_prefix("active "))
        .unwrap_or_else(|| panic!("no params reply in the log"));
    let value = |key: &str| -> f64 {
        active
            .split_whitespace()
            .find_map(|w| w.strip_prefix(key)?.strip_prefix('='))
            .unwrap()
            .parse()
            .unwrap()
    };
    let (d_r, d_l, b) = (value("d_right"), value("d_left"), value("wheelbase"));
    assert!((d_r / d_l - 0.995).abs() < 1e-5, "{active}");
    (d_r, d_l, b)
}

/// Checks that a `diff_drive_controller` YAML gives back `(D_R, D_L, b)` to 1e-9 m; its entries.
fn check_drop_in(yaml: &str, (d_r, d_l, b): (f64, f64, f64)) -> Vec<(String, String)> {
    let e = yaml_entries(yaml);
    let r = yaml_number(&e, "wheel_radius");
    let (sep, ml, mr) = (
        yaml_number(&e, "wheel_separation"),
        yaml_number(&e, "left_wheel_radius_multiplier"),
        yaml_number(&e, "right_wheel_radius_multiplier"),
    );
    assert!((sep - b).abs() <= 1e-9, "b {sep} vs {b}\n{yaml}");
    assert!(
        (2.0 * r * mr - d_r).abs() <= 1e-9,
        "D_R {} vs {d_r}\n{yaml}",
        2.0 * r * mr
    );
    assert!(
        (2.0 * r * ml - d_l).abs() <= 1e-9,
        "D_L {} vs {d_l}\n{yaml}",
        2.0 * r * ml
    );
    assert_eq!(yaml_number(&e, "wheel_separation_multiplier"), 1.0);
    e
}

/// A YAML list of numbers (`[1, 2.5, …]`).
fn number_list(text: &str) -> Vec<f64> {
    text.trim_matches(['[', ']'])
        .split(',')
        .map(|v| v.trim().parse().unwrap())
        .collect()
}

/// The URDF's joints sit at ±b/2, its wheels have the applied radii.
fn check_urdf(urdf: &str, (d_r, d_l, b): (f64, f64, f64)) {
    let attr = |name: &str| -> Vec<f64> {
        urdf.match_indices(&format!("{name}=\""))
            .map(|(i, m)| {
                let rest = &urdf[i + m.len()..];
                rest[..rest.find('"').unwrap()].to_string()
            })
            .map(|v| {
                v.split_whitespace()
                    .nth(if name == "xyz" { 1 } else { 0 })
                    .unwrap_or("0")
                    .parse()
                    .unwrap()
            })
            .collect()
    };
    let radii = attr("radius");
    assert!(
        (radii[0] - d_l / 2.0).abs() <= 1e-9 && (radii[1] - d_r / 2.0).abs() <= 1e-9,
        "{urdf}"
    );
    let y: Vec<f64> = attr("xyz").into_iter().filter(|v| *v != 0.0).collect();
    assert!(
        (y[0] - b / 2.0).abs() <= 1e-9 && (y[1] + b / 2.0).abs() <= 1e-9,
        "{urdf}"
    );
}

/// Drop-in: the controller's name, its wheels, and the twist covariance.
fn check_named_controller(log: &Path, geometry: (f64, f64, f64)) {
    let named = Command::new(env!("CARGO_BIN_EXE_odocal-console"))
        .arg("export")
        .arg(log)
        .args(["--controller", "base_controller"])
        .args([
            "--left-wheel",
            "wheel_l_joint",
            "--right-wheel",
            "wheel_r_joint",
        ])
        .output()
        .unwrap();
    assert!(named.status.success());
    let yaml = String::from_utf8(named.stdout).unwrap();
    assert!(
        yaml.contains("base_controller:\n  ros__parameters:\n"),
        "{yaml}"
    );
    let e = check_drop_in(&yaml, geometry);
    let value = |key: &str| &e.iter().find(|(k, _)| k == key).unwrap().1;
    assert_eq!(value("left_wheel_names"), "[\"wheel_l_joint\"]");
    assert_eq!(value("right_wheel_names"), "[\"wheel_r_joint\"]");
    let twist = number_list(value("twist_covariance_diagonal"));
    assert!(
        twist.len() == 6 && twist[0] > 0.0 && twist[5] > 0.0,
        "{yaml}"
    );
}

/// A log whose last `params` reply came before a `reset-params` the board accepted is refused,
/// naming the line.
fn check_stale_log_refused(log: &Path, dir: &Path) {
    let mut stale = std::fs::read_to_string(log).unwrap();
    let line = stale.lines().count() + 1;
    stale.push_str(
        "{\"kind\":\"tx\",\"line\":\"reset-params\",\"t\":0}\n\
         {\"kind\":\"rx\",\"line\":\"ok parameters reset to defaults (not saved; save to keep)\",\"t\":0}\n",
    );
    let stale_log = dir.join("stale.jsonl");
    std::fs::write(&stale_log, stale).unwrap();
    let refused = Command::new(env!("CARGO_BIN_EXE_odocal-console"))
        .arg("export")
        .arg(&stale_log)
        .output()
        .unwrap();
    let why = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success(), "a stale log exported");
    assert!(
        why.contains(&format!("stale.jsonl:{line}: `reset-params` came after")),
        "{why}"
    );
}

/// The ROS 2 export of a guided session's log: its `wheel_separation` and wheel radius
/// multipliers give back the geometry the board applied (its `params` after `apply`) to 1e-9 m,
/// read back from the YAML; the pose covariance is there, with the unobserved components large.
/// A plain terminal capture that holds only the board's lines (its `params` reply) exports the
/// same geometry.
#[test]
fn ros2_export() {
    let sim = Sim::start(&host_sim());
    let (mut tool, log) = tool_answering(&sim, "export", "0.5m\n1\n");
    let mut measured = 0;
    tool.converse(&sim, &mut measured, None);
    let (ok, text) = tool.finish();
    assert!(ok, "the session failed:\n{text}");
    assert!(
        text.contains("verified: params shows calibration exact"),
        "{text}"
    );
    let entries = json_lines(&log);
    let rx: Vec<String> = entries
        .iter()
        .filter(|v| v["kind"] == "rx")
        .map(|v| v["line"].as_str().unwrap().to_string())
        .collect();
    let geometry = applied_geometry(&rx);

    let dir = log.parent().unwrap();
    let yaml = export(&log, "ros2", &dir.join("diff_drive.yaml"));
    let e = check_drop_in(&yaml, geometry);
    assert!(yaml.starts_with("# odocal calibration `exact`"), "{yaml}");
    assert!(
        yaml.contains("diff_drive_controller:\n  ros__parameters:\n"),
        "{yaml}"
    );
    let cov = &e
        .iter()
        .find(|(k, _)| k == "pose_covariance_diagonal")
        .unwrap()
        .1;
    let cov = number_list(cov);
    assert_eq!(cov.len(), 6, "{yaml}");
    assert!(cov[0] > 0.0 && cov[1] > 0.0 && cov[5] > 0.0, "{yaml}");
    assert!(cov[2..5].iter().all(|&v| v >= 1e3), "{yaml}");

    // The board's lines alone, as a terminal program captures them (CR LF, echo on).
    let capture: String = std::iter::once("params".to_string())
        .chain(rx.iter().cloned())
        .map(|l| format!("{l}\r\n"))
        .collect();
    let capture_file = dir.join("terminal.log");
    std::fs::write(&capture_file, capture).unwrap();
    let yaml = export(&capture_file, "ros2", &dir.join("from-terminal.yaml"));
    check_drop_in(&yaml, geometry);

    check_urdf(&export(&log, "urdf", &dir.join("wheels.urdf")), geometry);
    // The JSON: the runs and the 1σ.
    let json: serde_json::Value =
        serde_json::from_str(&export(&log, "json", &dir.join("calibration.json"))).unwrap();
    assert_eq!(json["runs"].as_array().unwrap().len(), 2);
    assert!(json["sd"]["e_b"].as_f64().unwrap() >= 0.0);
    assert_eq!(json["method"], "exact");

    check_named_controller(&log, geometry);
    check_stale_log_refused(&log, dir);
}

/// The whole procedure on a factory-default board whose right motor is wired the other way
/// round, typed by the operator on stdin: the tool says the board holds the factory defaults,
/// takes the nominal geometry in the operator's units, runs the bring-up check (push, then
/// wheels up) and applies its proposal on a yes, checks again (`wiring ok`), identifies the
/// motors on the floor, drives 2 + 2 squares whose measurements are typed in millimetres (a
/// bare millimetre value is refused, the units named; `help` and an empty answer explain),
/// applies and saves only on a typed yes, drives the check square and ends
/// with the summary.
/// The whole procedure typed on a factory-default board whose right motor is wired the other
/// way round: the board, whether the tool ended well, its transcript (each answer after its
/// question), its log, and the poses measured.
pub(crate) fn factory_session(name: &str) -> (Sim, bool, String, PathBuf, usize) {
    let sim = Sim::start_with(&host_sim(), &["--fast", "--wiring", "right-motor-reversed"]);
    let dir = out_dir(name);
    let log = dir.join("session.jsonl");
    let mut tool = Tool::start(&["--port", &sim.pty, "--log", log.to_str().unwrap()]);
    let (mut measured, mut helped, mut bare, mut empty_apply) = (0, false, false, false);
    let mut questions = 0;
    while let Some(l) = tool.next() {
        let waiting = l.starts_with("? ") && l.trim_end().ends_with(':');
        if !waiting {
            continue;
        }
        // A question that keeps coming back would never end the session.
        questions += 1;
        assert!(questions < 200, "{}", tool.transcript.join("\n"));
        let q = &l[2..];
        let answer: String = if q.starts_with("Nominal geometry") {
            "e".into()
        } else if q.starts_with("Right wheel diameter") {
            "150mm".into()
        } else if q.starts_with("Wheelbase b") {
            "38.5 cm".into()
        } else if q.starts_with("Measured end pose of run") {
            if !helped {
                helped = true;
                "help".into()
            } else {
                let pose = sim.true_end(measured);
                let w: Vec<f64> = pose
                    .split_whitespace()
                    .map(|v| v.trim_end_matches(char::is_alphabetic).parse().unwrap())
                    .collect();
                if !bare && measured == 1 {
                    // Millimetres typed without their unit: refused, the units named.
                    bare = true;
                    format!("{:.1} {:.1}", w[0] * 1e3, w[1] * 1e3)
                } else {
                    measured += 1;
                    // The exact value in millimetres, the heading in degrees.
                    format!("{:.3}mm {:.3}mm {}deg", w[0] * 1e3, w[1] * 1e3, w[2])
                }
            }
        } else if q.starts_with("Square side L") {
            "1 m".into()
        } else if q.starts_with("Runs per direction") {
            "2".into()
        } else if q.starts_with("Apply exact") && !empty_apply {
            // An empty answer is no yes: asked again.
            empty_apply = true;
            String::new()
        } else if q.trim_end().ends_with("(y/n):") {
            "y".into()
        } else {
            // Every other question: its default (the setup steps on a factory board, Enter to
            // start, the recommended method, the check square).
            String::new()
        };
        tool.answer(&answer);
    }
    let (code, text, _) = tool.end();
    (sim, code == Some(0), text, log, measured)
}

#[test]
fn factory_default_board_full_procedure() {
    let (sim, ok, text, log, mut measured) = factory_session("factory");
    println!("{text}");
    assert!(ok, "the session failed:\n{text}");
    for expected in [
        "the board holds the factory defaults",
        "step: nominal geometry (factory default on the board",
        "  ok d_right = 0.150000000 m",
        "  ok wheelbase = 0.385000000 m",
        "  event bringup push: right encoder",
        "  event bringup propose: set motor_right_sign -1",
        "? Apply the proposed correction (set motor_right_sign -1)? (y/n):",
        "  ok motor_right_sign = -1",
        "  wiring ok",
        "  event identify done (floor): speed-loop tuning applied",
        "plan: 2 CW + 2 CCW squares of L = 1.000 m",
        "  Measure where the axle midpoint stopped",
        "verified: params shows calibration exact",
        "summary:",
        "  calibration: exact E_d=",
    ] {
        assert!(text.contains(expected), "no `{expected}` in:\n{text}");
    }
    // The bare millimetres: refused before anything is sent, the units named.
    let refused = text
        .lines()
        .find(|l| l.contains("has no unit") && l.contains("mm, cm or m"))
        .unwrap_or_else(|| panic!("no unit question:\n{text}"));
    assert!(refused.starts_with("  `"), "{refused}");
    // Apply asked twice (the empty answer is no yes), save once.
    assert_eq!(text.matches("? Apply exact").count(), 2, "{text}");
    assert!(text.contains("  ok saved"), "{text}");
    // The check square ends far closer than the runs did before.
    let check = text
        .lines()
        .find(|l| l.starts_with("check square ") && l.contains(": end error "))
        .unwrap_or_else(|| panic!("no check square:\n{text}"));
    let mm: Vec<f64> = check
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect();
    assert!(mm[0] * 5.0 < mm[1], "{check}");
    assert_eq!(measured, 5, "{text}");
    let entries = json_lines(&log);
    let sent: Vec<String> = entries
        .iter()
        .filter(|v| v["kind"] == "tx")
        .map(|v| v["line"].as_str().unwrap().to_string())
        .collect();
    for line in [
        "set d_right 0.15",
        "set wheelbase 0.385",
        "bringup push",
        "bringup",
        "set motor_right_sign -1",
        "identify floor",
        "save",
    ] {
        assert!(
            sent.iter().any(|l| l == line),
            "`{line}` not sent: {sent:#?}"
        );
    }
    // The measurements went to the board as typed, units included.
    assert!(
        sent.iter()
            .any(|l| l.starts_with("measure #") && l.contains("mm ") && l.ends_with("deg")),
        "{sent:#?}"
    );
    // Applied and saved only after the typed yes.
    let apply = sent.iter().position(|l| l.starts_with("apply ")).unwrap();
    let save = sent.iter().position(|l| l == "save").unwrap();
    assert!(apply < save, "{sent:#?}");

    // The same board again: it holds the setup and the calibration, so the setup steps default
    // to skipping; the operator keeps the calibration and only checks it (the board's runs from
    // before dropped, the default).
    let dir = out_dir("factory-again");
    let answers = dir.join("answers.txt");
    std::fs::write(&answers, "k\n\n\nc\n").unwrap();
    let log = dir.join("session.jsonl");
    let mut tool = Tool::start(&[
        "--port",
        &sim.pty,
        "--log",
        log.to_str().unwrap(),
        "--answers",
        answers.to_str().unwrap(),
        "--yes",
    ]);
    tool.converse(&sim, &mut measured, None);
    let (ok, text) = tool.finish();
    println!("{text}");
    assert!(ok, "the second session failed:\n{text}");
    for expected in [
        "the board holds: geometry factory default, wiring corrected, motor tuning identified or \
         entered, calibration applied",
        // (An empty answer from the file takes the default.)
        "? Bring-up check (r: run it, s: skip it) [s]: \n",
        "? Motor identification (f: floor, l: lifted, s: skip) [s]: \n",
        "? The board holds a calibration (n: new runs, c: check it only) [n]: c",
        "the board holds 4 run(s) from before this session",
        "  ok dropped all 4 runs",
        "check square cw: end error ",
        "  calibration: exact E_d=",
    ] {
        assert!(text.contains(expected), "no `{expected}` in:\n{text}");
    }
    assert!(!text.contains("? Square side L"), "{text}");
    assert_eq!(measured, 6, "{text}");
    let sent: Vec<String> = json_lines(&log)
        .iter()
        .filter(|v| v["kind"] == "tx")
        .map(|v| v["line"].as_str().unwrap().to_string())
        .collect();
    assert!(
        !sent.iter().any(|l| l.starts_with("apply") || l == "save"),
        "{sent:#?}"
    );
}
