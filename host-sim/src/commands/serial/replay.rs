//! `--replay`: a recorded OptiOdom session's wheel motion as the board's encoders, from `play`
//! on, with the announcements on stdout and the recorded ground truth for `--truth-hz`.

use std::path::Path;

use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;

use super::truth::print_flushed;
use crate::sim::optiodom::playback::{Cue, Playback};
use crate::sim::optiodom::read_session;
use crate::sim::robot::Sim;

/// Where `--replay` is.
#[derive(Clone, Copy, Debug, PartialEq)]
enum ReplayState {
    /// Until `play`.
    Waiting,
    /// `t_us` of board time into the playback; runs `0..announced` have been announced.
    Playing { t_us: u64, announced: usize },
    /// Every run has played.
    Done,
}

/// `--replay`: a session's recorded wheel motion as the board's encoders.
pub(super) struct Replay {
    pub(super) playback: Playback,
    /// The session's nominal geometry, which the simulated operator sets at boot.
    pub(super) geometry: Geometry,
    state: ReplayState,
}

impl Replay {
    /// The session in `dir`, waiting for `play`.
    ///
    /// # Errors
    /// The session reader's, naming the folder or file.
    pub(super) fn open(dir: &Path) -> Result<Replay, String> {
        let session = read_session(dir)?;
        Ok(Replay {
            playback: Playback::new(&session),
            geometry: session.nominal,
            state: ReplayState::Waiting,
        })
    }

    /// The recorded counts now (a new board's encoders take them as their start).
    pub(super) fn ticks(&self) -> WheelTicks {
        match self.state {
            ReplayState::Waiting => Default::default(),
            ReplayState::Playing { t_us, .. } => self.playback.at(t_us).ticks(),
            ReplayState::Done => self.playback.at(u64::MAX).ticks(),
        }
    }

    /// Before a control period: the encoders show the recording's counts at this time.
    pub(super) fn before_period(&self, sim: &mut Sim) {
        if let ReplayState::Playing { t_us, .. } = self.state {
            sim.play_counts(self.playback.at(t_us).ticks());
        }
    }

    /// A run that starts now is announced (`replay run N started`), before its first counts
    /// and truth line; after the last one, `replay done`.
    fn announce(&mut self) -> Result<(), String> {
        let ReplayState::Playing { t_us, announced } = &mut self.state else {
            return Ok(());
        };
        match self.playback.at(*t_us) {
            Cue::Run { index, .. } if index >= *announced => {
                *announced = index + 1;
                print_flushed(&format!("replay run {} started", index + 1))
            }
            Cue::Rest { done: true, .. } => {
                self.state = ReplayState::Done;
                print_flushed("replay done")
            }
            _ => Ok(()),
        }
    }

    /// After a control period of `period_us`: the time goes on, and what starts or ends is
    /// announced.
    pub(super) fn after_period(&mut self, period_us: u64) -> Result<(), String> {
        if let ReplayState::Playing { t_us, .. } = &mut self.state {
            *t_us += period_us;
        }
        self.announce()
    }

    /// The recorded ground truth now, while a run plays.
    pub(super) fn truth(&self) -> Option<PoseF64> {
        match self.state {
            ReplayState::Playing { t_us, .. } => match self.playback.at(t_us) {
                Cue::Run { truth, .. } => Some(truth),
                Cue::Rest { .. } => None,
            },
            ReplayState::Waiting | ReplayState::Done => None,
        }
    }

    /// `play` typed on the simulator's stdin.
    pub(super) fn play(&mut self) -> Result<(), String> {
        match self.state {
            ReplayState::Waiting => {
                self.state = ReplayState::Playing {
                    t_us: 0,
                    announced: 0,
                };
                return self.announce();
            }
            ReplayState::Playing { .. } => eprintln!("sim: the replay is playing"),
            ReplayState::Done => {
                eprintln!("sim: the replay has played (start the simulator again to replay it)")
            }
        }
        Ok(())
    }
}
