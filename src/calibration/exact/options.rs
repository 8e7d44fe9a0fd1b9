//! What the exact fit is asked for: when `E_s` is fitted, whether headings count, and the robust
//! fit's switches and measurement resolutions.

/// When the mean diameter `E_s` is fitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ScaleFit {
    /// Only when a straight-line run or a run with ground truth along its path is present.
    Auto,
    /// Always.
    Always,
    /// Never: keep the first run's driving scale.
    Never,
}

/// Options of the exact method.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExactOptions {
    /// When `E_s` is fitted.
    pub scale: ScaleFit,
    /// Use measured headings as residuals.
    pub use_heading: bool,
    /// Length scale of heading residuals, metres; `None` = each run's characteristic length.
    pub heading_length_m: Option<f64>,
    /// Multiplier `k` of each run's characteristic length in the heading residual's length
    /// scale `ℓ = k·L` (when [`ExactOptions::heading_length_m`] is `None`; `L` the side of a
    /// square, the radius of a circle, the length of a line). Default
    /// [`HEADING_WEIGHT`](super::HEADING_WEIGHT).
    pub heading_weight: f64,
    /// Iteration limit of each least-squares solve.
    pub max_iterations: u32,
    /// Robust fit (Cauchy weights per run, see the `exact` module docs); `false` = plain least
    /// squares.
    pub robust: bool,
    /// In the robust fit, weight the heading channel by the runs' own scatter (position against
    /// heading variance among a run's peers, see the `exact` module docs); `false` = by `ℓ`
    /// alone.
    pub channel_weights: bool,
    /// In the robust fit, give the heading row of a run its own Cauchy weight, from its own
    /// residual, and the position rows theirs (see the `exact` module docs, *Heading apart*);
    /// `false` = one weight per run from all its channels.
    pub heading_apart: bool,
    /// Fit an end-position offset common to the closed paths of one kind and size measured with
    /// their heading, with runs in both turn directions (see the `exact` module docs, *End
    /// offset*; the default); `false` = every end position as measured.
    pub end_offset: bool,
    /// Resolution of a measured position, metres: no channel's scale is taken below its
    /// rounding error `resolution/√12`.
    pub resolution_m: f64,
    /// Resolution of a measured heading, radians (as [`ExactOptions::resolution_m`]).
    pub resolution_rad: f64,
}

impl Default for ExactOptions {
    /// The robust fit with run weights only (the heading weighted a priori by
    /// [`HEADING_WEIGHT`](super::HEADING_WEIGHT) times the run's length, no channel weights) and
    /// the end offset: chosen by how the calibration transfers to the paths it did not see, with
    /// the end poses measured by hand (docs/calibration.md, *Transfer*); headings used, `E_s`
    /// when a line or a path run is present.
    fn default() -> Self {
        ExactOptions {
            scale: ScaleFit::Auto,
            use_heading: true,
            heading_length_m: None,
            heading_weight: super::HEADING_WEIGHT,
            max_iterations: 100,
            robust: true,
            channel_weights: false,
            heading_apart: false,
            end_offset: true,
            resolution_m: 1e-3,
            resolution_rad: 0.1 * core::f64::consts::PI / 180.0,
        }
    }
}

impl ExactOptions {
    /// The plain least-squares fit (every run weight 1), otherwise as [`ExactOptions::default`].
    pub fn plain() -> Self {
        ExactOptions {
            robust: false,
            channel_weights: false,
            ..ExactOptions::default()
        }
    }
}
