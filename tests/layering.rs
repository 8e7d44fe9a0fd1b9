//! The layering rule of `src/lib.rs`: a module may use its own folder and the layers below it,
//! never a layer above it or a sibling of its own layer. This test reads every source file and
//! fails on a `crate::<module>` path (outside comments) that points up or sideways.

use std::path::{Path, PathBuf};

/// Top-level modules and their layer (see the table in `src/lib.rs`).
const LAYERS: &[(&str, u32)] = &[
    ("fmt", 0),
    ("util", 0),
    ("kinematics", 1),
    ("motion", 2),
    ("calibration", 3),
    ("storage", 3),
    ("protocol", 4),
    ("session", 5),
    ("board", 6),
];

fn layer(module: &str) -> Option<u32> {
    LAYERS.iter().find(|(m, _)| *m == module).map(|&(_, l)| l)
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Every `crate::<name>` in the code of `text` (line comments and doc comments skipped).
fn crate_paths(text: &str) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let code = line.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some(i) = rest.find("crate::") {
            let after = &rest[i + "crate::".len()..];
            let name: String = after
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            if !name.is_empty() {
                found.push((n + 1, name));
            }
            rest = after;
        }
    }
    found
}

/// Violations of the rule in the crate rooted at `src`.
fn violations(src: &Path) -> Vec<String> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let mut bad = Vec::new();
    for file in files {
        let rel = file.strip_prefix(src).unwrap();
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy();
        let module = first.trim_end_matches(".rs").to_string();
        // The crate root and the RTIC binary sit above every layer.
        let Some(own) = layer(&module) else {
            assert!(
                module == "lib" || module == "main",
                "{}: module `{module}` is not in the layer table",
                rel.display()
            );
            continue;
        };
        let text = std::fs::read_to_string(&file).unwrap();
        for (line, used) in crate_paths(&text) {
            if used == module || used == "__host_log_args" || used == "__defmt" {
                continue;
            }
            match layer(&used) {
                Some(l) if l < own => {}
                Some(l) => bad.push(format!(
                    "{}:{line}: `{module}` (layer {own}) uses `crate::{used}` (layer {l})",
                    rel.display()
                )),
                None => bad.push(format!(
                    "{}:{line}: `crate::{used}` is not in the layer table",
                    rel.display()
                )),
            }
        }
    }
    bad
}

#[test]
fn no_module_uses_a_layer_above_or_beside_it() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let bad = violations(&src);
    assert!(
        bad.is_empty(),
        "upward or sideways imports:\n{}",
        bad.join("\n")
    );
}

#[test]
fn an_upward_import_is_caught() {
    let dir = std::env::temp_dir().join(format!("odocal-layering-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("kinematics")).unwrap();
    std::fs::write(
        dir.join("kinematics/odometry.rs"),
        "use crate::util::num::clamp;\n// crate::session in a comment is fine\nuse crate::session::Session;\n",
    )
    .unwrap();
    let bad = violations(&dir);
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert!(
        bad[0].contains("uses `crate::session` (layer 5)"),
        "{bad:?}"
    );
}
