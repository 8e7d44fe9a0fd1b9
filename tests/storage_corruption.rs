//! Damaged flash contents: boot falls back to defaults with a warning, and the next save works.

mod storage_support;

use odocal::storage::ParamRecord;
use storage_support::{BoardFlash, Rng, STOPPED, board_store, calibrated};

/// Saves `rec`, checks it loads, then the flash is damaged by `damage`; the next boot must give
/// defaults with a warning (never a panic, never garbage) and a new save must load back.
fn damaged_boot(seed: u64, damage: impl Fn(&mut BoardFlash, &mut Rng)) {
    let mut rng = Rng(seed);
    let mut flash = Box::new(BoardFlash::default());
    let rec = calibrated(seed as u32);
    {
        let mut store = board_store(&mut *flash);
        store.save_blocking(&rec, STOPPED).unwrap();
        assert_eq!(store.load_blocking().record, rec);
    }
    damage(&mut flash, &mut rng);

    let mut store = board_store(&mut *flash);
    let out = store.load_blocking();
    assert_eq!(out.record, ParamRecord::DEFAULT, "seed {seed}");
    assert!(out.warning.is_some(), "seed {seed}");

    let next = calibrated(seed as u32 + 1);
    store
        .save_blocking(&next, STOPPED)
        .unwrap_or_else(|e| panic!("seed {seed}: save after damage failed: {e}"));
    // The parameter region is repaired without wiping anything.
    assert_eq!(store.wipes(), 0, "seed {seed}");
    let out = store.load_blocking();
    assert_eq!(out.warning, None, "seed {seed}");
    assert_eq!(out.record, next, "seed {seed}");
}

/// The whole storage area (both regions) overwritten with random bytes.
#[test]
fn random_contents_give_defaults_and_the_next_save_works() {
    for seed in 0..8 {
        damaged_boot(seed, |flash, rng| {
            for i in 0..BoardFlash::CAPACITY {
                flash.corrupt_byte(i, rng.next_u64() as u8);
            }
        });
    }
}

/// Random bit flips inside the stored item only (bit rot): the CRC must catch every one.
#[test]
fn bit_flips_in_the_record_give_defaults_and_the_next_save_works() {
    for seed in 100..164 {
        damaged_boot(seed, |flash, rng| {
            // The only record is the parameter region's first slot; find its programmed bytes.
            let written: Vec<usize> = (1..4096).filter(|&i| flash.byte(i) != Some(0xFF)).collect();
            assert!(written.len() > ParamRecord::ENCODED_LEN);
            for _ in 0..=rng.below(3) {
                let at = written[rng.below(written.len())];
                let bit = 1u8 << rng.below(8);
                let b = flash.byte(at).unwrap();
                flash.corrupt_byte(at, b ^ bit);
            }
        });
    }
}

/// Random runs of garbage written over the first parameter sector (a stray program or a
/// glitching erase).
#[test]
fn garbage_bursts_give_defaults_and_the_next_save_works() {
    for seed in 200..232 {
        damaged_boot(seed, |flash, rng| {
            let start = rng.below(64);
            let len = 16 + rng.below(512);
            for i in start..start + len {
                flash.corrupt_byte(i, rng.next_u64() as u8);
            }
        });
    }
}

/// The newest record has a valid checksum but does not validate (a value out of range, as
/// another firmware could have written it): boot loads the valid record before it, says why
/// the newest was not used (in the boot line too), and the next save becomes the newest.
#[test]
fn load_falls_back_to_the_older_valid_record() {
    use odocal::session::write_boot_event;
    use odocal::storage::{LoadWarning, PARAM_DATA_MAX, params};
    use storage_support::BOARD_PARAMS;

    let mut flash = Box::new(BoardFlash::default());
    let older = calibrated(1);
    board_store(&mut *flash)
        .save_blocking(&older, STOPPED)
        .unwrap();
    // A record whose motion limit is out of range, appended as the newest slot (checksum ok).
    let mut bad = calibrated(2);
    bad.motion.max_speed_mps = 99.0;
    let mut buf = vec![0u8; 2048];
    let len = bad.encode(&mut buf[params::HEADER..]).unwrap();
    embassy_futures::block_on(params::append(
        &mut *flash,
        &BOARD_PARAMS,
        &mut buf,
        len,
        PARAM_DATA_MAX,
    ))
    .unwrap();

    let mut store = board_store(&mut *flash);
    let loaded = store.load_blocking();
    assert_eq!(loaded.record, older);
    assert_eq!(loaded.warning, None);
    assert!(
        matches!(loaded.older, Some(LoadWarning::Invalid(_))),
        "{loaded:?}"
    );
    let mut line = String::new();
    write_boot_event(&mut line, &loaded, &[], Some("power-on"), None).unwrap();
    assert_eq!(
        line,
        "event boot: parameters loaded (previous record; newest: stored parameters invalid: \
         motion limits: max speed must be within 0.01..2 m/s), reset: power-on\r\n"
    );

    let next = calibrated(3);
    store.save_blocking(&next, STOPPED).unwrap();
    let loaded = store.load_blocking();
    assert_eq!(
        (loaded.record, loaded.warning, loaded.older),
        (next, None, None)
    );
}
