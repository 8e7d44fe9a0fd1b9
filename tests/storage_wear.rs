//! 10,000 consecutive saves on the board-sized RAM flash: no error, wear spread over both
//! parameter sectors, the run region untouched.

mod storage_support;

use odocal::storage::ParamRecord;
use odocal::storage::params::slot_len;
use storage_support::{BoardFlash, SECTOR, STOPPED, board_store, calibrated};

const SAVES: u32 = 10_000;

#[test]
fn ten_thousand_saves_level_wear_over_both_sectors() {
    let mut flash = Box::new(BoardFlash::default());
    let mut store = board_store(&mut *flash);
    for n in 0..SAVES {
        store
            .save_blocking(&calibrated(n), STOPPED)
            .unwrap_or_else(|e| panic!("save {n} failed: {e}"));
    }
    let out = store.load_blocking();
    assert_eq!(out.warning, None);
    assert_eq!(out.record, calibrated(SAVES - 1));
    let erases = store.flash().erase_counts();
    let written = store.flash().bytes_touched();
    println!(
        "{SAVES} saves: erases per 16 KiB parameter sector {:?}, {written} bytes written or erased",
        &erases[..2]
    );

    // Every save appends one slot (12-byte header + record); a sector holds a whole number of
    // them, and each save that finds its sector full erases the other one: one erase per
    // sector's worth of saves after the first.
    let per_sector = (SECTOR / slot_len(ParamRecord::ENCODED_LEN, 1)) as u32;
    assert_eq!(erases[0] + erases[1], (SAVES - 1) / per_sector);
    // Levelling: the sectors are used in turn, so their erase counts differ by at most one.
    assert!(erases[0].abs_diff(erases[1]) <= 1, "{erases:?}");
    // The run region is never touched by a parameter save.
    assert!(erases[2..].iter().all(|&e| e == 0), "{erases:?}");
    println!(
        "{per_sector} saves per sector: about {:.2} million saves at 10,000 erases per sector",
        2.0 * 10_000.0 * f64::from(per_sector) / 1e6
    );
}
