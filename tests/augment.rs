//! `musculo augment` end to end: the emitted arrays satisfy the equations of motion when
//! recomputed from the `.npz` alone, activations lie in [0, 1], nothing is NaN; runs are
//! byte-identical for 1 and 2 threads, for sharded runs after `merge`, and after `kill -9`
//! and `--resume`; a failing clip is recorded and the run goes on.

mod common;

use common::{reference_file, run_musculo};
use musculo::augment::chain::{Chain, ChainOptions, ClipQuality, MeasuredLoads};
use musculo::augment::output::{self, ClipStatus};
use musculo::augment::perturb::Variant;
use musculo::augment::runner::{self, ClipInput, ClipSource, RunOptions};
use musculo::augment::{demo, describe};
use musculo::motion::skeleton::SkeletonMap;
use musculo::motion::{self, Format, Motion, ReadOptions};
use musculo::spatial::Vec3;
use musculo::{Data, Model, dynamics};
use nalgebra::DMatrix;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

fn chain() -> Chain {
    Chain::default_model(ChainOptions::default()).unwrap()
}

fn demo_inputs(chain: &Chain) -> Vec<ClipInput> {
    demo::inputs(&chain.model).unwrap()
}

fn options(out: &Path) -> RunOptions {
    RunOptions::new(out)
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("musculo-augment-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn read_npz(path: &Path) -> HashMap<String, (Vec<usize>, Vec<f64>)> {
    motion::npy::read_npz_as_f64(path)
        .unwrap()
        .into_iter()
        .map(|(k, a)| {
            let shape = a.shape().to_vec();
            (k, (shape, a.iter().copied().collect()))
        })
        .collect()
}

/// Recomputes M q̈ + C q̇ + G − τ − J_cᵀλ from the arrays of one clip on `model`; returns the
/// worst frame's ‖·‖∞ relative to that frame's ‖M q̈ + C q̇ + G‖∞, and checks the rest.
fn check_clip(model: &Model, npz: &Path) -> f64 {
    let a = read_npz(npz);
    let get = |name: &str| &a.get(name).unwrap_or_else(|| panic!("{name} missing")).1;
    for (name, (_, v)) in &a {
        if name == "ik_marker_error" {
            // NaN only where the input had no target
            assert!(v.iter().all(|x| x.is_nan() || *x >= 0.0), "{name}");
        } else {
            assert!(v.iter().all(|x| x.is_finite()), "{name} has NaN/inf");
        }
    }
    for &v in get("muscle_act") {
        assert!((0.0..=1.0).contains(&v), "activation {v}");
    }
    let n = model.nq();
    let (q, qd, qdd, tau) = (get("q"), get("qd"), get("qdd"), get("tau"));
    let frames = q.len() / n;
    let set = musculo::augment::chain::contact_set(model).unwrap();
    let p = set.points.len();
    let (force, pos) = (get("contact_point_force"), get("contact_point_pos"));
    assert_eq!(force.len(), frames * p * 3);
    let mut data = Data::new(model);
    let mut jac = DMatrix::zeros(3, n);
    let mut worst = 0.0f64;
    for f in 0..frames {
        let r = f * n..(f + 1) * n;
        let lhs: Vec<f64> =
            dynamics::rnea(model, &mut data, &q[r.clone()], &qd[r.clone()], &qdd[r])
                .unwrap()
                .iter()
                .copied()
                .collect();
        let mut rhs: Vec<f64> = tau[f * n..(f + 1) * n].to_vec();
        // measured loads' generalized forces (zero when the contacts were estimated)
        for (r, e) in rhs.iter_mut().zip(&get("external")[f * n..(f + 1) * n]) {
            *r += e;
        }
        for (i, point) in set.points.iter().enumerate() {
            let k = (f * p + i) * 3;
            let fv = Vec3::new(force[k], force[k + 1], force[k + 2]);
            if fv.norm() == 0.0 {
                continue;
            }
            let at = Vec3::new(pos[k], pos[k + 1], pos[k + 2]);
            let (rot, origin) = data.body_pose(point.body);
            let local = rot.transpose() * (at - origin);
            dynamics::point_jacobian(model, &data, point.body, &local, &mut jac).unwrap();
            for j in 0..n {
                rhs[j] += jac[(0, j)] * fv.x + jac[(1, j)] * fv.y + jac[(2, j)] * fv.z;
            }
        }
        let scale = lhs.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1.0);
        let err = lhs
            .iter()
            .zip(&rhs)
            .fold(0.0f64, |m, (l, r)| m.max((l - r).abs()));
        worst = worst.max(err / scale);
    }
    worst
}

#[test]
fn demo_clips_satisfy_the_equations_of_motion_from_the_files_alone() {
    let chain = chain();
    let layout = describe(&chain).unwrap();
    let clips = demo_inputs(&chain);
    let out = temp_dir("demo");
    let report = runner::run(&chain, &layout, &clips, &options(&out), &|_| {}).unwrap();
    let manifest = report.manifest.unwrap();
    assert_eq!(manifest.summary.clips_ok, 3);
    for (clip, record) in clips.iter().zip(&report.records) {
        let ClipSource::Motion(motion) = &clip.source else {
            unreachable!()
        };
        let model = chain
            .clip_model(motion, None, &Variant::identity())
            .unwrap();
        let worst = check_clip(&model, &output::npz_path(&out, &clip.name));
        let q = record.quality.as_ref().unwrap();
        println!(
            "{}: EL identity {worst:.2e} (relative), reserves {:.2} %, residual force ≤ {:.3} BW, \
             contact in {:.0} % of frames",
            clip.name,
            100.0 * q.reserve_share,
            q.residual_force_max_bw,
            100.0 * q.contact_fraction
        );
        assert!(worst <= 1e-6, "{}: {worst:e}", clip.name);
    }
    // x is the concatenation of the per-joint blocks, in the manifest's ranges
    let a = read_npz(&output::npz_path(&out, "march"));
    let (xs, x) = &a["x"];
    for r in &layout.x {
        let (_, block) = &a[&r.name];
        let width = r.end - r.start;
        for f in 0..xs[0] {
            for i in 0..width {
                assert_eq!(
                    x[f * xs[1] + r.start + i],
                    block[f * width + i],
                    "{}",
                    r.name
                );
            }
        }
    }
    let _ = std::fs::remove_dir_all(&out);
}

fn bytes_of(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                if !p.ends_with(".musculo") {
                    stack.push(p);
                }
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
fn threads_and_shards_give_identical_bytes() {
    let chain = chain();
    let layout = describe(&chain).unwrap();
    let clips = demo_inputs(&chain);
    let run_with = |threads: usize, dir: &Path, shard: Option<(usize, usize)>| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut o = options(dir);
        o.variants = 2;
        o.shard = shard;
        pool.install(|| runner::run(&chain, &layout, &clips, &o, &|_| {}))
            .unwrap();
    };
    let (one, two, sharded) = (temp_dir("t1"), temp_dir("t2"), temp_dir("sh"));
    run_with(1, &one, None);
    run_with(2, &two, None);
    run_with(2, &sharded, Some((1, 2)));
    run_with(1, &sharded, Some((0, 2)));
    assert!(
        runner::merge(&one).is_err(),
        "an unsharded run has no shard lists"
    );
    runner::merge(&sharded).unwrap();
    let reference = bytes_of(&one);
    assert_eq!(
        reference.len(),
        2 + 6,
        "manifest, stats and 3 clips × 2 variants"
    );
    assert!(reference == bytes_of(&two), "1 vs 2 threads");
    assert!(
        reference == bytes_of(&sharded),
        "sharded + merge vs one run"
    );
    for d in [one, two, sharded] {
        let _ = std::fs::remove_dir_all(d);
    }
}

/// `musculo merge` takes nothing in the shard lists or the records on trust: an absurd shard
/// count is answered at once (not by walking 0..N), a shard K of N outside 0 ≤ K < N and
/// lists that disagree on N are refused naming the files, a clip listed twice or named
/// outside the output folder is refused, and a clip recorded ok whose `.npz` is missing or
/// damaged fails the merge (non-zero exit) naming the clip. The untouched folder merges.
#[test]
fn merge_refuses_shard_lists_and_outputs_it_cannot_trust() {
    let chain = chain();
    let layout = describe(&chain).unwrap();
    let clips = demo_inputs(&chain);
    let out = temp_dir("merge-untrusted");
    for k in 0..2 {
        let mut o = options(&out);
        o.shard = Some((k, 2));
        runner::run(&chain, &layout, &clips, &o, &|_| {}).unwrap();
    }
    let lists = out.join(output::SHARDS);
    let paths = [lists.join("0-of-2.json"), lists.join("1-of-2.json")];
    let originals: Vec<String> = paths
        .iter()
        .map(|p| std::fs::read_to_string(p).unwrap())
        .collect();
    // the merge's error after `edit(k, list k)` of each list; the lists restored after it
    let merge_error = |edit: &dyn Fn(usize, &mut serde_json::Value)| -> String {
        for (k, (path, text)) in paths.iter().zip(&originals).enumerate() {
            let mut list: serde_json::Value = serde_json::from_str(text).unwrap();
            edit(k, &mut list);
            std::fs::write(path, list.to_string()).unwrap();
        }
        let result = runner::merge(&out);
        for (path, text) in paths.iter().zip(&originals) {
            std::fs::write(path, text).unwrap();
        }
        result
            .expect_err("merged untrustworthy shard lists")
            .to_string()
    };
    let huge = 1_000_000_000_000_000_000usize;
    let e = merge_error(&|_, l| l["shards"] = huge.into());
    assert!(
        e.contains(&format!(
            "shard(s) 2, 3, 4, 5, 6, 7, 8, 9, 10, 11 and {} more of {huge} have not finished",
            huge - 12
        )),
        "{e}"
    );
    let e = merge_error(&|_, l| l["shards"] = 0.into());
    assert!(
        e.contains("0-of-2.json: shard 0 of 0: a shard list must be shard K of N with 0 ≤ K < N"),
        "{e}"
    );
    let e = merge_error(&|k, l| {
        if k == 1 {
            l["shard"] = 5.into();
        }
    });
    assert!(e.contains("1-of-2.json: shard 5 of 2"), "{e}");
    let e = merge_error(&|k, l| {
        if k == 1 {
            l["shards"] = 3.into();
        }
    });
    assert!(
        e.contains("0-of-2.json is shard 0 of 2")
            && e.contains("1-of-2.json shard 1 of 3")
            && e.contains("disagree on the number of shards"),
        "{e}"
    );
    let e = merge_error(&|_, l| {
        let first = l["all"][0].clone();
        l["all"].as_array_mut().unwrap().push(first);
    });
    assert!(e.contains("clip \"march\" is listed twice"), "{e}");
    for name in ["../../../../outside/evil", "/tmp/evil", "a/./b", ""] {
        let e = merge_error(&|_, l| l["all"][0][0] = name.into());
        assert!(
            e.contains(&format!(
                "clip name \"{name}\" is not a relative path inside the output folder"
            )),
            "{name}: {e}"
        );
    }
    // a clip recorded ok whose output is gone, or is not an .npz
    let (march, squat) = (out.join("march.npz"), out.join("squat.npz"));
    let (march_bytes, squat_bytes) = (
        std::fs::read(&march).unwrap(),
        std::fs::read(&squat).unwrap(),
    );
    std::fs::remove_file(&march).unwrap();
    std::fs::write(&squat, b"garbage").unwrap();
    let (ok, _, stderr) = run_musculo(&[std::ffi::OsStr::new("merge"), out.as_os_str()]);
    assert!(!ok, "merged clips without their outputs: {stderr}");
    assert!(
        stderr.contains("2 clip(s) recorded ok have a missing or unreadable output")
            && stderr.contains("march (")
            && stderr.contains("squat (")
            && stderr.contains("not an .npz (zip) archive"),
        "{stderr}"
    );
    assert!(
        !out.join("manifest.json").exists(),
        "a manifest was written"
    );
    std::fs::write(&march, &march_bytes).unwrap();
    std::fs::write(&squat, &squat_bytes).unwrap();
    let manifest = runner::merge(&out).unwrap();
    assert_eq!(
        (manifest.summary.clips_ok, manifest.summary.clips_failed),
        (3, 0)
    );
    // augment refuses such names from a library caller before writing anything
    let mut outside = clips.clone();
    outside[0].name = "../evil".to_string();
    let e = runner::run(
        &chain,
        &layout,
        &outside,
        &options(&out.join("inner")),
        &|_| {},
    )
    .expect_err("ran a clip named outside its folder")
    .to_string();
    assert!(e.contains("clip name \"../evil\""), "{e}");
    assert!(!out.join("evil.npz").exists());
    let _ = std::fs::remove_dir_all(out);
}

/// Shards of one run write into one folder at once, and each begins by tidying what
/// interrupted runs left: it must remove only temporaries of its own files whose writer has
/// ended — never another shard's file in the middle of being written (the failure was a
/// rename of a vanished temporary in the other shard).
#[test]
fn a_run_removes_only_its_own_abandoned_temporaries() {
    let dir = temp_dir("tidy");
    let records = output::RECORDS;
    std::fs::create_dir_all(dir.join(records)).unwrap();
    // a process that has ended, and one that is still running
    let mut ended = std::process::Command::new("true").spawn().unwrap();
    let ended_pid = ended.id();
    ended.wait().unwrap();
    let mut live = std::process::Command::new("sleep")
        .arg("60")
        .spawn()
        .unwrap();
    // writers on this host, in this PID namespace (whose processes can be looked up)
    let (ended_pid, live_pid) = (
        musculo::io::output::writer_token(ended_pid),
        musculo::io::output::writer_token(live.id()),
    );
    let me = musculo::io::output::writer_token(std::process::id());
    let files = [
        (format!(".walk.npz.tmp-{ended_pid}-0"), false),
        (format!("{records}/.walk.json.tmp-{ended_pid}-1"), false),
        (format!(".walk_ik.mot.tmp-{ended_pid}-2"), false),
        // a shard of the same run still writing this file
        (format!(".walk.npz.tmp-{live_pid}-0"), true),
        // this very process writing it
        (format!(".walk.npz.tmp-{me}-9"), true),
        // a writer named by a bare process id (no host): it cannot be probed, and its
        // lease is fresh
        (format!(".walk.osim.tmp-{}-5", ended.id()), true),
        // a commit journal killed while being written (its clip's files are still
        // temporaries): removed, whichever shard owns the clip
        (
            format!("..musculo-commit-{ended_pid}-6.tmp-{ended_pid}-7"),
            false,
        ),
        // another shard's clip (whatever its writer)
        (format!(".walk_fast.npz.tmp-{ended_pid}-3"), true),
        (format!("{records}/.walk_fast.json.tmp-{ended_pid}-4"), true),
        // not a temporary
        ("walk.npz".to_string(), true),
    ];
    for (f, _) in &files {
        std::fs::write(dir.join(f), b"x").unwrap();
    }
    let own = output::clip_files("walk", &musculo::augment::chain::OPENSIM_SUFFIXES);
    let removed = output::remove_temporaries(&dir, |f| own.iter().any(|o| o == f)).unwrap();
    let _ = live.kill();
    let _ = live.wait();
    for (f, kept) in &files {
        assert_eq!(dir.join(f).exists(), *kept, "{f}");
    }
    assert_eq!(removed, 4);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn kill_minus_9_then_resume_gives_the_bytes_of_an_uninterrupted_run() {
    let exe = env!("CARGO_BIN_EXE_musculo");
    let whole = temp_dir("whole");
    let cut = temp_dir("cut");
    let args = |dir: &Path| {
        vec![
            "augment".to_string(),
            "--demo".into(),
            "--variants".into(),
            "3".into(),
            "--out".into(),
            dir.display().to_string(),
        ]
    };
    let status = std::process::Command::new(exe)
        .args(args(&whole))
        .stderr(std::process::Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    // kill at several points of the run, resuming each time
    let mut kills = 0;
    for delay_ms in [30u64, 90, 150, 220, 300, 400] {
        let mut a = args(&cut);
        a.push("--resume".into());
        let mut child = std::process::Command::new(exe)
            .args(&a)
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap(); // SIGKILL
            kills += 1;
        }
        child.wait().unwrap();
    }
    let mut a = args(&cut);
    a.push("--resume".into());
    let status = std::process::Command::new(exe)
        .args(&a)
        .stderr(std::process::Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    println!("killed {kills} run(s) mid-way");
    let (w, c) = (bytes_of(&whole), bytes_of(&cut));
    assert!(
        w.iter().map(|f| &f.0).eq(c.iter().map(|f| &f.0)),
        "same files (no partial file left): {:?} vs {:?}",
        w.iter().map(|f| &f.0).collect::<Vec<_>>(),
        c.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    assert!(w == c, "identical bytes after kill -9 and --resume");
    for d in [whole, cut] {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn a_failing_clip_is_recorded_and_the_run_goes_on() {
    let dir = temp_dir("inputs");
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    // a valid clip (the demo walk as a HumanML3D joints array) and a broken one
    let chain = chain();
    let (_, walk) = demo::clips(&chain.model).unwrap().remove(0);
    let values: Vec<f32> = walk
        .positions
        .iter()
        .flat_map(|p| [p.x as f32, p.y as f32, p.z as f32])
        .collect();
    let array = ndarray::ArrayD::from_shape_vec(vec![walk.n_frames(), 22, 3], values).unwrap();
    motion::npy::write_npy(&dir.join("sub/good.npy"), array.view()).unwrap();
    std::fs::write(dir.join("sub/broken.npy"), b"\x93NUMPY not really").unwrap();
    let exe = env!("CARGO_BIN_EXE_musculo");
    let out = temp_dir("failing-out");
    let result = std::process::Command::new(exe)
        .args(["augment", "--input"])
        .arg(&dir)
        .args(["--format", "humanml3d", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert!(
        !result.status.success(),
        "a failed clip makes the exit status non-zero"
    );
    assert!(stderr.contains("broken"), "{stderr}");
    let manifest: output::Manifest =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    let by_name: HashMap<_, _> = manifest
        .clips
        .iter()
        .map(|c| (c.clip.as_str(), c))
        .collect();
    assert_eq!(by_name["sub/good"].status, ClipStatus::Ok);
    assert_eq!(by_name["sub/broken"].status, ClipStatus::Failed);
    assert!(
        by_name["sub/broken"]
            .reason
            .as_ref()
            .unwrap()
            .contains("broken.npy")
    );
    assert!(
        out.join("sub/good.npz").exists(),
        "the tree mirrors the input tree"
    );
    // without --resume, an existing run is not overwritten
    let again = std::process::Command::new(exe)
        .args(["augment", "--input"])
        .arg(&dir)
        .args(["--format", "humanml3d", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("--resume"));
    // sharded: each shard exits as its clips went, and so does the merge, which writes the
    // same manifest as the one run and names the failed clip with its reason
    let sharded = temp_dir("failing-sharded");
    for k in 0..2 {
        let shard = std::process::Command::new(exe)
            .args(["augment", "--input"])
            .arg(&dir)
            .args([
                "--format",
                "humanml3d",
                "--shard",
                &format!("{k}/2"),
                "--out",
            ])
            .arg(&sharded)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&shard.stderr);
        assert_eq!(
            shard.status.success(),
            !text.contains("failed: sub/broken"),
            "{text}"
        );
    }
    let merged = std::process::Command::new(exe)
        .arg("merge")
        .arg(&sharded)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&merged.stderr);
    assert!(
        !merged.status.success(),
        "merge exits non-zero when a clip failed: {text}"
    );
    assert!(
        text.contains("failed: sub/broken (") && text.contains("broken.npy"),
        "{text}"
    );
    assert!(
        text.contains("merged: 1 of 2 clip(s) computed, 1 failed"),
        "{text}"
    );
    assert_eq!(
        std::fs::read(sharded.join("manifest.json")).unwrap(),
        std::fs::read(out.join("manifest.json")).unwrap(),
        "the merged manifest is the one run's"
    );
    for d in [dir, out, sharded] {
        let _ = std::fs::remove_dir_all(d);
    }
}

/// Marker data matched by name to a model that has none of those markers (a gait lab's
/// .trc on the default model) fails with a message naming both sides and the way out,
/// rather than IK's "no marker or coordinate task".
#[test]
fn markers_the_model_lacks_are_named() {
    let chain = chain();
    let names: Vec<String> = ["R.ASIS", "L.ASIS", "V.Sacral"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let positions = (0..10 * names.len())
        .map(|i| Vec3::new(0.1 * i as f64, 1.0, 0.0))
        .collect();
    let motion = Motion::uniform("walk.trc", names, 60.0, positions).unwrap();
    let Err(e) = chain.run(&motion, None, &Variant::identity()) else {
        panic!("a clip without any of the model's markers ran");
    };
    let message = e.to_string();
    for said in [
        "walk.trc: none of its 3 markers (R.ASIS, L.ASIS, V.Sacral)",
        "the model `musculo_fullbody`",
        "--model",
        "--map",
    ] {
        assert!(message.contains(said), "{said}: {message}");
    }
}

/// Measured-load options that cannot apply: a missing ExternalLoads file or a belt speed that
/// is not a speed stops the run before it makes its output folder; `--force-plates` on a clip that is not a C3D file
/// estimates its ground reactions and says so (on stderr and in the clip's warnings).
#[test]
fn measured_loads_that_cannot_apply_are_reported() {
    let dir = temp_dir("loads-inputs");
    std::fs::create_dir_all(&dir).unwrap();
    write_demo_as_joints(&chain(), 2, &dir.join("reach.npy"));
    let out = temp_dir("loads-out");
    let run = |args: &[&str]| augment_cli(&[dir.join("reach.npy")], &out, args);
    let missing = dir.join("no_such_loads.xml");
    let (ok, stderr) = run(&["--external-loads", missing.to_str().unwrap()]);
    assert!(!ok && stderr.contains("no_such_loads.xml"), "{stderr}");
    assert!(
        !out.exists(),
        "no output folder for a run that cannot start"
    );
    // a belt speed that is no speed stops the run before its output folder, naming the flag
    for speed in ["--treadmill=-1", "--treadmill=inf", "--treadmill=NaN"] {
        let (ok, stderr) = run(&[speed]);
        assert!(!ok && stderr.contains("`--treadmill`"), "{speed}: {stderr}");
        assert!(!out.exists(), "{speed}");
    }
    let (ok, stderr) = run(&["--force-plates"]);
    assert!(ok, "{stderr}");
    let said = "--force-plates: only C3D files carry force plates";
    assert!(
        stderr
            .lines()
            .any(|l| l.starts_with("warning: ") && l.contains(said)),
        "{stderr}"
    );
    let manifest: output::Manifest =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    assert!(manifest.clips[0].warnings.iter().any(|w| w.contains(said)));
    for d in [dir, out] {
        let _ = std::fs::remove_dir_all(d);
    }
}

/// `musculo augment` with `args` (HumanML3D joints input, output folder `out`): whether it
/// succeeded, and its stderr.
fn augment_cli(input: &[PathBuf], out: &Path, args: &[&str]) -> (bool, String) {
    let result = std::process::Command::new(env!("CARGO_BIN_EXE_musculo"))
        .args(["augment", "--format", "humanml3d", "--out"])
        .arg(out)
        .args(args)
        .arg("--input")
        .args(input)
        .output()
        .unwrap();
    (
        result.status.success(),
        String::from_utf8_lossy(&result.stderr).into_owned(),
    )
}

/// Demo clip `index` (march, squat, reach) written as a HumanML3D joints array.
fn write_demo_as_joints(chain: &Chain, index: usize, path: &Path) {
    let (_, clip) = demo::clips(&chain.model).unwrap().remove(index);
    let values: Vec<f32> = clip
        .positions
        .iter()
        .flat_map(|p| [p.x as f32, p.y as f32, p.z as f32])
        .collect();
    let array = ndarray::ArrayD::from_shape_vec(vec![clip.n_frames(), 22, 3], values).unwrap();
    motion::npy::write_npy(path, array.view()).unwrap();
}

/// A folder remembers the settings of the run that started it: `--resume` (or any later run
/// there) with other settings is refused before anything is computed, naming what differs,
/// so that a dataset never mixes two cutoffs or two models; more variants are accepted (a
/// variant depends on the seed, the clip and its index only).
#[test]
fn a_run_with_other_settings_is_refused_in_a_folder() {
    let dir = temp_dir("settings-inputs");
    std::fs::create_dir_all(&dir).unwrap();
    let chain = chain();
    write_demo_as_joints(&chain, 2, &dir.join("reach.npy"));
    write_demo_as_joints(&chain, 1, &dir.join("squat.npy"));
    let exe = env!("CARGO_BIN_EXE_musculo");
    let out = temp_dir("settings-out");
    let augment = |args: &[&str], inputs: &[&str]| {
        let inputs: Vec<PathBuf> = inputs.iter().map(|i| dir.join(i)).collect();
        augment_cli(&inputs, &out, args)
    };
    let (ok, stderr) = augment(&[], &["reach.npy"]);
    assert!(ok, "{stderr}");
    let settings: output::RunSettings =
        serde_json::from_str(&std::fs::read_to_string(out.join(output::SETTINGS)).unwrap())
            .unwrap();
    assert_eq!(settings.run.lowpass_hz, Some(6.0));
    let reach = std::fs::read(out.join("reach.npz")).unwrap();
    // another cutoff, seed and contact setting, and a new clip: refused, nothing written
    let (ok, stderr) = augment(
        &["--resume", "--lowpass", "4", "--seed", "3", "--treadmill"],
        &["reach.npy", "squat.npy"],
    );
    assert!(!ok, "{stderr}");
    for said in [
        "holds results of a run with other settings",
        "--lowpass: 6 Hz then → 4 Hz now",
        "--seed: 0 then → 3 now",
        "--treadmill",
    ] {
        assert!(stderr.contains(said), "{said}: {stderr}");
    }
    assert!(!out.join("squat.npz").exists());
    let (ok, stderr) = augment(&["--resume", "--opensim-files"], &["reach.npy"]);
    assert!(
        !ok && stderr.contains("--opensim-files (or --report, which implies it): false then"),
        "{stderr}"
    );
    // without --resume too (no clip of this run finished there yet)
    let (ok, stderr) = augment(&["--muscle-strength", "2"], &["squat.npy"]);
    assert!(
        !ok && stderr.contains("--muscle-strength: 1 then → 2 now"),
        "{stderr}"
    );
    // the same settings with a new clip and a second variant: accepted, the first clip kept
    let (ok, stderr) = augment(
        &["--resume", "--variants", "2"],
        &["reach.npy", "squat.npy"],
    );
    assert!(ok, "{stderr}");
    assert_eq!(std::fs::read(out.join("reach.npz")).unwrap(), reach);
    for f in ["squat.npz", "reach_v1.npz", "squat_v1.npz"] {
        assert!(out.join(f).exists(), "{f}");
    }
    // two shards started at the same moment with different settings both find no settings
    // in the folder (simulated by removing them in between): the merge refuses them
    let _ = std::fs::remove_dir_all(&out);
    let (ok, stderr) = augment(&["--shard", "0/2"], &["reach.npy", "squat.npy"]);
    assert!(ok, "{stderr}");
    std::fs::remove_file(out.join(output::SETTINGS)).unwrap();
    let (ok, stderr) = augment(
        &["--shard", "1/2", "--treadmill"],
        &["reach.npy", "squat.npy"],
    );
    assert!(ok, "{stderr}");
    let merged = std::process::Command::new(exe)
        .arg("merge")
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&merged.stderr);
    assert!(
        !merged.status.success() && stderr.contains("belongs to another run"),
        "{stderr}"
    );
    for d in [dir, out] {
        let _ = std::fs::remove_dir_all(d);
    }
}

/// A cutoff above 0.4 of a clip's sampling rate (where the filter rings) is lowered to that,
/// and the run says so: on stderr and in the clip's warnings in the manifest. At the default
/// 6 Hz the same clip has no warning.
#[test]
fn a_cutoff_above_the_clips_rate_is_reported() {
    let dir = temp_dir("cutoff-inputs");
    std::fs::create_dir_all(&dir).unwrap();
    // read back as HumanML3D joints: 20 fps, that format's rate
    write_demo_as_joints(&chain(), 2, &dir.join("reach.npy"));
    for (lowpass, expected) in [("20", true), ("6", false)] {
        let out = temp_dir(&format!("cutoff-out-{lowpass}"));
        let (ok, stderr) = augment_cli(&[dir.join("reach.npy")], &out, &["--lowpass", lowpass]);
        assert!(ok, "{stderr}");
        let manifest: output::Manifest =
            serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap())
                .unwrap();
        let warnings = &manifest.clips[0].warnings;
        let said = "the low-pass cutoff 20 Hz is above 0.4 of the clip's sampling rate (20 Hz), \
                    where the filter rings: its coordinates were filtered at 8 Hz";
        assert_eq!(
            warnings.iter().any(|w| w.contains(said)),
            expected,
            "--lowpass {lowpass}: {warnings:?}"
        );
        assert_eq!(
            stderr
                .lines()
                .any(|l| l.starts_with("warning: ") && l.contains(said)),
            expected,
            "--lowpass {lowpass}: {stderr}"
        );
        let _ = std::fs::remove_dir_all(out);
    }
    let _ = std::fs::remove_dir_all(dir);
}

/// A clip whose `.npz` cannot be put in place (a folder holds its name) fails the run with
/// that path in the error, on the writer threads as it did on the workers; the other clips
/// are still written, with their records, so `--resume` finishes the run once the obstacle
/// is gone.
#[test]
fn a_write_that_fails_on_the_writer_threads_fails_the_run() {
    let chain = chain();
    let layout = describe(&chain).unwrap();
    let inputs = demo_inputs(&chain);
    assert!(inputs.len() >= 2);
    let out = temp_dir("write-fails");
    let blocked = out.join(format!("{}.npz", inputs[0].name));
    std::fs::create_dir_all(blocked.join("occupied")).unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let result = pool.install(|| runner::run(&chain, &layout, &inputs, &options(&out), &|_| {}));
    let error = result
        .expect_err("the blocked clip fails the run")
        .to_string();
    assert!(error.contains(&inputs[0].name), "{error}");
    for input in &inputs[1..] {
        assert!(
            out.join(format!("{}.npz", input.name)).is_file(),
            "{}",
            input.name
        );
        assert!(
            output::record_path(&out, &input.name).is_file(),
            "{}",
            input.name
        );
    }
    assert!(!output::record_path(&out, &inputs[0].name).exists());
    // the obstacle removed, --resume computes the blocked clip only
    std::fs::remove_dir_all(&blocked).unwrap();
    let resumed = pool
        .install(|| {
            runner::run(
                &chain,
                &layout,
                &inputs,
                &RunOptions {
                    resume: true,
                    ..options(&out)
                },
                &|_| {},
            )
        })
        .unwrap();
    assert_eq!((resumed.computed, resumed.resumed), (1, inputs.len() - 1));
    let _ = std::fs::remove_dir_all(&out);
}

/// The dataset clips in ../shared/reference end to end, each checked from its file.
/// The reference clips at `rels` (path, format, BVH unit), or None when one is missing.
fn reference_clips(
    rels: &[(&str, Format, Option<&str>)],
) -> Option<Vec<(PathBuf, Motion, SkeletonMap)>> {
    let mut out = Vec::new();
    for &(rel, format, unit) in rels {
        let path = reference_file(rel)?;
        let read = ReadOptions {
            length_unit: unit.map(|u| motion::LengthUnit::parse(u).unwrap()),
        };
        let clip: Motion = motion::read(&path, Some(format), &read).unwrap();
        let map = SkeletonMap::builtin(format.default_map().unwrap()).unwrap();
        out.push((path, clip, map));
    }
    Some(out)
}

/// Runs `chain` on a clip and checks its arrays from the written `.npz` ([`check_clip`], on the
/// clip's model) in a scratch folder named by `test`; returns the quality figures and the
/// worst frame's relative residual.
fn run_and_check(
    test: &str,
    chain: &Chain,
    clip: &Motion,
    map: &SkeletonMap,
) -> (ClipQuality, f64) {
    let out = chain.run(clip, Some(map), &Variant::identity()).unwrap();
    let dir = temp_dir(test);
    output::write_clip(&dir, "clip", &out.arrays).unwrap();
    let model = chain
        .clip_model(clip, Some(map), &Variant::identity())
        .unwrap();
    let worst = check_clip(&model, &output::npz_path(&dir, "clip"));
    let _ = std::fs::remove_dir_all(dir);
    (out.quality, worst)
}

#[test]
fn reference_clips_end_to_end() {
    let Some(clips) = reference_clips(&[
        ("humanml3d/new_joints_012314.npy", Format::HumanMl3d, None),
        ("bvh/131_01.bvh", Format::Bvh, Some("0.056444")),
        ("bvh/cmu_01_01.bvh", Format::Bvh, Some("0.056444")),
    ]) else {
        return;
    };
    let chain = chain();
    for (path, clip, map) in clips {
        let (q, worst) = run_and_check("reference", &chain, &clip, &map);
        println!(
            "{}: {} frames, IK RMSE median {:.1} mm, EL identity {worst:.2e}, reserves {:.2} % \
             of joint moments, unexplained force ≤ {:.3} BW, {} clamped excitation(s)",
            path.display(),
            q.frames,
            q.ik_rmse_median * 1e3,
            100.0 * q.reserve_share,
            q.residual_force_max_bw,
            q.clamped_excitations
        );
        assert!(worst <= 1e-6, "{}: {worst:e}", path.display());
    }
}

/// `--muscle-strength 2` (every muscle's maximum isometric force doubled): on the dataset
/// clips with the largest demands on the default model's muscles (HumanML3D 012314: a jump
/// with the arms swung overhead, 13.0 % of the joint moments on the reserves; CMU 131_01: deep
/// squats and kneeling, 4.7 %) the reserves fall to less than half (measured 5.36 / 1.13 %),
/// the arrays still satisfy the equations of motion on the strengthened model, and the
/// manifest's run says so (factor, and the model hash of the strengthened text). The command's
/// hint at clips over 5 % shows at × 1 and goes at × 3 (HumanML3D 012314: 3.36 %).
#[test]
fn strengthened_muscles_carry_the_dataset_clips() {
    let Some(clips) = reference_clips(&[
        ("humanml3d/new_joints_012314.npy", Format::HumanMl3d, None),
        ("bvh/131_01.bvh", Format::Bvh, Some("0.056444")),
    ]) else {
        return;
    };
    let strong = Chain::default_model(ChainOptions {
        muscle_strength: 2.0,
        ..ChainOptions::default()
    })
    .unwrap();
    let plain = chain();
    let (a, b) = (
        runner::run_description(&plain, &options(Path::new("unused"))),
        runner::run_description(&strong, &options(Path::new("unused"))),
    );
    assert_eq!((a.muscle_strength, b.muscle_strength), (1.0, 2.0));
    assert_ne!(a.model_hash, b.model_hash);
    for (path, clip, map) in clips {
        let (q, worst) = run_and_check("strong", &strong, &clip, &map);
        let (q1, _) = run_and_check("plain", &plain, &clip, &map);
        println!(
            "{}, muscles × 2: reserves {:.2} % of joint moments (× 1: {:.2} %), EL identity \
             {worst:.2e}",
            path.display(),
            100.0 * q.reserve_share,
            100.0 * q1.reserve_share
        );
        assert!(worst <= 1e-6, "{}: {worst:e}", path.display());
        assert!(
            q.reserve_share < 0.5 * q1.reserve_share,
            "{}: {} against {}",
            path.display(),
            q.reserve_share,
            q1.reserve_share
        );
    }
    // The command says when clips leave more than 5 % to the reserves, and not once they don't;
    // the manifest records the factor.
    let sample = reference_file("humanml3d/new_joints_012314.npy").unwrap();
    for (k, hint) in [("1", true), ("3", false)] {
        let out = temp_dir(&format!("strength-cli-{k}"));
        let (ok, _, stderr) = run_musculo(&[
            "augment".as_ref(),
            "--input".as_ref(),
            sample.as_os_str(),
            "--muscle-strength".as_ref(),
            k.as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
        ]);
        assert!(ok, "{stderr}");
        let said = stderr.contains("1 of 1 clip(s) leave more than 5 % of the joint moments");
        assert_eq!(said, hint, "× {k}: {stderr}");
        let manifest: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
        assert_eq!(
            manifest["run"]["muscle_strength"],
            k.parse::<f64>().unwrap()
        );
        let _ = std::fs::remove_dir_all(out);
    }
    let bad = Chain::default_model(ChainOptions {
        muscle_strength: 0.0,
        ..ChainOptions::default()
    })
    .unwrap_err();
    assert!(bad.to_string().contains("muscle_strength"), "{bad}");
}

/// OpenSim's gait2392 walk (markers, subject01 model, measured ground reactions): with the
/// force plates the chain balances the walk with reserves under 5 % of the joint moments; the
/// estimate from kinematics alone (treadmill: belt speed estimated) is compared with them.
#[test]
fn gait2392_walk_with_measured_and_estimated_ground_reactions() {
    let dir = "opensim-models/Pipelines/Gait2392_Simbody";
    let (Some(model_path), Some(trc), Some(loads)) = (
        reference_file(&format!("{dir}/OutputReference/subject01_simbody.osim")),
        reference_file(&format!("{dir}/subject01_walk1.trc")),
        reference_file(&format!("{dir}/subject01_walk1_grf.xml")),
    ) else {
        return;
    };
    let xml = std::fs::read_to_string(&model_path).unwrap();
    let measured_chain = Chain::new(
        xml.clone(),
        model_path.display().to_string(),
        ChainOptions::default(),
    )
    .unwrap();
    let mut options = ChainOptions::default();
    options.contact.floor_velocity = None; // a treadmill
    let estimated_chain = Chain::new(xml, model_path.display().to_string(), options).unwrap();
    let clip = motion::read(&trc, None, &ReadOptions::default()).unwrap();
    let v = Variant::identity();
    let measured = measured_chain
        .run_with_loads(
            &clip,
            None,
            &v,
            Some(&MeasuredLoads::ExternalLoads(loads.clone())),
        )
        .unwrap();
    let estimated = estimated_chain.run(&clip, None, &v).unwrap();
    let dir = temp_dir("gait2392");
    output::write_clip(&dir, "measured", &measured.arrays).unwrap();
    output::write_clip(&dir, "estimated", &estimated.arrays).unwrap();
    let model = measured_chain.clip_model(&clip, None, &v).unwrap();
    let worst_measured = check_clip(&model, &output::npz_path(&dir, "measured"));
    let worst_estimated = check_clip(&model, &output::npz_path(&dir, "estimated"));
    let (qm, qe) = (&measured.quality, &estimated.quality);
    // vertical force per foot, estimate vs plates, over the trial
    let grf = |name: &str| read_npz(&output::npz_path(&dir, name))["grf"].1.clone();
    let (gm, ge) = (grf("measured"), grf("estimated"));
    let weight = qm.body_mass * 9.80665;
    let vertical: Vec<f64> = gm
        .chunks(3)
        .zip(ge.chunks(3))
        .map(|(a, b)| (a[1] - b[1]).powi(2))
        .collect();
    let rmse = (vertical.iter().sum::<f64>() / vertical.len() as f64).sqrt() / weight;
    println!(
        "gait2392 walk, {} frames: measured loads — EL identity {worst_measured:.1e}, reserves \
         {:.2} % (largest {:?}); estimated — EL identity {worst_estimated:.1e}, reserves {:.2} %, \
         vertical force per foot vs the plates RMSE {:.2} % BW",
        qm.frames,
        100.0 * qm.reserve_share,
        qm.reserve_by_coordinate.first(),
        100.0 * qe.reserve_share,
        100.0 * rmse
    );
    assert!(worst_measured <= 1e-6 && worst_estimated <= 1e-6);
    assert!(qm.reserve_share < 0.05, "{}", qm.reserve_share);
    assert!(qe.reserve_share < 0.05, "{}", qe.reserve_share);
    // the chain's own IK (all markers weighted equally) and filtering: looser than the
    // contact test on the stored IK (3.5 % BW), and still near the literature's 5.3 %
    assert!(rmse < 0.07, "{rmse}");
    // perturbed variants are refused with measured loads
    let mut variant = Variant::identity();
    variant.mass_scale = 1.1;
    assert!(
        measured_chain
            .run_with_loads(
                &clip,
                None,
                &variant,
                Some(&MeasuredLoads::ExternalLoads(loads.clone()))
            )
            .is_err()
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn ik_marker_error_names_each_marker_and_shows_a_displaced_one() {
    // the gait2392 walk's markers through the chain (muscles off: IK is what is looked at);
    // one marker's target moved 5 cm forward on frames 40–59 must show there, in its own
    // column, and hardly in the others'
    let dir = "opensim-models/Pipelines/Gait2392_Simbody";
    let (Some(model_path), Some(trc)) = (
        reference_file(&format!("{dir}/OutputReference/subject01_simbody.osim")),
        reference_file(&format!("{dir}/subject01_walk1.trc")),
    ) else {
        return;
    };
    let xml = std::fs::read_to_string(&model_path).unwrap();
    let options = ChainOptions {
        muscles: false,
        ..ChainOptions::default()
    };
    let chain = Chain::new(xml, model_path.display().to_string(), options).unwrap();
    let clip = motion::read(&trc, None, &ReadOptions::default()).unwrap();
    let v = Variant::identity();
    let errors = |clip: &Motion| {
        let out = chain.run(clip, None, &v).unwrap();
        let a = out
            .arrays
            .iter()
            .find(|a| a.name == "ik_marker_error")
            .unwrap();
        (
            out.quality.ik_markers.clone(),
            a.shape.clone(),
            a.values.clone(),
            out.quality.ik_rmse_by_marker.clone(),
        )
    };
    let (names, shape, plain, rmse) = errors(&clip);
    let k = names.len();
    assert_eq!(shape, [clip.time.len(), k]);
    // the manifest's per-marker RMSE is the RMS of the array's column
    assert_eq!(rmse.len(), k);
    for (i, r) in rmse.iter().enumerate() {
        let column: Vec<f64> = (plain.iter().skip(i).step_by(k))
            .map(|&e| e as f64)
            .filter(|e| e.is_finite())
            .collect();
        let rms = (column.iter().map(|e| e * e).sum::<f64>() / column.len() as f64).sqrt();
        assert!(
            (r.unwrap() - rms).abs() < 1e-6,
            "{}: {r:?} vs {rms}",
            names[i]
        );
    }
    assert!(k >= 30, "{k} markers");
    // the names are the model's markers that the file has, as IK pairs them
    for name in &names {
        assert!(clip.names.contains(name), "{name}");
    }
    let moved = 3; // the fourth IK marker
    let column = clip.names.iter().position(|n| *n == names[moved]).unwrap();
    let mut displaced = clip.clone();
    for f in 40..60 {
        displaced.positions[f * clip.names.len() + column].x += 0.05;
    }
    let (_, _, shifted, shifted_rmse) = errors(&displaced);
    assert!(
        shifted_rmse[moved].unwrap() > rmse[moved].unwrap() + 0.001,
        "{shifted_rmse:?} vs {rmse:?}"
    );
    let at = |e: &[f32], f: usize, i: usize| e[f * k + i] as f64;
    let mut own = f64::INFINITY;
    let mut others = 0.0f64;
    for f in 40..60 {
        own = own.min(at(&shifted, f, moved) - at(&plain, f, moved));
        for i in (0..k).filter(|&i| i != moved) {
            others = others.max((at(&shifted, f, i) - at(&plain, f, i)).abs());
        }
    }
    let mut away = 0.0f64;
    for f in (0..35).chain(65..clip.time.len()) {
        for i in 0..k {
            away = away.max((at(&shifted, f, i) - at(&plain, f, i)).abs());
        }
    }
    println!(
        "{} ({k} IK markers) moved 50 mm on frames 40–59: its error rose by ≥ {:.1} mm, the \
         others' changed ≤ {:.1} mm, frames away from it ≤ {:.2e} mm",
        names[moved],
        1e3 * own,
        1e3 * others,
        1e3 * away
    );
    // IK absorbs part of the displacement by moving the segment (all markers weigh
    // alike): the displaced marker keeps the larger part, and stands out from the others
    assert!(own > 0.020 && own > 2.0 * others, "{own} vs {others}");
    assert!(away < 1e-4, "{away}");
}

/// The C3D trials (OpenSim's walking2/walking5) through the chain with the c3d_lower_body map,
/// with their force plates as measured loads and with the contact estimate: reserves under
/// 5 % of the joint moments either way, and a walking posture. Gait studies put the hip at
/// about 30° of flexion at heel strike and 10–20° of extension late in stance (Perry &
/// Burnfield, Gait Analysis, 2010), the pelvis within a few degrees of its standing tilt;
/// the pelvis landmarks (ASIS, PSIS) fix that tilt, which the hip centres leave free
/// (placed without them, the pelvis sat at 18.8° and the hips at −30 … +15°).
#[test]
fn c3d_trials_end_to_end_with_force_plates_and_estimated_contacts() {
    let chain = chain();
    let map = SkeletonMap::builtin("c3d_lower_body").unwrap();
    for trial in ["walking2", "walking5"] {
        let Some(path) = reference_file(&format!("c3d/{trial}.c3d")) else {
            return;
        };
        let clip = motion::read(&path, Some(Format::C3d), &ReadOptions::default()).unwrap();
        let v = Variant::identity();
        let plates = MeasuredLoads::ForcePlates(path.clone());
        let measured = chain
            .run_with_loads(&clip, Some(&map), &v, Some(&plates))
            .unwrap();
        let estimated = chain.run(&clip, Some(&map), &v).unwrap();
        let dir = temp_dir(trial);
        output::write_clip(&dir, "measured", &measured.arrays).unwrap();
        output::write_clip(&dir, "estimated", &estimated.arrays).unwrap();
        let model = chain.clip_model(&clip, Some(&map), &v).unwrap();
        let wm = check_clip(&model, &output::npz_path(&dir, "measured"));
        let we = check_clip(&model, &output::npz_path(&dir, "estimated"));
        let (qm, qe) = (&measured.quality, &estimated.quality);
        println!(
            "{trial}: {} frames kept ({:?}), IK RMSE median {:.1} mm; plates — EL identity \
             {wm:.1e}, reserves {:.2} %, unexplained force ≤ {:.2} BW (steps off the two \
             plates); estimated — EL identity {we:.1e}, reserves {:.2} %",
            qm.frames,
            measured.warnings.first(),
            qm.ik_rmse_median * 1e3,
            100.0 * qm.reserve_share,
            qm.residual_force_max_bw,
            100.0 * qe.reserve_share
        );
        assert!(wm <= 1e-6 && we <= 1e-6);
        assert!(qm.reserve_share < 0.05, "{}", qm.reserve_share);
        assert!(qe.reserve_share < 0.05, "{}", qe.reserve_share);
        let q = &read_npz(&output::npz_path(&dir, "estimated"))["q"];
        let nq = model.nq();
        let degrees = |name: &str| -> Vec<f64> {
            let j = musculo::solve::ik::independent_index(&model, name).unwrap();
            q.1.chunks(nq).map(|f| f[j].to_degrees()).collect()
        };
        let mut tilt = degrees("pelvis_tilt");
        tilt.sort_by(f64::total_cmp);
        let median_tilt = tilt[tilt.len() / 2];
        println!("{trial}: pelvis tilt median {median_tilt:.1}° (the trial walks along ±x)");
        assert!(median_tilt.abs() <= 8.0, "{median_tilt}");
        for side in ["r", "l"] {
            let hip = degrees(&format!("hip_flexion_{side}"));
            let (lo, hi) = hip
                .iter()
                .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
            println!("{trial}: hip_flexion_{side} {lo:.0}° … {hi:.0}°");
            assert!((20.0..=40.0).contains(&hi) && lo >= -26.0, "{lo} … {hi}");
        }
        // the plates carry load: the measured vertical force reaches body weight
        let grf = &read_npz(&output::npz_path(&dir, "measured"))["grf"].1;
        let peak = grf.chunks(3).map(|f| f[1]).fold(0.0f64, f64::max);
        assert!(peak > 0.8 * qm.body_mass * 9.80665, "{peak}");
        let _ = std::fs::remove_dir_all(dir);
    }
}

/// `musculo loss` on the demo clips: the tensors `augment` writes satisfy the equations of
/// motion, r = M q̈ + C q̇ + G − τ − J_cᵀλ ≈ 0 to 1e-6 of |τ_ID| on every frame, while the same
/// file with one τ entry moved by 5 N·m shows a loss of 25 on that frame alone.
#[test]
fn augmented_tensors_have_a_zero_euler_lagrange_residual() {
    use musculo::loss::tensor_file::{TensorFrames, residual_of};
    let out = temp_dir("loss");
    let (ok, _, err) = run_musculo(&[
        "augment".to_string(),
        "--demo".into(),
        "--out".into(),
        out.display().to_string(),
    ]);
    assert!(ok, "{err}");
    let model = musculo::Model::default_fullbody();
    for clip in ["squat", "march", "reach"] {
        let path = out.join(format!("{clip}.npz"));
        let (ok, stdout, err) = run_musculo(&[
            "loss".to_string(),
            path.display().to_string(),
            "--json".into(),
        ]);
        assert!(ok, "{err}");
        let report: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        let worst = report["relative_residual"]["max"].as_f64().unwrap();
        eprintln!("{clip}: max |r|/|tau_ID| = {worst:.2e}");
        assert!(worst < 1e-6, "{clip}: {worst:.2e}");
        assert_eq!(report["contacts"], 8);

        // the muscle loss: reported, and with every activation set to 0 it is Σ q̈² exactly
        let muscle = &report["muscle"];
        assert!(muscle["loss"].as_f64().unwrap() > 0.0, "{report}");
        assert_eq!(muscle["activations_out_of_bounds"], 0);
        let mut frames = TensorFrames::read(&path, &model).unwrap();
        frames.muscle_act.fill(0.0);
        let m = musculo::loss::tensor_file::muscle_residual_of(&model, &frames)
            .unwrap()
            .unwrap();
        let sum: f64 = frames.qdd.iter().map(|v| v * v).sum();
        assert!((m.loss - sum).abs() <= 1e-12 * sum, "{} vs {sum}", m.loss);
        let n = model.nq();
        frames.tau[7 * n + 10] += 5.0;
        let s = residual_of(&model, &frames).unwrap();
        let l7 = s.frame_norm[7] * s.frame_norm[7];
        assert!((l7 - 25.0).abs() < 1e-3, "{clip}: frame 7 loss {l7}");
        assert!(s.frame_norm[6] < 1e-3 && s.frame_norm[8] < 1e-3);
    }
    // a file without the arrays is an error naming it
    let (ok, _, err) = run_musculo(&[
        "loss".to_string(),
        out.join("stats.npz").display().to_string(),
    ]);
    assert!(
        !ok && err.contains("stats.npz") && err.contains("`q`"),
        "{err}"
    );
}

/// The layout maps back to the coordinates of a dataset clip too, on the clip's scaled model.
/// HumanML3D 012314 swings both arms overhead through the shoulder's gimbal lock, where other
/// angles give the same rotations: there the inverse's continuation from frame to frame may
/// take another set than augment's (which stays nearest IK's own angles). Every coordinate
/// outside the shoulders comes back to 1e-5, and the recovered angles give the layout's
/// rotations everywhere.
#[test]
fn the_joint_layout_maps_back_through_the_shoulders_gimbal_lock() {
    use musculo::augment::layout::JointLayout;
    use musculo::augment::layout_inverse::{LayoutClip, coordinates_from_layout};
    use musculo::motion::npy::read_npz_as_f64;
    let Some(sample) = reference_file("humanml3d/new_joints_012314.npy") else {
        return;
    };
    let out = temp_dir("layout-inverse-hml");
    let (ok, _, err) = run_musculo(&[
        "augment".to_string(),
        "--input".into(),
        sample.display().to_string(),
        "--opensim-files".into(),
        "--out".into(),
        out.display().to_string(),
    ]);
    assert!(ok, "{err}");
    let model = musculo::Model::from_osim_file(out.join("new_joints_012314.osim")).unwrap();
    let n = model.nq();
    let muscles = musculo::muscle::MuscleSet::new(&model).unwrap().len();
    let layout = JointLayout::new(&model, muscles);
    let arrays = read_npz_as_f64(&out.join("new_joints_012314.npz")).unwrap();
    let get = |name: &str| -> Vec<f64> {
        (arrays.iter().find(|(k, _)| k == name).unwrap().1.iter())
            .copied()
            .collect()
    };
    let (pos, rot, vel, acc, torque) = (
        get("joint_pos"),
        get("joint_rot"),
        get("joint_vel"),
        get("joint_acc"),
        get("joint_torque"),
    );
    let frames = get("time").len();
    let c = coordinates_from_layout(
        &model,
        &layout,
        &LayoutClip {
            frames,
            rate_hz: 20.0,
            joint_pos: &pos,
            joint_rot: &rot,
            joint_vel: &vel,
            joint_acc: &acc,
            joint_torque: &torque,
        },
    )
    .unwrap();
    let q = get("q");
    let names = model.q_names();
    let shoulder = |j: usize| names[j].starts_with("arm_") && !names[j].starts_with("arm_elev");
    let mut worst = (0.0f64, 0, 0);
    let mut other_angles = std::collections::BTreeSet::new();
    for (i, (a, b)) in c.q.iter().zip(&q).enumerate() {
        let (f, j) = (i / n, i % n);
        if shoulder(j) {
            if (a - b).abs() > 1e-5 {
                other_angles.insert(f);
            }
        } else if (a - b).abs() > worst.0 {
            worst = ((a - b).abs(), f, j);
        }
    }
    let rot_err = c.rotation_error.iter().fold(0.0f64, |m, v| m.max(*v));
    eprintln!(
        "HumanML3D 012314: q outside the shoulders off by at most {:.1e} ({} at frame {}); \
         other shoulder angles for the same rotations at frames {other_angles:?}; rotation \
         error {rot_err:.1e} rad",
        worst.0, names[worst.2], worst.1
    );
    assert!(rot_err < 1e-5, "{rot_err}");
    assert!(
        worst.0 < 1e-5,
        "q off by {} at frame {}, {}",
        worst.0,
        worst.1,
        names[worst.2]
    );
    // the other angles are the lock's: frames of the arms' swing overhead (12 of 170 at
    // commit ddb136e), none elsewhere in the clip
    assert!(
        other_angles.iter().all(|f| (10..=35).contains(f)),
        "{other_angles:?}"
    );
}

/// The per-joint layout `augment` writes maps back to its coordinates
/// (`augment::layout_inverse`): q and the rotational rates to the float32 rounding of the
/// stored blocks, the root translation rates to the accuracy of central differences at the
/// clip's rate, τ on the angular coordinates exactly, and the fit leaves no rotation error.
#[test]
fn the_joint_layout_maps_back_to_the_coordinates() {
    use musculo::augment::layout::JointLayout;
    use musculo::augment::layout_inverse::{LayoutClip, coordinates_from_layout};
    use musculo::motion::npy::read_npz_as_f64;
    let out = temp_dir("layout-inverse");
    let (ok, _, err) = run_musculo(&[
        "augment".to_string(),
        "--demo".into(),
        "--out".into(),
        out.display().to_string(),
    ]);
    assert!(ok, "{err}");
    let model = musculo::Model::default_fullbody();
    let n = model.nq();
    let muscles = musculo::muscle::MuscleSet::new(&model).unwrap().len();
    let layout = JointLayout::new(&model, muscles);
    let translational: Vec<bool> = model
        .reduction
        .independent
        .iter()
        .map(|&c| model.coordinates[c].motion_type == musculo::model::MotionType::Translational)
        .collect();
    let angular: Vec<usize> = layout.angular_coordinates().collect();
    for clip in ["squat", "march", "reach"] {
        let arrays = read_npz_as_f64(&out.join(format!("{clip}.npz"))).unwrap();
        let get = |name: &str| -> Vec<f64> {
            arrays
                .iter()
                .find(|(k, _)| k == name)
                .unwrap_or_else(|| panic!("{clip}: no {name}"))
                .1
                .iter()
                .copied()
                .collect()
        };
        let time = get("time");
        let frames = time.len();
        let rate = (frames - 1) as f64 / (time[frames - 1] - time[0]);
        let (pos, rot, vel, acc, torque) = (
            get("joint_pos"),
            get("joint_rot"),
            get("joint_vel"),
            get("joint_acc"),
            get("joint_torque"),
        );
        let c = coordinates_from_layout(
            &model,
            &layout,
            &LayoutClip {
                frames,
                rate_hz: rate,
                joint_pos: &pos,
                joint_rot: &rot,
                joint_vel: &vel,
                joint_acc: &acc,
                joint_torque: &torque,
            },
        )
        .unwrap();
        let (q, qd, qdd, tau) = (get("q"), get("qd"), get("qdd"), get("tau"));
        let worst = |ours: &[f64], theirs: &[f64], pick: &dyn Fn(usize) -> bool| {
            let mut err = 0.0f64;
            let mut scale = 0.0f64;
            for (i, (a, b)) in ours.iter().zip(theirs).enumerate() {
                if pick(i % n) {
                    err = err.max((a - b).abs());
                    scale = scale.max(b.abs());
                }
            }
            (err, scale)
        };
        let rotational = |j: usize| !translational[j];
        let (eq, _) = worst(&c.q, &q, &|_| true);
        let (eqd, sqd) = worst(&c.qd, &qd, &rotational);
        let (eqdd, sqdd) = worst(&c.qdd, &qdd, &rotational);
        let (eqd_t, sqd_t) = worst(&c.qd, &qd, &|j| translational[j]);
        let (eqdd_t, sqdd_t) = worst(&c.qdd, &qdd, &|j| translational[j]);
        let (etau, stau) = worst(&c.tau, &tau, &|j| angular.contains(&j));
        let rot_err = c.rotation_error.iter().fold(0.0f64, |m, v| m.max(*v));
        eprintln!(
            "{clip}: q {eq:.1e}; rotational q̇ {eqd:.1e} of {sqd:.2}, q̈ {eqdd:.1e} of {sqdd:.2}; \
             translational q̇ {eqd_t:.1e} of {sqd_t:.2}, q̈ {eqdd_t:.1e} of {sqdd_t:.2}; \
             τ_K {etau:.1e} of {stau:.1}; rotation error {rot_err:.1e} rad"
        );
        assert!(eq < 1e-5, "{clip}: q off by {eq}");
        // `musculo loss` on the layout alone fits the same coordinates: its muscle loss equals
        // the full file's (the root's translation rates, from differences, enter only the
        // pelvis rows)
        if clip == "squat" {
            let keep = [
                "joint_pos",
                "joint_rot",
                "joint_vel",
                "joint_acc",
                "joint_torque",
                "muscle_act",
                "time",
            ];
            let views: Vec<(&str, ndarray::ArrayViewD<'_, f64>)> = arrays
                .iter()
                .filter(|(k, _)| keep.contains(&k.as_str()))
                .map(|(k, a)| (k.as_str(), a.view()))
                .collect();
            let layout_file = out.join("squat_layout.npz");
            musculo::motion::npy::write_npz(&layout_file, &views, false).unwrap();
            let report = |path: &std::path::Path| -> serde_json::Value {
                let (ok, stdout, err) = run_musculo(&[
                    "loss".to_string(),
                    path.display().to_string(),
                    "--json".into(),
                ]);
                assert!(ok, "{err}");
                serde_json::from_str(&stdout).unwrap()
            };
            let (full, layout_only) = (report(&out.join("squat.npz")), report(&layout_file));
            assert!(full["from_layout"].is_null());
            let fit = layout_only["from_layout"]["rotation_error"]
                .as_f64()
                .unwrap();
            assert!(fit < 1e-6, "{fit}");
            let (a, b) = (
                full["muscle"]["loss"].as_f64().unwrap(),
                layout_only["muscle"]["loss"].as_f64().unwrap(),
            );
            eprintln!("squat: L_muscle {a:.6e} from q, {b:.6e} from the layout alone");
            // the fitted q differ from the stored ones by ~5e-8 rad, enough to flip a wrap's
            // discrete choice (an ellipsoid's plane, a contact point's side) at a few poses,
            // where the moment arms jump
            assert!((a - b).abs() <= 1e-2 * a, "{a} vs {b}");
            // with the layout's contact forces (at the joint centres, the best couple on each
            // foot: loss::layout) the residual is what the layout cannot carry — the root's
            // translational generalized forces, which augment leaves in τ and the layout has
            // no place for, and the root's accelerations by differences
            let mut with_forces = views.clone();
            let force = arrays.iter().find(|(k, _)| k == "contact_force").unwrap();
            with_forces.push(("contact_force", force.1.view()));
            let forces_file = out.join("squat_layout_forces.npz");
            musculo::motion::npy::write_npz(&forces_file, &with_forces, false).unwrap();
            let forces = report(&forces_file);
            let median = |r: &serde_json::Value| r["relative_residual"]["median"].as_f64().unwrap();
            let rms = |r: &serde_json::Value, name: &str| {
                r["coordinates"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .find(|c| c["name"] == name)
                    .unwrap()["rms"]
                    .as_f64()
                    .unwrap()
            };
            eprintln!(
                "squat: median ‖r‖/‖τ_ID‖ {:.2e} from q, {:.2e} from the layout with its contact \
                 forces, {:.2e} without them; pelvis_ty residual RMS {:.1} / {:.1} N, \
                 pelvis_tilt {:.2} / {:.1} N·m",
                median(&full),
                median(&forces),
                median(&layout_only),
                rms(&forces, "pelvis_ty"),
                rms(&layout_only, "pelvis_ty"),
                rms(&forces, "pelvis_tilt"),
                rms(&layout_only, "pelvis_tilt"),
            );
            assert!(median(&forces) < 1e-3, "{}", median(&forces));
            assert!(median(&layout_only) > 0.5, "{}", median(&layout_only));
            assert!(
                rms(&forces, "pelvis_ty") < 2.0,
                "{}",
                rms(&forces, "pelvis_ty")
            );
        }
        assert!(
            eqd < 1e-5 * sqd.max(1.0) && eqdd < 1e-4 * sqdd.max(1.0),
            "{clip}"
        );
        assert!(etau < 1e-5 * stau.max(1.0), "{clip}: τ_K off by {etau}");
        assert!(rot_err < 1e-5, "{clip}: {rot_err}");
        // differences of the root centre at 30 Hz
        assert!(
            eqd_t < 5e-3 + 0.01 * sqd_t,
            "{clip}: translational q̇ off by {eqd_t}"
        );
    }
}

/// A clip whose results leave float32's range fails with a reason naming the array, instead
/// of writing infinities as an ok clip (a model of 10³⁰⁰ kg wrote a record it could not read
/// back, and every `--resume` then failed on it; muscles × 10³⁰⁰ wrote 55,035 infinite
/// forces, a factor now refused). A clip IK cannot follow (the demo walk turned upside down) is augmented
/// with a warning that says so, naming the worst frame and marker.
#[test]
fn out_of_range_results_fail_the_clip_and_a_fit_that_fails_is_reported() {
    // every body 10³⁰⁰ times heavier (as `model scale --mass 1e300` made it)
    let mut heavy = String::new();
    let mut rest = musculo::DEFAULT_MODEL_OSIM;
    while let Some(i) = rest.find("<mass>") {
        let j = i + rest[i..].find("</mass>").unwrap();
        let mass: f64 = rest[i + 6..j].trim().parse().unwrap();
        heavy.push_str(&rest[..i + 6]);
        heavy.push_str(&format!("{:e}", mass * 1e300));
        rest = &rest[j..];
    }
    heavy.push_str(rest);
    let huge = Chain::new(heavy, "heavy.osim".into(), ChainOptions::default()).unwrap();
    let (_, walk) = demo::clips(&huge.model).unwrap().remove(0);
    let e = huge.run(&walk, None, &Variant::identity()).unwrap_err();
    assert!(
        e.to_string().contains("holds") && e.to_string().contains("beyond float32's range"),
        "{e}"
    );
    let plain = chain();
    let ok = plain.run(&walk, None, &Variant::identity()).unwrap();
    assert!(
        !ok.warnings
            .iter()
            .any(|w| w.contains("IK could not follow")),
        "{:?}",
        ok.warnings
    );
    let mut flipped = walk.clone();
    for p in &mut flipped.positions {
        p.y = 2.0 - p.y;
    }
    let out = plain.run(&flipped, None, &Variant::identity()).unwrap();
    let warning = out
        .warnings
        .iter()
        .find(|w| w.contains("IK could not follow"))
        .unwrap_or_else(|| panic!("no warning: {:?}", out.warnings));
    assert!(
        out.quality.ik_error_max > musculo::augment::chain::IK_ERROR_WARNED
            && warning.contains("worst error")
            && warning.contains("frame "),
        "{warning}"
    );
}

/// Output names are checked over the whole dataset before anything is written: variant 1 of
/// clip `a` and a clip named `a_v1` would write the same files (the manifest listed `a_v1`
/// twice, and which clip's arrays survived depended on the threads), and a clip named `stats`
/// was overwritten by the dataset statistics' `stats.npz`.
#[test]
fn output_names_that_collide_are_refused_before_anything_is_written() {
    let chain = chain();
    let layout = describe(&chain).unwrap();
    let base = demo_inputs(&chain);
    let named = |names: &[&str]| -> Vec<ClipInput> {
        names
            .iter()
            .zip(base.iter().cycle())
            .map(|(n, c)| ClipInput {
                name: n.to_string(),
                input: format!("{n}.npy"),
                ..c.clone()
            })
            .collect()
    };
    let cases: [(&[&str], usize, &str); 3] = [
        (
            &["a", "a_v1"],
            2,
            "variant 1 of a.npy and a_v1.npy would both be written as a_v1.npz",
        ),
        (
            &["stats", "walk"],
            1,
            "stats.npy would be written as stats.npz",
        ),
        (&["data", "stats_v1"], 1, ""),
    ];
    for (names, variants, expected) in cases {
        let out = temp_dir("collide");
        let mut options = options(&out);
        options.variants = variants;
        let result = runner::run(&chain, &layout, &named(names), &options, &|_| {});
        if expected.is_empty() {
            // not a collision: `stats_v1` is not the statistics' name
            assert!(result.is_ok(), "{names:?}: {:?}", result.err());
        } else {
            let e = result.unwrap_err().to_string();
            assert!(e.contains(expected), "{names:?}: {e}");
            assert!(!out.exists(), "{names:?}: the output folder was made");
        }
        let _ = std::fs::remove_dir_all(out);
    }
}

/// Measured loads stand in for the contact estimate, so they must cover the clip: the
/// HumanML3D sample (8.45 s) with gait2392's plates (0–2.5 s) fails naming both spans
/// (extrapolated, the vertical force reached −17 kN at the end, under exit status 0).
#[test]
fn measured_loads_that_do_not_cover_the_clip_are_refused() {
    let (Some(clip), Some(loads)) = (
        reference_file("humanml3d/new_joints_012314.npy"),
        reference_file("opensim-models/Pipelines/Gait2392_Simbody/subject01_walk1_grf.xml"),
    ) else {
        return;
    };
    let out = temp_dir("loads-span");
    let (ok, _, stderr) = run_musculo(&[
        "augment".as_ref(),
        "--input".as_ref(),
        clip.as_os_str(),
        "--external-loads".as_ref(),
        loads.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(!ok, "{stderr}");
    assert!(
        stderr.contains("the measured loads span 0 s to 2.5 s")
            && stderr.contains("the loads must cover the clip"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(out);
}

#[test]
fn a_weightless_model_is_refused_before_any_clip_and_a_non_finite_record_is_not_written() {
    // Before: a model with zero gravity made every clip's record hold null (NaN ÷ body
    // weight), and every later `--resume` and `merge` failed with "not a clip record".
    let xml = musculo::DEFAULT_MODEL_OSIM.replace(
        "<gravity>0 -9.8066499999999994 0</gravity>",
        "<gravity>0 0 0</gravity>",
    );
    assert_ne!(xml, musculo::DEFAULT_MODEL_OSIM);
    let Err(e) = Chain::new(xml, "weightless.osim".into(), ChainOptions::default()) else {
        panic!("a weightless model was accepted");
    };
    let text = e.to_string();
    assert!(
        text.contains("weightless.osim") && text.contains("has no weight"),
        "{text}"
    );

    let out = temp_dir("non-finite-record");
    let record = output::ClipRecord {
        clip: "c".into(),
        input: "c.npy".into(),
        status: ClipStatus::Ok,
        reason: None,
        variant: Variant::identity(),
        quality: None,
        warnings: Vec::new(),
        x_sum: vec![1.0, f64::NAN],
        x_sum_sq: vec![1.0, 1.0],
        split: None,
    };
    let e = output::write_record(&out, &record).unwrap_err().to_string();
    assert!(e.contains("not finite") && e.contains("c:"), "{e}");
    assert_eq!(output::read_record(&out, "c").unwrap(), None);
    // a finite record is written and reads back
    let finite = output::ClipRecord {
        x_sum: vec![1.0, 2.0],
        ..record
    };
    output::write_record(&out, &finite).unwrap();
    assert_eq!(output::read_record(&out, "c").unwrap(), Some(finite));
    std::fs::remove_dir_all(&out).ok();
}
