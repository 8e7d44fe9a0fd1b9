//! Puts the selected board's `memory.x` (by the `board-*` cargo feature: the default board's at
//! the top level, every other board's in `src/board/<board>/memory.x`) where the linker finds
//! it. A target build needs exactly one board feature.
//!
//! The linker (`.cargo/firmware-linker.sh`: flip-link run from an empty directory) never looks in the
//! repository's top level: a linker script's `INCLUDE memory.x` searches the current directory
//! before the search path, so run from the top level every board would link the default
//! board's map (an F411CE image with its run region at the F407's 0x080C_0000, off its flash).
use std::env;
use std::fs;
use std::path::{Path, PathBuf};

/// Board features and their folders under `src/board/` (the default board's map is the
/// top-level `memory.x`).
const BOARDS: [(&str, &str); 3] = [
    ("BOARD_F407", "f407"),
    ("BOARD_NUCLEO_F446RE", "nucleo_f446re"),
    ("BOARD_BLACKPILL_F411CE", "blackpill_f411ce"),
];

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    for (_, folder) in BOARDS {
        println!("cargo:rerun-if-changed={}", map_of(folder).display());
    }
    let selected: Vec<&str> = BOARDS
        .iter()
        .filter(|(feature, _)| env::var_os(format!("CARGO_FEATURE_{feature}")).is_some())
        .map(|(_, folder)| *folder)
        .collect();
    let target_build = env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "none");
    let folder = match selected.as_slice() {
        [one] => *one,
        // Host builds (tests, host-sim) link no memory map.
        _ if !target_build => return,
        [] => panic!(
            "no board selected: build with one of the features board-f407 (the default), \
             board-nucleo-f446re, board-blackpill-f411ce (the `cargo fw-*` aliases do)"
        ),
        many => panic!(
            "more than one board selected ({}): add --no-default-features when choosing a \
             board other than the default (the `cargo fw-*` aliases do)",
            many.join(", ")
        ),
    };
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR is set by cargo"));
    fs::copy(map_of(folder), out.join("memory.x"))
        .expect("the board's memory.x is copied to OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
}

/// The memory map of the board in `folder`: the top-level `memory.x` for the default board.
fn map_of(folder: &str) -> PathBuf {
    if folder == "f407" {
        PathBuf::from("memory.x")
    } else {
        Path::new("src/board").join(folder).join("memory.x")
    }
}
