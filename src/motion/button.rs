//! User button: debouncing and short/long press classification, from time-stamped levels.
//!
//! Pure logic: the board feeds raw level changes with a millisecond time stamp ([`Button::edge`],
//! from the EXTI interrupt) and polls ([`Button::poll`], from a periodic task) — or simply
//! samples the level periodically ([`Button::sample`]). A level counts once it has been stable for
//! `debounce_ms`. A **long** press is reported as soon as the button has been held for
//! `long_press_ms` (so an abort does not wait for the release); a **short** press is reported on
//! release. Time stamps are wrapping `u32` milliseconds (all differences use `wrapping_sub`).

/// Debounce and classification times.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ButtonConfig {
    /// A level must be stable this long to count, ms.
    pub debounce_ms: u32,
    /// Held at least this long (debounced) is a long press, ms.
    pub long_press_ms: u32,
}

impl ButtonConfig {
    /// 20 ms debounce, 1 s long press.
    pub const DEFAULT: ButtonConfig = ButtonConfig {
        debounce_ms: 20,
        long_press_ms: 1000,
    };
}

impl Default for ButtonConfig {
    fn default() -> Self {
        ButtonConfig::DEFAULT
    }
}

/// A classified press.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Press {
    /// Pressed and released before `long_press_ms` (reported on release): start the next run.
    Short,
    /// Held for `long_press_ms` (reported while still held): abort.
    Long,
}

/// Debouncer and classifier state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Button {
    config: ButtonConfig,
    /// Latest raw level (true = pressed) and when it was seen first.
    raw: bool,
    raw_since_ms: u32,
    /// Debounced level.
    stable: bool,
    /// When the debounced press began (its first raw edge).
    pressed_at_ms: u32,
    /// A long press was already reported for the current press.
    long_reported: bool,
}

impl Button {
    /// A released button.
    pub const fn new(config: ButtonConfig) -> Self {
        Button {
            config,
            raw: false,
            raw_since_ms: 0,
            stable: false,
            pressed_at_ms: 0,
            long_reported: false,
        }
    }

    /// Records the raw level seen at `now_ms` (call on every edge; repeated levels are ignored).
    pub fn edge(&mut self, now_ms: u32, pressed: bool) {
        if pressed != self.raw {
            self.raw = pressed;
            self.raw_since_ms = now_ms;
        }
    }

    /// Advances the debouncer to `now_ms` and returns a press when one was completed.
    pub fn poll(&mut self, now_ms: u32) -> Option<Press> {
        let mut event = None;
        if self.raw != self.stable
            && now_ms.wrapping_sub(self.raw_since_ms) >= self.config.debounce_ms
        {
            self.stable = self.raw;
            if self.stable {
                self.pressed_at_ms = self.raw_since_ms;
                self.long_reported = false;
            } else if !self.long_reported {
                event = Some(Press::Short);
            }
        }
        if self.stable
            && !self.long_reported
            && now_ms.wrapping_sub(self.pressed_at_ms) >= self.config.long_press_ms
        {
            self.long_reported = true;
            event = Some(Press::Long);
        }
        event
    }

    /// [`Button::edge`] then [`Button::poll`]: for a periodically sampled pin.
    pub fn sample(&mut self, now_ms: u32, pressed: bool) -> Option<Press> {
        self.edge(now_ms, pressed);
        self.poll(now_ms)
    }

    /// The debounced level.
    pub fn is_pressed(&self) -> bool {
        self.stable
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples a level trace given as (from_ms, level) steps every ms until `end`.
    fn run(start: u32, trace: &[(u32, bool)], end: u32) -> std::vec::Vec<(u32, Press)> {
        let mut b = Button::new(ButtonConfig::DEFAULT);
        let mut out = std::vec::Vec::new();
        let mut level = false;
        for t in 0..end {
            if let Some(&(_, l)) = trace.iter().rev().find(|(from, _)| *from <= t) {
                level = l;
            }
            let now = start.wrapping_add(t);
            if let Some(p) = b.sample(now, level) {
                out.push((t, p));
            }
        }
        out
    }

    #[test]
    fn short_press_with_bounces() {
        // Bounces at press and release, 200 ms hold.
        let trace = [
            (100, true),
            (102, false),
            (104, true),
            (300, false),
            (301, true),
            (303, false),
        ];
        let events = run(0, &trace, 600);
        // Reported once, 20 ms after the last release bounce.
        assert_eq!(events, [(323, Press::Short)]);
    }

    #[test]
    fn long_press_is_reported_while_held_and_not_again_on_release() {
        let trace = [(100, true), (2500, false)];
        let events = run(0, &trace, 3000);
        // Held from 100 ms: long at 100 + 1000.
        assert_eq!(events, [(1100, Press::Long)]);
    }

    #[test]
    fn glitch_shorter_than_debounce_is_ignored() {
        let trace = [(100, true), (110, false)];
        assert!(run(0, &trace, 500).is_empty());
    }

    #[test]
    fn works_across_the_timestamp_wrap() {
        let trace = [(100, true), (250, false)];
        let events = run(u32::MAX - 150, &trace, 600);
        assert_eq!(events, [(270, Press::Short)]);
        let trace = [(100, true)];
        let events = run(u32::MAX - 500, &trace, 2000);
        assert_eq!(events, [(1100, Press::Long)]);
    }
}
