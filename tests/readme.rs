//! The README's examples, run as written (issue 12, "the newcomer's path").
//!
//! Convention for the README's fenced blocks (every block must carry one of these tags):
//! - ` ```sh ` — commands that run as written from the repository root with `../shared`
//!   beside it. This test runs every one of them, in README order, each as its own
//!   `bash -c` (lines ending in `\` or `&&` continue a command), from a scratch copy of the
//!   repository's `models/` and `data/` with `../shared/reference` linked beside it, with
//!   `cargo run --release --` replaced by the binary under test. A command is expected to exit
//!   0, or N when it ends with the comment `# exits N`.
//! - ` ```sh ci ` — commands that need a set-up step (the MuJoCo library, the OpenSim wheel)
//!   or are the CI itself (`cargo test`): `.ci/run` runs them after its set-up steps; this
//!   test checks that each of them appears in `.ci/run` (ignoring `--locked`, and the
//!   `--config .ci/…` that gives CI's build of a command its own settings).
//! - ` ```text ` — output listings; ` ```rust ` — library code.
//! - ` ```python ` — the Python package's examples, only in its section ("## Python package"):
//!   `python/tests/test_musculo.py::test_readme_examples` runs them against the built wheel
//!   (`scripts/build-python.sh`, in `.ci/run`).
//!
//! After the run, every file the commands wrote must be ignored by `.gitignore`, and the
//! README's rebuild commands (`model build`, `model reserves`) must reproduce the shipped
//! files byte for byte.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");
const BIN: &str = env!("CARGO_BIN_EXE_musculo");

/// A fenced block: its info string, the README line of its opening fence, its text.
struct Block {
    info: String,
    line: usize,
    text: String,
}

fn blocks(readme: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut open: Option<Block> = None;
    for (k, line) in readme.lines().enumerate() {
        let fence = line.trim_start().starts_with("```");
        match (&mut open, fence) {
            (None, true) => {
                open = Some(Block {
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
    assert!(open.is_none(), "README.md: a fenced block is not closed");
    out
}

/// One command of a block: the README line it starts on, its text (continuation lines
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
                    panic!("README.md:{}: `# exits` needs a number", done.line)
                });
            }
            out.push(done);
        }
    }
    assert!(
        current.is_none(),
        "README.md:{}: the block's last command continues past the block",
        block.line
    );
    out
}

fn readme() -> String {
    std::fs::read_to_string(Path::new(ROOT).join("README.md")).expect("README.md")
}

#[test]
fn every_fenced_block_is_tagged() {
    let known = ["sh", "sh ci", "text", "rust", "python"];
    let text = readme();
    let python_section = text
        .find("\n## Python package")
        .expect("a Python package section");
    let section_end = text[python_section + 1..]
        .find("\n## ")
        .map_or(text.len(), |e| python_section + 1 + e);
    let line_of = |at: usize| text[..at].lines().count() + 1;
    let (first, last) = (line_of(python_section), line_of(section_end));
    for b in blocks(&text) {
        assert!(
            b.info != "python" || (first..=last).contains(&b.line),
            "README.md:{}: python blocks belong in the Python package section, whose test runs them",
            b.line
        );
        assert!(
            known.contains(&b.info.as_str()),
            "README.md:{}: fenced block tagged `{}`; use one of {known:?} (see tests/readme.rs)",
            b.line,
            b.info
        );
    }
}

#[test]
fn shell_blocks_split_into_commands() {
    let block = Block {
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
    for b in blocks(&readme()).iter().filter(|b| b.info == "sh ci") {
        for c in commands(b) {
            let want = normalized(&c.text.replace("\\\n", " "));
            assert!(
                ci_lines.contains(&want),
                "README.md:{}: `{want}` is in a ```sh ci block but not in .ci/run",
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
    for block in blocks(&readme()).iter().filter(|b| b.info == "sh") {
        for c in commands(block) {
            let script = c
                .text
                .replace("cargo run --release --", &format!("'{BIN}'"));
            assert!(
                !script.contains("cargo "),
                "README.md:{}: a ```sh block may run cargo only as `cargo run --release --` \
                 (tag the block `sh ci` if CI runs it)",
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
                "README.md:{}: exit status {status}, expected {}\n{}\nstdout:\n{}\nstderr:\n{}",
                c.line,
                c.status,
                c.text,
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            );
            let stderr = String::from_utf8_lossy(&out.stderr);
            let first = c.text.lines().next().unwrap_or("").trim();
            println!(
                "README.md:{} {:6.2} s  {}",
                c.line,
                t.elapsed().as_secs_f64(),
                first.replace("cargo run --release -- ", "musculo ")
            );
            // progress bars are drawn on a terminal only: nothing of them when piped
            for (what, bytes) in [("stdout", &out.stdout), ("stderr", &out.stderr)] {
                assert!(
                    !bytes.iter().any(|&b| b == b'\r' || b == 0x1b),
                    "README.md:{}: terminal control characters on a piped {what}",
                    c.line
                );
            }
            // many-frame warnings come summarised, never one line per frame
            let warnings = stderr.lines().filter(|l| l.contains("warning")).count();
            assert!(
                warnings <= 40,
                "README.md:{}: {warnings} warning lines\n{stderr}",
                c.line
            );
            ran += 1;
        }
    }
    println!(
        "{ran} README commands in {:.1} s",
        start.elapsed().as_secs_f64()
    );
    assert!(ran >= 30, "only {ran} README commands found");

    // the rebuild commands reproduce the shipped files
    for shipped in [
        "models/musculo_fullbody.osim",
        "models/musculo_fullbody_reserves.xml",
    ] {
        let a = std::fs::read(Path::new(ROOT).join(shipped)).unwrap();
        let b = std::fs::read(repo.join(shipped)).unwrap();
        assert!(a == b, "the README's commands changed {shipped}");
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
        ".gitignore does not cover what the README's commands write: {not_ignored:?}"
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
