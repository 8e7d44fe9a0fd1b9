//! The session's SVG, written next to its log: left, every run's odometry path as the pose
//! stream showed it (in the run's start frame; CW runs red, CCW blue); right, the end clouds:
//! each run's end error `measured − odometry` with the geometry it was driven with (before,
//! open marks) and `measured − predicted` with the applied calibration (after, filled marks),
//! the prediction re-integrating the run's tick knots with the library's exact-arc model.

use std::fmt::Write as _;

use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::{ArcModel, PoseF64};
use odocal::motion::run::{Direction, PathKind, RunRecord};

/// One run for the plot.
pub struct PlotRun<'a> {
    /// The record (path, knots, odometry end, measurement).
    pub record: &'a RunRecord,
    /// Odometry poses from the stream, in the run's start frame (x, y).
    pub path: &'a [(f64, f64)],
}

const W: f64 = 900.0;
const H: f64 = 460.0;
const PANEL: f64 = 400.0;

struct Frame {
    left: f64,
    top: f64,
    min: (f64, f64),
    scale: f64,
}

impl Frame {
    fn new(left: f64, top: f64, points: &[(f64, f64)]) -> Frame {
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(x, y) in points {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        if x0 > x1 {
            (x0, x1, y0, y1) = (-1.0, 1.0, -1.0, 1.0);
        }
        let span = (x1 - x0).max(y1 - y0).max(1e-6) * 1.1;
        let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
        Frame {
            left,
            top,
            min: (cx - span / 2.0, cy - span / 2.0),
            scale: PANEL / span,
        }
    }
    fn at(&self, (x, y): (f64, f64)) -> (f64, f64) {
        (
            self.left + (x - self.min.0) * self.scale,
            self.top + PANEL - (y - self.min.1) * self.scale,
        )
    }

    /// Light grid lines at round values (1, 2 or 5 times a power of ten, three to eight per axis),
    /// labelled inside the panel's left and bottom edges, so that the plot can be read.
    fn grid(&self, s: &mut String) {
        let span = PANEL / self.scale;
        let raw = span / 4.0;
        let power = 10f64.powf(raw.log10().floor());
        let step = power
            * match raw / power {
                m if m < 1.5 => 1.0,
                m if m < 3.5 => 2.0,
                m if m < 7.5 => 5.0,
                _ => 10.0,
            };
        let decimals = (-step.log10().floor()).max(0.0) as usize;
        let (right, bottom) = (self.left + PANEL, self.top + PANEL);
        for axis in 0..2 {
            let min = if axis == 0 { self.min.0 } else { self.min.1 };
            let mut k = (min / step).ceil();
            while k * step <= min + span {
                let v = k * step;
                // `+ 0.0` turns −0 into 0 for the label.
                let label = format!("{:.decimals$}", v + 0.0);
                if axis == 0 {
                    let (x, _) = self.at((v, self.min.1));
                    let _ = writeln!(
                        s,
                        r##"<line x1="{x:.1}" y1="{}" x2="{x:.1}" y2="{bottom}" stroke="#eee"/><text x="{x:.1}" y="{}" font-size="10" fill="#666" text-anchor="middle">{label}</text>"##,
                        self.top,
                        bottom - 3.0
                    );
                } else {
                    let (_, y) = self.at((self.min.0, v));
                    let _ = writeln!(
                        s,
                        r##"<line x1="{}" y1="{y:.1}" x2="{right}" y2="{y:.1}" stroke="#eee"/><text x="{}" y="{:.1}" font-size="10" fill="#666">{label}</text>"##,
                        self.left,
                        self.left + 3.0,
                        y - 2.0
                    );
                }
                k += 1.0;
            }
        }
    }
}

fn colour(r: &RunRecord) -> &'static str {
    match r.path {
        PathKind::Square {
            direction: Direction::Cw,
            ..
        } => "#d62728",
        _ => "#1f77b4",
    }
}

/// The SVG text. `calibrated` is the applied geometry (no "after" cloud without one).
pub fn svg(runs: &[PlotRun<'_>], calibrated: Option<&Geometry>, title: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{W}" height="{H}" fill="white"/>"#);
    let _ = writeln!(s, r#"<text x="20" y="20" font-size="14">{title}</text>"#);

    let all: Vec<(f64, f64)> = runs.iter().flat_map(|r| r.path.iter().copied()).collect();
    let f = Frame::new(30.0, 40.0, &all);
    f.grid(&mut s);
    let _ = writeln!(
        s,
        r##"<rect x="30" y="40" width="{PANEL}" height="{PANEL}" fill="none" stroke="#999"/><text x="30" y="{}">odometry paths (pose stream), m; red CW, blue CCW</text>"##,
        40.0 + PANEL + 15.0
    );
    for r in runs {
        let pts: Vec<String> = r
            .path
            .iter()
            .map(|&p| {
                let (x, y) = f.at(p);
                format!("{x:.1},{y:.1}")
            })
            .collect();
        let _ = writeln!(
            s,
            r#"<polyline fill="none" stroke="{}" stroke-width="1" points="{}"/>"#,
            colour(r.record),
            pts.join(" ")
        );
    }

    // End errors in millimetres.
    let mut before = Vec::new();
    let mut after = Vec::new();
    for r in runs {
        let Some(m) = r.record.measured else { continue };
        let o = r.record.odometry_end;
        before.push((
            (m.x_m - o.x_m) * 1e3,
            (m.y_m - o.y_m) * 1e3,
            colour(r.record),
        ));
        if let Some(g) = calibrated {
            let p = ArcModel::from_geometry(g).integrate(PoseF64::default(), &r.record.knots);
            after.push((
                (m.x_m - p.x_m) * 1e3,
                (m.y_m - p.y_m) * 1e3,
                colour(r.record),
            ));
        }
    }
    let mut pts: Vec<(f64, f64)> = before.iter().chain(&after).map(|p| (p.0, p.1)).collect();
    pts.push((0.0, 0.0));
    let left = 30.0 + PANEL + 40.0;
    let e = Frame::new(left, 40.0, &pts);
    e.grid(&mut s);
    let _ = writeln!(
        s,
        r##"<rect x="{left}" y="40" width="{PANEL}" height="{PANEL}" fill="none" stroke="#999"/><text x="{left}" y="{}">end error, mm: open = measured - odometry, filled = after calibration</text>"##,
        40.0 + PANEL + 15.0
    );
    let (ox, oy) = e.at((0.0, 0.0));
    let _ = writeln!(
        s,
        r##"<line x1="{ox:.1}" y1="40" x2="{ox:.1}" y2="{}" stroke="#ccc"/><line x1="{left}" y1="{oy:.1}" x2="{}" y2="{oy:.1}" stroke="#ccc"/>"##,
        40.0 + PANEL,
        left + PANEL
    );
    for &(x, y, c) in &before {
        let (px, py) = e.at((x, y));
        let _ = writeln!(
            s,
            r#"<circle cx="{px:.1}" cy="{py:.1}" r="4" fill="none" stroke="{c}"/>"#
        );
    }
    for &(x, y, c) in &after {
        let (px, py) = e.at((x, y));
        let _ = writeln!(s, r#"<circle cx="{px:.1}" cy="{py:.1}" r="3" fill="{c}"/>"#);
    }
    s.push_str("</svg>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The labels of the grid lines, in drawing order (x axis, then y axis).
    fn labels(svg: &str) -> Vec<&str> {
        svg.split("fill=\"#666\"")
            .skip(1)
            .filter_map(|t| t.split('>').nth(1)?.split('<').next())
            .collect()
    }

    #[test]
    fn grid_lines_sit_at_round_values_across_the_panel() {
        // Points spanning 2 m by 1 m: the panel shows 2.2 m around (1, 0.5); steps of 0.5 m.
        let f = Frame::new(0.0, 0.0, &[(0.0, 0.0), (2.0, 1.0)]);
        let mut s = String::new();
        f.grid(&mut s);
        assert_eq!(
            labels(&s),
            [
                "0.0", "0.5", "1.0", "1.5", "2.0", "-0.5", "0.0", "0.5", "1.0", "1.5"
            ]
        );
        // Millimetres of end error from −3 to 12 (the panel −3.75 to 12.75): steps of 5, no
        // decimals.
        let e = Frame::new(0.0, 0.0, &[(-3.0, -3.0), (12.0, 12.0)]);
        let mut s = String::new();
        e.grid(&mut s);
        assert_eq!(labels(&s), ["0", "5", "10", "0", "5", "10"]);
    }
}
