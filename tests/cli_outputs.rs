//! What the `musculo` commands write: every command's outputs appear together or not at all
//! (a failed write, a refused path or a `kill -9` leaves no final-named partial file, and a
//! rerun gives the uninterrupted run's bytes), no output overwrites an input, `-o dir/` names
//! a folder, missing folders are created, and names from setup files stay in their folder.
//! Every input is generated here (or is the shipped models/demo.osim and
//! models/musculo_fullbody.osim).

mod common;
use common::*;
use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const DEMO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/models/demo.osim");
const FULLBODY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/models/musculo_fullbody.osim");

fn demo() -> &'static Path {
    Path::new(DEMO)
}

/// Every file below `dir` (relative path → bytes), hidden ones included.
fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(root: &Path, d: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
        let Ok(rd) = std::fs::read_dir(d) else { return };
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                let rel = p.strip_prefix(root).unwrap().to_string_lossy().into_owned();
                out.insert(rel, std::fs::read(&p).unwrap_or_default());
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

fn names(dir: &Path) -> Vec<String> {
    tree(dir).into_keys().collect()
}

/// A motion over the model's independent coordinates: each swings through a third of its
/// range about the middle, at its own frequency (radians and metres).
fn generated_motion(model_path: &Path, frames: usize, path: &Path) {
    let model = musculo::Model::from_osim_file(model_path).unwrap();
    let labels: Vec<String> = model.q_names().iter().map(|s| s.to_string()).collect();
    let time: Vec<f64> = (0..frames).map(|i| i as f64 * 0.01).collect();
    let mut values = Vec::with_capacity(frames * labels.len());
    for &t in &time {
        for (j, &c) in model.reduction.independent.iter().enumerate() {
            let [lo, hi] = model.coordinates[c].range;
            let (mid, half) = (0.5 * (lo + hi), 0.5 * (hi - lo).min(2.0));
            let w = 2.0 * std::f64::consts::PI * (0.5 + 0.1 * j as f64);
            values.push(mid + half / 3.0 * (w * t + j as f64).sin());
        }
    }
    let mut table = musculo::io::Table::new("generated", labels, time, values).unwrap();
    table.in_degrees = Some(false);
    table.write(path).unwrap();
}

/// A force set with an unbounded CoordinateActuator on every independent coordinate.
fn reserves_for(model_path: &Path, path: &Path) {
    let model = musculo::Model::from_osim_file(model_path).unwrap();
    let mut xml = String::from(
        "<?xml version=\"1.0\"?>\n<OpenSimDocument Version=\"40000\"><ForceSet name=\"r\"><objects>\n",
    );
    for c in model.q_names() {
        xml += &format!(
            "<CoordinateActuator name=\"reserve_{c}\"><coordinate>{c}</coordinate>\
             <optimal_force>100</optimal_force><min_control>-inf</min_control>\
             <max_control>inf</max_control></CoordinateActuator>\n"
        );
    }
    xml += "</objects></ForceSet></OpenSimDocument>\n";
    std::fs::write(path, xml).unwrap();
}

fn args(pattern: &str, paths: &[&Path]) -> Vec<OsString> {
    let mut paths = paths.iter();
    pattern
        .split_whitespace()
        .map(|a| match a {
            "{}" => paths.next().unwrap().as_os_str().to_owned(),
            _ => a.into(),
        })
        .collect()
}

fn run(args: &[OsString]) -> (bool, String) {
    let (ok, _, err) = run_musculo(args);
    (ok, err)
}

/// True when a root-owned process ignores the permission bits (writes to a read-only folder
/// succeed).
fn permissions_are_enforced(dir: &Path) -> bool {
    let ro = dir.join("probe-ro");
    std::fs::create_dir_all(&ro).unwrap();
    set_read_only(&ro, true);
    let enforced = std::fs::write(ro.join("x"), "x").is_err();
    set_read_only(&ro, false);
    let _ = std::fs::remove_dir_all(&ro);
    enforced
}

fn set_read_only(dir: &Path, read_only: bool) {
    let mut p = std::fs::metadata(dir).unwrap().permissions();
    #[allow(clippy::permissions_set_readonly_false)]
    p.set_readonly(read_only);
    std::fs::set_permissions(dir, p).unwrap();
}

#[test]
fn model_scale_refuses_to_overwrite_its_input_however_it_is_spelled() {
    let d = ScratchDir::new("outputs-scale-input");
    let model = d.join("leg.osim");
    std::fs::copy(demo(), &model).unwrap();
    let before = std::fs::read(&model).unwrap();
    let dot = d.0.join(".").join("leg.osim");
    let folder = d.0.join("sub").join("..").join("leg.osim");
    std::fs::create_dir_all(d.join("sub")).unwrap();
    for output in [&model, &dot, &folder] {
        let (ok, err) = run(&args(
            "model scale {} --mass 30 --height 1.8 --model-height 1.7 -o {}",
            &[&model, output],
        ));
        assert!(!ok);
        assert!(
            err.contains("cannot write output") && err.contains("it is an input"),
            "{err}"
        );
    }
    assert_eq!(
        std::fs::read(&model).unwrap(),
        before,
        "the input is intact"
    );
    assert_eq!(names(&d.0), vec!["leg.osim"]);
}

#[test]
fn model_scale_into_a_folder_creates_it_and_keeps_the_input_name() {
    let d = ScratchDir::new("outputs-scale-folder");
    let out = d.join("scaled/adults/");
    let mut out_text = out.into_os_string();
    out_text.push("/");
    let (ok, err) = run(&args(
        "model scale {} --mass 30 --height 1.8 --model-height 1.7 -o {}",
        &[demo(), Path::new(&out_text)],
    ));
    assert!(ok, "{err}");
    assert_eq!(names(&d.0), vec!["scaled/adults/demo.osim"]);
    let scaled = musculo::Model::from_osim_file(d.join("scaled/adults/demo.osim")).unwrap();
    assert!((scaled.total_mass() - 30.0).abs() < 1e-9);
}

#[test]
fn a_destination_that_is_a_folder_is_refused_and_nothing_is_written() {
    let d = ScratchDir::new("outputs-is-folder");
    let target = d.join("scaled.osim");
    std::fs::create_dir_all(&target).unwrap();
    let (ok, err) = run(&args(
        "model scale {} --mass 30 --height 1.8 --model-height 1.7 -o {}",
        &[demo(), &target],
    ));
    assert!(!ok);
    assert!(err.contains("scaled.osim: is an existing folder"), "{err}");
    let (ok, err) = run(&args("export-mjcf --demo -o {}", &[&target]));
    assert!(!ok);
    assert!(err.contains("is an existing folder"), "{err}");
    assert!(names(&d.0).is_empty(), "{:?}", names(&d.0));
}

#[test]
fn a_destination_that_is_a_pipe_is_refused_and_a_link_is_written_through() {
    use std::os::unix::fs::FileTypeExt;
    let d = ScratchDir::new("outputs-special");
    // A named pipe (a device such as /dev/null behaves alike): the rename of a new file onto
    // it would replace it, and as root `-o /dev/null` would delete the device.
    let pipe = d.join("pipe.xml");
    let made = Command::new("mkfifo").arg(&pipe).status();
    if made.map(|s| s.success()).unwrap_or(false) {
        let (ok, err) = run(&args("export-mjcf --demo -o {}", &[&pipe]));
        assert!(!ok);
        assert!(
            err.contains("pipe.xml: is a device, named pipe or socket"),
            "{err}"
        );
        let meta = std::fs::symlink_metadata(&pipe).unwrap();
        assert!(
            meta.file_type().is_fifo(),
            "the pipe was replaced: {meta:?}"
        );
        let (ok, err) = run(&args(
            "model scale {} --mass 30 --height 1.8 --model-height 1.7 -o {}",
            &[demo(), &pipe],
        ));
        assert!(!ok);
        assert!(err.contains("named pipe"), "{err}");
        assert!(
            std::fs::symlink_metadata(&pipe)
                .unwrap()
                .file_type()
                .is_fifo()
        );
    } else {
        eprintln!("skipped the named pipe: mkfifo is not available");
    }
    // A symbolic link to a file: the file is replaced, the link kept.
    let real = d.join("real.xml");
    std::fs::write(&real, b"old").unwrap();
    let link = d.join("link.xml");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let (ok, err) = run(&args("export-mjcf --demo -o {}", &[&link]));
    assert!(ok, "{err}");
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    let written = std::fs::read_to_string(&real).unwrap();
    assert!(
        written.contains("<mujoco"),
        "{}",
        &written[..written.len().min(200)]
    );
    // A link to nothing is refused, and stays a link.
    let dangling = d.join("dangling.xml");
    std::os::unix::fs::symlink(d.join("missing/nothing.xml"), &dangling).unwrap();
    let (ok, err) = run(&args("export-mjcf --demo -o {}", &[&dangling]));
    assert!(!ok);
    assert!(
        err.contains("symbolic link to a file that cannot be reached"),
        "{err}"
    );
    assert!(
        std::fs::symlink_metadata(&dangling)
            .unwrap()
            .file_type()
            .is_symlink()
    );
}

#[test]
fn a_write_into_a_read_only_folder_fails_and_leaves_no_file() {
    let d = ScratchDir::new("outputs-read-only");
    if !permissions_are_enforced(&d.0) {
        eprintln!("skipped: running as a user that ignores permissions (root)");
        return;
    }
    let ro = d.join("ro");
    std::fs::create_dir_all(&ro).unwrap();
    set_read_only(&ro, true);
    let motion = d.join("walk.mot");
    generated_motion(demo(), 20, &motion);
    let runs = [
        args(
            "model scale {} --mass 30 --height 1.8 --model-height 1.7 -o {}",
            &[demo(), &ro.join("s.osim")],
        ),
        args("export-mjcf --demo -o {}", &[&ro.join("demo.xml")]),
        args(
            "muscles {} --coords {} -o {}",
            &[demo(), &motion, &ro.join("walk")],
        ),
    ];
    for a in &runs {
        let (ok, err) = run(a);
        assert!(!ok);
        assert!(err.contains("cannot write output"), "{err}");
    }
    set_read_only(&ro, false);
    assert!(names(&ro).is_empty(), "{:?}", names(&ro));
}

#[test]
fn a_write_that_fails_after_some_files_leaves_none_of_them() {
    // Root ignores permissions, but not the 255-byte limit on a file name: a prefix this long
    // lets the first file's temporary name through and stops the second (…_MomentArm_…).
    let d = ScratchDir::new("outputs-fail-midway");
    let motion = d.join("walk.mot");
    generated_motion(demo(), 20, &motion);
    let pid_digits = 7; // at most, on Linux
    // `<host>-<pidns>-<pid>`: this host's and namespace's parts, a pid of at most 7 digits
    let writer_len = musculo::io::output::writer_token(0).len() - 1 + pid_digits;
    let prefix_len = 255 - ".".len() - "_Length.sto".len() - ".tmp-".len() - writer_len - 3;
    let prefix = d.join(&"p".repeat(prefix_len));
    let (ok, err) = run(&args(
        "muscles {} --coords {} -o {}",
        &[demo(), &motion, &prefix],
    ));
    assert!(!ok);
    assert!(
        err.contains("cannot write output") && err.contains("_MomentArm_"),
        "{err}"
    );
    assert_eq!(
        names(&d.0),
        vec!["walk.mot"],
        "no file and no temporary left"
    );

    // A folder that cannot be made (a file is in the way) is named as such.
    std::fs::write(d.join("blocker"), "").unwrap();
    let (ok, err) = run(&args(
        "muscles {} --coords {} -o {}",
        &[demo(), &motion, &d.join("blocker/walk")],
    ));
    assert!(!ok);
    assert!(err.contains("cannot create its folder"), "{err}");
    assert_eq!(names(&d.0), vec!["blocker", "walk.mot"]);
}

#[test]
fn muscles_creates_missing_folders_and_a_trailing_slash_names_a_folder() {
    let d = ScratchDir::new("outputs-muscles-folders");
    let motion = d.join("walk.mot");
    generated_motion(demo(), 20, &motion);
    // out/walk: a prefix in a folder that does not exist yet
    let (ok, err) = run(&args(
        "muscles {} --coords {} -o {}",
        &[demo(), &motion, &d.join("out/walk")],
    ));
    assert!(ok, "{err}");
    assert!(d.join("out/walk_Length.sto").is_file());
    // deep/walk/: a folder, the files named after the motion inside it
    let mut folder = d.join("deep/walk").into_os_string();
    folder.push("/");
    let (ok, err) = run(&args(
        "muscles {} --coords {} -o {}",
        &[demo(), &motion, Path::new(&folder)],
    ));
    assert!(ok, "{err}");
    let inside = names(&d.join("deep/walk"));
    assert!(
        inside.contains(&"walk_Length.sto".to_string()),
        "{inside:?}"
    );
    assert!(
        inside
            .iter()
            .all(|n| n.starts_with("walk_") && n.ends_with(".sto")),
        "{inside:?}"
    );
    assert_eq!(
        inside,
        names(&d.join("out"))
            .into_iter()
            .map(|n| n.to_string())
            .collect::<Vec<_>>(),
        "the same files either way"
    );
    // the prefix may not name the input
    let (ok, err) = run(&args(
        "muscles {} --coords {} -o {}",
        &[demo(), &d.join("out/walk_Length.sto"), &d.join("out/walk")],
    ));
    assert!(!ok);
    assert!(err.contains("it is an input"), "{err}");
}

#[test]
fn export_mjcf_writes_into_a_new_folder_and_leaves_nothing_else() {
    let d = ScratchDir::new("outputs-mjcf");
    let mut folder = d.join("mjcf").into_os_string();
    folder.push("/");
    let (ok, err) = run(&args("export-mjcf --demo -o {}", &[Path::new(&folder)]));
    assert!(ok, "{err}");
    let (ok, err) = run(&args(
        "export-mjcf {} -o {}",
        &[demo(), &d.join("x/leg.xml")],
    ));
    assert!(ok, "{err}");
    assert_eq!(names(&d.0), vec!["mjcf/demo.xml", "x/leg.xml"]);
    // the input itself is refused
    let model = d.join("leg.osim");
    std::fs::copy(demo(), &model).unwrap();
    let (ok, err) = run(&args("export-mjcf {} -o {}", &[&model, &model]));
    assert!(!ok && err.contains("it is an input"), "{err}");
}

#[test]
fn id_refuses_to_overwrite_its_coordinates() {
    let d = ScratchDir::new("outputs-id-input");
    let motion = d.join("walk.mot");
    generated_motion(demo(), 20, &motion);
    let before = std::fs::read(&motion).unwrap();
    let (ok, err) = run(&args(
        "id --model {} --coordinates {} -o {}",
        &[demo(), &motion, &d.0.join(".").join("walk.mot")],
    ));
    assert!(!ok);
    assert!(err.contains("it is an input of this command"), "{err}");
    assert_eq!(std::fs::read(&motion).unwrap(), before);
    // into a new folder: created, the default name inside
    let mut folder = d.join("id").into_os_string();
    folder.push("/");
    let (ok, err) = run(&args(
        "id --model {} --coordinates {} -o {}",
        &[demo(), &motion, Path::new(&folder)],
    ));
    assert!(ok, "{err}");
    assert_eq!(names(&d.0), vec!["id/inverse_dynamics.sto", "walk.mot"]);
}

#[test]
fn ik_refuses_to_overwrite_its_markers_and_writes_its_three_files_together() {
    let d = ScratchDir::new("outputs-ik");
    let trc = d.join("trial.trc");
    let mut text = String::from(
        "PathFileType\t4\t(X/Y/Z)\ttrial.trc\n\
         DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n\
         100\t100\t5\t4\tm\t100\t1\t5\n\
         Frame#\tTime\thip\t\t\tknee\t\t\tankle\t\t\ttoe\t\t\n\
         \t\tX1\tY1\tZ1\tX2\tY2\tZ2\tX3\tY3\tZ3\tX4\tY4\tZ4\n\n",
    );
    for f in 0..5 {
        let x = 0.01 * f as f64;
        text += &format!(
            "{}\t{}\t{x}\t0.93\t0.08\t{x}\t0.5\t0.08\t{x}\t0.1\t0.08\t{}\t0.05\t0.08\n",
            f + 1,
            0.01 * f as f64,
            x + 0.15
        );
    }
    std::fs::write(&trc, &text).unwrap();
    let (ok, err) = run(&args(
        "ik --model {} --input {} -o {}",
        &[demo(), &trc, &trc],
    ));
    assert!(!ok);
    assert!(err.contains("it is an input"), "{err}");
    assert_eq!(std::fs::read_to_string(&trc).unwrap(), text);
    let mut folder = d.join("ik").into_os_string();
    folder.push("/");
    let (ok, err) = run(&args(
        "ik --model {} --input {} -o {}",
        &[demo(), &trc, Path::new(&folder)],
    ));
    assert!(ok, "{err}");
    assert_eq!(
        names(&d.join("ik")),
        vec![
            "trial.mot",
            "trial_ik_marker_errors.sto",
            "trial_ik_marker_errors_by_marker.sto"
        ]
    );
}

const SCALE_SETUP: &str = r#"<OpenSimDocument Version="40000">
<ScaleTool name="subj">
  <mass>30</mass>
  <GenericModelMaker><model_file>leg.osim</model_file></GenericModelMaker>
  <ModelScaler>
    <apply>true</apply>
    <scaling_order> manualScale</scaling_order>
    <ScaleSet><objects><Scale><scales> 1.1 1.1 1.1</scales><segment>thigh</segment><apply>true</apply></Scale></objects></ScaleSet>
    <output_model_file>MODEL_OUT</output_model_file>
    <output_scale_file>subj_scales.xml</output_scale_file>
  </ModelScaler>
</ScaleTool>
</OpenSimDocument>
"#;

#[test]
fn scale_writes_all_its_outputs_or_none() {
    let d = ScratchDir::new("outputs-scale-tool");
    std::fs::copy(demo(), d.join("leg.osim")).unwrap();
    let setup = d.join("setup.xml");
    std::fs::write(&setup, SCALE_SETUP.replace("MODEL_OUT", "subj.osim")).unwrap();
    // one of the two outputs cannot be written (a folder is in its place): neither is
    let blocked = d.join("blocked");
    std::fs::create_dir_all(blocked.join("subj_scales.xml")).unwrap();
    let (ok, err) = run(&args(
        "scale --setup {} --output-dir {}",
        &[&setup, &blocked],
    ));
    assert!(!ok);
    assert!(
        err.contains("subj_scales.xml: is an existing folder"),
        "{err}"
    );
    assert!(!blocked.join("subj.osim").exists());
    // both, into a folder that does not exist yet
    let (ok, err) = run(&args(
        "scale --setup {} --output-dir {}",
        &[&setup, &d.join("new/out")],
    ));
    assert!(ok, "{err}");
    assert_eq!(
        names(&d.join("new/out")),
        vec!["subj.osim", "subj_scales.xml"]
    );
    // the setup's output naming the generic model is refused, the model intact
    let before = std::fs::read(d.join("leg.osim")).unwrap();
    std::fs::write(&setup, SCALE_SETUP.replace("MODEL_OUT", "leg.osim")).unwrap();
    let (ok, err) = run(&args("scale --setup {}", &[&setup]));
    assert!(!ok);
    assert!(
        err.contains("leg.osim") && err.contains("it is an input"),
        "{err}"
    );
    assert_eq!(std::fs::read(d.join("leg.osim")).unwrap(), before);
    assert!(!d.join("subj_scales.xml").exists());
}

#[test]
fn model_build_into_a_folder() {
    let d = ScratchDir::new("outputs-build");
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/model");
    let mut folder = d.join("models").into_os_string();
    folder.push("/");
    let (ok, _, err) = run_musculo(&args(
        "model build --data {} -o {}",
        &[&data, Path::new(&folder)],
    ));
    assert!(ok, "{err}");
    assert_eq!(names(&d.0), vec!["models/musculo_fullbody.osim"]);
    musculo::Model::from_osim_file(d.join("models/musculo_fullbody.osim")).unwrap();
    // a table of the data folder is an input
    let table = std::fs::read_dir(&data)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|x| x == "csv"))
        .unwrap();
    let (ok, _, err) = run_musculo(&args("model build --data {} -o {}", &[&data, &table]));
    assert!(!ok && err.contains("it is an input"), "{err}");
}

const ANALYZE_SETUP: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<OpenSimDocument Version="40000">
  <AnalyzeTool name="TOOL">
    <model_file>leg.osim</model_file>
    <coordinates_file>walk.mot</coordinates_file>
    <force_set_files>reserves.xml</force_set_files>
    <results_directory>results</results_directory>
    <AnalysisSet>
      <objects>
        <StaticOptimization name="ANALYSIS">
          <use_model_force_set>true</use_model_force_set>
        </StaticOptimization>
      </objects>
    </AnalysisSet>
  </AnalyzeTool>
</OpenSimDocument>
"#;

#[test]
fn setup_names_may_not_leave_the_results_folder() {
    let d = ScratchDir::new("outputs-setup-names");
    let work = d.join("a/b");
    std::fs::create_dir_all(&work).unwrap();
    std::fs::copy(demo(), work.join("leg.osim")).unwrap();
    generated_motion(demo(), 10, &work.join("walk.mot"));
    reserves_for(demo(), &work.join("reserves.xml"));
    let setup = work.join("setup.xml");
    for (tool, analysis, line, what) in [
        ("../../x", "so", 3, "AnalyzeTool \"../../x\""),
        (
            "walk",
            "../escaped",
            10,
            "StaticOptimization \"../escaped\"",
        ),
        ("walk", "..\\escaped", 10, "StaticOptimization"),
    ] {
        let text = ANALYZE_SETUP
            .replace("TOOL", tool)
            .replace("ANALYSIS", analysis);
        std::fs::write(&setup, text).unwrap();
        let (ok, err) = run(&args("so --setup {}", &[&setup]));
        assert!(!ok);
        assert!(
            err.contains(&format!("setup.xml:{line}:"))
                && err.contains(what)
                && err.contains("path separator"),
            "{err}"
        );
    }
    // the inverse dynamics file name likewise
    std::fs::write(
        &setup,
        "<OpenSimDocument Version=\"40000\">\n<InverseDynamicsTool name=\"id\">\n\
         <model_file>leg.osim</model_file>\n<coordinates_file>walk.mot</coordinates_file>\n\
         <results_directory>results</results_directory>\n\
         <output_gen_force_file>../../id.sto</output_gen_force_file>\n\
         </InverseDynamicsTool>\n</OpenSimDocument>\n",
    )
    .unwrap();
    let (ok, err) = run(&args("id --setup {}", &[&setup]));
    assert!(!ok);
    assert!(
        err.contains("setup.xml:6:") && err.contains("<output_gen_force_file>"),
        "{err}"
    );
    let all = names(&d.0);
    assert_eq!(
        all,
        vec![
            "a/b/leg.osim",
            "a/b/reserves.xml",
            "a/b/setup.xml",
            "a/b/walk.mot"
        ]
    );
    // a plain name writes into the results folder, created
    std::fs::write(
        &setup,
        ANALYZE_SETUP
            .replace("TOOL", "walk")
            .replace("ANALYSIS", "so"),
    )
    .unwrap();
    let (ok, err) = run(&args("so --setup {}", &[&setup]));
    assert!(ok, "{err}");
    assert!(work.join("results/walk_so_activation.sto").is_file());
    assert!(work.join("results/walk_so_force.sto").is_file());
}

/// Runs `args` once uninterrupted in `reference`, then kills it with SIGKILL in `dir` at
/// several moments — while it computes, and once a quarter, half and three quarters of its
/// files are under way (each file's temporary or final name seen) — and checks that no final-named file is partial; then reruns it in `dir` and checks the
/// result is the uninterrupted run's, byte for byte, with no temporary left.
fn killed_runs_leave_no_partial_file(
    make_args: impl Fn(&Path) -> Vec<OsString>,
    reference: &Path,
    dir: &Path,
) {
    let start = Instant::now();
    let (ok, err) = run(&make_args(reference));
    let full = start.elapsed();
    assert!(ok, "{err}");
    let expected = tree(reference);
    assert!(expected.len() >= 2, "{:?}", expected.keys());
    let mut saw_temporaries = false;
    for attempt in 0..4 {
        let mut child = Command::new(env!("CARGO_BIN_EXE_musculo"))
            .args(make_args(dir))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let t0 = Instant::now();
        let deadline = match attempt {
            0 => full / 3, // while computing
            _ => full * 3, // at the threshold below (or at the end)
        };
        // attempts 1–3: once a quarter, a half, three quarters of the files are being
        // written (temporary) or written (final name)
        let threshold = (expected.len() * attempt / 4).max(1);
        loop {
            let now = names(dir);
            let temporaries = now.iter().filter(|n| n.contains(".tmp-")).count();
            let finals = now.iter().filter(|n| expected.contains_key(*n)).count();
            if attempt > 0 && temporaries + finals >= threshold {
                saw_temporaries |= temporaries > 0;
                break;
            }
            if t0.elapsed() >= deadline || child.try_wait().unwrap().is_some() {
                break;
            }
            std::thread::sleep(Duration::from_micros(200));
        }
        let _ = child.kill(); // SIGKILL
        child.wait().unwrap();
        let now = tree(dir);
        let finals: Vec<&String> = now
            .keys()
            .filter(|n| !n.contains("/.") && !n.starts_with('.'))
            .collect();
        for name in &finals {
            assert_eq!(
                now[*name], expected[*name],
                "attempt {attempt}: {name} has its final name but not its final bytes"
            );
        }
        let journal = now.keys().any(|n| n.contains(".musculo-commit-"));
        assert!(
            finals.is_empty() || finals.len() == expected.len() || journal,
            "attempt {attempt}: an incomplete set with nothing saying so: {finals:?}"
        );
    }
    assert!(saw_temporaries, "the kills never caught the run writing");
    let (ok, err) = run(&make_args(dir));
    assert!(ok, "{err}");
    assert_eq!(
        tree(dir).keys().collect::<Vec<_>>(),
        expected.keys().collect::<Vec<_>>(),
        "the rerun leaves exactly the outputs (stale temporaries removed)"
    );
    assert!(tree(dir) == expected, "the rerun is byte-identical");
}

#[test]
fn a_killed_muscles_run_leaves_no_partial_file_and_a_rerun_is_identical() {
    let d = ScratchDir::new("outputs-kill-muscles");
    let motion = d.join("walk.mot");
    generated_motion(Path::new(FULLBODY), 400, &motion);
    let make = |dir: &Path| {
        args(
            "muscles {} --coords {} -o {}",
            &[Path::new(FULLBODY), &motion, &dir.join("walk")],
        )
    };
    let (a, b) = (d.join("reference"), d.join("killed"));
    std::fs::create_dir_all(&a).unwrap();
    std::fs::create_dir_all(&b).unwrap();
    killed_runs_leave_no_partial_file(make, &a, &b);
}

#[test]
fn a_killed_so_run_leaves_no_partial_file_and_a_rerun_is_identical() {
    let d = ScratchDir::new("outputs-kill-so");
    let motion = d.join("walk.mot");
    let reserves = d.join("reserves.xml");
    generated_motion(Path::new(FULLBODY), 300, &motion);
    reserves_for(Path::new(FULLBODY), &reserves);
    let make = |dir: &Path| {
        args(
            "so --model {} --coordinates {} --actuators {} -o {}",
            &[Path::new(FULLBODY), &motion, &reserves, &dir.join("walk")],
        )
    };
    let (a, b) = (d.join("reference"), d.join("killed"));
    std::fs::create_dir_all(&a).unwrap();
    std::fs::create_dir_all(&b).unwrap();
    killed_runs_leave_no_partial_file(make, &a, &b);
}
