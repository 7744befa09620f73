//! The verdict per clip (`augment::verdict`) end to end: a marker file whose markers are all
//! moved, each by its own amount of up to 0.1 m, is suspect, by up to 2 m failed (moved alike,
//! no marker disagrees with the rest for robust IK to single out), and `--fail-on` turns that
//! into the exit status; the demo and its sharded
//! merge print the verdict counts of how many clips; the contact consistency agrees with the
//! one recomputed from the `.npz` arrays.

mod common;

use common::{reference_file, run_musculo};
use musculo::augment::output::Manifest;
use musculo::augment::verdict::Verdict;
use std::path::{Path, PathBuf};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("musculo-verdict-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn manifest(out: &Path) -> Manifest {
    serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap()
}

/// `trc` with `shift_mm` added to the X coordinate of its `marker`-th marker (0-based) in
/// every data row.
fn shift_marker(trc: &str, marker: usize, shift_mm: f64) -> String {
    let mut out = String::with_capacity(trc.len() + 1024);
    for line in trc.lines() {
        let mut fields: Vec<String> = line.split('\t').map(str::to_string).collect();
        let data = fields
            .first()
            .is_some_and(|f| f.trim().parse::<u64>().is_ok())
            && fields
                .get(1)
                .is_some_and(|t| t.trim().parse::<f64>().is_ok());
        let column = 2 + 3 * marker;
        if data
            && let Some(x) = fields
                .get(column)
                .and_then(|v| v.trim().parse::<f64>().ok())
        {
            fields[column] = format!("{:.6}", x + shift_mm);
        }
        out.push_str(&fields.join("\t"));
        out.push('\n');
    }
    out
}

/// `trc` with every marker's X coordinate moved by its own constant amount, spread evenly
/// over [−amplitude, amplitude] (mm) in marker order shuffled by a fixed stride.
fn shift_all(trc: &str, markers: usize, amplitude_mm: f64) -> String {
    let mut text = trc.to_string();
    for k in 0..markers {
        let rank = (k * 7) % markers;
        let shift = amplitude_mm * (2.0 * rank as f64 / (markers - 1) as f64 - 1.0);
        text = shift_marker(&text, k, shift);
    }
    text
}

#[test]
fn markers_moved_apart_are_suspect_moved_far_failed_and_fail_on_says_so() {
    let dir = "opensim-models/Pipelines/Gait2392_Simbody";
    let (Some(model), Some(trc)) = (
        reference_file(&format!("{dir}/OutputReference/subject01_simbody.osim")),
        reference_file(&format!("{dir}/subject01_walk1.trc")),
    ) else {
        return;
    };
    let work = temp_dir("moved");
    std::fs::create_dir_all(&work).unwrap();
    let text = std::fs::read_to_string(&trc).unwrap();
    // every marker moved by up to 100 mm, each by its own amount
    let markers = text
        .lines()
        .nth(2)
        .and_then(|l| l.split('\t').nth(3))
        .and_then(|n| n.trim().parse::<usize>().ok())
        .unwrap();
    let moved = work.join("subject01_walk1.trc");
    std::fs::write(&moved, shift_all(&text, markers, 100.0)).unwrap();
    let run = |input: &Path, out: &Path, extra: &[&str]| {
        let mut args: Vec<&std::ffi::OsStr> = vec![
            "augment".as_ref(),
            "--model".as_ref(),
            model.as_os_str(),
            "--input".as_ref(),
            input.as_os_str(),
            "--no-scale".as_ref(),
            "--treadmill".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
        ];
        args.extend(extra.iter().map(|a| std::ffi::OsStr::new(*a)));
        run_musculo(&args)
    };
    // IK cannot fit them (median RMSE beyond OpenSim's 2 cm): suspect at least, and
    // --fail-on suspect exits non-zero
    let out = work.join("moved-out");
    let (ok, _, stderr) = run(&moved, &out, &["--fail-on", "suspect"]);
    assert!(!ok, "--fail-on suspect exits non-zero: {stderr}");
    let m = manifest(&out);
    let q = m.clips[0].quality.as_ref().unwrap();
    let v = q.verdict.as_ref().unwrap();
    println!(
        "markers moved by up to 0.1 m: IK RMSE median {:.1} mm, worst {:.0} mm; verdict {} ({:?})",
        q.ik_rmse_median * 1e3,
        q.ik_error_max * 1e3,
        v.verdict.name(),
        v.reason
    );
    assert!(v.verdict >= Verdict::Suspect, "{v:?}");
    assert!(
        v.crossed.iter().any(|c| c.starts_with("IK RMSE median")),
        "{v:?}"
    );
    let line = format!(
        "verdicts of 1 clip(s): 0 ok, {} suspect, {} failed",
        m.summary.verdicts.suspect, m.summary.verdicts.failed
    );
    assert!(stderr.contains(&line), "{stderr}");
    assert_eq!(m.summary.verdicts.clips, 1);
    // without --fail-on the clip was computed: exit 0 (resumed from its record)
    let (ok, _, stderr) = run(&moved, &out, &["--resume"]);
    assert!(ok, "{stderr}");
    assert!(stderr.contains(&line), "{stderr}");
    // up to 0.6 m (the markers still span a body, as the reader requires): the worst error
    // passes 0.3 m: failed
    std::fs::write(&moved, shift_all(&text, markers, 600.0)).unwrap();
    let out = work.join("moved-2m-out");
    let (ok, _, stderr) = run(&moved, &out, &["--fail-on", "failed"]);
    assert!(
        !ok,
        "--fail-on failed exits non-zero on a failed clip: {stderr}"
    );
    assert!(
        stderr.contains("verdicts of 1 clip(s): 0 ok, 0 suspect, 1 failed"),
        "{stderr}"
    );
    assert!(
        stderr.contains("failed: subject01_walk1: IK worst error"),
        "{stderr}"
    );
    let m = manifest(&out);
    assert!(m.clips[0].quality.as_ref().unwrap().ik_error_max > 0.3);
    assert_eq!(m.summary.verdicts.failed_clips[0].0, "subject01_walk1");
    // the recorded markers: IK within 0.3 m, so not failed by IK
    let out = work.join("recorded-out");
    let (ok, _, stderr) = run(&trc, &out, &["--fail-on", "failed"]);
    let m = manifest(&out);
    let q = m.clips[0].quality.as_ref().unwrap();
    let v = q.verdict.as_ref().unwrap();
    println!(
        "recorded walk: IK worst {:.0} mm; verdict {} ({:?})",
        q.ik_error_max * 1e3,
        v.verdict.name(),
        v.reason
    );
    assert!(q.ik_error_max < 0.1, "{}", q.ik_error_max);
    assert_eq!(ok, v.verdict != Verdict::Failed, "{stderr}");
    let _ = std::fs::remove_dir_all(work);
}

#[test]
fn the_demo_and_its_merged_shards_print_verdict_counts_of_how_many_clips() {
    let out = temp_dir("demo");
    let (ok, _, stderr) = run_musculo(&[
        "augment".as_ref(),
        "--demo".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(ok, "{stderr}");
    let m = manifest(&out);
    let v = &m.summary.verdicts;
    assert_eq!(v.clips, 3);
    assert_eq!(v.ok + v.suspect + v.failed, 3);
    let line = format!(
        "verdicts of 3 clip(s): {} ok, {} suspect, {} failed",
        v.ok, v.suspect, v.failed
    );
    assert!(stderr.contains(&line), "{stderr}");
    assert!(
        stderr.contains("3 of 3 clip(s) computed, 0 failed"),
        "{stderr}"
    );
    // the demo clips are made on the model: the contacts explain their support exactly
    for c in &m.clips {
        let q = c.quality.as_ref().unwrap();
        let consistency = q.contact_consistency.unwrap();
        assert!(
            (consistency - 1.0).abs() < 1e-6,
            "{}: {consistency}",
            c.clip
        );
        assert!(q.residual_force_max_bw < 1e-6, "{}", c.clip);
        assert!(
            q.muscle_samples_at_full_activation <= q.muscle_samples
                && q.muscle_samples == q.frames * 324,
            "{}: {} of {}",
            c.clip,
            q.muscle_samples_at_full_activation,
            q.muscle_samples
        );
    }
    // sharded, the merge carries the verdicts into the same manifest
    let sharded = temp_dir("demo-sharded");
    for k in ["0/2", "1/2"] {
        let (_, _, stderr) = run_musculo(&[
            "augment".as_ref(),
            "--demo".as_ref(),
            "--shard".as_ref(),
            k.as_ref(),
            "--out".as_ref(),
            sharded.as_os_str(),
        ]);
        assert!(stderr.contains("verdicts of"), "{stderr}");
    }
    let (ok, _, stderr) = run_musculo(&["merge".as_ref(), sharded.as_os_str()]);
    assert!(ok, "{stderr}");
    assert!(stderr.contains(&line), "{stderr}");
    assert_eq!(manifest(&sharded).summary, m.summary);
    for d in [out, sharded] {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn contact_consistency_agrees_with_the_arrays_under_measured_loads() {
    // With measured loads D_t (the vertical force the motion needs, from inverse dynamics'
    // root-joint force) splits into the plates' vertical force and the residual on
    // pelvis_ty — gait2392's pelvis translations run along ground's axes — so
    // Σ min(G⁺, D⁺) / Σ D⁺ recomputed from `grf` and `residual` must match the manifest.
    let dir = "opensim-models/Pipelines/Gait2392_Simbody";
    let (Some(model), Some(trc), Some(loads)) = (
        reference_file(&format!("{dir}/OutputReference/subject01_simbody.osim")),
        reference_file(&format!("{dir}/subject01_walk1.trc")),
        reference_file(&format!("{dir}/subject01_walk1_grf.xml")),
    ) else {
        return;
    };
    let out = temp_dir("measured");
    let (_, _, stderr) = run_musculo(&[
        "augment".as_ref(),
        "--model".as_ref(),
        model.as_os_str(),
        "--input".as_ref(),
        trc.as_os_str(),
        "--no-scale".as_ref(),
        "--external-loads".as_ref(),
        loads.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    let m = manifest(&out);
    let layout = m.layout.as_ref().unwrap();
    let q = m.clips[0].quality.as_ref().expect(&stderr);
    let ty = layout
        .floating_base
        .iter()
        .position(|n| n == "pelvis_ty")
        .unwrap();
    let arrays = musculo::motion::npy::read_npz_as_f64(&out.join("subject01_walk1.npz")).unwrap();
    let get = |name: &str| arrays.iter().find(|(k, _)| k == name).unwrap().1.clone();
    let (grf, residual) = (get("grf"), get("residual"));
    let (frames, groups, rows) = (grf.shape()[0], grf.shape()[1], residual.shape()[1]);
    let (mut demand, mut carried) = (0.0, 0.0);
    for f in 0..frames {
        let g: f64 = (0..groups).map(|k| grf[[f, k, 1]]).sum();
        let d = g + residual[[f, ty]];
        demand += d.max(0.0);
        carried += g.max(0.0).min(d.max(0.0));
    }
    assert_eq!(rows, 6);
    let from_arrays = carried / demand;
    let recorded = q.contact_consistency.unwrap();
    println!("contact consistency {recorded:.6} (manifest), {from_arrays:.6} (arrays)");
    assert!(
        (from_arrays - recorded).abs() < 1e-4,
        "{from_arrays} vs {recorded}"
    );
    // the residual force is what the plates leave: of the order of OpenSim's ID residuals
    assert!(q.residual_force_max_bw > 0.0 && q.residual_force_rms_bw > 0.0);
    let _ = std::fs::remove_dir_all(out);
}
