//! What the bridge lets through to the board, and when the odometry counts as flowing.
//!
//! A robot must never move on odometry that does not come: after a board reset (its boot event)
//! the board's pose stream is off, and a stream that stops for [`GAP_PERIODS`] periods (at least
//! [`GAP_MIN_S`]) has stopped for some other reason (a cable, the board's USB adapter). Until a
//! stream line comes again the bridge forwards no `cmd_vel`: each refused one is counted, the
//! first of each stretch is said on stderr, and `stream on` is sent again once a second. A
//! `cmd_vel` with a NaN or infinite field is refused as well (counted, said once per burst),
//! and stops the robot when the last forwarded command moved it: the planner that sent it
//! cannot be trusted with the one before.

/// Stream periods without a line after which the odometry is stale.
pub const GAP_PERIODS: f64 = 10.0;
/// The shortest gap that makes the odometry stale, seconds (a PC's scheduling can hold a line
/// back for tens of milliseconds).
pub const GAP_MIN_S: f64 = 0.2;
/// Seconds between two attempts to turn the stream on again while it is stale.
pub const RESTART_S: f64 = 1.0;

/// Why the odometry is not flowing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stale {
    /// No stream line yet since the bridge started.
    Starting,
    /// The board booted (its boot event): its stream is off and its pose restarted.
    BoardReset,
    /// The stream stopped for longer than its gap.
    Gap,
    /// The board's port went away (until it is reopened and its stream flows).
    Disconnected,
}

impl Stale {
    /// As the diagnostics and stderr name it.
    pub fn as_str(self) -> &'static str {
        match self {
            Stale::Starting => "no stream line yet",
            Stale::BoardReset => "the board was reset",
            Stale::Gap => "the stream stopped",
            Stale::Disconnected => "the board is disconnected",
        }
    }
}

/// What to do with a `cmd_vel`.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    /// Send `drive v w` (m/s, rad/s, finite).
    Forward(f64, f64),
    /// Do not send it; `say` on stderr if given; `stop` the robot first if set.
    Refuse {
        /// The line for stderr, for the first refusal of a stretch or burst.
        say: Option<String>,
        /// The last forwarded command moved the robot: send `stop`.
        stop: bool,
    },
}

/// The bridge's rules for `cmd_vel` and the odometry's freshness (see the module's text).
#[derive(Debug)]
pub struct Guard {
    gap_s: f64,
    last_line_s: Option<f64>,
    stale: Option<Stale>,
    said_stale: bool,
    in_nonfinite_burst: bool,
    moving: bool,
    last_restart_s: Option<f64>,
    /// `cmd_vel` refused because the odometry was stale.
    pub refused_stale: u64,
    /// `cmd_vel` refused for a NaN or infinite field.
    pub refused_nonfinite: u64,
    /// Board resets seen (boot events).
    pub resets: u32,
}

impl Guard {
    /// Rules for a stream at `rate_hz`, before its first line.
    pub fn new(rate_hz: u32) -> Guard {
        Guard {
            gap_s: (GAP_PERIODS / f64::from(rate_hz.max(1))).max(GAP_MIN_S),
            last_line_s: None,
            stale: Some(Stale::Starting),
            said_stale: false,
            in_nonfinite_burst: false,
            moving: false,
            last_restart_s: None,
            refused_stale: 0,
            refused_nonfinite: 0,
            resets: 0,
        }
    }

    /// A stream line arrived at `now_s` (the PC's clock): the odometry flows.
    pub fn line(&mut self, now_s: f64) {
        self.last_line_s = Some(now_s);
        self.stale = None;
        self.said_stale = false;
    }

    /// The board's boot event arrived: its stream is off and the robot stopped.
    pub fn board_reset(&mut self) {
        self.resets += 1;
        self.lose(Stale::BoardReset);
    }

    /// The board's port went away: stale until its stream flows again (the bridge turns it on
    /// when it reopens the port).
    pub fn disconnected(&mut self) {
        self.lose(Stale::Disconnected);
    }

    /// The odometry stopped for `why`: stale, said again at the next refusal, the stream turned
    /// on again at the next check; a board that reset or went away no longer moves the robot.
    fn lose(&mut self, why: Stale) {
        self.stale = Some(why);
        self.said_stale = false;
        if why != Stale::Gap {
            self.moving = false;
            self.last_restart_s = None;
        }
    }

    /// Why the odometry is stale, `None` while it flows.
    pub fn stale(&self) -> Option<Stale> {
        self.stale
    }

    /// The bridge's check at `now_s`: marks a stream that stopped for longer than its gap
    /// stale; whether to send `stream on` now (stale, and the last attempt a second ago).
    pub fn restart_stream(&mut self, now_s: f64) -> bool {
        if self.stale.is_none() && self.last_line_s.is_some_and(|t| now_s - t > self.gap_s) {
            self.lose(Stale::Gap);
        }
        if self.stale.is_none() || self.stale == Some(Stale::Starting) {
            return false;
        }
        if self.last_restart_s.is_some_and(|t| now_s - t < RESTART_S) {
            return false;
        }
        self.last_restart_s = Some(now_s);
        true
    }

    /// What to do with a `cmd_vel` of `v` m/s and `w` rad/s.
    pub fn cmd_vel(&mut self, v: f64, w: f64) -> Verdict {
        if !(v.is_finite() && w.is_finite()) {
            self.refused_nonfinite += 1;
            let say = (!self.in_nonfinite_burst).then(|| {
                format!(
                    "ros2: cmd_vel refused: a field is not finite (linear.x {v}, angular.z {w})"
                )
            });
            self.in_nonfinite_burst = true;
            let stop = std::mem::take(&mut self.moving);
            return Verdict::Refuse { say, stop };
        }
        self.in_nonfinite_burst = false;
        if let Some(why) = self.stale {
            self.refused_stale += 1;
            let say = (!self.said_stale).then(|| {
                format!("ros2: cmd_vel refused: no odometry ({}): nothing is forwarded until it flows again", why.as_str())
            });
            self.said_stale = true;
            return Verdict::Refuse { say, stop: false };
        }
        self.moving = v != 0.0 || w != 0.0;
        Verdict::Forward(v, w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bridge at 100 Hz that has seen lines up to t = 1 s.
    fn flowing() -> Guard {
        let mut g = Guard::new(100);
        for i in 0..=100 {
            g.line(f64::from(i) * 0.01);
        }
        g
    }

    #[test]
    fn nothing_is_forwarded_before_the_first_stream_line() {
        let mut g = Guard::new(100);
        assert_eq!(g.stale(), Some(Stale::Starting));
        assert!(matches!(
            g.cmd_vel(0.2, 0.0),
            Verdict::Refuse {
                say: Some(_),
                stop: false
            }
        ));
        assert_eq!(
            g.cmd_vel(0.2, 0.0),
            Verdict::Refuse {
                say: None,
                stop: false
            }
        );
        assert!(
            !g.restart_stream(5.0),
            "the bridge turned the stream on itself at start"
        );
        g.line(0.0);
        assert_eq!(g.cmd_vel(0.2, 0.0), Verdict::Forward(0.2, 0.0));
        assert_eq!(g.refused_stale, 2);
    }

    /// After the boot event nothing moves the robot until a stream line comes again; the stream
    /// is turned on again at once and then once a second; each stretch is said once.
    #[test]
    fn a_board_reset_refuses_cmd_vel_until_the_stream_flows_again() {
        let mut g = flowing();
        assert_eq!(g.cmd_vel(0.3, 0.1), Verdict::Forward(0.3, 0.1));
        g.board_reset();
        assert_eq!(g.stale(), Some(Stale::BoardReset));
        assert!(g.restart_stream(1.01));
        assert!(!g.restart_stream(1.5));
        assert!(g.restart_stream(2.02));
        let Verdict::Refuse {
            say: Some(say),
            stop: false,
        } = g.cmd_vel(0.3, 0.1)
        else {
            panic!("forwarded after a reset");
        };
        assert!(say.contains("the board was reset"), "{say}");
        assert_eq!(
            g.cmd_vel(0.3, 0.1),
            Verdict::Refuse {
                say: None,
                stop: false
            }
        );
        g.line(2.1);
        assert_eq!(g.cmd_vel(0.3, 0.1), Verdict::Forward(0.3, 0.1));
        assert_eq!((g.refused_stale, g.resets), (2, 1));
    }

    /// At 100 Hz the gap is 10 periods, 0.2 s at least: a line 0.19 s late is not a gap, one
    /// 0.21 s late is; at 1 Hz the gap is 10 s.
    #[test]
    fn a_stream_gap_longer_than_ten_periods_is_stale() {
        let mut g = flowing();
        assert!(!g.restart_stream(1.19));
        assert_eq!(g.stale(), None);
        assert!(g.restart_stream(1.21));
        assert_eq!(g.stale(), Some(Stale::Gap));
        assert!(matches!(
            g.cmd_vel(0.1, 0.0),
            Verdict::Refuse { say: Some(_), .. }
        ));
        let mut slow = Guard::new(1);
        slow.line(0.0);
        assert!(!slow.restart_stream(9.9));
        assert!(slow.restart_stream(10.1));
    }

    /// A burst of NaN commands: said once, counted each; the robot stopped when the last
    /// forwarded command moved it, not when it stood; a finite command ends the burst.
    #[test]
    fn a_non_finite_cmd_vel_is_refused_and_stops_a_moving_robot() {
        let mut g = flowing();
        assert_eq!(g.cmd_vel(0.3, 0.0), Verdict::Forward(0.3, 0.0));
        let Verdict::Refuse {
            say: Some(say),
            stop: true,
        } = g.cmd_vel(f64::NAN, 0.0)
        else {
            panic!("a NaN was forwarded or did not stop the robot");
        };
        assert!(say.contains("not finite"), "{say}");
        assert_eq!(
            g.cmd_vel(0.1, f64::INFINITY),
            Verdict::Refuse {
                say: None,
                stop: false
            }
        );
        assert_eq!(g.cmd_vel(0.0, 0.0), Verdict::Forward(0.0, 0.0));
        assert!(matches!(
            g.cmd_vel(f64::NEG_INFINITY, 0.0),
            Verdict::Refuse {
                say: Some(_),
                stop: false
            }
        ));
        assert_eq!(g.refused_nonfinite, 3);
    }
}
