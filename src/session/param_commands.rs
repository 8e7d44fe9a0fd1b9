//! The parameter commands: `set <name> <value>` (validated, handed to the controller at once,
//! not saved), `save` (the settings into the flash record) and `reset-params` (the defaults,
//! handed to the controller, not saved).
//!
//! Owns the rule that a calibration is relative to the nominal geometry it was computed for:
//! `set` of a geometry parameter drops it, and setting the old value back restores it.

use core::fmt::{self, Write};

use super::traits::{Calibrator, Robot, RobotError, SettingsAndRuns};
use super::{Dropped, Session, Settings, robot_err, storable, storage_err};
use crate::protocol::ParamGroup;
use crate::protocol::ParamName;
use crate::protocol::outcome::{ParamOutcome, SetChange, write_param_outcome};
use crate::protocol::refusal::{Refusal, write_refusal};

/// Hands every part of `settings` the controller runs with to `robot`: the active geometry, the
/// motion limits, the wiring, the speed-loop tuning and the control rate (the same parts as
/// [`Settings::controller_config`], which boots the controller).
///
/// # Errors
/// The first part the robot refuses (all are accepted while it is idle).
fn push_settings(robot: &mut dyn Robot, settings: &Settings) -> Result<(), RobotError> {
    robot.set_geometry(settings.active)?;
    robot.set_limits(&settings.motion)?;
    robot.set_wiring(settings.wiring)?;
    robot.set_tuning(&settings.tuning)?;
    robot.set_rate(settings.control_hz)
}

impl<C: Calibrator> Session<C> {
    /// `set <name> <value>`: refused while anything moves; says whether a calibration was
    /// dropped or restored with it.
    pub(super) fn set(
        &mut self,
        name: ParamName,
        value: f64,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        if robot.status().is_busy() {
            return robot_err(out, RobotError::Busy, robot);
        }
        let (mut new, changed) = match self.settings.with_value(name, value) {
            Ok(x) => x,
            Err(e) => return write_refusal(out, &Refusal::InvalidParams { why: &e }),
        };
        let Some(changed) = changed else {
            let outcome = ParamOutcome::Set {
                name,
                value: self.settings.value(name),
                change: SetChange::Unchanged,
            };
            return write_param_outcome(out, &outcome);
        };
        // A calibration is relative to the nominal geometry it was computed for: it is dropped
        // when that changes, and restored when the geometry is set back.
        let mut restored = None;
        if changed == ParamGroup::Geometry
            && let Some(d) = &self.dropped
            && d.nominal == new.nominal
        {
            new.active = d.active;
            new.calibration = Some(d.calibration.clone());
            restored = Some(d.calibration.method.clone());
        }
        let pushed = match changed {
            ParamGroup::Geometry => robot.set_geometry(new.active),
            ParamGroup::Motion => robot.set_limits(&new.motion),
            ParamGroup::Plan => Ok(()),
            ParamGroup::Wiring => robot.set_wiring(new.wiring),
            ParamGroup::Tuning => robot.set_tuning(&new.tuning),
            ParamGroup::Rate => robot.set_rate(new.control_hz),
        };
        if let Err(e) = pushed {
            return robot_err(out, e, robot);
        }
        let dropped = match (&self.settings.calibration, changed) {
            (Some(c), ParamGroup::Geometry) => {
                self.dropped = Some(Dropped {
                    nominal: self.settings.nominal,
                    active: self.settings.active,
                    calibration: c.clone(),
                });
                Some(c.method.clone())
            }
            _ => None,
        };
        if restored.is_some() && dropped.is_none() {
            self.dropped = None;
        }
        self.settings = new;
        self.unsaved = true;
        let change = match (&restored, &dropped) {
            (Some(m), _) => SetChange::CalibrationRestored(m),
            (None, Some(m)) => SetChange::CalibrationDropped(m),
            (None, None) => SetChange::Changed,
        };
        let outcome = ParamOutcome::Set {
            name,
            value: self.settings.value(name),
            change,
        };
        write_param_outcome(out, &outcome)
    }

    /// `save`: stores the settings, refused when they do not make a valid record or the motors
    /// are not confirmed stopped.
    pub(super) fn save(
        &mut self,
        robot: &mut dyn Robot,
        storage: &mut dyn SettingsAndRuns,
        out: &mut dyn Write,
    ) -> fmt::Result {
        if let Err(e) = storable(&self.settings) {
            return storage_err(out, e);
        }
        // A store that can never write says so before the motors are asked about.
        if let Err(e) = storage.usable() {
            return storage_err(out, e);
        }
        let stopped = match robot.motors_stopped() {
            Ok(stopped) => stopped,
            Err(e) => return write_refusal(out, &Refusal::MotorsRunning(e)),
        };
        // The parameter region is apart from the runs': a save leaves the run region alone.
        match storage.save(&self.settings, stopped) {
            Ok(()) => {
                self.unsaved = false;
                write_param_outcome(out, &ParamOutcome::Saved)
            }
            Err(e) => storage_err(out, e),
        }
    }

    /// `reset-params [yes]`: hands the default settings to the controller (every part:
    /// geometry, limits, wiring, tuning, rate), in RAM only like `set` (`save` stores them);
    /// refused while anything moves, and without `yes` when it would discard an applied
    /// calibration or a change not saved.
    pub(super) fn reset_params(
        &mut self,
        confirmed: bool,
        robot: &mut dyn Robot,
        out: &mut dyn Write,
    ) -> fmt::Result {
        let defaults = Settings::default();
        if robot.status().is_busy() {
            return robot_err(out, RobotError::Busy, robot);
        }
        let calibration = self
            .settings
            .calibration
            .as_ref()
            .map(|c| c.method.as_str());
        let unsaved = self.unsaved && self.settings != defaults;
        if !confirmed && (calibration.is_some() || unsaved) {
            let refusal = Refusal::ResetUnconfirmed {
                calibration,
                unsaved,
            };
            return write_refusal(out, &refusal);
        }
        // Idle was checked above, so the controller accepts every part.
        if let Err(e) = push_settings(robot, &defaults) {
            return robot_err(out, e, robot);
        }
        // RAM now differs from the flash, unless both hold the defaults (a further reset then
        // finds nothing to discard: the settings equal the defaults).
        self.unsaved = true;
        self.settings = defaults;
        self.dropped = None;
        write_param_outcome(out, &ParamOutcome::Reset)
    }
}
