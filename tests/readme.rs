//! The README's and the book's examples, run as written, and their links checked.
//!
//! The documents are `README.md` and the book's chapters, `docs/src/**/*.md` in the order of
//! `docs/src/SUMMARY.md`. Convention for their fenced blocks (every block must carry one of
//! these tags):
//! - ` ```sh ` — commands that run as written from the repository root with `../shared`
//!   beside it. This test runs every one of them, README first and then the book in its
//!   order, each as its own `bash -c` (lines ending in `\` or `&&` continue a command), from a
//!   scratch copy of the repository's `models/` and `data/` with `../shared/reference` linked
//!   beside it, with `cargo run --release --` replaced by the binary under test. A command is
//!   expected to exit 0, or N when it ends with the comment `# exits N`.
//! - ` ```sh ci ` — commands that need a set-up step (the MuJoCo library, the OpenSim wheel,
//!   mdBook) or are the CI itself (`cargo test`): `.ci/run` runs them after its set-up steps;
//!   this test checks that each of them appears in `.ci/run` (ignoring `--locked`, and the
//!   `--config .ci/…` that gives CI's build of a command its own settings).
//! - ` ```text ` — output listings and commands for other machines (a cluster); ` ```rust ` —
//!   library code.
//! - ` ```python ` — the Python package's examples: `python/tests/test_musculo.py::
//!   test_documentation_examples` runs every one of them against the built wheel
//!   (`scripts/build-python.sh`, in `.ci/run`).
//!
//! After the run, every file the commands wrote must be ignored by `.gitignore`, and the
//! rebuild commands (`model build`, `model reserves`) must reproduce the shipped files byte
//! for byte. Every relative link of the documents must name a file that exists, and every
//! `#anchor` a heading of its target (mdBook's and GitHub's heading ids), so that the book
//! builds without broken links with or without mdBook installed.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");
const BIN: &str = env!("CARGO_BIN_EXE_musculo");

/// A fenced block: its document, its info string, the line of its opening fence, its text.
struct Block {
    file: String,
    info: String,
    line: usize,
    text: String,
}

fn blocks(file: &str, text: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut open: Option<Block> = None;
    for (k, line) in text.lines().enumerate() {
        let fence = line.trim_start().starts_with("```");
        match (&mut open, fence) {
            (None, true) => {
                open = Some(Block {
                    file: file.to_string(),
                    info: line.trim_start()[3..].trim().to_string(),
                    line: k + 1,
                    text: String::new(),
                })
            }
            (Some(_), true) => out.push(open.take().expect("open block")),
            (Some(b), false) => {
                b.text.push_str(line);
                b.text.push('\n');
            }
            (None, false) => {}
        }
    }
    assert!(open.is_none(), "{file}: a fenced block is not closed");
    out
}

/// One command of a block: the line it starts on, its text (continuation lines
/// joined), and the exit status the README promises.
struct Example {
    line: usize,
    text: String,
    status: i32,
}

fn commands(block: &Block) -> Vec<Example> {
    let mut out = Vec::new();
    let mut current: Option<Example> = None;
    for (k, raw) in block.text.lines().enumerate() {
        let line = raw.trim();
        if current.is_none() && (line.is_empty() || line.starts_with('#')) {
            continue;
        }
        let cmd = current.get_or_insert_with(|| Example {
            line: block.line + 1 + k,
            text: String::new(),
            status: 0,
        });
        cmd.text.push_str(raw);
        cmd.text.push('\n');
        let continues = line.ends_with('\\') || line.ends_with("&&");
        if !continues {
            let mut done = current.take().expect("current command");
            if let Some(at) = done.text.rfind("# exits ") {
                let n: String = done.text[at + 8..]
                    .chars()
                    .take_while(|c| c.is_ascii_digit())
                    .collect();
                done.status = n.parse().unwrap_or_else(|_| {
                    panic!("{}:{}: `# exits` needs a number", block.file, done.line)
                });
            }
            out.push(done);
        }
    }
    assert!(
        current.is_none(),
        "{}:{}: the block's last command continues past the block",
        block.file,
        block.line
    );
    out
}

/// The documents whose blocks run and whose links are checked: README.md, then the book's
/// chapters in the order of docs/src/SUMMARY.md. Paths relative to the repository root.
fn documents() -> Vec<String> {
    let mut out = vec!["README.md".to_string()];
    let summary = read("docs/src/SUMMARY.md");
    for (_, target) in links(&summary) {
        out.push(format!("docs/src/{target}"));
    }
    out
}

fn read(path: &str) -> String {
    std::fs::read_to_string(Path::new(ROOT).join(path)).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// Every fenced block of every document, in order.
fn all_blocks() -> Vec<Block> {
    documents()
        .iter()
        .flat_map(|d| blocks(d, &read(d)))
        .collect()
}

/// The inline links `[text](target)` of a Markdown text outside fenced blocks and code spans,
/// with the line each is on.
fn links(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut fence = false;
    for (k, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fence = !fence;
            continue;
        }
        if fence {
            continue;
        }
        // code spans removed: `[a](b)` in backticks is not a link
        let mut plain = String::new();
        for (i, part) in line.split('`').enumerate() {
            if i % 2 == 0 {
                plain.push_str(part);
            }
        }
        let mut rest = plain.as_str();
        while let Some(at) = rest.find("](") {
            let after = &rest[at + 2..];
            let Some(end) = after.find(')') else { break };
            out.push((k + 1, after[..end].trim().to_string()));
            rest = &after[end..];
        }
    }
    out
}

/// The id mdBook (and GitHub) gives a heading: lower case, spaces to `-`, letters, digits,
/// `-` and `_` kept, everything else dropped; a repeated id gets `-1`, `-2`, ….
fn heading_ids(text: &str) -> BTreeSet<String> {
    let mut ids = BTreeSet::new();
    let mut fence = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fence = !fence;
            continue;
        }
        if fence || !line.starts_with('#') {
            continue;
        }
        let title = line.trim_start_matches('#');
        if !title.starts_with(' ') {
            continue;
        }
        let id: String = title
            .trim()
            .chars()
            .filter_map(|c| {
                if c.is_alphanumeric() || c == '_' || c == '-' {
                    Some(c.to_lowercase().next().unwrap_or(c))
                } else if c.is_whitespace() {
                    Some('-')
                } else {
                    None
                }
            })
            .collect();
        let mut unique = id.clone();
        let mut n = 1;
        while ids.contains(&unique) {
            unique = format!("{id}-{n}");
            n += 1;
        }
        ids.insert(unique);
    }
    ids
}

#[test]
fn heading_ids_follow_mdbook() {
    let ids =
        heading_ids("# Speed (`cargo bench --bench ik`)\n## A, b\n## A, b\n```sh\n# no\n```\n");
    let want: BTreeSet<String> = ["speed-cargo-bench---bench-ik", "a-b", "a-b-1"]
        .map(String::from)
        .into();
    assert_eq!(ids, want);
    assert_eq!(
        links("see [a](x.md#y) and `[b](z.md)` [c](../d.md)\n"),
        vec![(1, "x.md#y".to_string()), (1, "../d.md".to_string())]
    );
}

#[test]
fn every_chapter_is_in_the_summary() {
    let listed: BTreeSet<String> = documents().into_iter().collect();
    let mut files = BTreeSet::new();
    let src = Path::new(ROOT).join("docs/src");
    files_under(&src, Path::new(ROOT), &mut files);
    for f in files {
        let f = f.display().to_string();
        if f.ends_with(".md") && f != "docs/src/SUMMARY.md" {
            assert!(
                listed.contains(&f),
                "{f} is not listed in docs/src/SUMMARY.md"
            );
        }
    }
}

#[test]
fn every_relative_link_and_anchor_resolves() {
    let mut checked = 0;
    let mut docs = documents();
    docs.push("docs/src/SUMMARY.md".into());
    docs.push("CHANGELOG.md".into());
    for doc in &docs {
        let text = read(doc);
        let dir = Path::new(doc).parent().unwrap_or(Path::new(""));
        for (line, target) in links(&text) {
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (path, anchor) = match target.split_once('#') {
                Some((p, a)) => (p, Some(a)),
                None => (target.as_str(), None),
            };
            let file = if path.is_empty() {
                Path::new(doc).to_path_buf()
            } else {
                dir.join(path)
            };
            let full = Path::new(ROOT).join(&file);
            assert!(
                full.exists(),
                "{doc}:{line}: link to `{target}`: {} does not exist",
                file.display()
            );
            if doc.starts_with("docs/src/") && !path.is_empty() {
                let inside = full
                    .canonicalize()
                    .unwrap()
                    .starts_with(Path::new(ROOT).join("docs/src").canonicalize().unwrap());
                assert!(
                    inside,
                    "{doc}:{line}: `{target}` leaves docs/src, which the built book does not hold"
                );
            }
            if let Some(anchor) = anchor {
                let ids = heading_ids(&std::fs::read_to_string(&full).unwrap());
                assert!(
                    ids.contains(anchor),
                    "{doc}:{line}: `#{anchor}` is no heading of {}; its headings: {ids:?}",
                    file.display()
                );
            }
            checked += 1;
        }
    }
    assert!(checked >= 40, "only {checked} links checked");
}

#[test]
fn every_fenced_block_is_tagged() {
    let known = ["sh", "sh ci", "text", "rust", "python"];
    let all = all_blocks();
    for b in &all {
        assert!(
            known.contains(&b.info.as_str()),
            "{}:{}: fenced block tagged `{}`; use one of {known:?} (see tests/readme.rs)",
            b.file,
            b.line,
            b.info
        );
    }
    assert!(
        all.iter()
            .any(|b| b.file == "README.md" && b.info == "python")
    );
}

#[test]
fn shell_blocks_split_into_commands() {
    let block = Block {
        file: "README.md".into(),
        info: "sh".into(),
        line: 10,
        text: "# a comment\nmusculo a \\\n    --b c\n\nmusculo d && \\\nmusculo e   # exits 3\n"
            .into(),
    };
    let c = commands(&block);
    assert_eq!(c.len(), 2);
    assert_eq!((c[0].line, c[0].status), (12, 0));
    assert_eq!(c[0].text, "musculo a \\\n    --b c\n");
    assert_eq!((c[1].line, c[1].status), (15, 3));
}

/// `.ci/run`'s lines with `--locked` and `--config .ci/…` (a CI-only settings file) removed
/// and spaces collapsed.
fn normalized(line: &str) -> String {
    let line = line.split(" #").next().unwrap_or(line);
    let mut words = Vec::new();
    let mut it = line.split_whitespace().peekable();
    while let Some(w) = it.next() {
        if w == "--locked" {
            continue;
        }
        if w == "--config" && it.peek().is_some_and(|v| v.starts_with(".ci/")) {
            it.next();
            continue;
        }
        words.push(w);
    }
    words.join(" ")
}

#[test]
fn ci_lines_lose_locked_and_ci_settings_files_only() {
    assert_eq!(
        normalized("cargo --config .ci/a.toml test --release --locked -p m  # note"),
        "cargo test --release -p m"
    );
    assert_eq!(
        normalized("cargo --config b.toml build"),
        "cargo --config b.toml build"
    );
}

#[test]
fn ci_blocks_are_run_by_ci() {
    let ci = std::fs::read_to_string(Path::new(ROOT).join(".ci/run")).expect(".ci/run");
    let ci_lines: BTreeSet<String> = ci.lines().map(normalized).collect();
    let mut count = 0;
    for b in all_blocks().iter().filter(|b| b.info == "sh ci") {
        for c in commands(b) {
            let want = normalized(&c.text.replace("\\\n", " "));
            assert!(
                ci_lines.contains(&want),
                "{}:{}: `{want}` is in a ```sh ci block but not in .ci/run",
                b.file,
                c.line
            );
            count += 1;
        }
    }
    assert!(count >= 4, "only {count} ci commands found");
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), &target).unwrap();
        }
    }
}

fn files_under(dir: &Path, base: &Path, out: &mut BTreeSet<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let entry = entry.unwrap();
        if entry.file_type().unwrap().is_dir() {
            files_under(&entry.path(), base, out);
        } else {
            out.insert(entry.path().strip_prefix(base).unwrap().to_path_buf());
        }
    }
}

/// The README's commands need the reference data beside the repository.
fn reference_dir() -> Option<PathBuf> {
    let dir = musculo::reference::directory();
    if dir.join("opensim-models").is_dir() {
        return Some(dir.canonicalize().unwrap_or(dir));
    }
    if musculo::reference::required() {
        panic!(
            "reference data not found: {} (MUSCULO_REQUIRE_REFERENCE=1)",
            dir.display()
        );
    }
    eprintln!("skipped: reference data not found ({})", dir.display());
    None
}

#[test]
fn readme_shell_examples_run_as_written() {
    let Some(reference) = reference_dir() else {
        return;
    };
    let scratch = std::env::temp_dir().join(format!("musculo-readme-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&scratch);
    let repo = scratch.join("repo");
    for dir in ["models", "data"] {
        copy_dir(&Path::new(ROOT).join(dir), &repo.join(dir));
    }
    std::fs::create_dir_all(scratch.join("shared")).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(&reference, scratch.join("shared/reference")).unwrap();
    let mut before = BTreeSet::new();
    files_under(&repo, &repo, &mut before);

    let mut ran = 0;
    let start = Instant::now();
    for block in all_blocks().iter().filter(|b| b.info == "sh") {
        for c in commands(block) {
            let script = c
                .text
                .replace("cargo run --release --", &format!("'{BIN}'"));
            assert!(
                !script.contains("cargo "),
                "{}:{}: a ```sh block may run cargo only as `cargo run --release --` \
                 (tag the block `sh ci` if CI runs it)",
                block.file,
                c.line
            );
            let t = Instant::now();
            let out = Command::new("bash")
                .arg("-c")
                .arg(format!("set -euo pipefail\n{script}"))
                .current_dir(&repo)
                .output()
                .expect("bash runs");
            let status = out.status.code().unwrap_or(-1);
            assert_eq!(
                status,
                c.status,
                "{}:{}: exit status {status}, expected {}\n{}\nstdout:\n{}\nstderr:\n{}",
                block.file,
                c.line,
                c.status,
                c.text,
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            );
            let stderr = String::from_utf8_lossy(&out.stderr);
            let first = c.text.lines().next().unwrap_or("").trim();
            println!(
                "{}:{} {:6.2} s  {}",
                block.file,
                c.line,
                t.elapsed().as_secs_f64(),
                first.replace("cargo run --release -- ", "musculo ")
            );
            // progress bars are drawn on a terminal only: nothing of them when piped
            for (what, bytes) in [("stdout", &out.stdout), ("stderr", &out.stderr)] {
                assert!(
                    !bytes.iter().any(|&b| b == b'\r' || b == 0x1b),
                    "{}:{}: terminal control characters on a piped {what}",
                    block.file,
                    c.line
                );
            }
            // many-frame warnings come summarised, never one line per frame
            let warnings = stderr.lines().filter(|l| l.contains("warning")).count();
            assert!(
                warnings <= 40,
                "{}:{}: {warnings} warning lines\n{stderr}",
                block.file,
                c.line
            );
            ran += 1;
        }
    }
    println!(
        "{ran} commands of the README and the book in {:.1} s",
        start.elapsed().as_secs_f64()
    );
    assert!(ran >= 30, "only {ran} commands found");

    // the rebuild commands reproduce the shipped files
    for shipped in [
        "models/musculo_fullbody.osim",
        "models/musculo_fullbody_reserves.xml",
    ] {
        let a = std::fs::read(Path::new(ROOT).join(shipped)).unwrap();
        let b = std::fs::read(repo.join(shipped)).unwrap();
        assert!(a == b, "the documents' commands changed {shipped}");
    }

    // what the commands wrote is ignored by git
    let mut after = BTreeSet::new();
    files_under(&repo, &repo, &mut after);
    let written: Vec<String> = after
        .difference(&before)
        .map(|p| p.display().to_string())
        .collect();
    assert!(!written.is_empty());
    let not_ignored = not_ignored_by_git(&written);
    assert!(
        not_ignored.is_empty(),
        ".gitignore does not cover what the documents' commands write: {not_ignored:?}"
    );
    std::fs::remove_dir_all(&scratch).ok();
}

/// Which of `paths` (relative to the repository root) `.gitignore` does not ignore; all of
/// them are reported as ignored when git is not installed (printing that).
fn not_ignored_by_git(paths: &[String]) -> Vec<String> {
    use std::io::Write;
    let child = Command::new("git")
        .args(["check-ignore", "--no-index", "--stdin"])
        .current_dir(ROOT)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn();
    let Ok(mut child) = child else {
        eprintln!("skipped: git not found, .gitignore not checked");
        return Vec::new();
    };
    let mut stdin = child.stdin.take().expect("stdin");
    stdin
        .write_all((paths.join("\n") + "\n").as_bytes())
        .unwrap();
    drop(stdin);
    let out = child.wait_with_output().unwrap();
    let ignored: BTreeSet<&str> = std::str::from_utf8(&out.stdout).unwrap().lines().collect();
    paths
        .iter()
        .filter(|p| !ignored.contains(p.as_str()))
        .cloned()
        .collect()
}

#[test]
fn mujoco_crash_log_is_ignored_and_not_committed() {
    assert!(not_ignored_by_git(&["MUJOCO_LOG.TXT".into()]).is_empty());
    if let Ok(out) = Command::new("git")
        .args(["ls-files", "--", "MUJOCO_LOG.TXT"])
        .current_dir(ROOT)
        .output()
    {
        assert!(out.stdout.is_empty(), "MUJOCO_LOG.TXT is committed");
    }
}

#[test]
fn version_names_the_file_formats_read() {
    let out = Command::new(BIN).arg("--version").output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.starts_with(&format!("musculo {}\n", env!("CARGO_PKG_VERSION"))),
        "{text}"
    );
    for needle in [
        "OpenSim 4.x .osim",
        "Version >= 40000",
        ".sto/.mot",
        "C3D",
        "BVH",
        "HumanML3D",
        "MJCF",
        "CHANGELOG.md",
    ] {
        assert!(text.contains(needle), "--version lacks `{needle}`:\n{text}");
    }
    assert!(
        Path::new(ROOT).join("CHANGELOG.md").is_file(),
        "--version points to CHANGELOG.md, which is missing"
    );
}
