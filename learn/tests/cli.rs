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
    let (ok, out) = run(&[
        "train-diffusion",
        "--autoencoder",
        s(&ae),
        "--data",
        s(&data),
        "--out",
        s(&diff),
        "--text-embeddings",
        s(&embeddings),
        "--steps",
        "4",
        "--window",
        "32",
        "--batch",
        "2",
    ]);
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
    ] {
        let (ok, out) = run(&args);
        assert!(!ok && out.contains(expect), "{args:?}: {out}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
