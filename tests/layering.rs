//! The layering rule of `src/lib.rs`: a module may use its own folder and the layers below it,
//! never a layer above it or a sibling of its own layer. This test reads every source file,
//! resolves every `crate::`, `super::` and `self::` path in its code (grouped imports such as
//! `use crate::{session::X, util::Y}` expanded, `super::` taken from the module the path sits
//! in, inline `mod … { }` blocks included) and fails on one that points up or sideways.
//!
//! Inside a top-level module, its parts (the files and folders directly under its folder) may
//! use each other, but not in a circle: part A using part B while B uses A (or a longer
//! circle) fails too ([`KNOWN_CIRCLES`], the circles allowed, is empty).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Top-level modules and their layer (see the table in `src/lib.rs`).
const LAYERS: &[(&str, u32)] = &[
    ("fmt", 0),
    ("util", 0),
    ("kinematics", 1),
    ("motion", 2),
    ("calibration", 3),
    ("storage", 3),
    ("plant", 3),
    ("protocol", 4),
    ("session", 5),
    ("app", 6),
    ("board", 7),
];

/// Crate-root items every module may name: the logging macros' helpers.
const ROOT_HELPERS: &[&str] = &["__host_log_args", "__defmt"];

/// Import circles among the parts of one top-level module that are allowed, each as
/// `(module, parts)`. There are none: a shared item belongs in a part the others use (or in the
/// module itself), so every circle fails the test.
const KNOWN_CIRCLES: &[(&str, &[&str])] = &[];

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

/// One token of Rust code: an identifier or keyword, `::`, or a single punctuation character.
/// Comments, string and character literals and lifetimes are dropped; numbers are kept as
/// (meaningless) words.
#[derive(Clone, Debug, PartialEq)]
struct Token {
    text: String,
    line: usize,
}

fn tokens(text: &str) -> Vec<Token> {
    let c: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let (mut i, mut line) = (0, 1);
    let word = |ch: char| ch.is_alphanumeric() || ch == '_';
    // Skips a string body from just after its opening quote, `hashes` being the raw string's
    // number of `#` (`None` for a string with escapes).
    let skip_string = |mut i: usize, hashes: Option<usize>, line: &mut usize| -> usize {
        while i < c.len() {
            match c[i] {
                '\n' => *line += 1,
                '\\' if hashes.is_none() => i += 1,
                '"' => {
                    let n = hashes.unwrap_or(0);
                    if c[i + 1..].iter().take(n).filter(|&&h| h == '#').count() == n {
                        return i + 1 + n;
                    }
                }
                _ => {}
            }
            i += 1;
        }
        i
    };
    while i < c.len() {
        let ch = c[i];
        let next = c.get(i + 1).copied();
        if ch == '\n' {
            line += 1;
            i += 1;
        } else if ch.is_whitespace() {
            i += 1;
        } else if ch == '/' && next == Some('/') {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
        } else if ch == '/' && next == Some('*') {
            let mut depth = 0;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    if c[i] == '\n' {
                        line += 1;
                    }
                    i += 1;
                }
            }
        } else if ch == '"' {
            i = skip_string(i + 1, None, &mut line);
        } else if (ch == 'r' || ch == 'b' || ch == 'c')
            && (i == 0 || !word(c[i - 1]))
            && string_prefix(&c[i..]).is_some()
        {
            let (len, hashes) = string_prefix(&c[i..]).unwrap_or((0, None));
            i = skip_string(i + len, hashes, &mut line);
        } else if ch == '\'' {
            // A character literal (`'x'`, `'\n'`, `'\u{7b}'`) or a lifetime (`'a`).
            if next == Some('\\') {
                // Past the quote, the backslash and the escaped character.
                i += 3;
                while i < c.len() && c[i] != '\'' {
                    i += 1;
                }
                i += 1;
            } else if c.get(i + 2) == Some(&'\'') {
                i += 3;
            } else {
                i += 1;
                while i < c.len() && word(c[i]) {
                    i += 1;
                }
            }
        } else if word(ch) {
            let start = i;
            while i < c.len() && word(c[i]) {
                i += 1;
            }
            let mut text: String = c[start..i].iter().collect();
            // A raw identifier `r#name` is the word `name`.
            if text == "r" && c.get(i) == Some(&'#') && c.get(i + 1).is_some_and(|&n| word(n)) {
                let start = i + 1;
                i = start;
                while i < c.len() && word(c[i]) {
                    i += 1;
                }
                text = c[start..i].iter().collect();
            }
            out.push(Token { text, line });
        } else if ch == ':' && next == Some(':') {
            out.push(Token {
                text: "::".into(),
                line,
            });
            i += 2;
        } else {
            out.push(Token {
                text: ch.into(),
                line,
            });
            i += 1;
        }
    }
    out
}

/// The length of a string literal's prefix up to and including its opening quote, and its
/// number of `#` if it is a raw string: `r"`, `r#"`, `b"`, `br##"`, `c"`, … (`None` if `c`
/// does not start one).
fn string_prefix(c: &[char]) -> Option<(usize, Option<usize>)> {
    let mut i = 0;
    if matches!(c.first(), Some('b' | 'c')) {
        i += 1;
    }
    let raw = c.get(i) == Some(&'r');
    if raw {
        i += 1;
    }
    let mut hashes = 0;
    while raw && c.get(i) == Some(&'#') {
        hashes += 1;
        i += 1;
    }
    (c.get(i) == Some(&'"') && i > 0).then_some((i + 1, raw.then_some(hashes)))
}

/// A path as written from its first segment (`crate`, `super` or `self`), each grouped
/// import expanded into one path per member (`crate::{a::X, b}` → `crate::a::X`, `crate::b`).
/// Returns the paths and the index of the first token after the path.
fn path_tree(t: &[Token], mut i: usize, prefix: Vec<String>, out: &mut Vec<Vec<String>>) -> usize {
    let mut path = prefix;
    loop {
        match t.get(i).map(|t| t.text.as_str()) {
            Some("{") => {
                i += 1;
                while t.get(i).is_some_and(|t| t.text != "}") {
                    i = path_tree(t, i, path.clone(), out);
                    if t.get(i).is_some_and(|t| t.text == ",") {
                        i += 1;
                    }
                }
                return i + 1;
            }
            Some(s) if s.starts_with(|c: char| c.is_alphabetic() || c == '_') || s == "*" => {
                path.push(s.to_string());
                i += 1;
                if t.get(i).is_some_and(|t| t.text == "::") {
                    i += 1;
                } else {
                    break;
                }
            }
            _ => break,
        }
    }
    // `as alias` names the last segment; it does not change what is used.
    if t.get(i).is_some_and(|t| t.text == "as") {
        i += 2;
    }
    out.push(path);
    i
}

/// A path in a file resolved to the module path it names from the crate root.
#[derive(Debug)]
struct Used {
    line: usize,
    /// Segments from the crate root (`["protocol", "command", "keyword_eq"]`).
    path: Vec<String>,
    /// The path as written.
    written: String,
}

/// Every `crate::`, `super::` and `self::` path in `text`, the code of the module at
/// `module` (its segments from the crate root), resolved from the crate root. A `super::` that
/// climbs above the crate root is an error.
fn used_paths(text: &str, module: &[String]) -> Result<Vec<Used>, String> {
    let t = tokens(text);
    let mut found = Vec::new();
    // Inline modules open at the current point, with the brace depth inside each.
    let mut inline: Vec<(String, usize)> = Vec::new();
    let mut depth = 0usize;
    let mut i = 0;
    while i < t.len() {
        let s = t[i].text.as_str();
        let prev = i.checked_sub(1).map(|p| t[p].text.as_str());
        if s == "{" {
            depth += 1;
            if i >= 2 && t[i - 2].text == "mod" {
                inline.push((t[i - 1].text.clone(), depth));
            }
        } else if s == "}" {
            if inline.last().is_some_and(|&(_, d)| d == depth) {
                inline.pop();
            }
            depth = depth.saturating_sub(1);
        } else if matches!(s, "crate" | "super" | "self")
            && t.get(i + 1).is_some_and(|n| n.text == "::")
            && prev != Some("::")
        {
            let mut paths = Vec::new();
            let end = path_tree(&t, i, Vec::new(), &mut paths);
            let here: Vec<String> = module
                .iter()
                .cloned()
                .chain(inline.iter().map(|(m, _)| m.clone()))
                .collect();
            for written in paths {
                let mut segs = written.iter().peekable();
                let mut resolved = here.clone();
                if segs.next_if(|s| *s == "crate").is_some() {
                    resolved.clear();
                }
                segs.next_if(|s| *s == "self");
                while segs.next_if(|s| *s == "super").is_some() {
                    if resolved.pop().is_none() {
                        return Err(format!(
                            "line {}: `{}` climbs above the crate root",
                            t[i].line,
                            written.join("::")
                        ));
                    }
                }
                resolved.extend(segs.filter(|s| *s != "self" && *s != "*").cloned());
                found.push(Used {
                    line: t[i].line,
                    path: resolved,
                    written: written.join("::"),
                });
            }
            i = end;
            continue;
        }
        i += 1;
    }
    Ok(found)
}

/// The module path of the file `rel` (relative to `src`): `protocol/mod.rs` → `protocol`,
/// `motion/controller/fault.rs` → `motion::controller::fault`.
fn module_path(rel: &Path) -> Vec<String> {
    let mut segs: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if let Some(last) = segs.pop() {
        let stem = last.trim_end_matches(".rs");
        if stem != "mod" && stem != "lib" {
            segs.push(stem.to_string());
        }
    }
    segs
}

/// The parts of the top-level module `module` under `src`: its files (but `mod.rs`) and
/// folders.
fn parts(src: &Path, module: &str) -> BTreeSet<String> {
    let Ok(entries) = std::fs::read_dir(src.join(module)) else {
        return BTreeSet::new();
    };
    entries
        .map(|e| e.unwrap().path())
        .filter_map(|p| {
            let name = p.file_name()?.to_string_lossy().into_owned();
            if p.is_dir() {
                Some(name)
            } else {
                name.strip_suffix(".rs")
                    .filter(|n| *n != "mod")
                    .map(str::to_string)
            }
        })
        .collect()
}

/// What the check finds in the crate rooted at `src`.
#[derive(Debug, Default)]
struct Findings {
    /// Upward or sideways paths, and paths that do not resolve.
    violations: Vec<String>,
    /// Per top-level module, the uses among its parts: `(from, to)` → one place it happens.
    uses: BTreeMap<String, BTreeMap<(String, String), String>>,
}

fn check(src: &Path) -> Findings {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    files.sort();
    let mut found = Findings::default();
    for file in files {
        let rel = file.strip_prefix(src).unwrap();
        let module = module_path(rel);
        // The crate root and the RTIC binary (its own crate) sit above every layer.
        let Some(own_name) = module.first() else {
            continue;
        };
        if module == ["main"] {
            continue;
        }
        let Some(own) = layer(own_name) else {
            found.violations.push(format!(
                "{}: module `{own_name}` is not in the layer table",
                rel.display()
            ));
            continue;
        };
        let text = std::fs::read_to_string(&file).unwrap();
        let used = match used_paths(&text, &module) {
            Ok(used) => used,
            Err(e) => {
                found.violations.push(format!("{}: {e}", rel.display()));
                continue;
            }
        };
        let module_parts = parts(src, own_name);
        for Used {
            line,
            path,
            written,
        } in used
        {
            let Some(target) = path.first() else {
                continue;
            };
            if target == own_name {
                // Within the module: note a use of one part by another.
                let from = module.get(1).filter(|p| module_parts.contains(*p));
                let to = path.get(1).filter(|p| module_parts.contains(*p));
                if let (Some(from), Some(to)) = (from, to)
                    && from != to
                {
                    found
                        .uses
                        .entry(own_name.clone())
                        .or_default()
                        .entry((from.clone(), to.clone()))
                        .or_insert_with(|| format!("{}:{line} `{written}`", rel.display()));
                }
                continue;
            }
            if ROOT_HELPERS.contains(&target.as_str()) {
                continue;
            }
            match layer(target) {
                Some(l) if l < own => {}
                Some(l) => found.violations.push(format!(
                    "{}:{line}: `{own_name}` (layer {own}) uses `{written}` = `crate::{}` (layer {l})",
                    rel.display(),
                    path.join("::")
                )),
                None => found.violations.push(format!(
                    "{}:{line}: `{written}` = `crate::{}` is not in the layer table",
                    rel.display(),
                    path.join("::")
                )),
            }
        }
    }
    found
}

/// The circles among the parts of each top-level module: every set of two or more parts that
/// reach one another through their uses (a strongly connected component), with one use along
/// each edge inside it as evidence.
fn circles(found: &Findings) -> Vec<(String, BTreeSet<String>, Vec<String>)> {
    let mut out = Vec::new();
    for (module, uses) in &found.uses {
        let nodes: BTreeSet<&String> = uses.keys().flat_map(|(a, b)| [a, b]).collect();
        let reach = |from: &String| {
            let mut seen = BTreeSet::from([from.clone()]);
            let mut todo = vec![from.clone()];
            while let Some(n) = todo.pop() {
                for (a, b) in uses.keys() {
                    if *a == n && seen.insert(b.clone()) {
                        todo.push(b.clone());
                    }
                }
            }
            seen
        };
        let reached: BTreeMap<&String, BTreeSet<String>> =
            nodes.iter().map(|&n| (n, reach(n))).collect();
        let mut done = BTreeSet::new();
        for &n in &nodes {
            if done.contains(n) {
                continue;
            }
            let component: BTreeSet<String> = reached[n]
                .iter()
                .filter(|m| reached[*m].contains(n))
                .cloned()
                .collect();
            done.extend(component.iter().cloned());
            if component.len() > 1 {
                let evidence = uses
                    .iter()
                    .filter(|((a, b), _)| component.contains(a) && component.contains(b))
                    .map(|((a, b), at)| format!("{a} -> {b} ({at})"))
                    .collect();
                out.push((module.clone(), component, evidence));
            }
        }
    }
    out
}

/// The circles of `found` not within a [`KNOWN_CIRCLES`] entry, described.
fn new_circles(found: &Findings) -> Vec<String> {
    circles(found)
        .into_iter()
        .filter(|(module, parts, _)| {
            !KNOWN_CIRCLES
                .iter()
                .any(|(m, known)| m == module && parts.iter().all(|p| known.contains(&p.as_str())))
        })
        .map(|(module, parts, evidence)| {
            format!(
                "`{module}`: {:?} use one another:\n  {}",
                parts,
                evidence.join("\n  ")
            )
        })
        .collect()
}

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

#[test]
fn no_module_uses_a_layer_above_or_beside_it() {
    let found = check(&src());
    assert!(
        found.violations.is_empty(),
        "upward or sideways imports:\n{}",
        found.violations.join("\n")
    );
}

#[test]
fn no_new_import_circle_inside_a_module() {
    let found = check(&src());
    let new = new_circles(&found);
    assert!(
        new.is_empty(),
        "import circles among one module's parts:\n{}",
        new.join("\n")
    );
}

/// A scratch source tree with the given files, checked and removed.
fn check_files(name: &str, files: &[(&str, &str)]) -> Findings {
    let dir = std::env::temp_dir().join(format!("odocal-layering-{name}-{}", std::process::id()));
    for (path, text) in files {
        let path = dir.join(path);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    }
    let found = check(&dir);
    std::fs::remove_dir_all(&dir).unwrap();
    found
}

#[test]
fn an_upward_import_is_caught() {
    let found = check_files(
        "upward",
        &[(
            "kinematics/odometry.rs",
            "use crate::util::num::clamp;\n// crate::session in a comment is fine\nuse crate::session::Session;\n",
        )],
    );
    let bad = found.violations;
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert!(
        bad[0].contains(
            "kinematics/odometry.rs:3: `kinematics` (layer 1) uses `crate::session::Session`"
        ),
        "{bad:?}"
    );
}

#[test]
fn grouped_and_super_imports_are_resolved() {
    let found = check_files(
        "grouped",
        &[
            (
                "kinematics/odometry.rs",
                "use crate::{\n    util::num::clamp,\n    session::{Session, X as Y},\n};\n\
                 let s = \"crate::board::x\"; let c = ['{', '\\'', '\\u{7b}']; let l: &'static str = r#\"crate::board\"#;\n\
                 use super::super::protocol::Reply;\n",
            ),
            (
                "kinematics/deep/inner.rs",
                "use super::super::angle::wrap;\nuse super::super::super::motion::Controller;\n",
            ),
            (
                "kinematics/mod.rs",
                "mod tests {\n    const C: [char; 2] = ['}', '\\''];\n    use super::super::session::S;\n    use super::odometry::x;\n}\n",
            ),
            ("util/num.rs", "pub(crate) fn f() {} pub(super) fn g() {}\n"),
        ],
    );
    let mut bad = found.violations;
    bad.sort();
    let want = [
        // `super::super` from `kinematics::deep::inner` is the crate root.
        "kinematics/deep/inner.rs:2: `kinematics` (layer 1) uses `super::super::super::motion::Controller` = `crate::motion::Controller` (layer 2)",
        // Inside `mod tests` of `kinematics`, `super::super` is the crate root.
        "kinematics/mod.rs:3: `kinematics` (layer 1) uses `super::super::session::S` = `crate::session::S` (layer 5)",
        "kinematics/odometry.rs:1: `kinematics` (layer 1) uses `crate::session::Session` = `crate::session::Session` (layer 5)",
        "kinematics/odometry.rs:1: `kinematics` (layer 1) uses `crate::session::X` = `crate::session::X` (layer 5)",
        // From `kinematics::odometry`, `super::super` is the crate root too; the strings and
        // the character literal before it are not code.
        "kinematics/odometry.rs:6: `kinematics` (layer 1) uses `super::super::protocol::Reply` = `crate::protocol::Reply` (layer 4)",
    ];
    assert_eq!(bad.len(), want.len(), "{bad:#?}");
    for (got, want) in bad.iter().zip(want) {
        assert!(
            got.starts_with(want),
            "{got}\n  does not start with\n{want}"
        );
    }
}

#[test]
fn a_super_above_the_crate_root_is_caught() {
    let found = check_files("above", &[("util/num.rs", "use super::super::super::x;\n")]);
    assert_eq!(found.violations.len(), 1, "{:?}", found.violations);
    assert!(found.violations[0].contains("climbs above the crate root"));
}

#[test]
fn a_new_import_circle_is_caught() {
    let found = check_files(
        "circle",
        &[
            ("protocol/mod.rs", "pub mod command;\npub mod param;\n"),
            (
                "protocol/command.rs",
                "use super::param::ParamName;\nuse super::Eol;\n",
            ),
            // `param` reaches `command` through a folder part's deeper file: a longer circle.
            ("protocol/param.rs", "use crate::protocol::rx::Line;\n"),
            (
                "protocol/rx/line.rs",
                "use super::super::{command::Command, Eol};\n",
            ),
            ("motion/speed.rs", "use crate::motion::routine::Settle;\n"),
            ("motion/routine.rs", "use super::speed::Gain;\n"),
        ],
    );
    assert!(found.violations.is_empty(), "{:?}", found.violations);
    let circles = circles(&found);
    let sets: Vec<(&str, Vec<&str>)> = circles
        .iter()
        .map(|(m, parts, _)| (m.as_str(), parts.iter().map(String::as_str).collect()))
        .collect();
    assert_eq!(
        sets,
        [
            ("motion", vec!["routine", "speed"]),
            ("protocol", vec!["command", "param", "rx"]),
        ]
    );
    // No circle is allowed: both are reported.
    let new = new_circles(&found);
    assert_eq!(new.len(), 2, "{new:?}");
    assert!(
        new[0].contains("`motion`: {\"routine\", \"speed\"}")
            && new[0]
                .contains("speed -> routine (motion/speed.rs:1 `crate::motion::routine::Settle`)"),
        "{new:?}"
    );
    assert!(
        new[1].contains("`protocol`: {\"command\", \"param\", \"rx\"}")
            && new[1]
                .contains("rx -> command (protocol/rx/line.rs:1 `super::super::command::Command`)"),
        "{new:?}"
    );
}
