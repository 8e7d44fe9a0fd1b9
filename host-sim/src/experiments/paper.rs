//! The paper's experiment (`host-sim paper`): the simulation of Lee, Jung & Chung 2011 §3 in an ideal kinematic mode.
//!
//! Legs and turns are commanded as wheel pulse counts computed from the robot's belief (the
//! nominal geometry), the true end pose is the exact-arc integration of the same pulses with the
//! true geometry, and there are no motor dynamics, slip or noise. For each side `L` it drives one
//! CW and one CCW square, calibrates with every method, and re-drives the squares with the
//! corrected geometry to report the remaining `E_max`.

use clap::ValueEnum;
use odocal::calibration::synth::{end_poses, square_knots};
use odocal::calibration::{Method, RunObservation, calibrate};
use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;
use odocal::motion::run::{Direction, Measurement, PathKind};

/// Output format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// Aligned text table.
    Text,
    /// One JSON object per line.
    Json,
}

/// How the true wheel diameters follow from `E_d`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum TruthModel {
    /// Mean diameter nominal: `D_R = 2D/(1 + 1/E_d)`, `D_L = 2D/(1 + E_d)` (odocal's default model).
    Mean,
    /// Left wheel nominal, `D_R = E_d·D` (the model of the paper's derivation, eq. 6 and 9).
    Right,
}

/// The true geometry for `E_b`, `E_d` under `model`.
pub fn true_geometry(nominal: &Geometry, eb: f64, ed: f64, model: TruthModel) -> Geometry {
    match model {
        TruthModel::Mean => nominal.with_factors(ed, eb, 1.0),
        TruthModel::Right => Geometry {
            diameter_right_m: nominal.diameter_right_m * ed,
            wheelbase_m: nominal.wheelbase_m * eb,
            ..*nominal
        },
    }
}

/// One ideal square: knots, odometry end pose (belief) and true end pose.
pub struct IdealRun {
    /// Path.
    pub path: PathKind,
    /// Geometry driven with.
    pub belief: Geometry,
    /// Knots.
    pub knots: Vec<WheelTicks>,
    /// Odometry end pose.
    pub odometry_end: PoseF64,
    /// True end pose.
    pub measured: Measurement,
}

impl IdealRun {
    /// Drives one square.
    pub fn square(belief: &Geometry, truth: &Geometry, direction: Direction, side_m: f64) -> Self {
        let knots = square_knots(belief, direction, side_m).to_vec();
        let (odometry_end, measured) = end_poses(belief, truth, &knots);
        IdealRun {
            path: PathKind::Square { direction, side_m },
            belief: *belief,
            knots,
            odometry_end,
            measured,
        }
    }

    /// Borrows it as a calibration input.
    pub fn observation(&self) -> RunObservation<'_> {
        RunObservation {
            path: self.path,
            geometry: self.belief,
            knots: &self.knots,
            odometry_end: self.odometry_end,
            measured: self.measured,
            truth_path: &[],
        }
    }

    /// End error `true − odometry` (x, y).
    pub fn error(&self) -> (f64, f64) {
        (
            self.measured.x_m - self.odometry_end.x_m,
            self.measured.y_m - self.odometry_end.y_m,
        )
    }
}

/// `E_max` of one ideal CW and one ideal CCW square driven with `belief`.
pub fn e_max(belief: &Geometry, truth: &Geometry, side_m: f64) -> f64 {
    [Direction::Cw, Direction::Ccw]
        .iter()
        .map(|&d| {
            let (x, y) = IdealRun::square(belief, truth, d, side_m).error();
            x.hypot(y)
        })
        .fold(0.0, f64::max)
}

/// One output row: one side, one method.
pub struct Row {
    /// Square side, m.
    pub side: f64,
    /// The calibration method.
    pub method: Method,
    /// End errors (true − odometry) of the CW and CCW square: x, y, x, y, m.
    pub cg: [f64; 4],
    /// E_b, E_d and the `E_max` after re-driving with the corrected geometry (m), or the error.
    pub result: Result<(f64, f64, f64), String>,
    /// True E_b and E_d.
    pub truth: (f64, f64),
}

impl Row {
    /// The row as one JSON object.
    pub fn json(&self) -> String {
        let [xc, yc, xa, ya] = self.cg;
        let num = |v: f64| {
            if v.is_finite() {
                format!("{v:e}")
            } else {
                "null".into()
            }
        };
        let (eb, ed, emax, err) = match &self.result {
            Ok((eb, ed, emax)) => (*eb, *ed, *emax, None),
            Err(e) => (f64::NAN, f64::NAN, f64::NAN, Some(e.clone())),
        };
        let mut s = format!(
            "{{\"L\":{},\"method\":\"{}\",\"x_cw\":{},\"y_cw\":{},\"x_ccw\":{},\"y_ccw\":{},\
             \"E_b\":{},\"E_d\":{},\"E_b_err\":{},\"E_d_err\":{},\"E_max_after\":{}",
            self.side,
            self.method,
            num(xc),
            num(yc),
            num(xa),
            num(ya),
            num(eb),
            num(ed),
            num(eb / self.truth.0 - 1.0),
            num(ed / self.truth.1 - 1.0),
            num(emax)
        );
        if let Some(e) = err {
            s.push_str(&format!(",\"error\":\"{e}\""));
        }
        s.push('}');
        s
    }
}

/// The experiment's rows: for every side in `sides`, the CW and CCW square of the nominal robot
/// believing `nominal` with the true geometry `truth`, calibrated with every method.
///
/// # Errors
/// An invalid side.
pub fn rows(nominal: &Geometry, truth: &Geometry, sides: &[f64]) -> Result<Vec<Row>, String> {
    let t_eb = truth.wheelbase_m / nominal.wheelbase_m;
    let t_ed = truth.diameter_ratio();
    let mut rows = Vec::new();
    for &side in sides {
        if !(side.is_finite() && side > 0.0) {
            return Err(format!("invalid side {side}"));
        }
        let runs = [
            IdealRun::square(nominal, truth, Direction::Cw, side),
            IdealRun::square(nominal, truth, Direction::Ccw, side),
        ];
        let obs: Vec<_> = runs.iter().map(IdealRun::observation).collect();
        let (xc, yc) = runs[0].error();
        let (xa, ya) = runs[1].error();
        for method in Method::ALL {
            let result = calibrate(&obs, nominal, method)
                .map(|c| (c.e_b, c.e_d, e_max(&c.geometry, truth, side)))
                .map_err(|e| e.to_string());
            rows.push(Row {
                side,
                method,
                cg: [xc, yc, xa, ya],
                result,
                truth: (t_eb, t_ed),
            });
        }
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_has_exactly_the_issue_keys() {
        let row = Row {
            side: 2.0,
            method: Method::LeeX,
            cg: [0.1, 0.2, 0.3, 0.4],
            result: Ok((1.01, 0.995, 0.001)),
            truth: (1.01, 0.995),
        };
        let json = row.json();
        let keys: Vec<&str> = json
            .trim_matches(|c| c == '{' || c == '}')
            .split(',')
            .map(|kv| kv.split(':').next().unwrap().trim_matches('"'))
            .collect();
        assert_eq!(
            keys,
            [
                "L",
                "method",
                "x_cw",
                "y_cw",
                "x_ccw",
                "y_ccw",
                "E_b",
                "E_d",
                "E_b_err",
                "E_d_err",
                "E_max_after"
            ]
        );
        assert!(json.contains("\"method\":\"lee-x\""));
    }
}
