//! Reading one run file (`<id>_run-NN.csv`): rows of `time_s, x_gt_m, y_gt_m, theta_gt_rad,
//! ticks_right, ticks_left`, the per-cycle ticks summed into cumulative knots and the ground
//! truth moved into the run's start frame. Rows whose ground truth the motion capture lost are
//! interpolated inside a run and cut at its ends ([`TruthGaps`]); missing rows, a time that runs
//! backwards, and encoder or motion-capture glitches are refused with their file and line.

use std::f64::consts::TAU;
use std::path::Path;

use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;

use super::run::wheel_travel;

/// A hint for a value `s` of `line` that is not a number, when the file looks written with another
/// convention: fields separated by semicolons or tabs, or a decimal comma in a quoted field.
pub(super) fn number_hint(s: &str, line: &str) -> &'static str {
    if line.contains(';') || line.contains('\t') {
        " (fields are separated by commas and decimals use a point, e.g. 0.05,0.0012,…)"
    } else if s.contains('"') {
        " (a decimal point is expected: 0.2, not \"0,2\")"
    } else {
        ""
    }
}

/// Largest tick count one row may hold (raw, before scaling): a 32-bit counter's range. Beyond it
/// a value is a glitch whatever the row interval; within it, scaled ticks and their sums stay far
/// inside `i64` (the speed check then refuses any that is too fast).
pub const MAX_ROW_TICKS: i64 = i32::MAX as i64;

/// Largest cumulative (scaled) tick count of a run: half the `i64` range, so that the difference
/// of any two knots is exact.
const MAX_RUN_TICKS: i64 = i64::MAX / 2;

/// One row of a run file: time, ground truth (`None` where the motion capture lost the robot: any
/// of its three fields empty or NaN), and the ticks of this cycle (whole numbers within
/// ±[`MAX_ROW_TICKS`]).
fn read_row(line: &str, at: &str) -> Result<(f64, Option<PoseF64>, [i64; 2]), String> {
    let f: Vec<&str> = line.split(',').map(str::trim).collect();
    if f.len() < 6 {
        return Err(format!(
            "{at}: expected 6 fields, found {}{}",
            f.len(),
            number_hint("", line)
        ));
    }
    let value = |s: &str, what: &str| {
        s.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{at}: bad {what} {s:?}{}", number_hint(s, line)))
    };
    let lost = |s: &str| s.is_empty() || s.eq_ignore_ascii_case("nan");
    let truth = if f[1..4].iter().any(|s| lost(s)) {
        None
    } else {
        Some(PoseF64::new(
            value(f[1], "x")?,
            value(f[2], "y")?,
            value(f[3], "heading")?,
        ))
    };
    let ticks = |s: &str, wheel: &str| -> Result<i64, String> {
        let v = value(s, &format!("tick count ({wheel})"))?;
        if v.abs() > MAX_ROW_TICKS as f64 {
            Err(format!(
                "{at}: tick count ({wheel}) {s:?} out of range (over ±{MAX_ROW_TICKS} in one row): an encoder glitch"
            ))
        } else if v.fract() != 0.0 {
            Err(format!(
                "{at}: bad tick count ({wheel}) {s:?}: not a whole number"
            ))
        } else {
            // A whole number within ±2³¹: exact as i64.
            Ok(v as i64)
        }
    };
    Ok((
        value(f[0], "time")?,
        truth,
        [ticks(f[4], "right")?, ticks(f[5], "left")?],
    ))
}

/// Fastest wheel or ground-truth motion a run may show between two rows, m/s: 40 times what the
/// shared sessions' robot reaches (0.26 m/s); beyond it a row is a glitch, not motion.
pub const MAX_ROW_SPEED_M_S: f64 = 10.0;

/// Largest step between two rows' times, in the run's median row intervals, before rows count
/// as missing (a logger's jitter stays well within it; the shared sessions' rows are 50 ms apart
/// to 1e-10 s).
pub const MAX_ROW_GAP: f64 = 5.0;

/// Refuses a run with rows missing (a time step over [`MAX_ROW_GAP`] row intervals: their ticks
/// are lost) or a time that runs backwards, and a run in which a wheel or the ground truth
/// moves faster than [`MAX_ROW_SPEED_M_S`] between two rows (an encoder or motion-capture glitch
/// would silently distort every result). The row interval is the run's median, so that a bad
/// time stamp does not hide a glitch or make one.
fn check_speeds(
    lines: &[usize],
    times: &[f64],
    world: &[Option<PoseF64>],
    knots: &[WheelTicks],
    g: &Geometry,
    file: &Path,
) -> Result<(), String> {
    let mut steps: Vec<f64> = times.windows(2).map(|t| t[1] - t[0]).collect();
    steps.sort_by(f64::total_cmp);
    let Some(&dt) = steps.get(steps.len() / 2).filter(|&&dt| dt > 0.0) else {
        return Ok(());
    };
    let at = |j: usize| format!("{}:{}", file.display(), lines[j]);
    // Each row holds its own cycle's ticks: rows missing from the file are ticks lost, and the
    // odometry of the run would be wrong from there on.
    for j in 1..times.len() {
        let step = times[j] - times[j - 1];
        if !(step >= 0.0 && step <= MAX_ROW_GAP * dt) {
            return Err(format!(
                "{}: the time goes from {:.3} s to {:.3} s (the rows are {dt:.3} s apart): {}",
                at(j),
                times[j - 1],
                times[j],
                if step > 0.0 {
                    "rows are missing, and with them their ticks"
                } else {
                    "the time runs backwards"
                }
            ));
        }
    }
    for j in 1..knots.len() {
        let (right, left) = wheel_travel(knots[j] - knots[j - 1], g);
        let wheel = right.abs().max(left.abs());
        if wheel > MAX_ROW_SPEED_M_S * dt {
            let hint = if looks_cumulative(&knots[..=j]) {
                " (are the tick columns cumulative counts? The reader expects each row to hold the ticks of its own cycle, the motion since the previous row)"
            } else {
                ""
            };
            return Err(format!(
                "{}: a wheel travels {wheel:.3} m in one row ({:.0} m/s, over {MAX_ROW_SPEED_M_S} m/s): an encoder glitch{hint}",
                at(j),
                wheel / dt
            ));
        }
    }
    let mut prev: Option<(usize, PoseF64)> = None;
    for (j, p) in world.iter().enumerate() {
        let Some(p) = *p else { continue };
        if let Some((i, q)) = prev {
            let moved = (p.x_m - q.x_m).hypot(p.y_m - q.y_m);
            if moved > MAX_ROW_SPEED_M_S * dt * (j - i) as f64 {
                return Err(format!(
                    "{}: the ground truth moves {moved:.3} m in {} row(s) (over {MAX_ROW_SPEED_M_S} m/s): a motion-capture glitch",
                    at(j),
                    j - i
                ));
            }
        }
        prev = Some((j, p));
    }
    Ok(())
}

/// Whether the per-row ticks of the knots `k` look like cumulative counts: a wheel's column never
/// turns back (per-row increments that only grow, or only shrink) over at least
/// [`CUMULATIVE_MIN_ROWS`] rows, changing in at least half of them. Per-cycle increments of a
/// driving robot go up and down with its speed from row to row.
fn looks_cumulative(k: &[WheelTicks]) -> bool {
    let steps: Vec<WheelTicks> = k.windows(2).map(|w| w[1] - w[0]).collect();
    if steps.len() < CUMULATIVE_MIN_ROWS {
        return false;
    }
    let monotone = |column: &dyn Fn(&WheelTicks) -> i64| {
        let changes: Vec<i64> = steps
            .windows(2)
            .map(|w| column(&w[1]) - column(&w[0]))
            .collect();
        let moved = changes.iter().filter(|&&c| c != 0).count();
        (changes.iter().all(|&c| c >= 0) || changes.iter().all(|&c| c <= 0))
            && 2 * moved >= changes.len()
    };
    monotone(&|t| t.right) || monotone(&|t| t.left)
}

/// Fewest rows before an encoder glitch for [`looks_cumulative`] to judge them.
const CUMULATIVE_MIN_ROWS: usize = 5;

/// Rows whose ground truth the motion capture lost, over a session's runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TruthGaps {
    /// Rows inside a run, filled by interpolating between the neighbouring rows in time.
    pub interpolated: usize,
    /// Rows before the first or after the last row with ground truth: the run is cut to the rows
    /// with ground truth at both ends (the ticks before its new start are motion before it).
    pub cut: usize,
}

/// The cumulative knots and the ground truth in the start frame of one run file (`text`), one of
/// each per row; rows without ground truth are counted in `gaps` (see [`TruthGaps`]).
pub(super) fn read_run(
    text: &str,
    tick_scale: i64,
    g: &Geometry,
    file: &Path,
    gaps: &mut TruthGaps,
) -> Result<(Vec<WheelTicks>, Vec<PoseF64>), String> {
    let mut lines = Vec::new();
    let mut times = Vec::new();
    let mut world = Vec::new();
    let mut knots = Vec::new();
    let mut total = WheelTicks::new(0, 0);
    for (ln, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let at = format!("{}:{}", file.display(), ln + 1);
        let (t, pose, [dr, dl]) = read_row(line, &at).map_err(|e| {
            // A first line of words is a header the format does not have.
            let words = line
                .split(',')
                .all(|f| f.trim().starts_with(char::is_alphabetic));
            if ln == 0 && words {
                format!(
                    "{e} (a header row? The format has none: every row holds t, x, y, theta, \
                     right ticks, left ticks)"
                )
            } else {
                e
            }
        })?;
        // The first row's ticks are the motion before the run started: not part of it.
        if !knots.is_empty() {
            let add = |sum: i64, d: i64| {
                d.checked_mul(tick_scale)
                    .and_then(|d| sum.checked_add(d))
                    .filter(|s| s.unsigned_abs() <= MAX_RUN_TICKS.unsigned_abs())
                    .ok_or_else(|| {
                        format!("{at}: the run's cumulative tick count is out of range (over ±{MAX_RUN_TICKS} scaled ticks)")
                    })
            };
            total = WheelTicks::new(add(total.right, dr)?, add(total.left, dl)?);
        }
        lines.push(ln + 1);
        times.push(t);
        world.push(pose);
        knots.push(total);
    }
    check_speeds(&lines, &times, &world, &knots, g, file)?;
    // The rows with ground truth; the run is cut to the first and last of them.
    let known: Vec<(usize, PoseF64)> = world
        .iter()
        .enumerate()
        .filter_map(|(j, p)| p.map(|p| (j, p)))
        .collect();
    if known.len() < 2 {
        return Err(format!(
            "{}: a run needs at least two rows with ground truth",
            file.display()
        ));
    }
    let ((first, start), (last, _)) = (known[0], known[known.len() - 1]);
    gaps.cut += world.len() - (last + 1 - first);
    let origin = knots[first];
    let knots: Vec<WheelTicks> = knots[first..=last].iter().map(|&k| k - origin).collect();
    // Rows between two with ground truth: interpolated in time between them.
    let mut filled = Vec::with_capacity(knots.len());
    filled.push(start);
    for pair in known.windows(2) {
        let ((i, a), (k, b)) = (pair[0], pair[1]);
        // The heading the short way round, whether the file unwraps it or not.
        let turn = b.theta_rad - a.theta_rad;
        let turn = turn - TAU * (turn / TAU).round();
        let span = times[k] - times[i];
        for j in i + 1..k {
            gaps.interpolated += 1;
            let f = if span > 0.0 {
                (times[j] - times[i]) / span
            } else {
                (j - i) as f64 / (k - i) as f64
            };
            filled.push(PoseF64::new(
                a.x_m + f * (b.x_m - a.x_m),
                a.y_m + f * (b.y_m - a.y_m),
                a.theta_rad + f * turn,
            ));
        }
        filled.push(b);
    }
    Ok((knots, filled.iter().map(|w| start.relative(w)).collect()))
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::assert_mentions;
    use super::*;

    #[test]
    fn motion_capture_dropouts_are_interpolated_inside_a_run_and_cut_at_its_ends() {
        let file = Path::new("77_run-01.csv");
        let g = optiodom_robot();
        // A line along +x at 0.1 m/s (5 mm per 50 ms row): the truth is lost in the first row,
        // in rows 3–4 (empty fields) and 6 (NaN x only), and in the last row.
        let lost = |i: i32| [0, 3, 4, 6, 9].contains(&i);
        let rows: String = (0..10)
            .map(|i| {
                let t = f64::from(i) * 0.05;
                if lost(i) {
                    let gap = if i == 6 { "NaN,0,0" } else { ",," };
                    format!("{t},{gap},10,10\n")
                } else {
                    format!("{t},{},0,0,10,10\n", f64::from(i) * 0.005)
                }
            })
            .collect();
        let mut gaps = TruthGaps::default();
        let (knots, truth) = read_run(&rows, 1, &g, file, &mut gaps).unwrap();
        assert_eq!(
            gaps,
            TruthGaps {
                interpolated: 3,
                cut: 2
            }
        );
        // The run starts at row 1: its ticks count from there, its truth is in that row's frame.
        assert_eq!(knots.len(), 8);
        assert_eq!(knots[0], WheelTicks::new(0, 0));
        assert_eq!(knots[7], WheelTicks::new(70, 70));
        // On a straight line at constant speed the interpolation is exact (to rounding).
        for (j, p) in truth.iter().enumerate() {
            assert!((p.x_m - j as f64 * 0.005).abs() < 1e-15, "{j}: {p:?}");
            assert!(p.y_m == 0.0 && p.theta_rad == 0.0, "{j}: {p:?}");
        }
        // A run with fewer than two rows of truth cannot be placed: a clear error.
        let err = read_run("0,,,,0,0\n0.05,1,0,0,3,3\n", 1, &g, file, &mut gaps).unwrap_err();
        assert!(err.contains("at least two rows with ground truth"), "{err}");
        // A value that is neither a number nor a dropout names its file, line and field.
        let err = read_run("0,0,0,0,0,0\n0.05,abc,0,0,3,3\n", 1, &g, file, &mut gaps).unwrap_err();
        assert!(err.contains("77_run-01.csv:2: bad x \"abc\""), "{err}");
        let err = read_run("0,0,0,0,0,0\n0.05,0,0,0,,3\n", 1, &g, file, &mut gaps).unwrap_err();
        assert!(err.contains(":2: bad tick count"), "{err}");
    }

    /// The shared sessions' robot with the reader's scaled resolution (27,968 counts per turn).
    fn optiodom_robot() -> Geometry {
        Geometry {
            diameter_right_m: 0.084,
            diameter_left_m: 0.084,
            wheelbase_m: 0.2,
            counts_per_rev: 27_968,
        }
    }

    /// The robot, a run file's name and an empty dropout count, for [`read_run`] tests.
    fn run_fixture() -> (Geometry, &'static Path, TruthGaps) {
        (
            optiodom_robot(),
            Path::new("5_run-01.csv"),
            TruthGaps::default(),
        )
    }

    /// Six rows at 0.1 m/s (5 mm and 53 raw ticks, 530 scaled at 9.4e-6 m each, per 50 ms row),
    /// the fourth replaced by `row3`.
    fn steady_run_with_row3(row3: &str) -> String {
        (0..6)
            .map(|i| {
                if i == 3 {
                    format!("{row3}\n")
                } else {
                    format!(
                        "{},{},0,0,53,53\n",
                        f64::from(i) * 0.05,
                        f64::from(i) * 0.005
                    )
                }
            })
            .collect()
    }

    #[test]
    fn missing_rows_and_a_backward_time_are_refused_with_their_line() {
        let (g, file, mut gaps) = run_fixture();
        let mut read = |row3: &str| read_run(&steady_run_with_row3(row3), 10, &g, file, &mut gaps);
        // Row 4's time 0.15 s: in step. 0.4 s: rows missing (their ticks with them), 0.1 s:
        // backwards. A repeated time or jitter (0.17 s) is read.
        assert!(read("0.15,0.015,0,0,53,53").is_ok());
        let err = read("0.4,0.015,0,0,53,53").unwrap_err();
        assert!(
            err.contains("5_run-01.csv:4: the time goes from 0.100 s to 0.400 s (the rows are 0.050 s apart): rows are missing, and with them their ticks"),
            "{err}"
        );
        let err = read("0.05,0.015,0,0,53,53").unwrap_err();
        assert!(
            err.contains("5_run-01.csv:4: the time goes from 0.100 s to 0.050 s"),
            "{err}"
        );
        assert!(err.ends_with("the time runs backwards"), "{err}");
        for t in ["0.1", "0.17"] {
            assert!(read(&format!("{t},0.015,0,0,53,53")).is_ok(), "{t}");
        }
    }

    #[test]
    fn encoder_and_motion_capture_glitches_are_refused_with_their_line() {
        let (g, file, mut gaps) = run_fixture();
        let run = steady_run_with_row3;
        assert!(read_run(&run("0.15,0.015,0,0,53,53"), 10, &g, file, &mut gaps).is_ok());
        // A counter glitch: 99,999,999 raw ticks in 50 ms is 9.4 km of wheel travel.
        let err =
            read_run(&run("0.15,0.015,0,0,99999999,53"), 10, &g, file, &mut gaps).unwrap_err();
        assert_mentions(&err, &["5_run-01.csv:4: a wheel travels", "encoder glitch"]);
        // 20 m/s is refused, 8 m/s is not (10 m/s: 0.5 m per row); the time column does not
        // matter (the run's median interval is used).
        let err = read_run(&run("0.15,0,0,0,10600,10600"), 10, &g, file, &mut gaps).unwrap_err();
        assert!(err.contains("encoder glitch"), "{err}");
        let fast = read_run(&run("0.15,0.015,0,0,4240,4240"), 10, &g, file, &mut gaps);
        assert!(fast.is_ok(), "{fast:?}");
        // The motion capture places the robot 1,000 km away for one row.
        let err = read_run(&run("0.15,1e6,0,0,53,53"), 10, &g, file, &mut gaps).unwrap_err();
        assert_mentions(
            &err,
            &[
                "5_run-01.csv:4: the ground truth moves",
                "motion-capture glitch",
            ],
        );
    }

    #[test]
    fn huge_or_fractional_tick_counts_are_refused_with_their_line_and_field() {
        let (g, file, mut gaps) = run_fixture();
        let run = |right: &str| steady_run_with_row3(&format!("0.15,0.015,0,0,{right},53"));
        // Values an i64 saturates at or a product with the scale overflows: refused as read, never
        // turned into a wrong travel (or an overflow).
        for v in [
            "99999999999999999999",
            "-99999999999999999999",
            "9223372036854775807",
            "-9223372036854775807",
            "1e18",
            "2147483648",
        ] {
            let err = read_run(&run(v), 10, &g, file, &mut gaps).unwrap_err();
            assert!(
                err.contains(&format!(
                    "5_run-01.csv:4: tick count (right) {v:?} out of range"
                )) && err.contains("encoder glitch"),
                "{v}: {err}"
            );
        }
        // Within ±2³¹ the speed check judges it; a whole number written with a point is one.
        let err = read_run(&run("2147483647"), 10, &g, file, &mut gaps).unwrap_err();
        assert!(err.contains("5_run-01.csv:4: a wheel travels"), "{err}");
        assert!(read_run(&run("53.0"), 10, &g, file, &mut gaps).is_ok());
        let err = read_run(&run("53.5"), 10, &g, file, &mut gaps).unwrap_err();
        assert!(
            err.contains("5_run-01.csv:4: bad tick count (right) \"53.5\": not a whole number"),
            "{err}"
        );
        // Rows each within range whose sum leaves the cumulative range (here at the largest
        // scale) are refused before any knot difference could wrap.
        let rows = 1 + (MAX_RUN_TICKS / (MAX_ROW_TICKS * 10_000)) as usize;
        let text: String = (0..=rows)
            .map(|i| format!("{i},0,0,0,0,{MAX_ROW_TICKS}\n"))
            .collect();
        let err = read_run(&text, 10_000, &g, file, &mut gaps).unwrap_err();
        assert!(
            err.contains(&format!(
                "5_run-01.csv:{}: the run's cumulative tick count is out of range",
                rows + 1
            )),
            "{err}"
        );
    }

    #[test]
    fn cumulative_ticks_and_other_separators_get_a_hint() {
        let (g, file, mut gaps) = run_fixture();
        // Cumulative counts of a robot at 0.1 m/s (53 raw ticks per row): at row 101 a row holds
        // 5,300 raw ticks, 0.5 m, over 10 m/s.
        let rows: String = (0..200)
            .map(|i| {
                let t = f64::from(i) * 0.05;
                format!("{t},{},0,0,{},{}\n", f64::from(i) * 0.005, 53 * i, 53 * i)
            })
            .collect();
        let err = read_run(&rows, 10, &g, file, &mut gaps).unwrap_err();
        assert_mentions(
            &err,
            &[
                "5_run-01.csv:101: a wheel travels",
                "are the tick columns cumulative counts?",
            ],
        );
        // A single glitch among per-row increments gets no such hint.
        let rows: String = (0..20)
            .map(|i| {
                let r = if i == 10 { 99_999 } else { 53 + i % 3 };
                format!(
                    "{},{},0,0,{r},53\n",
                    f64::from(i) * 0.05,
                    f64::from(i) * 0.005
                )
            })
            .collect();
        let err = read_run(&rows, 10, &g, file, &mut gaps).unwrap_err();
        assert!(
            err.contains("5_run-01.csv:11: a wheel travels") && !err.contains("cumulative"),
            "{err}"
        );
        // Semicolons between fields (and decimal commas).
        let err = read_run("0;0;0;0;0;0\n", 10, &g, file, &mut gaps).unwrap_err();
        assert_mentions(
            &err,
            &[
                "5_run-01.csv:1: expected 6 fields, found 1",
                "fields are separated by commas and decimals use a point",
            ],
        );
        let err = read_run("0;0,0012;0;0;0;0\n", 10, &g, file, &mut gaps).unwrap_err();
        assert!(err.contains("separated by commas"), "{err}");
        // A plain bad field gets no hint.
        let err = read_run("abc,0,0,0,0,0\n", 10, &g, file, &mut gaps).unwrap_err();
        assert!(err.ends_with("bad time \"abc\""), "{err}");
    }
}
