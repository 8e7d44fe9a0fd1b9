//! SVG figures (plotters, no system fonts needed): trajectories, end-pose clouds, error growth,
//! parameter error against track size.

use std::path::Path;

use plotters::prelude::*;

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// A polyline.
    Line,
    /// A dashed-looking thin polyline (drawn lighter), for "belief" paths.
    ThinLine,
    /// Markers only.
    Points,
}

/// One named series of `(x, y)` points.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// The points.
    pub points: Vec<(f64, f64)>,
    /// How to draw it.
    pub style: Style,
    /// Palette index (same index, same colour across figures).
    pub color: usize,
}

impl Series {
    /// A series.
    pub fn new(
        label: impl Into<String>,
        points: Vec<(f64, f64)>,
        style: Style,
        color: usize,
    ) -> Self {
        Series {
            label: label.into(),
            points,
            style,
            color,
        }
    }
}

/// A figure: axes, scales and series.
#[derive(Clone, Debug, Default)]
pub struct Figure {
    /// Title above the plot.
    pub title: String,
    /// x axis label.
    pub x_label: String,
    /// y axis label.
    pub y_label: String,
    /// Same scale on both axes (paths in the plane).
    pub equal_aspect: bool,
    /// Logarithmic x axis.
    pub log_x: bool,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// The data.
    pub series: Vec<Series>,
}

const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

fn color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// Data range with a margin; equal-aspect figures get a square window.
fn ranges(fig: &Figure) -> ((f64, f64), (f64, f64)) {
    let pts = fig.series.iter().flat_map(|s| s.points.iter().copied());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in pts.filter(|(x, y)| x.is_finite() && y.is_finite()) {
        if (fig.log_x && x <= 0.0) || (fig.log_y && y <= 0.0) {
            continue;
        }
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x0 > x1 {
        return ((0.0, 1.0), (0.0, 1.0));
    }
    let pad = |a: f64, b: f64, log: bool| {
        if log {
            (a / 1.5, b * 1.5)
        } else {
            let m = ((b - a) * 0.08).max(1e-9);
            (a - m, b + m)
        }
    };
    let (mut xr, mut yr) = (pad(x0, x1, fig.log_x), pad(y0, y1, fig.log_y));
    if fig.equal_aspect {
        let (cx, cy) = (0.5 * (xr.0 + xr.1), 0.5 * (yr.0 + yr.1));
        let half = 0.5 * (xr.1 - xr.0).max(yr.1 - yr.0);
        xr = (cx - half, cx + half);
        yr = (cy - half, cy + half);
    }
    (xr, yr)
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    fig: &Figure,
) -> Result<(), Box<dyn std::error::Error>>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let ((x0, x1), (y0, y1)) = ranges(fig);
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(&fig.title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70);
    macro_rules! body {
        ($chart:expr) => {{
            let mut chart = $chart;
            chart
                .configure_mesh()
                .x_desc(fig.x_label.as_str())
                .y_desc(fig.y_label.as_str())
                .draw()?;
            for s in &fig.series {
                let c = color(s.color);
                let pts = s
                    .points
                    .iter()
                    .copied()
                    .filter(|(x, y)| x.is_finite() && y.is_finite());
                // A series with an empty label gets no legend entry (e.g. the 2nd..nth run
                // of a group that shares one label).
                let labelled = !s.label.is_empty();
                match s.style {
                    Style::Line => {
                        let a = chart.draw_series(LineSeries::new(pts, c.stroke_width(2)))?;
                        if labelled {
                            a.label(s.label.as_str()).legend(move |(x, y)| {
                                PathElement::new([(x, y), (x + 16, y)], c.stroke_width(2))
                            });
                        }
                    }
                    Style::ThinLine => {
                        let a =
                            chart.draw_series(LineSeries::new(pts, c.mix(0.6).stroke_width(1)))?;
                        if labelled {
                            a.label(s.label.as_str()).legend(move |(x, y)| {
                                PathElement::new([(x, y), (x + 16, y)], c.mix(0.6))
                            });
                        }
                    }
                    Style::Points => {
                        let a = chart.draw_series(pts.map(|p| Circle::new(p, 3, c.filled())))?;
                        if labelled {
                            a.label(s.label.as_str())
                                .legend(move |(x, y)| Circle::new((x + 8, y), 3, c.filled()));
                        }
                    }
                }
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()?;
        }};
    }
    match (fig.log_x, fig.log_y) {
        (false, false) => body!(builder.build_cartesian_2d(x0..x1, y0..y1)?),
        (true, false) => body!(builder.build_cartesian_2d((x0..x1).log_scale(), y0..y1)?),
        (false, true) => body!(builder.build_cartesian_2d(x0..x1, (y0..y1).log_scale())?),
        (true, true) => {
            body!(builder.build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?)
        }
    }
    root.present()?;
    Ok(())
}

/// Writes `fig` as an SVG file (800 × 700 px for planar paths, 900 × 600 otherwise), creating
/// its folder if needed.
///
/// # Errors
/// File or drawing errors, naming the file.
pub fn write_svg(path: &Path, fig: &Figure) -> Result<(), Box<dyn std::error::Error>> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    draw_svg(path, fig).map_err(|e| format!("{}: {e}", path.display()).into())
}

fn draw_svg(path: &Path, fig: &Figure) -> Result<(), Box<dyn std::error::Error>> {
    let size = if fig.equal_aspect {
        (800, 760)
    } else {
        (900, 600)
    };
    let root = SVGBackend::new(path, size).into_drawing_area();
    draw(root, fig)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_an_svg_with_every_series() {
        let dir = std::env::temp_dir().join(format!("odocal-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.svg");
        let fig = Figure {
            title: "square".into(),
            x_label: "x [m]".into(),
            y_label: "y [m]".into(),
            equal_aspect: true,
            series: vec![
                Series::new(
                    "true",
                    vec![(0.0, 0.0), (1.0, 0.0), (1.0, -1.0)],
                    Style::Line,
                    0,
                ),
                Series::new("ends", vec![(0.01, 0.02)], Style::Points, 1),
            ],
            ..Figure::default()
        };
        write_svg(&path, &fig).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        // A folder that does not exist yet is made.
        let nested = dir.join("new").join("t.svg");
        write_svg(&nested, &fig).unwrap();
        assert!(nested.exists());
        assert!(svg.contains("<svg") && svg.contains("square") && svg.contains("ends"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
