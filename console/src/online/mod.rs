//! Online calibration: `E_d`, `E_b` (and `E_s`) kept current from the robot's own localization
//! while it drives (`cargo console ros2 --reference TOPIC`), by the library's exact path fit
//! ([`estimator`]) of windows of driving ([`window`]), every window logged ([`log`]).
//!
//! The reference is a pose in any fixed frame: only its motion between its samples is used. Its
//! stamps are mapped to the board's clock (the bridge's clock map, less `--reference-delay`
//! for a source that stamps late); a tracked point off the axle centre is moved onto it
//! (`--reference-offset X Y`, in the robot's frame). Its 1σ comes from its covariance
//! (`PoseWithCovarianceStamped`, `Odometry`) or, for a plain pose, from
//! `--reference-sd-xy`/`--reference-sd-deg`.

pub mod estimator;
pub mod log;
pub mod window;

#[cfg(test)]
mod tests;

use std::path::PathBuf;

use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;

use estimator::{Estimate, Estimator, EstimatorOptions};
use log::LogFile;
use window::{RefSample, WindowOptions, Windower};

/// The reference's message type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ReferenceType {
    /// `geometry_msgs/PoseWithCovarianceStamped` (AMCL, robot_localization).
    PoseCov,
    /// `geometry_msgs/PoseStamped` (motion capture).
    Pose,
    /// `nav_msgs/Odometry`.
    Odometry,
}

impl ReferenceType {
    /// The type a discovered topic's DDS type name says, if one of these.
    pub fn of_dds_type(name: &str) -> Option<ReferenceType> {
        if name.ends_with("PoseWithCovarianceStamped_") {
            Some(ReferenceType::PoseCov)
        } else if name.ends_with("PoseStamped_") {
            Some(ReferenceType::Pose)
        } else if name.ends_with("Odometry_") {
            Some(ReferenceType::Odometry)
        } else {
            None
        }
    }
}

/// What the bridge does with an estimate that differs from the board's calibration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ApplyMode {
    /// Report it on `/diagnostics` only.
    Never,
    /// Ask on the bridge's terminal (type `yes`).
    Ask,
    /// Apply and save it at rest when it is sure and different enough.
    Auto,
}

/// The options of the online calibration (`ros2 --reference …`).
#[derive(clap::Args, Debug, Clone)]
pub struct OnlineArgs {
    /// Topic of the robot's reference pose (its localization or motion capture): turns the
    /// online calibration on.
    #[arg(long)]
    pub reference: Option<String>,
    /// The reference's type (default: the type the topic is discovered with).
    #[arg(long, value_enum)]
    pub reference_type: Option<ReferenceType>,
    /// Seconds the reference's stamps are late (a source that stamps on arrival).
    #[arg(long, default_value_t = 0.0)]
    pub reference_delay: f64,
    /// Where the reference's tracked point sits in the robot's frame, metres (x forward, y
    /// left of the axle centre).
    #[arg(long, num_args = 2, value_names = ["X", "Y"], allow_negative_numbers = true)]
    pub reference_offset: Option<Vec<f64>>,
    /// 1σ of a plain pose's position (and of one whose covariance is empty), metres.
    #[arg(long, default_value_t = 0.02)]
    pub reference_sd_xy: f64,
    /// 1σ of a plain pose's heading, degrees.
    #[arg(long, default_value_t = 1.0)]
    pub reference_sd_deg: f64,
    /// Fit the mean wheel diameter `E_s` too (only for a reference whose scale can be trusted:
    /// motion capture, a map not built with this odometry).
    #[arg(long)]
    pub fit_scale: bool,
    /// Forgetting horizon: the estimate remembers this much wheel travel, metres.
    #[arg(long, default_value_t = 100.0)]
    pub horizon: f64,
    /// Wheel travel of one window, metres.
    #[arg(long, default_value_t = 5.0)]
    pub window: f64,
    /// Longest interval between two reference samples inside a window, seconds.
    #[arg(long, default_value_t = 0.5)]
    pub max_gap: f64,
    /// What to do with an estimate that differs from the board's calibration.
    #[arg(long, value_enum, default_value_t = ApplyMode::Never)]
    pub apply: ApplyMode,
    /// `ask`/`auto`: the largest 1σ of `E_d` and `E_b` an estimate may have to be applied.
    #[arg(long, default_value_t = 1e-3)]
    pub max_sd: f64,
    /// `ask`/`auto`: the least distance of the board's calibration from the estimate, in σ.
    #[arg(long, default_value_t = 3.0)]
    pub min_change: f64,
    /// Log every window and estimate to this file (JSON lines; `recalibrate --reference-log`
    /// redoes the estimate from it).
    #[arg(long)]
    pub reference_log: Option<PathBuf>,
}

/// Seconds of rest (both wheels still) before `auto` applies.
pub const REST_S: f64 = 1.0;

/// The online calibration while the bridge runs.
pub struct Online {
    pub args: OnlineArgs,
    windower: Windower,
    pub estimator: Estimator,
    log: LogFile,
    /// Board time since which both wheels stood still.
    rest_since: Option<f64>,
    last_t_s: f64,
    /// The last fit's failure, said once.
    failed: Option<String>,
    /// An estimate offered with `ask`, waiting for `yes`.
    pub offered: Option<Estimate>,
}

impl Online {
    /// The online calibration for a board with `nominal` geometry driving with `active`.
    ///
    /// # Errors
    /// Bad options or a log that cannot be created, as text.
    pub fn new(args: &OnlineArgs, nominal: Geometry, active: Geometry) -> Result<Online, String> {
        for (v, name) in [
            (args.horizon, "--horizon"),
            (args.window, "--window"),
            (args.max_gap, "--max-gap"),
            (args.reference_sd_xy, "--reference-sd-xy"),
            (args.reference_sd_deg, "--reference-sd-deg"),
            (args.max_sd, "--max-sd"),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} {v}: a positive number"));
            }
        }
        if !(args.reference_delay.is_finite() && args.min_change.is_finite()) {
            return Err("--reference-delay and --min-change: finite numbers".into());
        }
        let options = EstimatorOptions {
            horizon_m: args.horizon,
            fit_scale: args.fit_scale,
        };
        let mut log = LogFile::create(args.reference_log.as_deref())?;
        log.write(&log::header(&nominal, &options, args.window));
        Ok(Online {
            args: args.clone(),
            windower: Windower::new(
                WindowOptions {
                    length_m: args.window,
                    max_gap_s: args.max_gap,
                },
                active,
            ),
            estimator: Estimator::new(nominal, options),
            log,
            rest_since: None,
            last_t_s: 0.0,
            failed: None,
            offered: None,
        })
    }

    /// A stream line of the board (board time, wheel speeds).
    pub fn stream(&mut self, t_s: f64, v_right: f64, v_left: f64) {
        if v_right == 0.0 && v_left == 0.0 {
            // Still since this line (or since the board's reset restarted its time).
            if self.rest_since.is_none() || t_s < self.last_t_s {
                self.rest_since = Some(t_s);
            }
        } else {
            self.rest_since = None;
        }
        self.last_t_s = t_s;
        let cut = self.windower.stream(t_s, v_right, v_left);
        self.take(cut.into_iter().collect());
        let closed = self.windower.step();
        self.take(closed);
    }

    /// A reference sample: its stamp mapped to the board's clock (`board_s`), its pose and its
    /// covariance's x, y and yaw variances (`None`: the stated defaults).
    pub fn reference(&mut self, board_s: f64, pose: PoseF64, var: Option<(f64, f64, f64)>) {
        let (sd_xy, sd_th) =
            match var.filter(|(x, y, t)| [x, y, t].iter().all(|v| v.is_finite() && **v > 0.0)) {
                Some((x, y, t)) => ((0.5 * (x + y)).sqrt(), t.sqrt()),
                None => (
                    self.args.reference_sd_xy,
                    self.args.reference_sd_deg.to_radians(),
                ),
            };
        if ![pose.x_m, pose.y_m, pose.theta_rad, board_s]
            .iter()
            .all(|v| v.is_finite())
        {
            return;
        }
        // The tracked point moved onto the axle centre.
        let (ox, oy) = match self.args.reference_offset.as_deref() {
            Some([x, y]) => (*x, *y),
            _ => (0.0, 0.0),
        };
        let (s, c) = pose.theta_rad.sin_cos();
        let axle = PoseF64::new(
            pose.x_m - (c * ox - s * oy),
            pose.y_m - (s * ox + c * oy),
            pose.theta_rad,
        );
        self.windower.reference(RefSample {
            t_s: board_s - self.args.reference_delay,
            pose: axle,
            sd_xy_m: sd_xy,
            sd_theta_rad: sd_th,
        });
        let closed = self.windower.step();
        self.take(closed);
    }

    /// Closed windows into the log and the estimator.
    fn take(&mut self, windows: Vec<window::Window>) {
        for w in windows {
            self.log.write(&log::window(&w));
            match self.estimator.push(w) {
                Ok(()) => {
                    self.failed = None;
                    if let Some(e) = self.estimator.estimate() {
                        self.log.write(&log::estimate(&e));
                        self.windower.set_carry(self.estimator.geometry_of(&e));
                    }
                }
                Err(why) => {
                    if self.failed.as_deref() != Some(why.as_str()) {
                        eprintln!("online: the fit failed ({why}); the estimate stays");
                    }
                    self.failed = Some(why);
                }
            }
        }
    }

    /// Whether the robot has stood still for [`REST_S`].
    pub fn at_rest(&self) -> bool {
        self.rest_since
            .is_some_and(|since| self.last_t_s - since >= REST_S)
    }

    /// The estimate to apply now by the `ask`/`auto` rules, given the board's factors.
    pub fn to_apply(&self, applied: (f64, f64)) -> Option<Estimate> {
        if self.args.apply == ApplyMode::Never || !self.at_rest() {
            return None;
        }
        let e = self.estimator.estimate()?;
        (e.sd_e_d.max(e.sd_e_b) < self.args.max_sd
            && e.distance_sigma(applied.0, applied.1) > self.args.min_change)
            .then_some(e)
    }

    /// The board applied `e` (its geometry is now `active`): the window being built is dropped
    /// and the log says where the calibration came from.
    pub fn applied(&mut self, e: &Estimate, active: Geometry) {
        self.windower.set_geometry(active);
        let mut record = log::estimate(e);
        record["k"] = "applied".into();
        record["from"] = format!(
            "the online estimate over the last {} windows ({:.1} m of driving)",
            e.windows, e.travel_m
        )
        .into();
        self.log.write(&record);
    }
}
