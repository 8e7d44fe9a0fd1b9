//! The robot's setup before the squares: what the board holds (factory defaults or not), the
//! nominal geometry (with how to measure it), the bring-up check (push, then wheels up; its
//! proposals applied only on a yes) and the motor identification. Each step can be skipped, and
//! is skipped by default when the board already holds its result.

use std::time::Duration;

use odocal::kinematics::geometry::Geometry;
use odocal::motion::bringup::CheckKind;
use odocal::motion::identify::IdentifyMode;
use odocal::motion::speed::MotorParams;
use odocal::protocol::token::{self, EventTag};
use odocal::protocol::{Command, ErrorCode, FinalLine, ParamName};

use super::{Guide, REPLY, Stop, WHEEL_DIAMETER_M, WHEELBASE_M, event_head, event_tag};
use crate::log::{calibration_of, param};

/// How to measure the nominal geometry, and how precisely it needs to be known.
pub(super) const HOW_TO_MEASURE: &str = "\
  How to measure the nominal geometry:
  - D_R, D_L (each wheel's diameter): mark the tyre where it touches the floor, roll the robot
    straight along a tape measure for 10 wheel revolutions and divide the distance by 10*pi
    (a 150 mm wheel rolls 4.71 m; reading the tape to 5 mm gives D to 0.16 mm, 0.1 %). The
    squares correct D_R/D_L and b, not the mean diameter: its error is the scale error of every
    distance the robot drives, so measure it as well as you can (a line run measures it too).
  - b (wheelbase): from the middle of one tyre's contact patch to the other's, e.g. the outer
    edges' distance minus one tyre width, to about 1 mm (0.3 %): the calibration corrects it.
  - counts per revolution: encoder lines per motor turn x 4 (quadrature) x the gear ratio,
    from the data sheets; it must be exact.
  Every length with its unit (150mm, 15 cm, 0.15m): a bare number is refused.";

/// A length in metres as sent to the board: to the picometre, without the binary noise of a
/// unit conversion (`150mm` is `0.15`, not `0.15000000000000002`).
pub(super) fn metres_text(v: f64) -> String {
    let s = format!("{v:.12}");
    let s = s.trim_end_matches('0');
    s.strip_suffix('.').unwrap_or(s).to_string()
}

/// What the board holds, from its `params` reply.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Holds {
    /// A nominal geometry other than the factory one.
    pub geometry: bool,
    /// A wiring correction (a sign reversed).
    pub wiring: bool,
    /// A motor tuning other than the factory one (identified or entered).
    pub tuning: bool,
    /// An applied calibration.
    pub calibration: bool,
}

impl Holds {
    /// Reads a `params` reply's data lines.
    pub fn of(params: &[String]) -> Holds {
        let n = Geometry::PAPER_NOMINAL;
        let differs = |name: &str, v: f64, resolution: f64| {
            param(params, name).is_none_or(|p| (p - v).abs() > resolution)
        };
        // The board prints lengths with 9 decimals and the motor parameters with 4.
        let geometry = differs("d_right", n.diameter_right_m, 1e-9)
            || differs("d_left", n.diameter_left_m, 1e-9)
            || differs("wheelbase", n.wheelbase_m, 1e-9)
            || differs("counts_per_rev", f64::from(n.counts_per_rev), 0.5);
        let wiring = [
            "motor_right_sign",
            "motor_left_sign",
            "encoder_right_sign",
            "encoder_left_sign",
        ]
        .iter()
        .any(|s| differs(s, 1.0, 0.0));
        let m = MotorParams::DEFAULT;
        let tuning = ["right", "left"].iter().any(|w| {
            differs(
                &format!("motor_{w}_gain_fwd"),
                f64::from(m.gain_forward_mps),
                5e-5,
            ) || differs(
                &format!("motor_{w}_gain_back"),
                f64::from(m.gain_backward_mps),
                5e-5,
            ) || differs(
                &format!("motor_{w}_tau"),
                f64::from(m.time_constant_s),
                5e-5,
            ) || differs(&format!("motor_{w}_deadband"), f64::from(m.deadband), 5e-5)
        });
        Holds {
            geometry,
            wiring,
            tuning,
            calibration: calibration_of(params) != "none",
        }
    }

    /// Nothing entered: the parameters are the factory defaults.
    pub fn factory(&self) -> bool {
        !(self.geometry || self.wiring || self.tuning || self.calibration)
    }
}

impl Guide {
    /// What the board holds, before the setup steps ([`super::Step`]: geometry, bring-up,
    /// identification).
    pub(super) fn setup_intro(&mut self, holds: Holds) {
        if holds.factory() {
            self.ui.say(
                "the board holds the factory defaults (nothing entered, or not saved): the \
                 robot's setup comes first: nominal geometry, bring-up check, motor \
                 identification",
            );
        } else {
            let yes_no = |b: bool| if b { "entered" } else { "factory default" };
            self.ui.say(&format!(
                "the board holds: geometry {}, wiring {}, motor tuning {}, calibration {}",
                yes_no(holds.geometry),
                if holds.wiring {
                    "corrected"
                } else {
                    "standard"
                },
                if holds.tuning {
                    "identified or entered"
                } else {
                    "factory default"
                },
                if holds.calibration { "applied" } else { "none" }
            ));
        }
    }

    /// Asks `question` with `choices` (`key: meaning`); `help` and `?` show `help`, an empty
    /// answer takes `default`. Returns the key chosen.
    pub(super) fn choose(
        &mut self,
        question: &str,
        choices: &[(&str, &str)],
        default: &str,
        help: &str,
    ) -> Result<String, Stop> {
        let keys: Vec<String> = choices.iter().map(|(k, m)| format!("{k}: {m}")).collect();
        loop {
            let a = self
                .ui
                .ask(&format!("{question} ({})", keys.join(", ")), Some(default))?
                .to_ascii_lowercase();
            if let Some((k, _)) = choices
                .iter()
                .find(|(k, m)| a == *k || a == m.split_whitespace().next().unwrap_or(""))
            {
                return Ok((*k).to_string());
            }
            if a != "help" && a != "?" {
                self.ui.say(&format!("  `{a}` is none of these"));
            }
            self.ui.say(help);
        }
    }

    /// The nominal geometry: kept, or entered question by question (`back` returns to the
    /// question before; from the first, to the choice; from the choice, to the step before).
    pub(super) fn geometry_step(&mut self, held: bool) -> Result<(), Stop> {
        let (d_right, d_left, b, counts) = loop {
            let n = self.nominal;
            let now = format!(
                "D_R={} m D_L={} m b={} m, {} counts/rev",
                n.diameter_right_m, n.diameter_left_m, n.wheelbase_m, n.counts_per_rev
            );
            self.ui.say(&format!(
                "step: nominal geometry ({} on the board: {now})",
                if held { "entered" } else { "factory default" }
            ));
            let help = format!(
                "  e enters the robot's measured wheel diameters, wheelbase and encoder counts; k \
                 keeps the board's ({now}).\n{HOW_TO_MEASURE}"
            );
            let choice = self.choose(
                "Nominal geometry",
                &[("e", "enter it"), ("k", "keep the board's")],
                if held { "k" } else { "e" },
                &help,
            )?;
            if choice == "k" {
                return Ok(());
            }
            self.ui.say(HOW_TO_MEASURE);
            if let Some(entered) = self.ask_geometry()? {
                break entered;
            }
        };
        for (name, value) in [
            (ParamName::DiameterRight, d_right),
            (ParamName::DiameterLeft, d_left),
            (ParamName::Wheelbase, b),
            (ParamName::CountsPerRev, f64::from(counts)),
        ] {
            let r = self.cmd(Command::Set { name, value })?;
            self.ui.say(&format!("  {}", r.last));
            if token::is_not_saved(&r.last) && !self.pending.contains(&"nominal geometry") {
                self.pending.push("nominal geometry");
            }
            if !r.ok() {
                self.ui.warn(&format!(
                    "the board refused {} {value}: the geometry stays as it was for it",
                    name.as_str()
                ));
            }
        }
        self.done.geometry = true;
        let params = self.cmd(Command::Params)?;
        if let Some(g) = crate::log::nominal_of(&params.data) {
            self.nominal = g;
        }
        self.link.log.entry(
            "nominal",
            serde_json::json!({ "params": params.data }),
            true,
        );
        Ok(())
    }

    /// D_R, D_L, b and the counts per revolution, each question in turn (defaults: the board's);
    /// `back` goes to the one before, and from the first `None` (to the choice).
    fn ask_geometry(&mut self) -> Result<Option<(f64, f64, f64, u32)>, Stop> {
        let n = self.nominal;
        let (mut d_right, mut d_left, mut b) =
            (n.diameter_right_m, n.diameter_left_m, n.wheelbase_m);
        let mut step = 0;
        loop {
            let answer = match step {
                0 => self.ask_length("Right wheel diameter D_R", d_right, WHEEL_DIAMETER_M),
                1 => self.ask_length("Left wheel diameter D_L", d_right, WHEEL_DIAMETER_M),
                2 => self.ask_length("Wheelbase b", b, WHEELBASE_M),
                _ => {
                    let a = match self.ui.ask(
                        "Encoder counts per wheel revolution",
                        Some(&n.counts_per_rev.to_string()),
                    ) {
                        Err(crate::ui::AskError::Back) => {
                            step = 2;
                            continue;
                        }
                        r => r?,
                    };
                    match a.parse::<u32>() {
                        Ok(c) if c > 0 => return Ok(Some((d_right, d_left, b, c))),
                        _ => {
                            self.ui
                                .say("  a whole number of counts (lines x 4 x gear ratio)");
                            continue;
                        }
                    }
                }
            };
            match (answer, step) {
                (Err(Stop::Back), 0) => return Ok(None),
                (Err(Stop::Back), _) => step -= 1,
                (Err(e), _) => return Err(e),
                (Ok(v), 0) => (d_right, step) = (v, 1),
                (Ok(v), 1) => (d_left, step) = (v, 2),
                (Ok(v), _) => (b, step) = (v, 3),
            }
        }
    }

    /// A length in metres, typed with its unit, within the board's range.
    ///
    /// # Errors
    /// [`Stop::Back`] for `back`.
    fn ask_length(&mut self, what: &str, default: f64, plausible: (f64, f64)) -> Result<f64, Stop> {
        loop {
            let a = self.ui.ask(
                &format!("{what} (with its unit: 150mm, 15cm, 0.15m)"),
                Some(&format!("{}m", metres_text(default))),
            )?;
            if a == "help" || a == "?" {
                self.ui.say(HOW_TO_MEASURE);
                continue;
            }
            match super::length(&a, plausible) {
                Ok(v) if v > 0.0 && v <= 5.0 => return Ok(v),
                Ok(v) => self.ui.say(&format!(
                    "  {v} m is not a plausible {what} (check the unit: 150mm, 0.15m)"
                )),
                Err(e) => self.ui.say(&format!("  {e}")),
            }
        }
    }

    /// The events of a check until one starting with one of `ends`; each is shown.
    fn check_events(&mut self, ends: &[EventTag], seconds: u64) -> Result<Vec<String>, Stop> {
        let mut seen = Vec::new();
        let deadline = std::time::Instant::now() + Duration::from_secs(seconds);
        loop {
            if std::time::Instant::now() > deadline {
                return Err(Stop::Failed(format!(
                    "no `{}` from the board",
                    ends.iter()
                        .map(|e| event_head(*e))
                        .collect::<Vec<_>>()
                        .join("` or `")
                )));
            }
            let Some(l) = self.link.next_unsolicited(Duration::from_millis(200))? else {
                continue;
            };
            if !l.starts_with(token::EVENT) {
                continue;
            }
            self.ui.say(&format!("  {l}"));
            let end = event_tag(&l).is_some_and(|t| ends.contains(&t));
            seen.push(l);
            if end {
                return Ok(seen);
            }
        }
    }

    /// The bring-up check: the choice, the push check, the motor check (`back` returns to the
    /// question before; from the choice, to the step before). `run`: the default is to run it.
    pub(super) fn bringup_step(&mut self, run: bool) -> Result<(), Stop> {
        self.ui.say(
            "step: bring-up check: which way each encoder counts (you push the robot) and each \
             motor turns (short pulses, wheels off the ground)",
        );
        let help = "  r runs the check (about a minute: a push by hand, then 2 s of pulses with \
                    the wheels off the ground); s skips it (the wiring was checked before). A \
                    reversed motor or encoder makes the first square stop with a \
                    following-error fault.";
        let mut question = 0;
        loop {
            question = match question {
                0 => {
                    let choice = self.choose(
                        "Bring-up check",
                        &[("r", "run it"), ("s", "skip it")],
                        if run { "r" } else { "s" },
                        help,
                    )?;
                    if choice == "s" {
                        return Ok(());
                    }
                    1
                }
                1 => match self.push_check() {
                    Err(Stop::Back) => 0,
                    Ok(false) => return Ok(()),
                    r => {
                        r?;
                        2
                    }
                },
                _ => match self.motor_check() {
                    Err(Stop::Back) => 1,
                    r => {
                        self.done.bringup = true;
                        return r;
                    }
                },
            };
        }
    }

    /// The push check after Enter; whether the board ran it.
    fn push_check(&mut self) -> Result<bool, Stop> {
        self.ui.say(
            "  wheels on the ground, motors powered: after Enter, push the robot straight \
             forward by hand about 5 cm within 5 s",
        );
        self.ui.ask("Enter starts the push check", Some("go"))?;
        let r = self.cmd(Command::Bringup {
            kind: CheckKind::Push,
        })?;
        self.ui.say(&format!("  {}", r.last));
        if !r.ok() {
            self.check_refused(&r.last)?;
            return Ok(false);
        }
        self.check_events(&[EventTag::BringupDone], 60)?;
        Ok(true)
    }

    /// The motor check after Enter, its proposals applied on a typed yes and checked again;
    /// `back` at its first question returns to the push check (at a later one, to the motor
    /// check's start).
    fn motor_check(&mut self) -> Result<(), Stop> {
        let mut attempt = 0;
        while attempt < 3 {
            self.ui.say(
                "  now lift the wheels off the ground (robot on a box): each motor gets a short \
                 pulse forward and back",
            );
            match self.ui.ask("Enter starts the motor check", Some("go")) {
                Err(crate::ui::AskError::Back) if attempt > 0 => {
                    self.ui.say(
                        "  back: the correction is applied (and offered for save); the motor \
                         check that confirms it comes next",
                    );
                    continue;
                }
                r => r?,
            };
            let r = self.cmd(Command::Bringup {
                kind: CheckKind::Pulses,
            })?;
            self.ui.say(&format!("  {}", r.last));
            if !r.ok() {
                return self.check_refused(&r.last);
            }
            let events = self.check_events(&[EventTag::BringupDone], 60)?;
            // Each proposal is a `set` the board worded; read by its grammar, sent as read.
            let mut proposals = Vec::new();
            for l in &events {
                if let Some((EventTag::BringupPropose, set)) = EventTag::parse(l) {
                    let command = Command::parse(set)
                        .map_err(|e| Stop::Failed(format!("the board proposed `{set}`: {e}")))?;
                    proposals.push(command);
                }
            }
            if events.last().is_some_and(|l| {
                matches!(EventTag::parse(l), Some((EventTag::BringupDone, verdict)) if token::is_wiring_ok(verdict))
            }) {
                self.ui.say("  wiring ok");
                return Ok(());
            }
            if proposals.is_empty() {
                self.ui.warn(
                    "the check found a problem it has no setting for (no motion, swapped \
                     wheels): fix the wiring, then run the bring-up check again",
                );
                return Err(Stop::Failed("bring-up check: wiring not ok".into()));
            }
            let proposed: Vec<String> = proposals.iter().map(ToString::to_string).collect();
            let question = format!("Apply the proposed correction ({})", proposed.join("; "));
            let apply = attempt < 2
                && match self.ui.confirm_explicit(&question) {
                    // Back to the motor check's start: the pulses again, on Enter.
                    Err(crate::ui::AskError::Back) => continue,
                    r => r?,
                };
            if !apply {
                self.ui
                    .say("  nothing applied: the wiring is as it was (the squares need it right)");
                return Ok(());
            }
            for p in proposals {
                let r = self.cmd(p)?;
                self.ui.say(&format!("  {}", r.last));
                if !r.ok() {
                    return Err(Stop::Failed(format!("{p}: {}", r.last)));
                }
                if !self.pending.contains(&"wiring") {
                    self.pending.push("wiring");
                }
            }
            self.ui.say("  checking again with the correction");
            attempt += 1;
        }
        Ok(())
    }

    fn check_refused(&mut self, reply: &str) -> Result<(), Stop> {
        self.ui
            .warn(&format!("the board refused the check: {reply}"));
        if FinalLine::parse(reply).is_some_and(|f| f.is_err(ErrorCode::Fault)) {
            let c = self.cmd(Command::Clear)?;
            self.ui.say(&format!(
                "  {} (run the step again from a terminal, or restart)",
                c.last
            ));
        }
        Ok(())
    }

    /// The motor identification (`back` at the choice returns to the step before; at the start,
    /// to the choice).
    pub(super) fn identify_step(&mut self, tuned: bool) -> Result<(), Stop> {
        self.ui.say(
            "step: motor identification: the speed loops are tuned from each motor's gain, time \
             constant and dead-band (the factory tuning fits few robots)",
        );
        let help = "  f: on the floor with about 1 m free ahead and behind (both wheels, 4 s; \
                    includes the robot's inertia: preferred); l: lifted, wheels off the ground \
                    (each wheel in turn, 8 s); s: skip (the board keeps its tuning: do it again \
                    after changing motors, wheels, battery or payload).";
        loop {
            let choice = self.choose(
                "Motor identification",
                &[("f", "floor"), ("l", "lifted"), ("s", "skip")],
                if tuned { "s" } else { "f" },
                help,
            )?;
            let mode = match choice.as_str() {
                "f" => IdentifyMode::Floor,
                "l" => IdentifyMode::Lifted,
                _ => return Ok(()),
            };
            let start = self.ui.ask(
                &format!(
                    "Robot {}; Enter starts the identification",
                    if mode == IdentifyMode::Floor {
                        "on the floor, 1 m free ahead and behind"
                    } else {
                        "on a box, wheels off the ground"
                    }
                ),
                Some("go"),
            );
            match start {
                Err(crate::ui::AskError::Back) => continue,
                r => r?,
            };
            let r = self.cmd_timeout(Command::Identify { mode }, REPLY)?;
            self.ui.say(&format!("  {}", r.last));
            if !r.ok() {
                self.check_refused(&r.last)?;
                continue;
            }
            let events =
                self.check_events(&[EventTag::IdentifyDone, EventTag::IdentifyErr], 120)?;
            if events
                .last()
                .is_some_and(|l| event_tag(l) == Some(EventTag::IdentifyDone))
            {
                if !self.pending.contains(&"speed-loop tuning") {
                    self.pending.push("speed-loop tuning");
                }
                self.done.identify = true;
                return Ok(());
            }
            self.ui.warn(
                "the identification refused its result: the tuning is unchanged and the fault \
                 `identify` is latched; it is cleared now (see the reason above: a reversed \
                 motor or encoder needs the bring-up check)",
            );
            let c = self.cmd(Command::Clear)?;
            self.ui.say(&format!("  {}", c.last));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Holds;

    fn params(lines: &[&str]) -> Vec<String> {
        lines.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn a_length_is_sent_without_conversion_noise() {
        assert_eq!(super::metres_text(150.0 * 0.001), "0.15");
        assert_eq!(super::metres_text(38.5 * 0.01), "0.385");
        assert_eq!(super::metres_text(2.0), "2");
    }

    #[test]
    fn factory_defaults_are_told_from_an_entered_setup() {
        let mut p = params(&[
            "d_right 0.150000000 m",
            "d_left 0.150000000 m",
            "wheelbase 0.385000000 m",
            "counts_per_rev 200000 counts/rev",
            "motor_right_sign 1 (1 standard, -1 reversed)",
            "motor_left_sign 1 (1 standard, -1 reversed)",
            "encoder_right_sign 1 (1 standard, -1 reversed)",
            "encoder_left_sign 1 (1 standard, -1 reversed)",
            "motor_right_gain_fwd 1.0000 m/s per duty",
            "motor_right_gain_back 1.0000 m/s per duty",
            "motor_right_tau 0.0500 s",
            "motor_right_deadband 0.0000 duty",
            "motor_left_gain_fwd 1.0000 m/s per duty",
            "motor_left_gain_back 1.0000 m/s per duty",
            "motor_left_tau 0.0500 s",
            "motor_left_deadband 0.0000 duty",
            "calibration none",
        ]);
        assert!(Holds::of(&p).factory());
        p[1] = "d_left 0.150100000 m".into();
        assert_eq!(
            Holds::of(&p),
            Holds {
                geometry: true,
                ..Holds::default()
            }
        );
        p[1] = "d_left 0.150000000 m".into();
        p[4] = "motor_right_sign -1 (1 standard, -1 reversed)".into();
        p[14] = "motor_left_tau 0.1200 s".into();
        let h = Holds::of(&p);
        assert!(h.wiring && h.tuning && !h.geometry && !h.factory(), "{h:?}");
    }
}
