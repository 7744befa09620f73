//! Output folders shared between runs that cannot see each other's processes, and outputs
//! cut short by a full disk:
//! - two `augment --shard` runs in separate PID namespaces (as on two hosts, or two pods of
//!   one Kubernetes job) writing into one folder at the same time: neither removes a file
//!   another writer may still be writing, and the merged folder equals one run's;
//! - a full disk in the middle of a clip: none of the clip's files under its name (a clip's
//!   files commit together, record included), one error message, exit status 1.
//!
//! Both need Linux namespaces without root (`unshare --user --map-root-user`); where they
//! cannot be made the tests say "skipped".

use std::path::{Path, PathBuf};
use std::process::Command;

const MUSCULO: &str = env!("CARGO_BIN_EXE_musculo");

fn temp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("musculo-sharing-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Whether `unshare` with these namespace flags works here.
fn unshare_works(flags: &[&str]) -> bool {
    Command::new("unshare")
        .args(flags)
        .arg("true")
        .status()
        .is_ok_and(|s| s.success())
}

/// The files under `dir` but hidden ones (temporaries) and the `.musculo` folder, with
/// their bytes.
fn visible_files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            if name.starts_with('.') {
                continue;
            }
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().display().to_string();
                files.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    files.sort();
    files
}

#[test]
fn shards_in_separate_pid_namespaces_keep_each_others_files_and_merge_to_one_run() {
    let namespace = ["--user", "--map-root-user", "--pid", "--fork"];
    if !unshare_works(&namespace) {
        println!("skipped: `unshare --user --map-root-user --pid --fork` does not work here");
        return;
    }
    let (single, sharded) = (temp_dir("single"), temp_dir("sharded"));
    let args = [
        "augment",
        "--demo",
        "--variants",
        "2",
        "--jobs",
        "2",
        "--out",
    ];
    let one = Command::new(MUSCULO)
        .args(args)
        .arg(&single)
        .output()
        .unwrap();
    assert!(
        one.status.success(),
        "{}",
        String::from_utf8_lossy(&one.stderr)
    );
    // Live temporaries of writers this run cannot probe, of files the shards write: one of a
    // process on another host, one named before names carried a host (a bare process id
    // that no process here has). Both fresh: their writers may be running.
    let foreign = [
        sharded.join(format!(
            ".march.npz.tmp-5a5a5a5a-4026531836-{}-0",
            u32::MAX - 7
        )),
        sharded.join(format!(".reach.npz.tmp-{}-0", u32::MAX - 7)),
        sharded.join(format!(".musculo/.settings.json.tmp-{}-1", u32::MAX - 7)),
    ];
    std::fs::create_dir_all(sharded.join(".musculo")).unwrap();
    for f in &foreign {
        std::fs::write(f, "being written").unwrap();
    }
    // Both shards at once, each in a PID namespace of its own: each sees the other's process
    // ids as nothing (or as other processes).
    let shards: Vec<_> = (0..2)
        .map(|k| {
            Command::new("unshare")
                .args(namespace)
                .arg(MUSCULO)
                .args(args)
                .arg(&sharded)
                .args(["--shard", &format!("{k}/2")])
                .output()
                .unwrap()
        })
        .collect();
    for (k, out) in shards.iter().enumerate() {
        assert!(
            out.status.success(),
            "shard {k}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    for f in &foreign {
        assert!(
            f.exists(),
            "{} was removed while its writer may live",
            f.display()
        );
    }
    let merged = Command::new(MUSCULO)
        .arg("merge")
        .arg(&sharded)
        .output()
        .unwrap();
    assert!(
        merged.status.success(),
        "{}",
        String::from_utf8_lossy(&merged.stderr)
    );
    let reference = visible_files(&single);
    assert_eq!(
        reference.len(),
        2 + 6,
        "manifest, stats, 3 clips × 2 variants"
    );
    let names = |v: &[(String, Vec<u8>)]| v.iter().map(|f| f.0.clone()).collect::<Vec<_>>();
    let got = visible_files(&sharded);
    assert_eq!(names(&got), names(&reference));
    assert!(got == reference, "sharded + merge differs from one run");
    for d in [single, sharded] {
        let _ = std::fs::remove_dir_all(d);
    }
}

/// Runs `augment --demo --opensim-files` into a tmpfs of `size` mounted in a private mount
/// namespace; returns the exit status, stderr and the files left (paths relative to the
/// output folder), read inside the namespace before the tmpfs goes away.
fn augment_on_a_small_disk(size: &str) -> (i32, String, Vec<String>) {
    let mount = temp_dir(&format!("disk-{size}"));
    let script = format!(
        "mount -t tmpfs -o size={size} tmpfs '{m}' || exit 99; \
         '{MUSCULO}' augment --demo --opensim-files --jobs 1 --out '{m}/out' 2>'{m}/err' >/dev/null; \
         echo \"rc=$?\"; cat '{m}/err' >&2; cd '{m}/out' && find . -type f",
        m = mount.display()
    );
    let out = Command::new("unshare")
        .args(["--user", "--map-root-user", "--mount", "sh", "-c", &script])
        .output()
        .unwrap();
    let _ = std::fs::remove_dir_all(&mount);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let mut lines = stdout.lines();
    let rc = lines
        .next()
        .and_then(|l| l.strip_prefix("rc="))
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| {
            panic!(
                "no exit status: {stdout} {}",
                String::from_utf8_lossy(&out.stderr)
            )
        });
    let files = lines
        .map(|l| l.trim_start_matches("./").to_string())
        .collect();
    (rc, String::from_utf8_lossy(&out.stderr).into_owned(), files)
}

#[test]
fn a_clip_cut_short_by_a_full_disk_leaves_none_of_its_files() {
    if !unshare_works(&["--user", "--map-root-user", "--mount"]) {
        println!("skipped: `unshare --user --map-root-user --mount` does not work here");
        return;
    }
    // 1 MB: the first clip's `.npz` does not fit. 2 MB: it does, with its first OpenSim
    // files, and a later file of the clip does not.
    for size in ["1m", "2m"] {
        let (rc, stderr, files) = augment_on_a_small_disk(size);
        assert_eq!(rc, 1, "{size}: {stderr}");
        assert_eq!(
            stderr.matches("No space left on device").count(),
            1,
            "{size}: one message: {stderr}"
        );
        assert!(!stderr.contains("ZipWriter"), "{size}: {stderr}");
        assert!(
            stderr.lines().all(|l| l.starts_with("error: ")),
            "{size}: {stderr}"
        );
        for f in &files {
            assert!(!f.contains(".tmp-"), "{size}: temporary left: {f}");
            if f.starts_with(".musculo/") {
                continue;
            }
            // every clip file belongs to a clip with a record
            let clip = f.split(['.', '_']).next().unwrap();
            let record = format!(".musculo/records/{clip}.json");
            assert!(
                files.contains(&record),
                "{size}: {f} without its clip's record: {files:?}"
            );
        }
    }
}
