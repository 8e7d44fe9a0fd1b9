//! The bridge's `/diagnostics`: the board's state and faults (its `status` reply), the last
//! reply to a forwarded `cmd_vel`, the distance and rotation driven, and the bridge's own
//! figures (rates, handling time, latency, the clock map's offset and jitter).

use super::clock::ClockMap;
use super::msgs::builtin_interfaces::Time;
use super::msgs::diagnostic_msgs::{self, DiagnosticArray, DiagnosticStatus, KeyValue};
use super::msgs::std_msgs::Header;
use super::odometry::Odometer;
use odocal::protocol::FinalLine;

/// Percentile `q` of sorted values (0 when empty).
fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

/// The measured performance of a run of the bridge.
#[derive(Default)]
pub(super) struct Stats {
    pub first: Option<(f64, f64)>,
    pub last: Option<(f64, f64)>,
    pub lines: usize,
    /// Seconds from a line's arrival to its odometry being published.
    pub handling: Vec<f64>,
    /// Seconds from the pose's instant (its stamp) to its odometry being published.
    pub latency: Vec<f64>,
    pub commands: usize,
}

impl Stats {
    pub(super) fn summary(&self, clock: &ClockMap) -> Vec<(String, String)> {
        let mut out = Vec::new();
        if let (Some((b0, p0)), Some((b1, p1))) = (self.first, self.last)
            && self.lines > 1
        {
            let n = (self.lines - 1) as f64;
            out.push(("rate_board_hz".into(), format!("{:.2}", n / (b1 - b0))));
            out.push(("rate_pc_hz".into(), format!("{:.2}", n / (p1 - p0))));
        }
        out.push(("lines".into(), self.lines.to_string()));
        for (key, v) in [("handling", &self.handling), ("latency", &self.latency)] {
            let mut s = v.clone();
            s.sort_by(f64::total_cmp);
            out.push((
                format!("{key}_ms_median_p99_max"),
                format!(
                    "{:.3} {:.3} {:.3}",
                    1e3 * percentile(&s, 0.5),
                    1e3 * percentile(&s, 0.99),
                    1e3 * percentile(&s, 1.0)
                ),
            ));
        }
        if let Some(c) = clock.stats() {
            out.push(("clock_offset_s".into(), format!("{:.6}", c.offset_s)));
            out.push((
                "clock_jitter_ms_median_p99_max".into(),
                format!(
                    "{:.3} {:.3} {:.3}",
                    1e3 * c.jitter_median_s,
                    1e3 * c.jitter_p99_s,
                    1e3 * c.jitter_max_s
                ),
            ));
        }
        out.push(("cmd_vel_forwarded".into(), self.commands.to_string()));
        out
    }
}

/// What the diagnostics say besides the board's `status` reply.
pub(super) struct Context<'a> {
    pub node_name: &'a str,
    pub port: &'a str,
    /// The calibration the board holds (its `params` reply).
    pub calibration: &'a str,
    pub last_drive_reply: &'a str,
    pub odometer: &'a Odometer,
    pub stats: &'a Stats,
}

/// The `/diagnostics` message for the board's `status` reply `status` at `now_s` (the PC's
/// clock): an error while a fault is latched, a warning while `cmd_vel` is refused.
pub(super) fn diagnostics(status: &str, c: &Context<'_>, now_s: f64) -> DiagnosticArray {
    let field = |k: &str| {
        status
            .split_whitespace()
            .find_map(|w| w.strip_prefix(k)?.strip_prefix('='))
            .unwrap_or("?")
            .to_string()
    };
    let (state, fault) = (field("state"), field("fault"));
    let (level, message) = if fault != "none" {
        (diagnostic_msgs::ERROR, format!("fault latched: {fault}"))
    } else if FinalLine::parse(c.last_drive_reply).is_some_and(|l| !l.is_ok()) {
        (
            diagnostic_msgs::WARN,
            format!("cmd_vel refused: {}", c.last_drive_reply),
        )
    } else {
        (diagnostic_msgs::OK, format!("state {state}"))
    };
    let mut values = vec![
        KeyValue {
            key: "state".into(),
            value: state,
        },
        KeyValue {
            key: "fault".into(),
            value: fault,
        },
        KeyValue {
            key: "calibration".into(),
            value: c.calibration.to_string(),
        },
        KeyValue {
            key: "cmd_vel_last_reply".into(),
            value: c.last_drive_reply.to_string(),
        },
        KeyValue {
            key: "distance_driven_m".into(),
            value: format!("{:.3}", c.odometer.covariance().distance_m),
        },
        KeyValue {
            key: "rotation_driven_rad".into(),
            value: format!("{:.3}", c.odometer.covariance().rotation_rad),
        },
    ];
    values.extend(
        c.stats
            .summary(c.odometer.clock())
            .into_iter()
            .map(|(key, value)| KeyValue { key, value }),
    );
    DiagnosticArray {
        header: Header {
            stamp: Time::from_secs(now_s),
            frame_id: String::new(),
        },
        status: vec![DiagnosticStatus {
            level,
            name: format!("{}: board", c.node_name),
            message,
            hardware_id: format!("odocal {}", c.port),
            values,
        }],
    }
}
