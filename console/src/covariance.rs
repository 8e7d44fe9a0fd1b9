//! The uncertainty of the board's odometry as ROS messages carry it: the pose covariance of the
//! library's model ([`odocal::calibration::covariance`]: the calibration's systematic error,
//! slip and scrub along the path driven) as the 6×6 of `nav_msgs/Odometry`, and the twist's.
//!
//! **Twist.** The board's wheel speeds are means over the stream period `T` of counted encoder
//! edges: an edge count is off by up to one count at each end (a triangular error of variance
//! `q²/6`, `q = πD/counts_per_rev`), so a wheel speed has variance `q²/(6T²)`; and the speed
//! loop changes the speed during the period by up to `a·T` (`a` the board's `max_accel`), so the
//! mean departs from the speed at the period's end by up to `a·T/2` (variance `(a·T/2)²/3`,
//! uniform). The robot's `v = (v_R + v_L)/2` and `ω = (v_R − v_L)/b` carry these.

pub use odocal::calibration::covariance::{
    Floor, PoseCovariance, RandomError, SAME_DAY_S, Uncertainty,
};

/// Variance written for the components a planar robot's odometry does not observe (z, roll,
/// pitch; linear y and z, angular x and y of the twist), as ROS configurations of
/// `diff_drive_controller` commonly do.
pub const UNOBSERVED_VARIANCE: f64 = 1.0e6;

/// The row-major 6×6 covariance of (x, y, z, roll, pitch, yaw) of `c` as ROS writes it.
pub fn pose_ros(c: &PoseCovariance) -> [f64; 36] {
    let m = c.xy_yaw();
    let mut out = [0.0; 36];
    let idx = [0usize, 1, 5];
    for (a, &i) in idx.iter().enumerate() {
        for (b, &j) in idx.iter().enumerate() {
            out[i * 6 + j] = m[a][b];
        }
    }
    for k in [2usize, 3, 4] {
        out[k * 6 + k] = UNOBSERVED_VARIANCE;
    }
    out
}

/// Variances of the forward speed (m²/s²) and the turn rate (rad²/s²) measured as the means of
/// the wheel speeds over `period_s` (see the module's text).
pub fn twist_variance(
    diameter_m: f64,
    counts_per_rev: u32,
    wheelbase_m: f64,
    period_s: f64,
    max_accel: f64,
) -> (f64, f64) {
    let q = std::f64::consts::PI * diameter_m / f64::from(counts_per_rev.max(1));
    let wheel = q * q / (6.0 * period_s * period_s) + (max_accel * period_s * 0.5).powi(2) / 3.0;
    // Independent wheels: v = (v_R + v_L)/2, ω = (v_R − v_L)/b.
    (0.5 * wheel, 2.0 * wheel / (wheelbase_m * wheelbase_m))
}

/// The row-major 6×6 twist covariance (vx, vy, vz, wx, wy, wz) of [`twist_variance`].
pub fn twist_ros(var_v: f64, var_w: f64) -> [f64; 36] {
    let mut c = [0.0; 36];
    c[0] = var_v;
    c[35] = var_w;
    for k in [1usize, 2, 3, 4] {
        c[k * 6 + k] = UNOBSERVED_VARIANCE;
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn twist_variance_from_counts_and_acceleration() {
        // 1000 counts/rev on 0.1 m wheels, 10 ms: q = 0.314 mm, wheel σ² = q²/(6T²) + (aT/2)²/3.
        let (v, w) = twist_variance(0.1, 1000, 0.4, 0.01, 1.0);
        let q = std::f64::consts::PI * 0.1 / 1000.0;
        let wheel = q * q / 6e-4 + (0.005f64).powi(2) / 3.0;
        assert!((v - wheel / 2.0).abs() < 1e-15);
        assert!((w - 2.0 * wheel / 0.16).abs() < 1e-12);
    }
}
