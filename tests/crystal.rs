//! The boards' crystal decision (`odocal::board::crystal`): from the count of internal-oscillator
//! ticks over a fixed number of external clock periods alone, every board's documented crystal
//! is recognised wherever the internal oscillator (HSI) runs in its rated range, and a crystal
//! that is none of them boots on the HSI with a boot note that says what was measured.

use odocal::board::crystal::{
    BLACKPILL_F411CE_CRYSTALS, ClockNote, Crystal, F407_CRYSTALS, HSI_HZ, HSI_MAX_HZ, HSI_MIN_HZ,
    NUCLEO_F446RE_CRYSTALS, expected_count, identify,
};

/// Every board's documented external clocks, by board.
const BOARDS: &[(&str, &[u32])] = &[
    ("f407", F407_CRYSTALS),
    ("nucleo-f446re", NUCLEO_F446RE_CRYSTALS),
    ("blackpill-f411ce", BLACKPILL_F411CE_CRYSTALS),
];

/// HSI frequencies across its whole rated range (−8 % … +4.5 %), both ends included, Hz.
fn hsi_range() -> impl Iterator<Item = u32> {
    (HSI_MIN_HZ..=HSI_MAX_HZ)
        .step_by(10_000)
        .chain([HSI_MAX_HZ])
}

#[test]
fn unknown_crystal_boots_on_hsi_and_says_so() {
    // Every documented crystal of every board, whatever the HSI's error: recognised, and the
    // PLL is set for it.
    for &(board, crystals) in BOARDS {
        for (index, &hz) in crystals.iter().enumerate() {
            for hsi in hsi_range() {
                let count = expected_count(hz, hsi);
                for quantised in [count - 1, count, count + 1] {
                    let found = identify(quantised, crystals);
                    assert_eq!(
                        found,
                        Crystal::Documented { index, hz },
                        "{board}: {hz} Hz crystal, HSI at {hsi} Hz, count {quantised}"
                    );
                    assert_eq!(found.pll_source_hz(), hz);
                }
            }
        }
    }
    // A crystal none of the board's documents (the Black Pill's 8 MHz on a board that only
    // documents 25 MHz is covered by its list; these are not on any list): over the HSI's whole
    // range it is unknown, the PLL runs from the HSI, and the note says the measured frequency.
    for &(board, crystals) in BOARDS {
        for unknown in [4_000_000, 6_000_000, 12_000_000, 16_000_000] {
            for hsi in hsi_range() {
                let found = identify(expected_count(unknown, hsi), crystals);
                let Crystal::Unknown { measured_hz } = found else {
                    panic!("{board}: {unknown} Hz taken for {found:?} (HSI at {hsi} Hz)");
                };
                assert_eq!(found.pll_source_hz(), HSI_HZ);
                // The measurement is as wrong as the HSI is, and no more (0.1 % quantisation).
                let expected = unknown as f64 * HSI_HZ as f64 / hsi as f64;
                assert!(
                    (measured_hz as f64 - expected).abs() <= expected * 1e-3,
                    "{board}: {unknown} Hz measured {measured_hz} Hz at HSI {hsi} Hz"
                );
            }
            let count = expected_count(unknown, HSI_HZ);
            let Crystal::Unknown { measured_hz } = identify(count, crystals) else {
                panic!("{board}: {unknown} Hz recognised");
            };
            let note = ClockNote {
                text: "clock: internal oscillator (HSI 16 MHz), 100 MHz",
                unknown_crystal_hz: Some(measured_hz),
            }
            .to_string();
            assert_eq!(
                note,
                format!(
                    "clock: internal oscillator (HSI 16 MHz), 100 MHz; crystal measured at {} \
                     kHz, none of the board's: HSE off",
                    measured_hz / 1000
                ),
                "{board}"
            );
        }
        // No edge seen at all (the timer never captured): unknown, measured as 0.
        assert_eq!(identify(0, crystals), Crystal::Unknown { measured_hz: 0 });
    }
    // A documented crystal's note is the board's text alone.
    let note = ClockNote {
        text: "clock: 25 MHz crystal (HSE), 100 MHz",
        unknown_crystal_hz: None,
    };
    assert_eq!(note.to_string(), "clock: 25 MHz crystal (HSE), 100 MHz");
}
