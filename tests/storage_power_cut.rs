//! Power cut at every byte of a save: the next boot must load exactly the old or the new record.
//!
//! The sweep uses 1 KiB pages instead of the board's 128 KiB sectors so that one test run crosses
//! page boundaries several times (page close, migration of the live record, erase of the old
//! page) while staying fast: the logic of `sequential-storage` does not depend on the page size,
//! only the number of cut points inside an erase does (1 KiB here, 128 Ki on the board).

mod storage_support;

use odocal::storage::ram_flash::RamFlash;
use odocal::storage::{
    FlashFault, LoadOutcome, LoadWarning, ParamRecord, ParamStore, RunsLoaded, StoreError,
};
use std::sync::atomic::AtomicUsize;
use std::sync::atomic::Ordering::Relaxed;
use storage_support::calibrated;

const PAGE: usize = 1024;

#[derive(Debug, Default)]
struct Tally {
    /// Cut points tried (one per byte written or erased by the interrupted save).
    cuts: u64,
    /// Cuts that fell inside an erase-containing save.
    cuts_in_saves_with_erase: u64,
    /// Boots that loaded the old record (or "missing" when there was none).
    old: u64,
    /// Boots that loaded the new record.
    new: u64,
    /// Boots that lost the old record (defaults with a warning although one was stored).
    lost: u64,
    /// Boots that loaded anything else.
    garbage: u64,
    /// Saves that did not report the power cut, or recovery saves that failed or had to fall
    /// back to erasing the whole range.
    other_failures: u64,
}

fn sweep<const WORD: usize>(prefills: u32) -> Tally {
    type F<const W: usize> = RamFlash<2, PAGE, W>;
    let range = 0..(2 * PAGE) as u32;
    let mut tally = Tally::default();
    let mut base = F::<WORD>::default();
    let mut old: Option<ParamRecord> = None;
    for p in 0..prefills {
        let new = calibrated(1000 + p);
        // Length of the operation in bytes: run it once without a cut.
        let mut probe = base.clone();
        let before = probe.bytes_touched();
        let erases_before: u32 = probe.erase_counts().iter().sum();
        ParamStore::new(&mut probe, range.clone())
            .unwrap()
            .save_blocking(&new, true)
            .unwrap();
        let len = probe.bytes_touched() - before;
        let with_erase = probe.erase_counts().iter().sum::<u32>() > erases_before;

        for cut in 0..len {
            let mut flash = base.clone();
            flash.cut_power_after(Some(cut as u32));
            let res = ParamStore::new(&mut flash, range.clone())
                .unwrap()
                .save_blocking(&new, true);
            if res.is_ok() || flash.is_powered() {
                eprintln!("p={p} cut={cut}/{len}: save returned {res:?}");
                tally.other_failures += 1;
            }
            flash.restore_power();
            tally.cuts += 1;
            if with_erase {
                tally.cuts_in_saves_with_erase += 1;
            }

            // Reboot.
            let mut store = ParamStore::new(&mut flash, range.clone()).unwrap();
            let out = store.load_blocking();
            let is_old = match &old {
                Some(o) => out.record == *o && out.warning.is_none(),
                None => {
                    out.record == ParamRecord::DEFAULT && out.warning == Some(LoadWarning::Missing)
                }
            };
            if out.record == new && out.warning.is_none() {
                tally.new += 1;
            } else if is_old {
                tally.old += 1;
            } else if out.warning.is_some() {
                tally.lost += 1;
            } else {
                tally.garbage += 1;
            }
            // The flash must stay usable after the cut.
            let again = calibrated(5000 + p);
            let r2 = store.save_blocking(&again, true);
            let l2 = store.load_blocking();
            if r2.is_err() || l2.record != again || store.wipes() != 0 {
                eprintln!(
                    "p={p} cut={cut}/{len}: recovery save {r2:?}, load {:?}",
                    l2.warning
                );
                tally.other_failures += 1;
            }
        }

        // Advance the base state by one completed save.
        ParamStore::new(&mut base, range.clone())
            .unwrap()
            .save_blocking(&new, true)
            .unwrap();
        old = Some(new);
    }
    tally
}

fn check(tally: &Tally, word: usize) {
    println!("power-cut sweep, {word}-byte words, 2 x {PAGE} B pages: {tally:?}");
    // Exact requirement: no cut may lose the old record or produce anything but old or new.
    assert_eq!(tally.lost, 0, "{tally:?}");
    assert_eq!(tally.garbage, 0, "{tally:?}");
    assert_eq!(tally.other_failures, 0, "{tally:?}");
    assert_eq!(tally.old + tally.new, tally.cuts);
    // The sweep must really have covered saves that close a page and erase the old one.
    assert!(tally.cuts_in_saves_with_erase >= PAGE as u64, "{tally:?}");
}

/// 24 consecutive saves (each ~134-byte item, ~7 per page) cross page boundaries three times.
#[test]
fn every_cut_during_a_save_leaves_old_or_new_byte_words() {
    let tally = sweep::<1>(24);
    check(&tally, 1);
}

#[test]
fn every_cut_during_a_save_leaves_old_or_new_word_words() {
    let tally = sweep::<4>(24);
    check(&tally, 4);
}

/// A second cut while the next boot repairs the flash: after an interrupted save,
/// `sequential-storage` may write or erase during the first load. Cut that repair too, at every
/// byte of it, after every first cut of 16 consecutive saves (about 2 × 10^6 boots); the boot
/// after it must still load old or new. The saves are swept on all cores: about 60 s of CPU in
/// the test profile, half that in wall time on two idle cores.
#[test]
fn a_second_cut_at_every_byte_of_the_boot_repair_still_leaves_old_or_new() {
    type F = RamFlash<2, PAGE, 1>;
    let range = 0..(2 * PAGE) as u32;
    // The flash before each of the saves, with the record it holds and the one being saved.
    let mut saves: Vec<(u32, F, Option<ParamRecord>, ParamRecord)> = Vec::new();
    let mut base = F::default();
    let mut old: Option<ParamRecord> = None;
    for p in 0..16u32 {
        let new = calibrated(2000 + p);
        saves.push((p, base.clone(), old.clone(), new.clone()));
        ParamStore::new(&mut base, range.clone())
            .unwrap()
            .save_blocking(&new, true)
            .unwrap();
        old = Some(new);
    }
    let next = AtomicUsize::new(0);
    let workers = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(saves.len());
    let tally = std::thread::scope(|s| {
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                s.spawn(|| {
                    let mut tally = DoubleCut::default();
                    while let Some((p, base, old, new)) = saves.get(next.fetch_add(1, Relaxed)) {
                        double_cut(*p, base, old.clone(), new.clone(), &mut tally);
                    }
                    tally
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap())
            .fold(DoubleCut::default(), DoubleCut::add)
    });
    println!("double cut: {tally:?}");
    assert_eq!(tally.unreported_cuts, 0, "{tally:?}");
    assert_eq!(tally.bad, 0, "{tally:?}");
    // Every save was cut at each of its bytes (a save writes at least its record), and the
    // repairs really wrote or erased.
    assert!(
        tally.first_cuts >= 16 * ParamRecord::ENCODED_LEN as u64,
        "{tally:?}"
    );
    assert!(
        tally.repairs > 0 && tally.second_cuts > tally.first_cuts,
        "{tally:?}"
    );
}

/// Counts of the double-cut sweep.
#[derive(Debug, Default)]
struct DoubleCut {
    /// Saves cut (one per byte each save writes or erases).
    first_cuts: u64,
    /// Cut saves that did not report the cut as the flash driver's error.
    unreported_cuts: u64,
    /// Boots after a first cut that wrote or erased (repaired the flash).
    repairs: u64,
    /// Repairing boots cut (one per byte each repair writes or erases).
    second_cuts: u64,
    /// Boots after a second cut that loaded neither the old nor the new record.
    bad: u64,
}

impl DoubleCut {
    fn add(self, o: DoubleCut) -> DoubleCut {
        DoubleCut {
            first_cuts: self.first_cuts + o.first_cuts,
            unreported_cuts: self.unreported_cuts + o.unreported_cuts,
            repairs: self.repairs + o.repairs,
            second_cuts: self.second_cuts + o.second_cuts,
            bad: self.bad + o.bad,
        }
    }
}

/// Cuts the save of `new` over `base` (holding `old`) at every byte, and each boot repair after
/// it at every byte.
fn double_cut(
    p: u32,
    base: &RamFlash<2, PAGE, 1>,
    old: Option<ParamRecord>,
    new: ParamRecord,
    tally: &mut DoubleCut,
) {
    let range = 0..(2 * PAGE) as u32;
    let mut probe = base.clone();
    let before = probe.bytes_touched();
    ParamStore::new(&mut probe, range.clone())
        .unwrap()
        .save_blocking(&new, true)
        .unwrap();
    let len = probe.bytes_touched() - before;
    for cut in 0..len {
        tally.first_cuts += 1;
        let mut cut_once = base.clone();
        cut_once.cut_power_after(Some(cut as u32));
        let res = ParamStore::new(&mut cut_once, range.clone())
            .unwrap()
            .save_blocking(&new, true);
        // The cut falls inside the save: the save fails with the driver's power-cut error.
        if res != Err(StoreError::Flash(FlashFault::Other)) || cut_once.is_powered() {
            eprintln!("p={p} cut={cut}/{len}: save returned {res:?}");
            tally.unreported_cuts += 1;
        }
        cut_once.restore_power();
        // How many bytes does the repairing boot write or erase?
        let mut probe = cut_once.clone();
        let before = probe.bytes_touched();
        ParamStore::new(&mut probe, range.clone())
            .unwrap()
            .load_blocking();
        let repair_len = probe.bytes_touched() - before;
        if repair_len > 0 {
            tally.repairs += 1;
        }
        for cut2 in 0..repair_len {
            tally.second_cuts += 1;
            let mut flash = cut_once.clone();
            flash.cut_power_after(Some(cut2 as u32));
            ParamStore::new(&mut flash, range.clone())
                .unwrap()
                .load_blocking();
            flash.restore_power();
            let out = ParamStore::new(&mut flash, range.clone())
                .unwrap()
                .load_blocking();
            let ok_old = match &old {
                Some(o) => out.record == *o && out.warning.is_none(),
                None => out.warning == Some(LoadWarning::Missing),
            };
            let ok_new = out.record == new && out.warning.is_none();
            if !(ok_old || ok_new) {
                eprintln!(
                    "p={p} cut={cut} cut2={cut2}/{repair_len}: {:?}",
                    out.warning
                );
                tally.bad += 1;
            }
        }
    }
}

// ---- The run store: power cut at every byte of every run-store update ----

use odocal::motion::run::{MAX_RUNS, RunRecord};
use odocal::storage::StoredRun;
use storage_support::{measurement, run_record};

/// Pages of the run-store sweep: 4 × 1 KiB, so a sequence of ~40 updates closes pages, migrates
/// live runs and erases pages several times while staying fast (the logic of
/// `sequential-storage` does not depend on the page size, only the number of cut points inside
/// an erase does).
const RUN_PAGE: usize = 1024;
type RunFlash = RamFlash<4, RUN_PAGE, 1>;
/// Knots per test run: small items (132 B), so that many updates fit the small pages.
const KNOTS: usize = 4;

type Runs = heapless::Vec<RunRecord, MAX_RUNS>;
type Ids = heapless::Vec<Option<StoredRun>, MAX_RUNS>;

/// One change of the session's runs, as the session makes it before storing them.
#[derive(Clone, Copy, Debug)]
enum Update {
    /// A run finished (record `n`).
    Finish(u32),
    /// Run `index` (0-based) measured (or re-measured) with measurement `n`.
    Measure(usize, u32),
    /// Run `index` dropped.
    Drop(usize),
    /// Every run dropped.
    DropAll,
    /// Not a run update: the parameters saved (record `n`), runs unchanged.
    SaveParams(u32),
}

fn apply(update: Update, runs: &mut Runs, ids: &mut Ids) {
    match update {
        Update::Finish(n) => {
            runs.push(run_record(n, KNOTS)).unwrap();
            ids.push(None).unwrap();
        }
        Update::Measure(i, n) => runs[i].measured = Some(measurement(n)),
        Update::Drop(i) => {
            runs.remove(i);
            ids.remove(i);
        }
        Update::DropAll => {
            runs.clear();
            ids.clear();
        }
        Update::SaveParams(_) => {}
    }
}

/// A booted store over `flash`: parameters and runs loaded as `init` loads them.
fn boot(
    flash: &mut RunFlash,
) -> (
    ParamStore<&mut RunFlash>,
    LoadOutcome,
    Runs,
    Ids,
    RunsLoaded,
) {
    let mut store = ParamStore::new(flash, 0..(4 * RUN_PAGE) as u32).unwrap();
    let params = store.load_blocking();
    let (mut runs, mut ids) = (Runs::new(), Ids::new());
    let loaded = store.load_runs_blocking(&mut runs, &mut ids);
    (store, params, runs, ids, loaded)
}

/// Runs the update on a booted store.
fn perform(
    store: &mut ParamStore<&mut RunFlash>,
    update: Update,
    runs: &mut Runs,
    ids: &mut Ids,
) -> Result<(), odocal::storage::StoreError> {
    apply(update, runs, ids);
    match update {
        Update::SaveParams(n) => store.save_blocking(&calibrated(n), true),
        _ => store.save_runs_blocking(runs, ids, true),
    }
}

/// The session of the sweep: runs finish, are measured and re-measured, dropped one by one and
/// all at once, the store fills to 6 runs, and the parameters are saved in between.
fn run_script() -> Vec<Update> {
    use Update::*;
    let mut script = vec![SaveParams(1)];
    for round in 0..3u32 {
        let b = 10 * round;
        script.extend([
            Finish(b + 1),
            Measure(0, b + 1),
            Finish(b + 2),
            Measure(1, b + 2),
            Finish(b + 3),
            Measure(2, b + 3),
            Measure(0, b + 4),
            Finish(b + 4),
            Drop(1),
            Finish(b + 5),
            Measure(3, b + 5),
            SaveParams(b + 2),
            Finish(b + 6),
            Finish(b + 7),
            Measure(5, b + 6),
            Drop(0),
            DropAll,
        ]);
    }
    script
}

#[derive(Debug, Default)]
struct RunTally {
    /// Cut points tried (one per byte written or erased by the interrupted update).
    cuts: u64,
    /// Cuts inside updates that erased a page.
    cuts_in_updates_with_erase: u64,
    /// Boots that restored the old runs / the new runs.
    old: u64,
    new: u64,
    /// Boots that restored anything else, or reported a run as skipped.
    mixed: u64,
    /// Boots whose parameters were not the last saved ones (old or new for a parameter save).
    params_lost: u64,
    /// Updates that did not report a cut before their commit point, cuts that never happened,
    /// or a next update after the cut that failed.
    other_failures: u64,
}

#[test]
fn every_cut_during_a_run_store_update_leaves_old_or_new_runs_and_the_parameters() {
    let mut base = RunFlash::default();
    let mut tally = RunTally::default();
    let mut params_old: Option<ParamRecord> = None;
    for (step, &update) in run_script().iter().enumerate() {
        // The update once without a cut: its length and the state it commits.
        let mut probe = base.clone();
        let (old_runs, new_runs, params_new, len, with_erase) = {
            let erases_before: u32 = probe.erase_counts().iter().sum();
            let (mut store, _, mut runs, mut ids, _) = boot(&mut probe);
            let old_runs = runs.clone();
            let before = store.flash().bytes_touched();
            perform(&mut store, update, &mut runs, &mut ids).unwrap();
            let len = store.flash().bytes_touched() - before;
            let params_new = match update {
                Update::SaveParams(n) => Some(calibrated(n)),
                _ => params_old.clone(),
            };
            let with_erase = probe.erase_counts().iter().sum::<u32>() > erases_before;
            (old_runs, runs, params_new, len, with_erase)
        };
        for cut in 0..len {
            let mut flash = base.clone();
            {
                let (mut store, _, mut runs, mut ids, _) = boot(&mut flash);
                store.flash().cut_power_after(Some(cut as u32));
                let res = perform(&mut store, update, &mut runs, &mut ids);
                // A cut while a dropped run's item is removed comes after the commit point:
                // the update reports success (the item left behind is unlisted).
                let removing = res.is_ok() && matches!(update, Update::Drop(_) | Update::DropAll);
                if (res.is_ok() && !removing) || store.flash().is_powered() {
                    eprintln!("step {step} {update:?} cut={cut}/{len}: returned {res:?}");
                    tally.other_failures += 1;
                }
                store.flash().restore_power();
            }
            tally.cuts += 1;
            if with_erase {
                tally.cuts_in_updates_with_erase += 1;
            }
            // Reboot: the runs are the old or the new ones, measurements included, nothing
            // skipped; the parameters are the last saved ones (old or new for a save).
            let (mut store, params, mut runs, mut ids, loaded) = boot(&mut flash);
            let params_ok = match (&params_old, &params_new) {
                (Some(o), Some(n)) => {
                    params.warning.is_none() && (params.record == *o || params.record == *n)
                }
                (None, Some(n)) => {
                    (params.warning.is_none() && params.record == *n)
                        || params.warning == Some(LoadWarning::Missing)
                }
                (_, None) => params.warning == Some(LoadWarning::Missing),
            };
            if !params_ok {
                eprintln!(
                    "step {step} {update:?} cut={cut}: parameters {:?}",
                    params.warning
                );
                tally.params_lost += 1;
            }
            if loaded.skipped != 0 || loaded.problem.is_some() {
                eprintln!("step {step} {update:?} cut={cut}: {loaded:?}");
                tally.mixed += 1;
            } else if runs == new_runs {
                tally.new += 1;
            } else if runs == old_runs {
                tally.old += 1;
            } else {
                eprintln!(
                    "step {step} {update:?} cut={cut}: {} runs restored",
                    runs.len()
                );
                tally.mixed += 1;
            }
            // The flash stays usable: the next update from the restored state succeeds and
            // is restored.
            let next = Update::Finish(900 + step as u32);
            let stored = perform(&mut store, next, &mut runs, &mut ids);
            let (_, _, again, _, _) = boot(&mut flash);
            if stored.is_err() || again != runs {
                eprintln!("step {step} {update:?} cut={cut}: next update {stored:?}");
                tally.other_failures += 1;
            }
        }
        base = probe;
        params_old = params_new;
    }
    println!("run-store power-cut sweep, 4 x {RUN_PAGE} B pages, 1-byte words: {tally:?}");
    assert_eq!(tally.mixed, 0, "{tally:?}");
    assert_eq!(tally.params_lost, 0, "{tally:?}");
    assert_eq!(tally.other_failures, 0, "{tally:?}");
    assert_eq!(tally.old + tally.new, tally.cuts);
    // The sweep must really have covered updates that move live runs and erase a page.
    assert!(
        tally.cuts_in_updates_with_erase >= RUN_PAGE as u64,
        "{tally:?}"
    );
    // And both outcomes must occur: cuts before and after the commit point.
    assert!(tally.old > 0 && tally.new > 0, "{tally:?}");
}
