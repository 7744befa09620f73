//! Every reader's limits ([`musculo::limits`]): what is not a regular file, an `.npz` whose
//! members inflate past the limit (as the archive's directory says, or beyond what it says),
//! an XML element with too many attributes, a BVH hierarchy too deep — each refused by the
//! command with exit status 1 and a message naming the file and where, within 10 s and
//! under a 2 GiB address-space limit. And a UTF-8 byte-order mark read like no mark in every
//! text format.

mod common;

use musculo::Error;
use musculo::motion::{self, ReadOptions, npy};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// A fresh directory for one test's files, removed at the end.
struct Scratch(PathBuf);

impl Scratch {
    fn new(test: &str) -> Scratch {
        let d = std::env::temp_dir().join(format!("musculo-limits-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        Scratch(d)
    }
    fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Runs `musculo args…` under a 2 GiB address-space limit (`ulimit -v`); returns the exit
/// status (None: killed by a signal), stderr and the time it took.
fn musculo_bounded(args: &[&str]) -> (Option<i32>, String, Duration) {
    let start = Instant::now();
    let out = std::process::Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 2097152 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_musculo"))
        .args(args)
        .output()
        .expect("run musculo under sh");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        start.elapsed(),
    )
}

/// A refusal as the brief asks for it: exit status 1, the message naming the file, in 10 s.
fn assert_refused(args: &[&str], file: &Path, needle: &str) {
    let (code, stderr, took) = musculo_bounded(args);
    assert_eq!(code, Some(1), "{args:?}: {stderr}");
    assert!(
        stderr.contains(&file.display().to_string()) && stderr.contains(needle),
        "{args:?}: {stderr}"
    );
    assert!(took < Duration::from_secs(10), "{args:?} took {took:?}");
}

/// The bytes of an `.npz` holding one float32 array `x` of `n` zeros (deflated: a few
/// kilobytes), with the inflated size the archive's directory gives the member replaced by
/// `declared` (both in the local header and in the central directory).
fn npz_declaring(n: usize, declared: u32) -> Vec<u8> {
    let x = ndarray::ArrayD::<f32>::zeros(ndarray::IxDyn(&[n]));
    let mut bytes = npy::npz_bytes(&[("x", x.view())], &[], true).unwrap();
    let patch = |bytes: &mut Vec<u8>, signature: &[u8; 4], offset: usize| {
        let at = bytes
            .windows(4)
            .position(|w| w == signature)
            .expect("zip record");
        bytes[at + offset..at + offset + 4].copy_from_slice(&declared.to_le_bytes());
    };
    patch(&mut bytes, b"PK\x03\x04", 22); // local file header: uncompressed size
    patch(&mut bytes, b"PK\x01\x02", 24); // central directory: uncompressed size
    bytes
}

#[test]
fn an_npz_inflating_past_the_limit_is_refused_before_it_is_inflated() {
    let d = Scratch::new("npz");
    // The directory says 3.75 GiB: refused from the directory, nothing inflated.
    let bomb = d.join("bomb.npz");
    std::fs::write(&bomb, npz_declaring(1000, 0xF000_0000)).unwrap();
    match npy::read_npz_as_f64(&bomb) {
        Err(Error::Limit {
            location, message, ..
        }) => {
            assert_eq!(location, "archive member \"x.npy\"");
            assert!(message.contains("MAX_NPZ_INFLATED_BYTES"), "{message}");
        }
        other => panic!("expected a limit refusal, got {other:?}"),
    }
    // The directory says 100 bytes and the member inflates to 4 MB: inflating stops at 101.
    let liar = d.join("liar.npz");
    std::fs::write(&liar, npz_declaring(1 << 20, 100)).unwrap();
    let e = npy::read_npz_as_f64(&liar).unwrap_err().to_string();
    assert!(e.contains("inflates past the 100 bytes"), "{e}");
    for args in [
        vec!["loss", bomb.to_str().unwrap()],
        vec![
            "evaluate",
            "--input",
            bomb.to_str().unwrap(),
            "--out",
            d.join("e.json").to_str().unwrap(),
        ],
        vec![
            "report",
            bomb.to_str().unwrap(),
            "--out",
            d.join("pages").to_str().unwrap(),
        ],
    ] {
        assert_refused(&args, &bomb, "MAX_NPZ_INFLATED_BYTES");
    }
}

#[test]
fn devices_and_named_pipes_are_refused_without_reading_them() {
    let zero = Path::new("/dev/zero");
    if !zero.exists() {
        println!("skipped: no /dev/zero here");
        return;
    }
    assert_refused(&["inspect", "/dev/zero"], zero, "not a regular file");
    let d = Scratch::new("fifo");
    let fifo = d.join("model.osim");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    if made {
        // reading a named pipe with no writer would block forever
        assert_refused(
            &["inspect", fifo.to_str().unwrap()],
            &fifo,
            "not a regular file",
        );
    } else {
        println!("skipped the named pipe: no mkfifo here");
    }
}

#[test]
fn two_hundred_thousand_attributes_on_one_element_are_refused_at_once() {
    let d = Scratch::new("attributes");
    let attributes: String = (0..200_000).map(|i| format!(" a{i}=\"1\"")).collect();
    let text = musculo::DEMO_MODEL_OSIM.replacen("<Body ", &format!("<Body{attributes} "), 1);
    let path = d.join("attributes.osim");
    std::fs::write(&path, text).unwrap();
    assert_refused(
        &["inspect", path.to_str().unwrap()],
        &path,
        "MAX_XML_ATTRIBUTES",
    );
}

/// A BVH hierarchy of one chain `depth` joints deep, one frame.
fn deep_bvh(depth: usize) -> String {
    let mut s = String::from(
        "HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 3 Xposition Yposition Zposition\n",
    );
    for k in 0..depth {
        s += &format!("JOINT j{k}\n{{\nOFFSET 0 1 0\nCHANNELS 1 Zrotation\n");
    }
    s += "End Site\n{\nOFFSET 0 1 0\n}\n";
    s += &"}\n".repeat(depth + 1);
    s += &format!(
        "MOTION\nFrames: 1\nFrame Time: 0.01\n{}\n",
        vec!["0"; 3 + depth].join(" ")
    );
    s
}

#[test]
fn a_bvh_hierarchy_deeper_than_the_limit_is_refused_and_one_within_it_is_read_in_linear_time() {
    let d = Scratch::new("bvh");
    let deep = d.join("deep.bvh");
    std::fs::write(&deep, deep_bvh(100_000)).unwrap();
    assert_refused(
        &[
            "ik",
            "--input",
            deep.to_str().unwrap(),
            "-o",
            d.join("out/").to_str().unwrap(),
        ],
        &deep,
        "MAX_BVH_DEPTH",
    );
    // Within the limits, twice the joints take about twice the time (the duplicate-name
    // check was quadratic): 999 deep and, as siblings, 9,000 wide.
    let wide = |n: usize| {
        let mut s = String::from(
            "HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 3 Xposition Yposition Zposition\n",
        );
        for k in 0..n {
            s += &format!("JOINT j{k}\n{{\nOFFSET 0 1 0\nCHANNELS 1 Zrotation\n}}\n");
        }
        s += &format!(
            "}}\nMOTION\nFrames: 1\nFrame Time: 0.01\n{}\n",
            vec!["0"; 3 + n].join(" ")
        );
        s
    };
    musculo::motion::bvh::Bvh::parse(&deep_bvh(999), "deep999.bvh").unwrap();
    let time = |text: &str| {
        let start = Instant::now();
        musculo::motion::bvh::Bvh::parse(text, "wide.bvh").unwrap();
        start.elapsed()
    };
    let (small, large) = (wide(4_500), wide(9_000));
    time(&small); // warm
    let (t_small, t_large) = (time(&small), time(&large));
    assert!(
        t_large < t_small * 4 + Duration::from_millis(20),
        "4,500 joints {t_small:?}, 9,000 joints {t_large:?}: not linear"
    );
    let e = musculo::motion::bvh::Bvh::parse(&wide(10_001), "many.bvh").unwrap_err();
    assert!(e.to_string().contains("MAX_BVH_JOINTS"), "{e}");
}

#[test]
fn a_utf8_byte_order_mark_is_read_like_none_in_trc_and_bvh_files() {
    let d = Scratch::new("bom");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for seed in ["fuzz/seeds/trc/walk.trc", "fuzz/seeds/bvh/walk.bvh"] {
        let original = root.join(seed);
        let name = original.file_name().unwrap().to_str().unwrap();
        let marked = d.join(name);
        let mut bytes = vec![0xEF, 0xBB, 0xBF];
        bytes.extend(std::fs::read(&original).unwrap());
        std::fs::write(&marked, &bytes).unwrap();
        let plain = motion::read(&original, None, &ReadOptions::default()).unwrap();
        let with_mark = motion::read(&marked, None, &ReadOptions::default())
            .unwrap_or_else(|e| panic!("{seed} with a byte-order mark: {e}"));
        assert_eq!(with_mark.names, plain.names, "{seed}");
        assert_eq!(with_mark.time, plain.time, "{seed}");
        // NaN marks a missing marker: compared as printed
        assert_eq!(
            format!("{:?}", with_mark.positions),
            format!("{:?}", plain.positions),
            "{seed}"
        );
    }
    // the text parsers too
    let text = std::fs::read_to_string(root.join("fuzz/seeds/bvh/walk.bvh")).unwrap();
    musculo::motion::bvh::Bvh::parse(&format!("\u{feff}{text}"), "walk.bvh").unwrap();
    let text = std::fs::read_to_string(root.join("fuzz/seeds/trc/walk.trc")).unwrap();
    musculo::io::trc::Trc::parse(&format!("\u{feff}{text}"), "walk.trc").unwrap();
}

/// An OpenSim model of `n` bodies in one chain of pin joints.
fn chain_osim(n: usize) -> String {
    let mut bodies = String::new();
    let mut joints = String::new();
    for i in 0..n {
        bodies += &common::body(
            &format!("b{i}"),
            1.0,
            [0.0; 3],
            [0.01, 0.01, 0.01, 0.0, 0.0, 0.0],
        );
        let parent = if i == 0 {
            "/ground".to_string()
        } else {
            format!("/bodyset/b{}", i - 1)
        };
        joints += &common::joint(
            "PinJoint",
            &format!("j{i}"),
            &parent,
            [0.0, 0.01, 0.0],
            &format!("/bodyset/b{i}"),
            &[common::coordinate(&format!("q{i}"), [-3.0, 3.0])],
            "",
        );
    }
    common::osim(&bodies, &joints, "", [0.0, -9.81, 0.0])
}

#[test]
fn a_workspace_for_many_bodies_holds_no_body_by_body_table() {
    // 2,000 bodies: an n × n inertia matrix (and its full-coordinate twin) would be 64 MB;
    // inverse dynamics needs neither, and the workspace allocates them at the first crba.
    let model = musculo::Model::from_osim_str(&chain_osim(2_000), "chain.osim").unwrap();
    let mut data = musculo::Data::new(&model);
    let bytes = data.memory_bytes();
    assert!(bytes < 2_000 * 4_096, "{bytes} bytes for 2,000 bodies");
    let q = vec![0.1; model.nq()];
    let zero = vec![0.0; model.nq()];
    musculo::dynamics::rnea(&model, &mut data, &q, &zero, &zero).unwrap();
    assert!(data.memory_bytes() < 2_000 * 4_096);
    let m = musculo::dynamics::crba(&model, &mut data, &q).unwrap();
    assert_eq!(m.shape(), (2_000, 2_000));
}

#[test]
fn a_model_with_more_bodies_than_the_limit_is_refused() {
    let d = Scratch::new("bodies");
    let path = d.join("chain.osim");
    std::fs::write(&path, chain_osim(musculo::limits::MAX_BODIES)).unwrap();
    // ground + MAX_BODIES bodies: one too many
    assert_refused(&["inspect", path.to_str().unwrap()], &path, "MAX_BODIES");
}
