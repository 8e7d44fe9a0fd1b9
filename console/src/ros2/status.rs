//! The bridge's `/diagnostics`: the board's state and faults (its `status` reply), the last
//! reply to a forwarded `cmd_vel`, the distance and rotation driven, and the bridge's own
//! figures (rates, handling time, latency, the clock map's offset and jitter).

use super::clock::ClockMap;
use super::guard::{Guard, Stale};
use super::msgs::builtin_interfaces::Time;
use super::msgs::diagnostic_msgs::{self, DiagnosticArray, DiagnosticStatus, KeyValue};
use super::msgs::std_msgs::Header;
use super::odometry::Odometer;
use super::reference::Reference;
use crate::online::Online;
use odocal::protocol::FinalLine;
use odocal::protocol::token;

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
    /// Board and PC times of the first and the last line since the board's last reset.
    pub first: Option<(f64, f64)>,
    pub last: Option<(f64, f64)>,
    pub lines: usize,
    /// Lines since the board's last reset.
    pub lines_since_reset: usize,
    /// Line intervals and board seconds before the board's last reset (its time restarted).
    pub before_reset: (usize, f64),
    /// Seconds from a line's arrival to its odometry being published.
    pub handling: Vec<f64>,
    /// Seconds from the pose's instant (its stamp) to its odometry being published.
    pub latency: Vec<f64>,
    pub commands: usize,
}

impl Stats {
    /// A stream line at board time `board_s` arrived at `pc_s`.
    pub(super) fn line(&mut self, board_s: f64, pc_s: f64) {
        self.first.get_or_insert((board_s, pc_s));
        self.last = Some((board_s, pc_s));
        self.lines += 1;
        self.lines_since_reset += 1;
    }

    /// The board reset: its time restarts, so the rate in board time goes on from a new span.
    pub(super) fn board_reset(&mut self) {
        if let (Some((b0, _)), Some((b1, _))) = (self.first, self.last) {
            self.before_reset.0 += self.lines_since_reset.saturating_sub(1);
            self.before_reset.1 += b1 - b0;
        }
        self.first = None;
        self.last = None;
        self.lines_since_reset = 0;
    }

    pub(super) fn summary(&self, clock: &ClockMap) -> Vec<(String, String)> {
        let mut out = Vec::new();
        if let (Some((b0, p0)), Some((b1, p1))) = (self.first, self.last) {
            let n = self.before_reset.0 + self.lines_since_reset.saturating_sub(1);
            let board_s = self.before_reset.1 + (b1 - b0);
            if n > 0 && board_s > 0.0 {
                out.push(("rate_board_hz".into(), format!("{:.2}", n as f64 / board_s)));
            }
            if self.lines_since_reset > 1 {
                let n = (self.lines_since_reset - 1) as f64;
                out.push(("rate_pc_hz".into(), format!("{:.2}", n / (p1 - p0))));
            }
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
    /// The bridge's rules: whether odometry flows, the refused commands, the resets.
    pub guard: &'a Guard,
    /// The pose `odom` went on from at the last board reset (x, y, θ).
    pub carried: Option<(f64, f64, f64)>,
}

/// The `/diagnostics` message for the board's `status` reply `status` at `now_s` (the PC's
/// clock): an error while the board does not answer (`None`: no reply in time, a board without
/// power or hung behind a live USB adapter) or a fault is latched, a warning while `cmd_vel` is
/// refused.
pub(super) fn diagnostics(status: Option<&str>, c: &Context<'_>, now_s: f64) -> DiagnosticArray {
    let field = |k: &str| {
        status
            .unwrap_or("")
            .split_whitespace()
            .find_map(|w| w.strip_prefix(k)?.strip_prefix('='))
            .unwrap_or("?")
            .to_string()
    };
    let (state, fault) = (field("state"), field("fault"));
    let (level, message) = if status.is_none() {
        (
            diagnostic_msgs::ERROR,
            format!("board not answering: {} (no reply to status)", c.port),
        )
    } else if fault != "none" {
        (diagnostic_msgs::ERROR, format!("fault latched: {fault}"))
    } else if let Some(why) = c.guard.stale() {
        // A board that reset or went away: the robot's odometry is gone (ERROR); a stream that
        // paused or has not started yet: WARN.
        let level = match why {
            Stale::BoardReset | Stale::Disconnected => diagnostic_msgs::ERROR,
            Stale::Starting | Stale::Gap => diagnostic_msgs::WARN,
        };
        (
            level,
            format!("no odometry ({}): cmd_vel not forwarded", why.as_str()),
        )
    } else if FinalLine::parse(c.last_drive_reply).is_some_and(|l| !l.is_ok()) {
        (
            diagnostic_msgs::WARN,
            format!("cmd_vel refused: {}", c.last_drive_reply),
        )
    } else if token::is_drive_limited(c.last_drive_reply) {
        // The board cut the command to its max_speed or max_turn_rate: the reply names both.
        (
            diagnostic_msgs::WARN,
            format!("cmd_vel cut by the board's limits: {}", c.last_drive_reply),
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
            key: "odometry".into(),
            value: c.guard.stale().map_or("flowing", Stale::as_str).to_string(),
        },
        KeyValue {
            key: "board_resets".into(),
            value: c.guard.resets.to_string(),
        },
        KeyValue {
            key: "odom_carried_over".into(),
            value: c.carried.map_or_else(
                || "none".to_string(),
                |(x, y, th)| format!("x={x:.6} y={y:.6} theta={th:.6}"),
            ),
        },
        KeyValue {
            key: "cmd_vel_refused_no_odometry".into(),
            value: c.guard.refused_stale.to_string(),
        },
        KeyValue {
            key: "cmd_vel_refused_not_finite".into(),
            value: c.guard.refused_nonfinite.to_string(),
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

/// The `/diagnostics` message while the board's port is gone: ERROR, `board disconnected:
/// PORT`.
pub(super) fn disconnected(node_name: &str, port: &str, now_s: f64) -> DiagnosticArray {
    DiagnosticArray {
        header: Header {
            stamp: Time::from_secs(now_s),
            frame_id: String::new(),
        },
        status: vec![DiagnosticStatus {
            level: diagnostic_msgs::ERROR,
            name: format!("{node_name}: board"),
            message: format!("board disconnected: {port}"),
            hardware_id: format!("odocal {port}"),
            values: vec![KeyValue {
                key: "odometry".into(),
                value: "none: the board is disconnected".into(),
            }],
        }],
    }
}

/// The online calibration's status (`--reference`): the estimate with its 1σ, the windows used
/// and rejected, and how far the board's calibration `applied` (`E_d`, `E_b`, `E_s`) is from the
/// estimate, in σ: WARN from `--min-change` σ on (the calibration went stale), OK otherwise.
pub(super) fn online(
    node_name: &str,
    o: &Online,
    r: &Reference,
    applied: (f64, f64, f64),
) -> DiagnosticStatus {
    let e = o.estimator.estimate();
    let num = |v: Option<f64>| v.map_or_else(|| "none".to_string(), |v| format!("{v:.6}"));
    let drift = e.map(|e| e.distance_sigma(applied.0, applied.1));
    let (level, message) = match (r.kind(), e, drift) {
        (None, _, _) => (
            diagnostic_msgs::WARN,
            format!("waiting for the reference {}", r.topic()),
        ),
        (Some(_), None, _) => (
            diagnostic_msgs::OK,
            format!(
                "collecting windows ({} used, {} rejected; an estimate from {})",
                o.estimator.used,
                o.estimator.rejected,
                crate::online::estimator::MIN_WINDOWS
            ),
        ),
        (Some(_), Some(_), Some(d)) if d > o.args.min_change => (
            diagnostic_msgs::WARN,
            format!("the board's calibration is {d:.1} sigma from the online estimate"),
        ),
        (Some(_), Some(_), _) => (
            diagnostic_msgs::OK,
            "the board's calibration agrees with the online estimate".to_string(),
        ),
    };
    let kv = |key: &str, value: String| KeyValue {
        key: key.into(),
        value,
    };
    DiagnosticStatus {
        level,
        name: format!("{node_name}: online calibration"),
        message,
        hardware_id: format!("odocal reference {}", r.topic()),
        values: vec![
            kv("online_E_b", num(e.map(|e| e.e_b))),
            kv("online_E_d", num(e.map(|e| e.e_d))),
            kv("online_E_s", num(e.map(|e| e.e_s))),
            kv("online_sd_E_b", num(e.map(|e| e.sd_e_b))),
            kv("online_sd_E_d", num(e.map(|e| e.sd_e_d))),
            kv("windows_used", o.estimator.used.to_string()),
            kv("windows_rejected", o.estimator.rejected.to_string()),
            kv(
                "drift_sigma",
                drift.map_or_else(|| "none".into(), |d| format!("{d:.2}")),
            ),
            kv("applied_E_d", format!("{:.6}", applied.0)),
            kv("applied_E_b", format!("{:.6}", applied.1)),
            kv("applied_E_s", format!("{:.6}", applied.2)),
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 100 lines at 100 Hz, a board reset (its time restarts at 0), 51 more: the rate in board
    /// time is still 100 Hz, not a negative or huge one from times that went backwards.
    #[test]
    fn the_board_rate_spans_a_board_reset() {
        let mut s = Stats::default();
        for i in 0..100 {
            let t = 5.0 + f64::from(i) * 0.01;
            s.line(t, 1000.0 + t);
        }
        s.board_reset();
        for i in 0..51 {
            let t = 0.02 + f64::from(i) * 0.01;
            s.line(t, 1010.0 + t);
        }
        let summary = s.summary(&ClockMap::new(None, 10.0));
        let rate = |k: &str| {
            summary
                .iter()
                .find(|(key, _)| key == k)
                .map(|(_, v)| v.parse::<f64>().unwrap())
        };
        assert_eq!(rate("rate_board_hz"), Some(100.0));
        assert_eq!(rate("rate_pc_hz"), Some(100.0));
        assert_eq!(rate("lines"), Some(151.0));
    }
}
