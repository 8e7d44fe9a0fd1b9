//! Reading one OptiOdom session folder: its metadata (`<id>_metadata.csv`: kinematics type,
//! gear and encoder resolution, wheel diameters `Di`, wheelbase `Li`, run count `N`, square side
//! `L`), its run files in order, and the checks that need a whole run or session: the turn
//! direction of a closed run, right and left tick columns swapped, and a square side not in
//! metres. The session's heading offset and each run's anchor are set once all runs are read.

use std::f64::consts::TAU;
use std::fs;
use std::path::Path;

use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;
use odocal::motion::run::Direction;

use super::heading_offset::{align_truth, truth_heading_offset};
use super::run::{OptiRun, wheel_travel};
use super::run_file::{TruthGaps, number_hint, read_run};
use super::{Kind, Session};

fn parse_f64(s: &str, what: &str, file: &Path) -> Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| format!("{}: bad {what} {s:?}{}", file.display(), number_hint(s, s)))
}

/// The error for a session file that cannot be read, with how the files must be named when it is
/// absent: `<folder name>_metadata.csv` and `<folder name>_run-01.csv` … (two digits), and the
/// metadata file the folder holds instead, if any.
fn unreadable(
    path: &Path,
    e: &std::io::Error,
    dir: &Path,
    id: &str,
    runs: Option<usize>,
) -> String {
    let mut msg = format!("{}: {e}", path.display());
    if e.kind() != std::io::ErrorKind::NotFound {
        return msg;
    }
    msg.push_str(&format!(
        " (the files of a session folder are named after it: {id}_metadata.csv, {id}_run-01.csv, {id}_run-02.csv, …"
    ));
    if let Some(n) = runs {
        msg.push_str(&format!(
            "; its metadata says N = {n}, so up to {id}_run-{n:02}.csv"
        ));
    }
    let other = fs::read_dir(dir).ok().and_then(|entries| {
        entries
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter(|name| name.ends_with("_metadata.csv"))
            .min()
    });
    if let Some(other) = other.filter(|o| *o != format!("{id}_metadata.csv")) {
        let other_id = other.trim_end_matches("_metadata.csv");
        msg.push_str(&format!(
            "; this folder holds {other}: name the folder {other_id}"
        ));
    }
    msg.push(')');
    msg
}

/// Reads one session folder; its kind is the parent folder's name.
///
/// # Errors
/// A message naming the folder or file when it is absent or malformed.
pub fn read_session(dir: &Path) -> Result<Session, String> {
    if !dir.is_dir() {
        return Err(format!(
            "OptiOdom session folder {} does not exist (expected e.g. ../shared/data/optiodom/diff/square/<id>)",
            dir.display()
        ));
    }
    let dir = &dir
        .canonicalize()
        .map_err(|e| format!("{}: {e}", dir.display()))?;
    let id = dir
        .file_name()
        .and_then(|s| s.to_str())
        .ok_or_else(|| format!("{}: not a session folder", dir.display()))?
        .to_string();
    let parent = dir
        .parent()
        .and_then(|p| p.file_name())
        .and_then(|s| s.to_str())
        .unwrap_or("");
    let kind = Kind::parse(parent).ok_or_else(|| {
        format!(
            "{}: the parent folder {parent:?} is not a session kind (square, circular, ivanjko, free)",
            dir.display()
        )
    })?;
    let meta_path = dir.join(format!("{id}_metadata.csv"));
    let meta =
        fs::read_to_string(&meta_path).map_err(|e| unreadable(&meta_path, &e, dir, &id, None))?;
    let separator_hint = number_hint("", &meta);
    let field = |key: &str| -> Result<Vec<String>, String> {
        meta.lines()
            .map(|l| l.split(',').map(str::trim).collect::<Vec<_>>())
            .find(|f| f.first() == Some(&key))
            .map(|f| {
                f[1..]
                    .iter()
                    .filter(|s| !s.is_empty())
                    .map(|s| s.to_string())
                    .collect()
            })
            .ok_or_else(|| format!("{}: no {key}{separator_hint}", meta_path.display()))
    };
    let first = |key: &str| -> Result<f64, String> {
        let v = field(key)?;
        let s = v
            .first()
            .ok_or_else(|| format!("{}: empty {key}", meta_path.display()))?;
        parse_f64(s, key, &meta_path)
    };
    // Omnidirectional and other robots' sessions have other columns and another kinematics.
    let kinematics = field("type").unwrap_or_default();
    if let Some(t) = kinematics.first().filter(|t| t.as_str() != "diff") {
        return Err(format!(
            "{}: type {t:?} is not a differential-drive session (type diff)",
            meta_path.display()
        ));
    }
    let resolution = first("ngear")? * first("encRes")?;
    let tick_scale = [1i64, 10, 100, 1000, 10_000]
        .into_iter()
        .find(|&k| {
            let v = resolution * k as f64;
            (v - v.round()).abs() < 1e-6 * v
        })
        .ok_or_else(|| {
            format!(
                "{}: resolution {resolution} is not decimal",
                meta_path.display()
            )
        })?;
    let counts = (resolution * tick_scale as f64).round();
    let di = field("Di")?;
    if di.len() < 2 {
        return Err(format!("{}: Di needs right and left", meta_path.display()));
    }
    let nominal = Geometry {
        diameter_right_m: parse_f64(&di[0], "Di", &meta_path)?,
        diameter_left_m: parse_f64(&di[1], "Di", &meta_path)?,
        wheelbase_m: first("Li")?,
        counts_per_rev: counts as u32,
    };
    nominal
        .validate()
        .map_err(|e| format!("{}: {e}", meta_path.display()))?;
    let n = first("N")?;
    if !(n >= 1.0 && n.fract() == 0.0) {
        return Err(format!(
            "{}: N must be a positive count",
            meta_path.display()
        ));
    }
    let n = n as usize;
    let side_m = if kind == Kind::Square {
        let l = first("L")?;
        if l <= 0.0 {
            return Err(format!("{}: L must be positive", meta_path.display()));
        }
        l
    } else {
        0.0
    };
    let mut runs = Vec::with_capacity(n);
    let mut truth_gaps = TruthGaps::default();
    for i in 0..n {
        let file = dir.join(format!("{id}_run-{:02}.csv", i + 1));
        let text =
            fs::read_to_string(&file).map_err(|e| unreadable(&file, &e, dir, &id, Some(n)))?;
        let (knots, truth) = read_run(&text, tick_scale, &nominal, &file, &mut truth_gaps)?;
        check_turn(&knots, &truth, &nominal, &file)?;
        let direction = matches!(kind, Kind::Square | Kind::Circular).then(|| {
            turn_direction(&knots, &nominal).unwrap_or(if i < n / 2 {
                Direction::Cw
            } else {
                Direction::Ccw
            })
        });
        runs.push(OptiRun::new(direction, knots, truth));
    }
    if kind == Kind::Square {
        check_side(side_m, &runs, &meta_path)?;
    }
    let truth_offset = truth_heading_offset(&runs);
    if let Some(o) = truth_offset {
        align_truth(&mut runs, o);
    }
    for r in &mut runs {
        r.set_anchor(&nominal);
    }
    Ok(Session {
        id,
        kind,
        nominal,
        tick_scale,
        side_m,
        runs,
        truth_offset,
        truth_gaps,
    })
}

/// Largest factor between the metadata's square side and the side the ground truth drove (a
/// quarter of a run's path length, the median over the runs): a side in centimetres or
/// millimetres is 100 or 1000 times off, a real square within a few per cent.
pub const SIDE_MISMATCH: f64 = 2.0;

/// Refuses a square session whose `L` is not the side its runs drove (e.g. given in
/// centimetres): the closed-form methods compute with it.
fn check_side(side_m: f64, runs: &[OptiRun], meta_path: &Path) -> Result<(), String> {
    let mut sides: Vec<f64> = runs.iter().map(|r| r.truth_length_m() / 4.0).collect();
    sides.sort_by(f64::total_cmp);
    let Some(&driven) = sides.get(sides.len() / 2) else {
        return Ok(());
    };
    if driven > 0.0 && (side_m / driven).max(driven / side_m) <= SIDE_MISMATCH {
        return Ok(());
    }
    Err(format!(
        "{}: L = {side_m} m, but the runs drive squares of about {driven:.3} m (a quarter of \
         the ground-truth path): L is the square's side in metres",
        meta_path.display()
    ))
}

/// The direction a closed run (square, circle) turned in, from its wheels: the odometry heading
/// turns by about −2π (CW) or +2π (CCW) over the run, far more than any calibration error changes;
/// `None` below half a turn, where the file order decides.
fn turn_direction(knots: &[WheelTicks], g: &Geometry) -> Option<Direction> {
    let turn = odometry_turn_rad(knots, g)?;
    (turn.abs() > std::f64::consts::PI).then_some(if turn < 0.0 {
        Direction::Cw
    } else {
        Direction::Ccw
    })
}

/// How far the wheels turn the robot over a run with `g` (odometry heading change, radians,
/// unwrapped); `None` without knots.
fn odometry_turn_rad(knots: &[WheelTicks], g: &Geometry) -> Option<f64> {
    let (right, left) = wheel_travel(*knots.last()? - *knots.first()?, g);
    Some((right - left) / g.wheelbase_m)
}

/// Smallest turn, radians, that both the odometry (with the session's belief) and the ground truth
/// must show over a run before turns of opposite sign refuse it: a quarter turn, far beyond what
/// any wheel or wheelbase error makes of a turn (in the shared sessions the two differ by at most
/// 0.25 rad over a run, two full circles), and below the half turns of Ivanjko's in-place turns.
pub const SWAP_MIN_TURN_RAD: f64 = std::f64::consts::FRAC_PI_2;

/// Refuses a run whose wheels turn it clearly the other way than its ground truth turns (both more
/// than [`SWAP_MIN_TURN_RAD`]): the right and left tick columns are swapped, or one encoder counts
/// backwards. The truth's turn is the sum of its row-to-row turns the short way round, whether
/// the file unwraps the heading or not.
fn check_turn(
    knots: &[WheelTicks],
    truth: &[PoseF64],
    g: &Geometry,
    file: &Path,
) -> Result<(), String> {
    let Some(odometry) = odometry_turn_rad(knots, g) else {
        return Ok(());
    };
    let truth_turn: f64 = truth
        .windows(2)
        .map(|w| {
            let t = w[1].theta_rad - w[0].theta_rad;
            t - TAU * (t / TAU).round()
        })
        .sum();
    if odometry.abs() > SWAP_MIN_TURN_RAD
        && truth_turn.abs() > SWAP_MIN_TURN_RAD
        && (odometry > 0.0) != (truth_turn > 0.0)
    {
        return Err(format!(
            "{}: the wheels turn the robot {odometry:+.2} rad over the run, the ground truth {truth_turn:+.2} rad, the other way: are the right and left tick columns swapped (the fifth field is the right wheel, the sixth the left), or does an encoder count backwards?",
            file.display()
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{assert_mentions, metadata, session_folder};
    use super::*;

    /// Reads a session folder made by [`session_folder`] with `runs` as its run files (run 1
    /// first), then removes it.
    fn read_folder(
        tag: &str,
        kind: &str,
        id: &str,
        metadata: &str,
        runs: &[&str],
    ) -> Result<Session, String> {
        let (root, dir) = session_folder(tag, kind, id, metadata);
        for (i, run) in runs.iter().enumerate() {
            fs::write(dir.join(format!("{id}_run-{:02}.csv", i + 1)), run).unwrap();
        }
        let r = read_session(&dir);
        fs::remove_dir_all(&root).unwrap();
        r
    }

    #[test]
    fn a_header_row_is_named() {
        let run = "t,x_gt_m,y_gt_m,theta_gt_rad,right,left\n0,1,2,0,0,0\n";
        let metadata = metadata("0.084,0.083", 1, "L,0.25,,\n");
        let e = read_folder("header", "square", "1234", &metadata, &[run])
            .map(|_| ())
            .unwrap_err();
        assert!(
            e.ends_with(
                "1234_run-01.csv:1: bad x \"x_gt_m\" (a header row? The format has none: every \
                 row holds t, x, y, theta, right ticks, left ticks)"
            ),
            "{e}"
        );
    }

    #[test]
    fn a_square_side_not_in_metres_is_refused() {
        // The runs drive 1 m (a square of 0.25 m); L typed in centimetres is refused, in
        // metres (within a factor of 2 of the driven side) accepted.
        for (l, ok) in [
            ("25", false),
            ("0.025", false),
            ("0.25", true),
            ("0.4", true),
        ] {
            let run = "0,1,2,1.5707963267948966,0,0\n0.05,1,2.5,1.5707963267948966,3,4\n0.1,1,3,1.5707963267948966,5,5\n";
            let metadata = metadata("0.084,0.083", 1, &format!("L,{l},,\n"));
            match (read_folder("side", "square", "1234", &metadata, &[run]), ok) {
                (Ok(s), true) => assert_eq!(s.side_m, l.parse::<f64>().unwrap()),
                (Err(e), false) => assert!(
                    e.ends_with(&format!(
                        "1234_metadata.csv: L = {l} m, but the runs drive squares of about \
                         0.250 m (a quarter of the ground-truth path): L is the square's side in \
                         metres"
                    )),
                    "{e}"
                ),
                (r, _) => panic!("L = {l}: {:?}", r.map(|s| s.side_m)),
            }
        }
    }

    #[test]
    fn reads_a_session_and_moves_truth_into_the_start_frame() {
        // Start at (1, 2) heading +y; the robot ends 1 m ahead (world (1, 3)), heading −x: a
        // path of 4 × 0.25 m.
        let run = "0,1,2,1.5707963267948966,0,0\n0.05,1,2.5,1.5707963267948966,3,4\n0.1,1,3,3.141592653589793,-2,5\n";
        let metadata = metadata("0.084,0.083", 2, "L,0.25,,\n");
        let s = read_folder("optiodom", "square", "1234", &metadata, &[run, run]).unwrap();
        assert_eq!(s.tick_scale, 10);
        assert_eq!(s.nominal.counts_per_rev, 27_968);
        assert_eq!(s.nominal.diameter_left_m, 0.083);
        assert_eq!(s.kind, Kind::Square);
        assert_eq!(s.runs[0].direction, Some(Direction::Cw));
        assert_eq!(s.runs[1].direction, Some(Direction::Ccw));
        assert_eq!(
            s.runs[0].knots,
            [
                WheelTicks::new(0, 0),
                WheelTicks::new(30, 40),
                WheelTicks::new(10, 90)
            ]
        );
        let e = s.runs[0].truth_end;
        // In the start frame: 1 m ahead along +x, turned +90°. Exact up to f64 rounding.
        assert!((e.x_m - 1.0).abs() < 1e-12 && e.y_m.abs() < 1e-12, "{e:?}");
        assert!((e.theta_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn a_quoted_decimal_comma_in_the_metadata_asks_for_a_decimal_point() {
        // The wheelbase written with a decimal comma, quoted.
        let metadata = metadata("0.084,0.084", 1, "").replace("Li,0.2", "Li,\"0,2\"");
        let err = read_folder("comma", "ivanjko", "66", &metadata, &[])
            .map(|_| ())
            .unwrap_err();
        assert_mentions(
            &err,
            &[
                "66_metadata.csv: bad Li \"\\\"0\"",
                "a decimal point is expected",
            ],
        );
    }

    #[test]
    fn a_renamed_session_folder_says_how_the_files_are_named() {
        let root = std::env::temp_dir().join(format!("odocal-renamed-{}", std::process::id()));
        let dir = root.join("square").join("mysession");
        fs::create_dir_all(&dir).unwrap();
        fs::write(dir.join("22_metadata.csv"), "type,diff\n").unwrap();
        let err = read_session(&dir).unwrap_err();
        // A run file named with one digit.
        let (root2, dir2) =
            session_folder("onedigit", "ivanjko", "23", &metadata("0.084,0.084", 2, ""));
        fs::write(dir2.join("23_run-1.csv"), "0,0,0,0,0,0\n").unwrap();
        let err2 = read_session(&dir2).unwrap_err();
        fs::remove_dir_all(&root).unwrap();
        fs::remove_dir_all(&root2).unwrap();
        assert_mentions(
            &err,
            &[
                "mysession_metadata.csv: ",
                "named after it: mysession_metadata.csv, mysession_run-01.csv",
                "this folder holds 22_metadata.csv: name the folder 22",
            ],
        );
        assert!(
            err2.contains("23_run-01.csv: ")
                && err2.contains("metadata says N = 2, so up to 23_run-02.csv")
                && !err2.contains("this folder holds"),
            "{err2}"
        );
    }

    #[test]
    fn a_run_turning_against_its_ground_truth_is_refused_as_swapped_columns() {
        let (root, dir) =
            session_folder("swapped", "circular", "89", &metadata("0.084,0.084", 2, ""));
        // A full turn in place to the left (CCW) in ten rows: each wheel rolls 666 raw ticks
        // per row, 2π·0.1 m in all, and the ground truth turns 2π, its heading written wrapped
        // into (−π, π]. Run 2 is run 1 with the tick columns swapped.
        let turn = |swap: bool| -> String {
            (0..=10)
                .map(|i| {
                    let k = if i == 0 { 0 } else { 666 };
                    let (r, l) = if swap { (-k, k) } else { (k, -k) };
                    let th = odocal::calibration::wrap_angle(f64::from(i) * TAU / 10.0);
                    format!("{},0,0,{th},{r},{l}\n", f64::from(i) * 0.05)
                })
                .collect()
        };
        fs::write(dir.join("89_run-01.csv"), turn(false)).unwrap();
        fs::write(dir.join("89_run-02.csv"), turn(true)).unwrap();
        let err = read_session(&dir).unwrap_err();
        // Unswapped, the session is read and both runs turned CCW.
        fs::write(dir.join("89_run-02.csv"), turn(false)).unwrap();
        let s = read_session(&dir).unwrap();
        fs::remove_dir_all(&root).unwrap();
        assert_mentions(
            &err,
            &[
                "89_run-02.csv: the wheels turn the robot -6.28 rad over the run, the ground truth +6.28 rad",
                "right and left tick columns swapped",
            ],
        );
        assert_eq!(s.runs[1].direction, Some(Direction::Ccw));
    }

    #[test]
    fn the_turn_direction_of_a_closed_run_is_read_from_its_wheels() {
        let (root, dir) =
            session_folder("turns", "circular", "88", &metadata("0.084,0.084", 3, ""));
        // Full turns in place: each wheel rolls π·b = 0.628 m = 2.38 wheel turns = 6,658 raw
        // ticks, in ten rows of ±666. The file order would make run 1 CW and runs 2–3 CCW; the
        // wheels turned run 1 CCW (right forwards) and run 2 CW. Run 3 turns a quarter turn
        // only, so the file order decides.
        let turn = |right: i32, rows: i32| -> String {
            (0..=rows)
                .map(|i| {
                    let k = if i == 0 { 0 } else { right };
                    format!("{},0,0,0,{k},{}\n", f64::from(i) * 0.05, -k)
                })
                .collect()
        };
        fs::write(dir.join("88_run-01.csv"), turn(666, 10)).unwrap();
        fs::write(dir.join("88_run-02.csv"), turn(-666, 10)).unwrap();
        fs::write(dir.join("88_run-03.csv"), turn(-666, 3)).unwrap();
        let s = read_session(&dir).unwrap();
        fs::remove_dir_all(&root).unwrap();
        let dirs: Vec<_> = s.runs.iter().map(|r| r.direction).collect();
        assert_eq!(
            dirs,
            [
                Some(Direction::Ccw),
                Some(Direction::Cw),
                Some(Direction::Ccw)
            ]
        );
    }

    #[test]
    fn a_session_of_another_kinematics_is_a_clear_error() {
        let metadata = metadata("0.084,0.084", 1, "L,1,,\n").replace("type,diff", "type,omni3");
        let err = read_folder("omni", "square", "99", &metadata, &[])
            .map(|_| ())
            .unwrap_err();
        assert!(
            err.contains("type \"omni3\" is not a differential-drive session"),
            "{err}"
        );
    }

    #[test]
    fn absent_folder_is_a_clear_error() {
        let err = read_session(Path::new("/nonexistent/optiodom/xyz")).unwrap_err();
        assert!(err.contains("does not exist"), "{err}");
    }
}
