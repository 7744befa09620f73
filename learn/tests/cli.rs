//! `musculo-learn` end to end at toy sizes: train-ae → reconstruct → train-diffusion on
//! precomputed caption embeddings → generate from an embedding file and with a control; the
//! checkpoints' files and plots exist, the generated files are tensor files, and misuse is an
//! error with a message (never a panic).

use std::path::{Path, PathBuf};
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_musculo-learn");

fn run(args: &[&str]) -> (bool, String) {
    let out = Command::new(BIN).args(args).output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(!text.contains("panicked"), "{args:?}: {text}");
    (out.status.success(), text)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn train_reconstruct_train_diffusion_and_generate() {
    let dir: PathBuf =
        std::env::temp_dir().join(format!("musculo-learn-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (data, ae, diff, gen_dir) = (
        dir.join("data"),
        dir.join("ae"),
        dir.join("diffusion"),
        dir.join("generated"),
    );
    musculo_learn::data::augment_demo(&data).unwrap();
    let (ok, out) = run(&[
        "train-ae",
        "--data",
        s(&data),
        "--out",
        s(&ae),
        "--steps",
        "6",
        "--window",
        "32",
        "--save-every",
        "4",
        "--d-model",
        "32",
    ]);
    assert!(ok, "{out}");
    for file in [
        "autoencoder.bpk",
        "autoencoder.json",
        "loss.csv",
        "loss.html",
    ] {
        assert!(ae.join(file).is_file(), "{file}");
    }
    assert_eq!(
        std::fs::read_to_string(ae.join("loss.csv"))
            .unwrap()
            .lines()
            .count(),
        7
    );
    let (ok, out) = run(&["reconstruct", "--checkpoint", s(&ae), "--data", s(&data)]);
    assert!(ok, "{out}");
    let figures: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!(figures["joint_pos_error"].as_f64().unwrap() > 0.0);
    // precomputed caption embeddings: 8 values per clip
    let embeddings = dir.join("captions.npz");
    let arrays: Vec<(String, ndarray::ArrayD<f32>)> = ["march", "squat", "reach"]
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let v: Vec<f32> = (0..8).map(|k| ((i * 8 + k) as f32).sin()).collect();
            (
                name.to_string(),
                ndarray::ArrayD::from_shape_vec(vec![8], v).unwrap(),
            )
        })
        .collect();
    let views: Vec<(&str, ndarray::ArrayViewD<'_, f32>)> =
        arrays.iter().map(|(k, a)| (k.as_str(), a.view())).collect();
    musculo::motion::npy::write_npz(&embeddings, &views, false).unwrap();
    let mut args = diffusion_args(&ae, &data, &diff, "4");
    args.extend(["--text-embeddings", s(&embeddings)]);
    let (ok, out) = run(&args);
    assert!(ok, "{out}");
    for file in ["denoiser.bpk", "denoiser.json", "loss.csv", "loss.html"] {
        assert!(diff.join(file).is_file(), "{file}");
    }
    let prompt = dir.join("prompt.npy");
    musculo::motion::npy::write_npy_f32(&prompt, arrays[1].1.view()).unwrap();
    let (ok, out) = run(&[
        "generate",
        "--diffusion",
        s(&diff),
        "--text-embedding",
        s(&prompt),
        "--frames",
        "32",
        "--count",
        "2",
        "--sampling-steps",
        "4",
        "--out",
        s(&gen_dir),
    ]);
    assert!(ok, "{out}");
    let (ok, out) = run(&[
        "generate",
        "--diffusion",
        s(&diff),
        "--frames",
        "32",
        "--sampling-steps",
        "4",
        "--control",
        s(&data.join("squat.npz")),
        "--control-blocks",
        "joint_pos,tau",
        "--control-frames",
        "4:20",
        "--guidance",
        "1",
        "--name",
        "controlled",
        "--out",
        s(&gen_dir),
    ]);
    assert!(ok, "{out}");
    let model = musculo::model::Model::default_fullbody();
    for name in ["sample_000", "sample_001", "controlled_000"] {
        let frames = musculo::loss::tensor_file::TensorFrames::read(
            &gen_dir.join(format!("{name}.npz")),
            &model,
        )
        .unwrap();
        assert_eq!(frames.frames, 32, "{name}");
    }
    // each generated file names the body it was generated on: the base model augment recorded
    // for the training clips (the built-in model), unscaled, no variant; evaluate finds that
    // body from it without the "no model identity" warning
    let trained_on = musculo::augment::identity::read_identity(&data.join("squat.npz"))
        .unwrap()
        .expect("augment writes an identity");
    let bodies = musculo::augment::identity::Bodies::new(None).unwrap();
    for name in ["sample_000", "sample_001", "controlled_000"] {
        let path = gen_dir.join(format!("{name}.npz"));
        let text = musculo::motion::npy::read_npz_text(&path, "model_identity")
            .unwrap()
            .unwrap_or_else(|| panic!("{name}: no model_identity"));
        let identity: musculo::augment::identity::ModelIdentity =
            serde_json::from_str(&text).unwrap();
        assert_eq!(identity.base, trained_on.base, "{name}");
        assert!(identity.base.is_builtin(), "{name}");
        assert_eq!(identity.base.name, model.name, "{name}");
        assert!(identity.scale.is_none(), "{name}");
        assert_eq!(
            (identity.mass_scale, identity.load_kg),
            (1.0, 0.0),
            "{name}"
        );
        let body = bodies.of_tensor_file(&path).unwrap();
        assert!(body.warning.is_none(), "{name}: {:?}", body.warning);
        assert_eq!(body.model.name, model.name, "{name}");
    }
    // the built-in text encoder (captions: the clip names, there being no texts.json): a
    // caption, a conjunction and a negation on the command line; the composed concepts change
    // the motion that the caption alone gives from the same seed
    let diff_text = dir.join("diffusion-text");
    let (ok, out) = run(&diffusion_args(&ae, &data, &diff_text, "4"));
    assert!(ok, "{out}");
    let generate_text = |extra: &[&str], name: &str| {
        let mut args = vec![
            "generate",
            "--diffusion",
            s(&diff_text),
            "--text",
            "a squat",
            "--frames",
            "32",
            "--sampling-steps",
            "4",
            "--name",
            name,
            "--out",
            s(&gen_dir),
        ];
        args.extend_from_slice(extra);
        let (ok, out) = run(&args);
        assert!(ok, "{args:?}: {out}");
        musculo::loss::tensor_file::TensorFrames::read(
            &gen_dir.join(format!("{name}_000.npz")),
            &model,
        )
        .unwrap()
    };
    let alone = generate_text(&[], "squat");
    let composed = generate_text(&["--and", "march", "--not", "reach"], "composed");
    assert_eq!((alone.frames, composed.frames), (32, 32));
    let largest = alone
        .q
        .iter()
        .zip(&composed.q)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f64, f64::max);
    assert!(largest > 1e-6, "--and/--not left the motion unchanged");
    // --and on a model trained on precomputed embeddings is refused, naming the way out
    let (ok, out) = run(&[
        "generate",
        "--diffusion",
        s(&diff),
        "--text-embedding",
        s(&prompt),
        "--and",
        "march",
        "--out",
        s(&gen_dir),
    ]);
    assert!(
        !ok && out.contains("--and/--not need the built-in text encoder"),
        "{out}"
    );
    // a model other than the autoencoder's is refused (its identity would be wrong)
    let other = dir.join("other.osim");
    std::fs::write(
        &other,
        format!("{}\n<!-- another model -->\n", musculo::DEFAULT_MODEL_OSIM),
    )
    .unwrap();
    // misuse
    for (args, expect) in [
        (
            vec![
                "generate",
                "--diffusion",
                s(&diff),
                "--text",
                "a squat",
                "--out",
                s(&gen_dir),
            ],
            "precomputed embeddings",
        ),
        (
            vec![
                "generate",
                "--diffusion",
                s(&diff),
                "--frames",
                "30",
                "--out",
                s(&gen_dir),
            ],
            "multiple of 4",
        ),
        (
            vec![
                "generate",
                "--diffusion",
                s(&diff),
                "--model",
                s(&other),
                "--out",
                s(&gen_dir),
            ],
            "pass the model it was trained on",
        ),
        (
            vec![
                "generate",
                "--diffusion",
                s(&diff),
                "--control",
                s(&data.join("squat.npz")),
                "--control-frames",
                "20:10",
                "--out",
                s(&gen_dir),
            ],
            "--control-frames",
        ),
        (
            vec![
                "train-ae",
                "--data",
                s(&dir.join("missing")),
                "--out",
                s(&ae),
            ],
            "no such file or folder",
        ),
        (
            vec![
                "reconstruct",
                "--checkpoint",
                s(&ae),
                "--data",
                s(&data),
                "--device",
                "gpu",
            ],
            "expected cpu, wgpu, cuda",
        ),
    ] {
        let (ok, out) = run(&args);
        assert!(!ok && out.contains(expect), "{args:?}: {out}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The arguments of a toy `train-ae` run of `steps` steps into `out`.
fn train_args<'a>(data: &'a Path, out: &'a Path, steps: &'a str) -> Vec<&'a str> {
    vec![
        "train-ae",
        "--data",
        s(data),
        "--out",
        s(out),
        "--steps",
        steps,
        "--window",
        "32",
        "--save-every",
        "3",
        "--d-model",
        "32",
        "--seed",
        "5",
    ]
}

/// The arguments of a toy `train-diffusion` run of `steps` steps on the autoencoder `ae`
/// into `out`.
fn diffusion_args<'a>(ae: &'a Path, data: &'a Path, out: &'a Path, steps: &'a str) -> Vec<&'a str> {
    vec![
        "train-diffusion",
        "--autoencoder",
        s(ae),
        "--data",
        s(data),
        "--out",
        s(out),
        "--steps",
        steps,
        "--window",
        "32",
        "--batch",
        "2",
    ]
}

#[test]
fn a_killed_train_ae_resumes_to_the_uninterrupted_network() {
    let dir: PathBuf =
        std::env::temp_dir().join(format!("musculo-learn-resume-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (data, whole, killed) = (dir.join("data"), dir.join("whole"), dir.join("killed"));
    musculo_learn::data::augment_demo(&data).unwrap();
    let (ok, out) = run(&train_args(&data, &whole, "60"));
    assert!(ok, "{out}");
    // the same run, killed (SIGKILL) as soon as its first snapshot is there
    let mut child = Command::new(BIN)
        .args(train_args(&data, &killed, "60"))
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let state = killed.join("resume.json");
    let started = std::time::Instant::now();
    while !state.is_file() && started.elapsed().as_secs() < 120 {
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let mut args = train_args(&data, &killed, "60");
    args.push("--resume");
    let (ok, out) = run(&args);
    assert!(ok, "{out}");
    let step: usize = out
        .split("from step ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no resume message: {out}"));
    assert!((3..60).contains(&step), "resumed from step {step}");
    eprintln!("train-ae resumed from step {step} of 60");
    // the same network: the same reconstruction figures, and the whole loss curve
    let figures = |checkpoint: &Path| {
        let (ok, out) = run(&[
            "reconstruct",
            "--checkpoint",
            s(checkpoint),
            "--data",
            s(&data),
        ]);
        assert!(ok, "{out}");
        serde_json::from_str::<serde_json::Value>(&out).unwrap()
    };
    let (a, b) = (figures(&whole), figures(&killed));
    for key in ["joint_pos_error", "residual_rms"] {
        let (x, y) = (a[key].as_f64().unwrap(), b[key].as_f64().unwrap());
        assert!((x - y).abs() <= 1e-6 * x.abs(), "{key}: {y} resumed vs {x}");
    }
    let losses = |checkpoint: &Path| -> Vec<String> {
        std::fs::read_to_string(checkpoint.join("loss.csv"))
            .unwrap()
            .lines()
            .map(|l| l.rsplit_once(',').unwrap().0.to_string())
            .collect()
    };
    assert_eq!(losses(&killed), losses(&whole));
    // a finished run has nothing left; other settings are another run
    let mut again = train_args(&data, &killed, "60");
    again.push("--resume");
    let (ok, out) = run(&again);
    assert!(ok && out.contains("from step 60 of 60"), "{out}");
    let mut other = train_args(&data, &killed, "61");
    other.push("--resume");
    let (ok, out) = run(&other);
    assert!(!ok && out.contains("another run"), "{out}");

    // the same for the denoiser: killed after its first snapshot, resumed, then both models
    // generate the same motion from the same seed
    let resumable_args = |out: &Path| -> Vec<String> {
        let mut args = diffusion_args(&whole, &data, out, "40");
        args.extend(["--save-every", "3"]);
        args.iter().map(|a| a.to_string()).collect()
    };
    let (d_whole, d_killed) = (dir.join("diffusion_whole"), dir.join("diffusion_killed"));
    let args = resumable_args(&d_whole);
    let (ok, out) = run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(ok, "{out}");
    let mut child = Command::new(BIN)
        .args(resumable_args(&d_killed))
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let state = d_killed.join("denoiser-resume.json");
    let started = std::time::Instant::now();
    while !state.is_file() && started.elapsed().as_secs() < 120 {
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let mut args = resumable_args(&d_killed);
    args.push("--resume".into());
    let (ok, out) = run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(ok, "{out}");
    assert!(
        out.contains("from step ") && !out.contains("from step 40 "),
        "{out}"
    );
    let line = out.lines().find(|l| l.contains("from step")).unwrap_or("");
    eprintln!("train-diffusion: {line}");
    assert_eq!(losses(&d_killed), losses(&d_whole));
    let sample = |checkpoint: &Path, name: &str| {
        let (ok, out) = run(&[
            "generate",
            "--diffusion",
            s(checkpoint),
            "--frames",
            "32",
            "--sampling-steps",
            "4",
            "--name",
            name,
            "--out",
            s(&dir.join("generated")),
        ]);
        assert!(ok, "{out}");
        musculo::motion::npy::read_npz_f32(&dir.join("generated").join(format!("{name}_000.npz")))
            .unwrap()
    };
    let (a, b) = (sample(&d_whole, "whole"), sample(&d_killed, "killed"));
    assert_eq!(a.len(), b.len());
    for ((ka, va), (kb, vb)) in a.iter().zip(&b) {
        assert_eq!(ka, kb);
        assert_eq!(va, vb, "{ka}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn usage_lines_name_the_musculo_command_that_runs_this_program() {
    // reached as `musculo train-ae …` (src/bin/musculo/learn.rs), so usage says `musculo`
    for sub in ["train-ae", "reconstruct", "train-diffusion", "generate"] {
        let (ok, text) = run(&[sub, "--help"]);
        assert!(ok, "{text}");
        assert!(
            text.contains(&format!("Usage: musculo {sub}")),
            "{sub} --help:\n{text}"
        );
        assert!(!text.contains("musculo-learn"), "{sub} --help:\n{text}");
    }
}
