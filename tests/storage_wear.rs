//! 10,000 consecutive saves on the board-sized RAM flash: no error, wear spread over both sectors.

mod storage_support;

use odocal::storage::{ParamRecord, ParamStore};
use storage_support::{BOARD_RANGE, BoardFlash, SECTOR, calibrated};

const SAVES: u32 = 10_000;

#[test]
fn ten_thousand_saves_level_wear_over_both_sectors() {
    let mut flash = Box::new(BoardFlash::default());
    let mut store = ParamStore::new(&mut *flash, BOARD_RANGE).unwrap();
    for n in 0..SAVES {
        store
            .save_blocking(&calibrated(n), true)
            .unwrap_or_else(|e| panic!("save {n} failed: {e}"));
    }
    let out = store.load_blocking();
    assert_eq!(out.warning, None);
    assert_eq!(out.record, calibrated(SAVES - 1));
    let erases = store.flash().erase_counts();
    let written = store.flash().bytes_touched();
    println!(
        "{SAVES} saves: erases per 128 KiB sector {erases:?}, {written} bytes written or erased"
    );

    // Expected erases: every save appends one item (8-byte header + 1-byte key + record); each
    // erase reclaims one sector minus its two page-state bytes. Tolerance 2: the first two
    // sectors fill without an erase, and the last one may be partly filled.
    let item = (8 + 1 + ParamRecord::ENCODED_LEN) as f64;
    let expected = f64::from(SAVES) * item / (SECTOR - 2) as f64;
    let total = f64::from(erases[0] + erases[1]);
    assert!(
        (total - expected).abs() <= 2.0,
        "erases {total}, expected {expected:.1}"
    );
    // Levelling: the sectors are used in turn, so their erase counts differ by at most one.
    assert!(erases[0].abs_diff(erases[1]) <= 1, "{erases:?}");
}
