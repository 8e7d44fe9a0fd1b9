//! `--truth-hz`: the robot's true pose on stdout on the board's clock, and that clock's
//! seconds as the board's `stream` line writes them.

use std::io::Write;

use odocal::kinematics::reference::PoseF64;

/// Board time as the `stream` line writes it: seconds with 6 decimals, from whole microseconds.
pub(super) fn board_seconds(us: u64) -> String {
    format!("{}.{:06}", us / 1_000_000, us % 1_000_000)
}

/// Prints one line on stdout and flushes it (a test process reads it at once).
pub(super) fn print_flushed(line: &str) -> Result<(), String> {
    let mut stdout = std::io::stdout().lock();
    writeln!(stdout, "{line}")
        .and_then(|()| stdout.flush())
        .map_err(|e| e.to_string())
}

/// Prints `truth T X Y THETA` for board time `t_us` and the true pose `pose` (m, m, rad).
pub(super) fn print_truth(t_us: u64, pose: PoseF64) -> Result<(), String> {
    print_flushed(&format!(
        "truth {} {:.6} {:.6} {:.6}",
        board_seconds(t_us),
        pose.x_m,
        pose.y_m,
        pose.theta_rad
    ))
}

/// The `--truth-hz` schedule: due times every `period_us` of the board's clock from boot.
pub(super) struct TruthClock {
    period_us: u64,
    next_us: u64,
}

impl TruthClock {
    /// `hz` lines per second of board time (a period rounded to whole microseconds, at least
    /// one), the first one period after boot.
    pub(super) fn new(hz: f64) -> Self {
        // Saturating: a rate below 1e-13 Hz is never due.
        let period_us = ((1e6 / hz).round() as u64).max(1);
        TruthClock {
            period_us,
            next_us: period_us,
        }
    }

    /// A new board: its clock starts again from 0.
    pub(super) fn restart(&mut self) {
        self.next_us = self.period_us;
    }

    /// Whether a line is due at `now_us`; if so, the next one is the next grid time after it.
    pub(super) fn due(&mut self, now_us: u64) -> bool {
        if now_us < self.next_us {
            return false;
        }
        self.next_us = (now_us / self.period_us)
            .saturating_add(1)
            .saturating_mul(self.period_us);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_due_on_a_grid_from_boot() {
        let mut c = TruthClock::new(20.0);
        // At 1 kHz: every 50th period, exactly 50 ms apart.
        let due: Vec<u64> = (1..=200u64)
            .map(|p| p * 1000)
            .filter(|&t| c.due(t))
            .collect();
        assert_eq!(due, [50_000, 100_000, 150_000, 200_000]);
        // Periods that do not divide the grid: the first period at or after each grid time.
        let mut c = TruthClock::new(3.0);
        let due: Vec<u64> = (1..=3000u64)
            .map(|p| p * 1000)
            .filter(|&t| c.due(t))
            .collect();
        assert_eq!(
            due,
            [
                334_000, 667_000, 1_000_000, 1_334_000, 1_667_000, 2_000_000, 2_334_000, 2_667_000,
                3_000_000
            ]
        );
        // A new board's clock starts again.
        c.restart();
        assert!(!c.due(1000) && c.due(333_333));
        assert_eq!(board_seconds(85_000_000), "85.000000");
        assert_eq!(board_seconds(1_000_001), "1.000001");
    }
}
