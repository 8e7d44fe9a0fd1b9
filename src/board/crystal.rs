//! Which external clock a board really has: before the PLL is set, the board counts the internal
//! oscillator's ticks (HSI, 16 MHz, independent of the crystal) over a fixed number of external
//! clock periods (TIM11's input capture of HSE_RTC = HSE / [`RTC_DIVIDER`], every
//! [`EDGES_PER_CAPTURE`]th edge, over [`CAPTURES`] captures: [`HSE_PERIODS`] periods), and
//! [`identify`] decides from that count alone which of the board's documented frequencies it
//! is. A crystal that is none of them (or a count of 0: the timer saw no edge) boots on the HSI,
//! and the boot line says what was measured ([`ClockNote`]).
//!
//! Portable (no registers): the host tests cover the decision for every board's crystals over
//! the HSI's whole rated range (tests/crystal.rs).

/// The internal oscillator's nominal frequency, Hz (the core's clock out of reset).
pub const HSI_HZ: u32 = 16_000_000;
/// The HSI's lowest frequency over temperature and supply, Hz: −8 % (STM32F407, F411 and F446
/// datasheets, ACC_HSI, factory-trimmed, −40…105 °C).
pub const HSI_MIN_HZ: u32 = 14_720_000;
/// The HSI's highest frequency, Hz: +4.5 % (the same tables).
pub const HSI_MAX_HZ: u32 = 16_720_000;
/// RCC_CFGR.RTCPRE: HSE_RTC, TIM11's remapped input, is the external clock divided by 31 (the
/// largest divider: at most 1.6 MHz for a 50 MHz clock input, well below the timer's 16 MHz).
pub const RTC_DIVIDER: u32 = 31;
/// TIM11's input-capture prescaler: a capture every 8 edges of HSE_RTC.
pub const EDGES_PER_CAPTURE: u32 = 8;
/// Captures the count spans (after the first one, which starts it).
pub const CAPTURES: u32 = 8;
/// External clock periods the count spans: 1,984 (0.25 ms of an 8 MHz crystal).
pub const HSE_PERIODS: u32 = RTC_DIVIDER * EDGES_PER_CAPTURE * CAPTURES;

/// The documented external clocks of each board, Hz (in the order their boot texts name them).
/// STM32F4-Discovery class: an 8 MHz crystal.
pub const F407_CRYSTALS: &[u32] = &[8_000_000];
/// NUCLEO-F446RE: the ST-LINK's 8 MHz MCO (HSE bypass).
pub const NUCLEO_F446RE_CRYSTALS: &[u32] = &[8_000_000];
/// WeAct Black Pill F411CE: sold with a 25 MHz and with an 8 MHz crystal.
pub const BLACKPILL_F411CE_CRYSTALS: &[u32] = &[25_000_000, 8_000_000];

/// The count an external clock of `hse_hz` gives while the HSI runs at `hsi_hz` (rounded): HSI
/// ticks in [`HSE_PERIODS`] periods of the external clock.
pub const fn expected_count(hse_hz: u32, hsi_hz: u32) -> u32 {
    if hse_hz == 0 {
        return 0;
    }
    let ticks = hsi_hz as u64 * HSE_PERIODS as u64;
    ((ticks + hse_hz as u64 / 2) / hse_hz as u64) as u32
}

/// The external clock's frequency a count means at the HSI's nominal 16 MHz, Hz (0 for a count
/// of 0: nothing was measured).
pub const fn measured_hz(count: u32) -> u32 {
    if count == 0 {
        return 0;
    }
    let ticks = HSI_HZ as u64 * HSE_PERIODS as u64;
    ((ticks + count as u64 / 2) / count as u64) as u32
}

/// What the board runs on, decided from the measured count.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Crystal {
    /// One of the board's documented external clocks: `documented[index]`, `hz`. The PLL is set
    /// for it.
    Documented {
        /// Its position in the board's list (and in its boot texts).
        index: usize,
        /// Its frequency, Hz.
        hz: u32,
    },
    /// None of them (the HSE is switched off again): the core runs on the HSI.
    Unknown {
        /// What the count means at the HSI's nominal frequency, Hz (0: no edge seen).
        measured_hz: u32,
    },
}

impl Crystal {
    /// The frequency the PLL is set for: the crystal's, or the HSI's.
    pub fn pll_source_hz(self) -> u32 {
        match self {
            Crystal::Documented { hz, .. } => hz,
            Crystal::Unknown { .. } => HSI_HZ,
        }
    }
}

/// Which of `documented` (the board's external clock frequencies, Hz) gave `count`: the first
/// whose count at some HSI frequency in the rated range (±1 count of quantisation) is `count`;
/// otherwise [`Crystal::Unknown`].
pub fn identify(count: u32, documented: &[u32]) -> Crystal {
    if count != 0 {
        for (index, &hz) in documented.iter().enumerate() {
            let low = expected_count(hz, HSI_MIN_HZ).saturating_sub(1);
            let high = expected_count(hz, HSI_MAX_HZ) + 1;
            if (low..=high).contains(&count) {
                return Crystal::Documented { index, hz };
            }
        }
    }
    Crystal::Unknown {
        measured_hz: measured_hz(count),
    }
}

/// The end of the boot line: the board's text for the clock that runs, and, when the crystal
/// was none of the board's, what it measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClockNote {
    /// The board's text for the clock that runs.
    pub text: &'static str,
    /// The unknown crystal's measured frequency, Hz.
    pub unknown_crystal_hz: Option<u32>,
}

impl core::fmt::Display for ClockNote {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.text)?;
        match self.unknown_crystal_hz {
            Some(hz) => write!(
                f,
                "; crystal measured at {} kHz, none of the board's: HSE off",
                hz / 1000
            ),
            None => Ok(()),
        }
    }
}

#[cfg(target_os = "none")]
impl defmt::Format for ClockNote {
    fn format(&self, f: defmt::Formatter) {
        match self.unknown_crystal_hz {
            Some(hz) => defmt::write!(
                f,
                "{=str}; crystal measured at {=u32} kHz, none of the board's: HSE off",
                self.text,
                hz / 1000
            ),
            None => defmt::write!(f, "{=str}", self.text),
        }
    }
}
