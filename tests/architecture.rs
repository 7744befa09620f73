//! The shape of the code, checked on its sources: the floors of the architecture chapter
//! (`docs/src/reference/architecture.md`) hold — no module imports one on its own floor or
//! above —, no two files of one module use each other, and no function is longer than a
//! reader can hold (150 lines) in the library, the learned module and the Python package.
//!
//! The sources are read as text. Comments, string and character literals are blanked first,
//! and items under `#[cfg(test)]` are left out of the floor check (a unit test may check a
//! module against one above it, as the model's tests check against dynamics).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The library's top-level modules, floor by floor from the ground up. A module uses only
/// modules on lower floors.
const FLOORS: &[&[&str]] = &[
    &["spatial", "random", "linalg", "reference"],
    &["error"],
    &["limits"],
    &["xml"],
    &["text"],
    &["model"],
    &["dynamics", "io"],
    &["mjcf", "motion", "muscle"],
    &["mujoco", "solve", "check"],
    &["augment"],
    &["loss"],
    &["evaluate"],
    &["report"],
];

/// The longest a function may be, in lines from its `fn` line to its closing brace.
const MAX_FUNCTION_LINES: usize = 150;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every `.rs` file below `dir`, sorted.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap_or_else(|e| panic!("{}: {e}", d.display())) {
            let p = entry.expect("directory entry").path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// The source with comments blanked and string and character literals emptied (`""`,
/// `' '`), newlines kept so that line numbers stay those of the file.
fn blank(src: &str) -> String {
    let b = src.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    // keeps the newlines of a skipped span
    let skip = |out: &mut Vec<u8>, span: &[u8]| {
        out.extend(span.iter().filter(|&&c| c == b'\n'));
    };
    while i < b.len() {
        let c = b[i];
        let next = b.get(i + 1).copied();
        if c == b'/' && next == Some(b'/') {
            let end = b[i..]
                .iter()
                .position(|&c| c == b'\n')
                .map_or(b.len(), |k| i + k);
            i = end;
        } else if c == b'/' && next == Some(b'*') {
            // block comments nest in Rust
            let (mut depth, mut j) = (1, i + 2);
            while j < b.len() && depth > 0 {
                if b[j] == b'/' && b.get(j + 1) == Some(&b'*') {
                    depth += 1;
                    j += 2;
                } else if b[j] == b'*' && b.get(j + 1) == Some(&b'/') {
                    depth -= 1;
                    j += 2;
                } else {
                    j += 1;
                }
            }
            skip(&mut out, &b[i..j]);
            i = j;
        } else if c == b'r' && (next == Some(b'"') || next == Some(b'#')) && !ident_before(b, i) {
            // raw string r"…", r#"…"#
            let hashes = b[i + 1..].iter().take_while(|&&c| c == b'#').count();
            if b.get(i + 1 + hashes) != Some(&b'"') {
                out.push(c);
                i += 1;
                continue;
            }
            let close: Vec<u8> = std::iter::once(b'"')
                .chain(std::iter::repeat_n(b'#', hashes))
                .collect();
            let start = i + 2 + hashes;
            let end = b[start..]
                .windows(close.len())
                .position(|w| w == close.as_slice())
                .map_or(b.len(), |k| start + k + close.len());
            out.extend_from_slice(b"\"\"");
            skip(&mut out, &b[i..end]);
            i = end;
        } else if c == b'"' {
            let mut j = i + 1;
            while j < b.len() && b[j] != b'"' {
                j += if b[j] == b'\\' { 2 } else { 1 };
            }
            out.extend_from_slice(b"\"\"");
            skip(&mut out, &b[i..(j + 1).min(b.len())]);
            i = j + 1;
        } else if c == b'\'' {
            // a character literal ('x', '\n', '\u{1F600}', '{'), or a lifetime ('a)
            let len = if next == Some(b'\\') {
                b[i + 2..].iter().position(|&c| c == b'\'').map(|k| k + 3)
            } else {
                // `'` is ASCII, so the character after it starts at i + 1
                src[i + 1..]
                    .chars()
                    .next()
                    .map(|ch| ch.len_utf8())
                    .filter(|&n| b.get(i + 1 + n) == Some(&b'\''))
                    .map(|n| n + 2)
            };
            match len {
                Some(n) => {
                    out.extend_from_slice(b"' '");
                    i += n;
                }
                None => {
                    out.push(c);
                    i += 1;
                }
            }
        } else {
            out.push(c);
            i += 1;
        }
    }
    String::from_utf8(out).expect("blanking keeps UTF-8")
}

fn ident_before(b: &[u8], i: usize) -> bool {
    i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')
}

/// The index just past the item that starts at `from`: its matching closing brace, or its
/// `;` when the item has no body.
fn item_end(text: &str, from: usize) -> usize {
    let b = text.as_bytes();
    // braces, and brackets and parentheses (a `;` inside `[f64; 3]` ends nothing)
    let (mut braces, mut others) = (0i32, 0i32);
    let mut i = from;
    while i < b.len() {
        match b[i] {
            b'{' => braces += 1,
            b'}' => {
                braces -= 1;
                if braces == 0 {
                    return i + 1;
                }
            }
            b'(' | b'[' => others += 1,
            b')' | b']' => others -= 1,
            b';' if braces == 0 && others == 0 => return i + 1,
            _ => {}
        }
        i += 1;
    }
    b.len()
}

/// The blanked source without the items under `#[cfg(test)]`.
fn without_test_items(blanked: &str) -> String {
    let mut out = String::with_capacity(blanked.len());
    let mut rest = blanked;
    while let Some(k) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..k]);
        let end = item_end(rest, k + "#[cfg(test)]".len());
        out.extend(rest[k..end].chars().filter(|&c| c == '\n'));
        rest = &rest[end..];
    }
    out.push_str(rest);
    out
}

/// The identifiers that follow `prefix` (`crate::` or `super::`) in `text`, including the
/// members of a group (`crate::{a, b::c}` gives a and b).
fn paths_after(text: &str, prefix: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for (k, _) in text.match_indices(prefix) {
        if ident_before(text.as_bytes(), k) {
            continue;
        }
        let rest = &text[k + prefix.len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let inner = &group[..item_end(rest, 0).saturating_sub(2).min(group.len())];
            // the first identifier of each comma-separated member at the group's top level
            let mut depth = 0;
            let mut start = true;
            for (j, c) in inner.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' => depth -= 1,
                    ',' if depth == 0 => start = true,
                    c if start && (c.is_alphanumeric() || c == '_') => {
                        out.insert(identifier(&inner[j..]));
                        start = false;
                    }
                    _ => {}
                }
            }
        } else {
            let id = identifier(rest);
            if !id.is_empty() {
                out.insert(id);
            }
        }
    }
    out
}

fn identifier(s: &str) -> String {
    s.chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect()
}

fn floor_of(module: &str) -> Option<usize> {
    FLOORS.iter().position(|f| f.contains(&module))
}

/// The top-level module a file of `src/` belongs to (`src/model/osim/mod.rs` → `model`).
fn top_module(relative: &Path) -> String {
    let first = relative.components().next().expect("a file below src");
    let name = first.as_os_str().to_string_lossy();
    name.trim_end_matches(".rs").to_string()
}

#[test]
fn every_library_module_uses_only_lower_floors() {
    let src = root().join("src");
    let mut upward = Vec::new();
    let mut unplaced = BTreeSet::new();
    for path in rust_files(&src) {
        let relative = path.strip_prefix(&src).expect("below src");
        let top = top_module(relative);
        if top == "bin" || top == "lib" {
            continue;
        }
        let Some(floor) = floor_of(&top) else {
            unplaced.insert(top);
            continue;
        };
        let text = without_test_items(&blank(&std::fs::read_to_string(&path).expect("read")));
        for used in paths_after(&text, "crate::") {
            if used == top {
                continue;
            }
            match floor_of(&used) {
                Some(f) if f >= floor => upward.push(format!(
                    "{} (floor {floor}) uses crate::{used} (floor {f})",
                    relative.display()
                )),
                _ => {}
            }
        }
    }
    assert!(
        unplaced.is_empty(),
        "modules without a floor (add them to FLOORS and the architecture chapter): {unplaced:?}"
    );
    assert!(
        upward.is_empty(),
        "imports on the same floor or up:\n{}",
        upward.join("\n")
    );
}

/// For each folder of a crate's sources: which of its files use which sibling (by
/// `super::NAME`, or by the folder's full path from `crate::`). A file `a.rs` and a folder
/// `a/` are the sibling `a`; the folder's `mod.rs` is the parent, not a sibling.
fn sibling_uses(src: &Path) -> BTreeMap<PathBuf, BTreeMap<String, BTreeSet<String>>> {
    let mut out: BTreeMap<PathBuf, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for path in rust_files(src) {
        let relative = path.strip_prefix(src).expect("below src").to_path_buf();
        let name = relative
            .file_stem()
            .expect("file name")
            .to_string_lossy()
            .to_string();
        // the sibling this file belongs to, and the folder that holds the siblings
        let (sibling, folder) = if name == "mod" {
            let dir = relative.parent().expect("mod.rs in a folder");
            match (dir.file_name(), dir.parent()) {
                (Some(d), Some(parent)) => (d.to_string_lossy().to_string(), parent.to_path_buf()),
                _ => continue,
            }
        } else if name == "lib" || name == "main" || name == "tests" {
            continue;
        } else {
            (
                name,
                relative.parent().unwrap_or(Path::new("")).to_path_buf(),
            )
        };
        let text = without_test_items(&blank(&std::fs::read_to_string(&path).expect("read")));
        let module_path: String = folder
            .components()
            .map(|c| format!("{}::", c.as_os_str().to_string_lossy()))
            .collect();
        // from `a.rs` and from `a/mod.rs` alike, `super::` is the folder holding the siblings
        let mut used = paths_after(&text, "super::");
        used.extend(paths_after(&text, &format!("crate::{module_path}")));
        used.remove(&sibling);
        out.entry(folder)
            .or_default()
            .entry(sibling)
            .or_default()
            .extend(used);
    }
    out
}

/// Pairs of sibling files that use each other, and longer circles, in one crate's sources.
fn circles(src: &Path) -> Vec<String> {
    let mut found = Vec::new();
    for (folder, uses) in sibling_uses(src) {
        let names: Vec<&String> = uses.keys().collect();
        // a circle exists when a sibling reaches itself through the "uses" relation
        for start in &names {
            let mut seen = BTreeSet::new();
            let mut stack: Vec<&String> = uses[*start].iter().collect();
            while let Some(n) = stack.pop() {
                if n == *start {
                    found.push(format!(
                        "{}: {start} is in a circle of uses",
                        src.join(&folder).display()
                    ));
                    break;
                }
                if seen.insert(n.clone())
                    && let Some(next) = uses.get(n)
                {
                    stack.extend(next.iter());
                }
            }
        }
    }
    found
}

#[test]
fn no_two_files_of_a_module_use_each_other() {
    let mut found = Vec::new();
    for dir in ["src", "learn/src", "python/src"] {
        found.extend(circles(&root().join(dir)));
    }
    assert!(found.is_empty(), "circles:\n{}", found.join("\n"));
}

/// Every function of a source as (first line, lines, name).
fn functions(blanked: &str) -> Vec<(usize, usize, String)> {
    let b = blanked.as_bytes();
    let mut out = Vec::new();
    for (k, _) in blanked.match_indices("fn ") {
        if ident_before(b, k) {
            continue;
        }
        let name = identifier(&blanked[k + 3..]);
        if name.is_empty() {
            continue;
        }
        // the item ends at the body's closing brace, or at the `;` of a declaration without one
        let end = item_end(blanked, k);
        if b[end - 1] != b'}' {
            continue;
        }
        let first = blanked[..k].matches('\n').count() + 1;
        let last = blanked[..end].matches('\n').count() + 1;
        out.push((first, last - first + 1, name));
    }
    out
}

#[test]
fn no_function_is_longer_than_150_lines() {
    let mut long = Vec::new();
    for dir in ["src", "learn/src", "python/src"] {
        for path in rust_files(&root().join(dir)) {
            let text = blank(&std::fs::read_to_string(&path).expect("read"));
            for (line, lines, name) in functions(&text) {
                if lines > MAX_FUNCTION_LINES {
                    long.push(format!(
                        "{}:{line} fn {name}: {lines} lines",
                        path.strip_prefix(root()).unwrap_or(&path).display()
                    ));
                }
            }
        }
    }
    assert!(
        long.is_empty(),
        "functions over {MAX_FUNCTION_LINES} lines:\n{}",
        long.join("\n")
    );
}

/// The checks above see what they should: an upward import, a circle and a long function
/// written into a source are found; comments and strings do not count.
#[test]
fn the_source_checks_find_what_they_look_for() {
    let src = "use crate::model::Model; // crate::report is a comment\n\
               let s = \"crate::augment\";\n\
               #[cfg(test)]\nmod tests { use crate::dynamics::crba; }\n\
               use crate::{spatial::Vec3, io};\n";
    let text = without_test_items(&blank(src));
    let used = paths_after(&text, "crate::");
    assert_eq!(
        used,
        ["io", "model", "spatial"]
            .into_iter()
            .map(String::from)
            .collect()
    );
    assert_eq!(text.matches('\n').count(), src.matches('\n').count());

    let body = "    let x = '{';\n".repeat(200);
    let long = format!(
        "/// doc\nfn long<'a>(s: &'a str) -> char {{\n{body}    'x'\n}}\nfn short() {{}}\n"
    );
    let found = functions(&blank(&long));
    assert_eq!(found.len(), 2);
    assert_eq!(
        (found[0].0, found[0].1, found[0].2.as_str()),
        (2, 203, "long")
    );
    assert_eq!(found[1].1, 1);

    let dir = std::env::temp_dir().join(format!("musculo-architecture-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("m")).expect("temp folder");
    std::fs::write(dir.join("m/mod.rs"), "mod a; mod b;\n").expect("write");
    std::fs::write(dir.join("m/a.rs"), "use super::b::B;\npub struct A;\n").expect("write");
    std::fs::write(dir.join("m/b.rs"), "use crate::m::a::A;\npub struct B;\n").expect("write");
    std::fs::write(dir.join("m/c.rs"), "use super::a::A;\n").expect("write");
    let found = circles(&dir);
    std::fs::remove_dir_all(&dir).expect("clean up");
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(
        found.iter().any(|f| f.contains(": a is")) && found.iter().any(|f| f.contains(": b is"))
    );
}
