//! Reader for OptiOdom square-path sessions (`<id>_metadata.csv` + `<id>_run-NN.csv`).
//!
//! Each run row is `time_s, x_gt_m, y_gt_m, theta_gt_rad, ticks_right, ticks_left` per 50 ms
//! cycle; the ticks are per-cycle increments. The reader turns them into cumulative knots (one
//! knot per row) and expresses the last ground-truth pose in the frame of the first one (the
//! run's start frame: origin, heading +x). The first `N/2` runs are CW, the rest CCW.
//!
//! The encoder resolution `ngear · encRes` is not an integer (43.7 · 64 = 2796.8 ticks per wheel
//! revolution); [`Geometry::counts_per_rev`] is, so ticks and resolution are both multiplied by
//! the smallest power of ten that makes it one (here 10). Travel per tick is unchanged.

use std::fs;
use std::path::Path;

use odocal::calibration::RunObservation;
use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::{ArcModel, PoseF64};
use odocal::motion::run::{Direction, Measurement, PathKind};

/// One recorded run.
#[derive(Clone, Debug)]
pub struct OptiRun {
    /// Direction.
    pub direction: Direction,
    /// Cumulative (scaled) ticks, first `(0, 0)`.
    pub knots: Vec<WheelTicks>,
    /// Ground-truth end pose in the start frame.
    pub truth_end: PoseF64,
}

/// One session (one folder).
#[derive(Clone, Debug)]
pub struct Session {
    /// Session id (folder name).
    pub id: String,
    /// Nominal geometry of the session (its `Di`, `Li`, scaled resolution).
    pub nominal: Geometry,
    /// Factor applied to the raw ticks.
    pub tick_scale: i64,
    /// Square side, metres.
    pub side_m: f64,
    /// Runs in file order.
    pub runs: Vec<OptiRun>,
}

fn parse_f64(s: &str, what: &str, file: &Path) -> Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .map_err(|_| format!("{}: bad {what} {s:?}", file.display()))
}

/// Reads one session folder.
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
    let id = dir
        .file_name()
        .and_then(|s| s.to_str())
        .ok_or_else(|| format!("{}: not a session folder", dir.display()))?
        .to_string();
    let meta_path = dir.join(format!("{id}_metadata.csv"));
    let meta =
        fs::read_to_string(&meta_path).map_err(|e| format!("{}: {e}", meta_path.display()))?;
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
            .ok_or_else(|| format!("{}: no {key}", meta_path.display()))
    };
    let first = |key: &str| -> Result<f64, String> {
        let v = field(key)?;
        let s = v
            .first()
            .ok_or_else(|| format!("{}: empty {key}", meta_path.display()))?;
        parse_f64(s, key, &meta_path)
    };
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
    let n = first("N")? as usize;
    let side_m = first("L")?;
    let mut runs = Vec::with_capacity(n);
    for i in 0..n {
        let file = dir.join(format!("{id}_run-{:02}.csv", i + 1));
        let text = fs::read_to_string(&file).map_err(|e| format!("{}: {e}", file.display()))?;
        let mut knots = vec![WheelTicks::new(0, 0)];
        let mut start: Option<PoseF64> = None;
        let mut last = PoseF64::default();
        for (ln, line) in text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty())
        {
            let f: Vec<&str> = line.split(',').collect();
            if f.len() < 6 {
                return Err(format!("{}:{}: expected 6 fields", file.display(), ln + 1));
            }
            let v: Vec<f64> = f[..6]
                .iter()
                .map(|s| parse_f64(s, "value", &file))
                .collect::<Result<_, _>>()?;
            let pose = PoseF64::new(v[1], v[2], v[3]);
            if start.is_none() {
                start = Some(pose);
            }
            last = pose;
            let prev = *knots.last().unwrap_or(&WheelTicks::new(0, 0));
            let (dr, dl) = (v[4].round() as i64, v[5].round() as i64);
            if dr != 0 || dl != 0 {
                knots.push(WheelTicks::new(
                    prev.right + dr * tick_scale,
                    prev.left + dl * tick_scale,
                ));
            }
        }
        let start = start.ok_or_else(|| format!("{}: empty", file.display()))?;
        runs.push(OptiRun {
            direction: if i < n / 2 {
                Direction::Cw
            } else {
                Direction::Ccw
            },
            knots,
            truth_end: start.relative(&last),
        });
    }
    Ok(Session {
        id,
        nominal,
        tick_scale,
        side_m,
        runs,
    })
}

impl OptiRun {
    /// The run as a calibration input, driven with `belief` (odometry re-integrated with it).
    pub fn observation(&self, belief: &Geometry, side_m: f64) -> RunObservation<'_> {
        RunObservation {
            path: PathKind::Square {
                direction: self.direction,
                side_m,
            },
            geometry: *belief,
            knots: &self.knots,
            odometry_end: ArcModel::from_geometry(belief)
                .integrate(PoseF64::default(), &self.knots),
            measured: Measurement {
                x_m: self.truth_end.x_m,
                y_m: self.truth_end.y_m,
                theta_rad: Some(self.truth_end.theta_rad),
            },
            truth_path: &[],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_a_session_and_moves_truth_into_the_start_frame() {
        let dir = std::env::temp_dir().join(format!("odocal-optiodom-{}", std::process::id()));
        let dir = dir.join("1234");
        fs::create_dir_all(&dir).unwrap();
        fs::write(
            dir.join("1234_metadata.csv"),
            "type,diff,,\nngear,43.7,,\nencRes,64,,\nLi,0.2,,\nDi,0.084,0.083,\nN,2,,\nL,0.75,,\n",
        )
        .unwrap();
        // Start at (1, 2) heading +y; the robot ends 1 m ahead (world (1, 3)), heading −x.
        let run = "0,1,2,1.5707963267948966,0,0\n0.05,1,2.5,1.5707963267948966,3,4\n0.1,1,3,3.141592653589793,-2,5\n";
        fs::write(dir.join("1234_run-01.csv"), run).unwrap();
        fs::write(dir.join("1234_run-02.csv"), run).unwrap();
        let s = read_session(&dir).unwrap();
        fs::remove_dir_all(dir.parent().unwrap()).unwrap();
        assert_eq!(s.tick_scale, 10);
        assert_eq!(s.nominal.counts_per_rev, 27_968);
        assert_eq!(s.nominal.diameter_left_m, 0.083);
        assert_eq!(s.runs[0].direction, Direction::Cw);
        assert_eq!(s.runs[1].direction, Direction::Ccw);
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
    fn absent_folder_is_a_clear_error() {
        let err = read_session(Path::new("/nonexistent/optiodom/xyz")).unwrap_err();
        assert!(err.contains("does not exist"), "{err}");
    }
}
