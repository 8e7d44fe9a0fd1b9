//! What a board boots into: the controller and the session from the stored parameters, and the
//! boot event that says how they were found. The firmware's `init` and host-sim's simulated
//! board both boot through [`boot`].

use core::fmt::{self, Write};

use super::Session;
use super::crash::{CrashRecord, FILE_LEN};
use super::events::write_boot_event;
use super::traits::Calibrator;
use crate::kinematics::geometry::Geometry;
use crate::motion::controller::{ConfigError, Controller, ControllerConfig, DEFAULT_RATE_HZ};
use crate::storage::LoadOutcome;

/// Longest board note of the boot event, bytes (a longer one is cut).
pub const NOTE_LEN: usize = 384;

/// The booted controller and session.
pub struct Booted<C: Calibrator> {
    /// The controller, at the stored control rate (or on the built-in defaults).
    pub controller: Controller,
    /// The session on the stored settings (the values their rules refuse at their defaults).
    pub session: Session<C>,
    /// Why the controller refused the stored settings, when it runs on the built-in defaults.
    pub controller_refused: Option<ConfigError>,
}

/// Boots from `loaded`: the settings (the values their rules refuse take their defaults), the
/// controller for them (or for the built-in defaults, when it refuses them), the session with
/// `calibrator` and `crash` (the record a fault handler left, if any); writes the boot event to
/// `out`, naming the reset by `crash` or else `reset_cause`, and ending with what `board_note`
/// writes once it has seen the controller (the board starts its control timer at the
/// controller's rate there, and says what it found; nothing written: no note).
///
/// # Errors
/// [`ConfigError`] if the controller refuses even the built-in defaults (the library's tests
/// check that it does not); `out`'s errors are not errors of the boot, and are ignored.
pub fn boot<C: Calibrator>(
    loaded: &LoadOutcome,
    calibrator: C,
    crash: Option<CrashRecord>,
    reset_cause: Option<&str>,
    board_note: impl FnOnce(&Controller, &mut dyn Write) -> fmt::Result,
    out: &mut dyn Write,
) -> Result<Booted<C>, ConfigError> {
    let (settings, refused) = loaded.record.for_boot();
    let (controller, controller_refused) = match Controller::new(settings.controller_config()) {
        Ok(c) => (c, None),
        Err(e) => {
            let defaults = ControllerConfig::new(Geometry::default(), DEFAULT_RATE_HZ);
            (Controller::new(defaults)?, Some(e))
        }
    };
    // A fault handler's record names the reset better than the reset flags' `software`.
    let mut cause = heapless::String::<{ 24 + FILE_LEN }>::new();
    match &crash {
        Some(c) => {
            let _ = write!(cause, "{c}");
        }
        None => {
            let _ = cause.push_str(reset_cause.unwrap_or(""));
        }
    }
    let cause = (crash.is_some() || reset_cause.is_some()).then_some(cause.as_str());
    let mut note = heapless::String::<NOTE_LEN>::new();
    let _ = board_note(&controller, &mut note);
    let note = (!note.is_empty()).then_some(note.as_str());
    let _ = write_boot_event(out, loaded, &refused, cause, note);
    let mut session = Session::new(settings, calibrator);
    if let Some(crash) = crash {
        session.note_crash(crash);
    }
    Ok(Booted {
        controller,
        session,
        controller_refused,
    })
}
