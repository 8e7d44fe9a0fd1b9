//! Puts the selected board's `memory.x` (`src/board/<board>/memory.x`, by the `board-*` cargo
//! feature) where the linker finds it. A target build needs exactly one board feature.
use std::env;
use std::fs;
use std::path::{Path, PathBuf};

/// Board features and their folders under `src/board/`.
const BOARDS: [(&str, &str); 3] = [
    ("BOARD_F407", "f407"),
    ("BOARD_NUCLEO_F446RE", "nucleo_f446re"),
    ("BOARD_BLACKPILL_F411CE", "blackpill_f411ce"),
];

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    for (_, folder) in BOARDS {
        println!("cargo:rerun-if-changed=src/board/{folder}/memory.x");
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
    let map = Path::new("src/board").join(folder).join("memory.x");
    fs::copy(&map, out.join("memory.x")).expect("the board's memory.x is copied to OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
}
