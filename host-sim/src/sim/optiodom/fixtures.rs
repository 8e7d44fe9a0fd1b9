//! Test fixtures shared by the reader's modules: session folders written to a temporary
//! directory, their metadata, and error-text checks.

use std::fs;
use std::path::PathBuf;

/// Asserts that the error `err` says every one of `parts`.
pub(super) fn assert_mentions(err: &str, parts: &[&str]) {
    for part in parts {
        assert!(err.contains(part), "{err:?} does not say {part:?}");
    }
}

/// A session folder `<temp>/odocal-<tag>-<pid>/<kind>/<id>` holding `metadata` as its
/// metadata file: (the folder to remove afterwards, the session folder).
pub(super) fn session_folder(
    tag: &str,
    kind: &str,
    id: &str,
    metadata: &str,
) -> (PathBuf, PathBuf) {
    let root = std::env::temp_dir().join(format!("odocal-{tag}-{}", std::process::id()));
    let dir = root.join(kind).join(id);
    fs::create_dir_all(&dir).unwrap();
    fs::write(dir.join(format!("{id}_metadata.csv")), metadata).unwrap();
    (root, dir)
}

/// Metadata of a differential-drive session of the shared robot's kind (gear 43.7, 64
/// counts, Li 0.2 m) with wheel diameters `di` (right,left), `n` runs and `extra` lines.
pub(super) fn metadata(di: &str, n: usize, extra: &str) -> String {
    format!("type,diff,,\nngear,43.7,,\nencRes,64,,\nLi,0.2,,\nDi,{di},\nN,{n},,\n{extra}")
}
