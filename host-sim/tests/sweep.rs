//! `host-sim sweep` on a tiny grid: two sides, one noise level.

use host_sim::experiments::sweep::{SWEEP_METHODS, SweepArgs, csv, sweep, write_outputs};
use indicatif::ProgressBar;
use odocal::calibration::Method;

fn tiny() -> SweepArgs {
    SweepArgs {
        sides: vec![1.0, 8.0],
        meas_sigmas: vec![0.002],
        slips: vec![0.0005],
        trials: 24,
        ..SweepArgs::default()
    }
}

#[test]
fn tiny_sweep_matches_the_advice_and_is_reproducible() {
    let a = tiny();
    let r = sweep(&a, &ProgressBar::hidden()).unwrap();
    assert_eq!(r.cells.len(), 2);
    assert_eq!(r.best.len(), SWEEP_METHODS.len());
    let k = SWEEP_METHODS
        .iter()
        .position(|m| *m == Method::UmbmarkX)
        .unwrap();
    let (small, large) = (&r.cells[0].methods[k], &r.cells[1].methods[k]);
    assert_eq!(small.n + small.failed, 24);
    // UMBmark's small-angle bias grows with L (≈1e-2 at 8 m for E_b = 1.01, against ≈5e-4 of
    // random error at 1 m), so 8 m is worse by far; a factor 5 leaves room for the noise.
    assert!(
        large.rms_error > 5.0 * small.rms_error,
        "{} vs {}",
        large.rms_error,
        small.rms_error
    );
    // The advice predicts the RMS error: with 24 trials the RMS itself scatters by
    // ~1/sqrt(2·24) ≈ 15 %, so a factor 1.5 either way is a > 3σ bound.
    for c in &r.cells {
        let s = &c.methods[k];
        let p = s.predicted.unwrap();
        assert!(
            s.rms_error < 1.5 * p && s.rms_error > p / 1.5,
            "L = {}: sweep {} vs advice {p}",
            c.side_m,
            s.rms_error
        );
    }
    let b = r
        .best
        .iter()
        .find(|b| b.method == Method::UmbmarkX)
        .unwrap();
    assert_eq!(b.sweep.unwrap().0, 1.0);
    assert_eq!(b.advice_on_grid.unwrap().0, 1.0);
    // Seeds are per trial, so the thread schedule does not change the numbers.
    assert_eq!(sweep(&a, &ProgressBar::hidden()).unwrap(), r);

    let text = csv(&r);
    assert_eq!(text.lines().count(), 1 + 2 * SWEEP_METHODS.len());
    let dir = std::env::temp_dir().join(format!("odocal-sweep-{}", std::process::id()));
    let files = write_outputs(&r, &dir).unwrap();
    assert_eq!(files.len(), 2);
    assert!(std::fs::read_to_string(&files[1]).unwrap().contains("<svg"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn empty_grid_is_an_error() {
    let a = SweepArgs {
        sides: vec![],
        ..tiny()
    };
    assert!(sweep(&a, &ProgressBar::hidden()).is_err());
}
