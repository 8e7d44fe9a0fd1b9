//! The parameter sets `replay` evaluates and how each is calibrated: the library's methods by
//! name, `exact-ls` and `exact-path` (the exact fit by plain least squares, and to the ground
//! truth along every run's whole path), `exact-mocap` (the exact fit for end headings measured
//! by motion capture, the default), `nominal`, and an absolute `--geometry`; the fit options the
//! command line sets.

use odocal::calibration::{Calibration, ExactOptions, Method, ScaleFit, calibrate_with};
use odocal::kinematics::geometry::Geometry;

use crate::experiments::montecarlo::Rng;
use crate::sim::optiodom::{Kind, Session};

/// A parameter set name beyond the library's methods.
pub const EXACT_LS: &str = "exact-ls";
/// The exact fit along the ground-truth path.
pub const EXACT_PATH: &str = "exact-path";
/// The exact fit of logs whose end headings come from motion capture: the end heading weighted
/// by [`MOCAP_HEADING_WEIGHT`] times the run's length and an end offset per group of closed
/// paths (`ExactOptions::end_offset`). `replay`'s default; `exact` is the board's fit.
pub const EXACT_MOCAP: &str = "exact-mocap";
/// Heading weight `k` of [`EXACT_MOCAP`]: chosen by transfer (docs/calibration.md, *Transfer*,
/// *Heading weight and end offset*), the smallest `k` within 0.1 mm of the best mean final error on the other kinds
/// in both rows (from the 1.7 m squares 16.1, 16.0, 16.0, 16.0 mm at k = 2, 3, 4, 8; from every
/// other session 17.7, 17.5, 17.4, 17.4; and again with the campaign nearest in time, *The
/// campaign*: 16.08 / 16.26, 16.04 / 16.18, 16.03 / 16.15, 16.02 / 16.12 at k = 2, 3, 4, 8). A
/// motion-capture heading is good to about a milliradian;
/// an operator's is not, and the board keeps the library's `k` (1.5, chosen the same way with
/// the end poses measured as by hand; `exact` is the board's fit).
pub const MOCAP_HEADING_WEIGHT: f64 = 3.0;
/// The library options of [`EXACT_MOCAP`] (robust, the end offset, the heading at
/// [`MOCAP_HEADING_WEIGHT`] times the run's length).
pub fn mocap_options() -> ExactOptions {
    ExactOptions {
        heading_weight: MOCAP_HEADING_WEIGHT,
        ..ExactOptions::default()
    }
}

/// Whether `name` is one of the exact fits (the library's `exact` and replay's variants of it).
fn is_exact(name: &str) -> bool {
    [Method::Exact.as_str(), EXACT_LS, EXACT_PATH, EXACT_MOCAP].contains(&name)
}

/// The uncalibrated row.
pub const NOMINAL: &str = "nominal";
/// The `--geometry` row.
pub const GEOMETRY: &str = "geometry";

/// Every calibrated parameter set, in display order.
pub fn calibrated_methods() -> Vec<&'static str> {
    let mut v: Vec<&'static str> = Method::ALL.iter().map(|m| m.as_str()).collect();
    v.extend([EXACT_LS, EXACT_PATH, EXACT_MOCAP]);
    v
}

/// The name of the parameter set `replay` marks as its default: the exact fit for
/// motion-capture end poses ([`EXACT_MOCAP`]).
pub fn default_method() -> &'static str {
    EXACT_MOCAP
}

/// One parameter set to evaluate.
#[derive(Clone, Debug)]
pub struct ParamSet {
    /// `nominal`, `geometry` or a method name.
    pub method: String,
    /// Ids of the sessions it was calibrated on.
    pub calib_sessions: Vec<String>,
    /// The absolute geometry; `None` = each evaluated session's own nominal.
    pub geometry: Option<Geometry>,
    /// The calibration result, for calibrated sets.
    pub calibration: Option<Calibration>,
}

/// Which calibration runs let the exact fits fit the mean diameter `E_s`.
///
/// By default straight lines, or paths when every run is read along its path (`exact-path`,
/// and any exact fit of free paths alone): a line's end pose measures a distance directly, while a few
/// free paths among end-pose runs leave `E_s` tied to `E_b` (their turns fix the ratio) and let
/// it wander: from the four square sessions, the circles and the free paths, `E_s` = 0.9896 with
/// a 1σ of 0.016, where every shared session's straight legs measure 0.995–1.001, and the line
/// session it was then evaluated on lost 10.0 mm against 6.6 with `E_s` held (leave one session
/// out, docs/calibration.md, *Transfer*).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum ScaleRuns {
    /// Straight lines, or paths when every run is read along its path (the default).
    #[default]
    Lines,
    /// Lines and runs fitted along their paths (the library's `ScaleFit::Auto`).
    Paths,
    /// None: `E_s` stays at the driving scale.
    Never,
}

/// How the exact fits combine several calibration sessions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Pool {
    /// One fit of every session's runs together.
    #[default]
    Runs,
    /// Every session fitted alone, the factors combined over sessions by a random-effects mean
    /// ([`super::pooled`]).
    Sessions,
}

/// Noise added to the calibration runs' measured end poses: a measurement by hand in place of
/// motion capture (`--end-noise`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EndNoise {
    /// 1σ of x and of y, metres.
    pub position_m: f64,
    /// 1σ of the heading, radians.
    pub heading_rad: f64,
    /// Seed; a run's draw depends on it, its session and its index only, so a session is
    /// measured the same way in every calibration it is part of.
    pub seed: u64,
}

impl EndNoise {
    /// The draw for run `index` of session `id`: `(x, y, θ)`.
    fn draw(&self, id: &str, index: usize) -> [f64; 3] {
        let session = id.bytes().fold(0xCBF2_9CE4_8422_2325u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x100_0000_01B3)
        });
        let mut rng = Rng::new(self.seed ^ session ^ (index as u64).wrapping_mul(0x9E37_79B9));
        [
            self.position_m * rng.normal(),
            self.position_m * rng.normal(),
            self.heading_rad * rng.normal(),
        ]
    }
}

/// Options of the exact fits.
#[derive(Clone, Copy, Debug)]
pub struct FitOptions {
    /// Use ground-truth headings.
    pub heading: bool,
    /// Always fit E_s.
    pub fit_scale: bool,
    /// Which runs let the exact fits fit `E_s` (unless `fit_scale`).
    pub scale_from: ScaleRuns,
    /// How several calibration sessions are combined.
    pub pool: Pool,
    /// Heading residual length scale.
    pub heading_length_m: Option<f64>,
    /// Multiplier of each end-pose run's length in its heading residual's length scale (`None`:
    /// each method's own, [`MOCAP_HEADING_WEIGHT`] for [`EXACT_MOCAP`], the library's otherwise).
    pub heading_weight: Option<f64>,
    /// Calibrate against the ground truth as recorded (not turned by its heading offset).
    pub recorded_truth: bool,
    /// Calibrate from each run's first knot, not from its anchor.
    pub from_start: bool,
    /// Weight the residual channels of the robust fit by their own scatter (default: the
    /// library's default, by the run's length a priori).
    pub channel_weights: bool,
    /// Give each run's end-heading row its own robust weight.
    pub heading_apart: bool,
    /// Fit an end offset per group of closed paths.
    pub end_offset: bool,
    /// Noise added to the calibration runs' measured end poses (all methods).
    pub end_noise: Option<EndNoise>,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            heading: true,
            fit_scale: false,
            scale_from: ScaleRuns::default(),
            pool: Pool::default(),
            heading_length_m: None,
            heading_weight: None,
            recorded_truth: false,
            from_start: true,
            channel_weights: ExactOptions::default().channel_weights,
            heading_apart: ExactOptions::default().heading_apart,
            end_offset: ExactOptions::default().end_offset,
            end_noise: None,
        }
    }
}

/// Calibrates `method` on `sessions` (relative to the first one's nominal geometry).
///
/// # Errors
/// The library's reason, or an unknown method name.
pub fn calibrate_method(
    sessions: &[Session],
    method: &str,
    fit: &FitOptions,
) -> Result<Calibration, String> {
    let first = sessions.first().ok_or("no calibration session")?;
    // A free path is fitted along its whole path by every exact fit: its end pose alone (a few
    // numbers from a path of metres that need not close) does not determine the factors.
    let along_path = |kind: Kind| method == EXACT_PATH || kind == Kind::Free;
    // The method's own options, which the command line's refine.
    let base = if method == EXACT_MOCAP {
        mocap_options()
    } else {
        ExactOptions::default()
    };
    let lib_method = match method {
        m if is_exact(m) => Method::Exact,
        m => Method::parse(m).ok_or_else(|| format!("unknown method {m:?}"))?,
    };
    let obs: Vec<_> = sessions
        .iter()
        .flat_map(|s| {
            s.runs.iter().enumerate().map(move |(i, r)| {
                let mut o = r.observation(
                    s.kind,
                    s.side_m,
                    &s.nominal,
                    along_path(s.kind),
                    fit.recorded_truth,
                    fit.from_start,
                );
                if !fit.heading {
                    o.measured.theta_rad = None;
                }
                if let (Some(noise), false) = (fit.end_noise, along_path(s.kind)) {
                    let [dx, dy, dt] = noise.draw(&s.id, i);
                    o.measured.x_m += dx;
                    o.measured.y_m += dy;
                    if let Some(t) = o.measured.theta_rad.as_mut() {
                        *t += dt;
                    }
                }
                o
            })
        })
        .collect();
    let has_lines = sessions.iter().any(|s| s.kind == Kind::Ivanjko);
    let all_paths = sessions.iter().all(|s| along_path(s.kind));
    let options = ExactOptions {
        scale: if fit.fit_scale {
            ScaleFit::Always
        } else {
            match fit.scale_from {
                ScaleRuns::Paths => ScaleFit::Auto,
                ScaleRuns::Never => ScaleFit::Never,
                ScaleRuns::Lines if !has_lines && !all_paths => ScaleFit::Never,
                ScaleRuns::Lines => ScaleFit::Auto,
            }
        },
        use_heading: fit.heading,
        heading_length_m: fit.heading_length_m,
        heading_weight: fit.heading_weight.unwrap_or(base.heading_weight),
        robust: method != EXACT_LS,
        channel_weights: method != EXACT_LS && fit.channel_weights,
        heading_apart: method != EXACT_LS && fit.heading_apart,
        end_offset: fit.end_offset,
        ..base
    };
    calibrate_with(&obs, &first.nominal, lib_method, &options).map_err(|e| e.to_string())
}

/// Parses `D_R,D_L,b` (metres) into a geometry with `counts_per_rev` of `like`.
///
/// # Errors
/// A message when the text is not three positive numbers or the geometry is invalid.
pub fn parse_geometry(text: &str, like: &Geometry) -> Result<Geometry, String> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("--geometry {text:?}: expected D_R,D_L,b in metres"))?;
    let [dr, dl, b] = v[..] else {
        return Err(format!(
            "--geometry {text:?}: expected three numbers D_R,D_L,b in metres"
        ));
    };
    let g = Geometry {
        diameter_right_m: dr,
        diameter_left_m: dl,
        wheelbase_m: b,
        counts_per_rev: like.counts_per_rev,
    };
    g.validate()
        .map_err(|e| format!("--geometry {text:?}: {e}"))?;
    Ok(g)
}

/// The calibrated parameter sets `names` on `calib` (errors on stderr, the set skipped).
pub fn calibrated_sets(calib: &[Session], names: &[&str], fit: &FitOptions) -> Vec<ParamSet> {
    let ids: Vec<String> = calib.iter().map(|s| s.id.clone()).collect();
    let mut sets = Vec::new();
    for name in names {
        if is_exact(name) && fit.pool == Pool::Sessions && calib.len() > 1 {
            match super::pooled::calibrate_pooled(calib, name, fit) {
                Ok(set) => sets.push(set),
                Err(e) => eprintln!("{name}: not calibrated on {}: {e}", ids.join(", ")),
            }
            continue;
        }
        match calibrate_method(calib, name, fit) {
            Ok(c) => sets.push(ParamSet {
                method: (*name).to_string(),
                calib_sessions: ids.clone(),
                geometry: Some(c.geometry),
                calibration: Some(c),
            }),
            Err(e) => eprintln!("{name}: not calibrated on {}: {e}", ids.join(", ")),
        }
    }
    sets
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geometry_text_is_checked() {
        let like = Geometry::PAPER_NOMINAL;
        let g = parse_geometry("0.084, 0.0841,0.2", &like).unwrap();
        assert_eq!(g.diameter_left_m, 0.0841);
        assert_eq!(g.counts_per_rev, like.counts_per_rev);
        for bad in [
            "0.084,0.084",
            "a,b,c",
            "0.084,-0.084,0.2",
            "0.084,0.084,0.2,1",
        ] {
            assert!(parse_geometry(bad, &like).is_err(), "{bad}");
        }
    }
}
