//! Damaged flash contents: boot falls back to defaults with a warning, and the next save works.

mod storage_support;

use odocal::storage::ParamRecord;
use storage_support::{BoardFlash, Rng, board_store, calibrated};

/// Saves `rec`, checks it loads, then the flash is damaged by `damage`; the next boot must give
/// defaults with a warning (never a panic, never garbage) and a new save must load back.
fn damaged_boot(seed: u64, damage: impl Fn(&mut BoardFlash, &mut Rng)) {
    let mut rng = Rng(seed);
    let mut flash = Box::new(BoardFlash::default());
    let rec = calibrated(seed as u32);
    {
        let mut store = board_store(&mut *flash);
        store.save_blocking(&rec, true).unwrap();
        assert_eq!(store.load_blocking().record, rec);
    }
    damage(&mut flash, &mut rng);

    let mut store = board_store(&mut *flash);
    let out = store.load_blocking();
    assert_eq!(out.record, ParamRecord::DEFAULT, "seed {seed}");
    assert!(out.warning.is_some(), "seed {seed}");

    let next = calibrated(seed as u32 + 1);
    store
        .save_blocking(&next, true)
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
