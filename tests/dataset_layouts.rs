//! HumanML3D / KIT-ML roots given to `augment --input` (`augment::dataset`): the clips of one
//! motion folder (`new_joints/` before `new_joint_vecs/`), each once, named by its id; the
//! statistics and split lists are not clips; captions copied beside the outputs where the
//! learned module reads them; each clip's split in its record.

mod common;

use common::{reference_file, run_musculo};
use musculo::augment::runner::{self, ClipSource};
use musculo::motion::Format;
use std::path::{Path, PathBuf};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("musculo-layouts-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

const CAPTIONS: [(&str, &str); 2] = [
    (
        "012314",
        "a person jumps forward.#a/DET person/NOUN jump/VERB forward/ADV#0.0#0.0\n\
         someone leaps ahead.#someone/PRON leap/VERB ahead/ADV#0.0#0.0\n",
    ),
    (
        "M012314",
        "a person jumps forward, mirrored.#a/DET person/NOUN jump/VERB#0.0#0.0\n",
    ),
];

/// A HumanML3D root in `dir` made of the reference sample (as clips 012314 and M012314, in
/// both motion folders), its Mean/Std, captions and split lists (012314 in train, M012314 in
/// test, val empty, and the unions train_val and all). None without reference data.
fn humanml3d_root(dir: &Path) -> Option<()> {
    let joints = reference_file("humanml3d/new_joints_012314.npy")?;
    let features = reference_file("humanml3d/new_joint_vecs_012314.npy")?;
    let mean = reference_file("humanml3d/Mean.npy")?;
    let std = reference_file("humanml3d/Std.npy")?;
    for sub in ["new_joints", "new_joint_vecs", "texts"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
    }
    for (id, caption) in CAPTIONS {
        std::fs::copy(&joints, dir.join(format!("new_joints/{id}.npy"))).unwrap();
        std::fs::copy(&features, dir.join(format!("new_joint_vecs/{id}.npy"))).unwrap();
        std::fs::write(dir.join(format!("texts/{id}.txt")), caption).unwrap();
    }
    std::fs::copy(mean, dir.join("Mean.npy")).unwrap();
    std::fs::copy(std, dir.join("Std.npy")).unwrap();
    for (split, ids) in [
        ("train", "012314\n"),
        ("val", ""),
        ("test", "M012314\n"),
        ("train_val", "012314\n"),
        ("all", "012314\nM012314\n"),
    ] {
        std::fs::write(dir.join(format!("{split}.txt")), ids).unwrap();
    }
    Some(())
}

fn manifest(out: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap()
}

#[test]
fn a_humanml3d_root_gives_each_joint_clip_once_with_its_caption_and_split() {
    let root = temp_dir("root");
    if humanml3d_root(&root).is_none() {
        return;
    }
    let out = temp_dir("root-out");
    let (ok, _, stderr) = run_musculo(&[
        "augment".as_ref(),
        "--input".as_ref(),
        root.as_os_str(),
        "--variants".as_ref(),
        "2".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(ok, "{stderr}");
    assert!(
        stderr.contains("clips from new_joints/; new_joint_vecs/ left out"),
        "{stderr}"
    );
    let m = manifest(&out);
    let clips = m["clips"].as_array().unwrap();
    let rows: Vec<(String, String, String, String)> = clips
        .iter()
        .map(|c| {
            (
                c["clip"].as_str().unwrap().to_string(),
                c["status"].as_str().unwrap().to_string(),
                c["split"].as_str().unwrap_or("none").to_string(),
                c["input"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    let expected = [
        ("012314", "train"),
        ("012314_v1", "train"),
        ("M012314", "test"),
        ("M012314_v1", "test"),
    ];
    assert_eq!(rows.len(), expected.len(), "{rows:?}");
    for ((clip, status, split, input), (name, want)) in rows.iter().zip(expected) {
        assert_eq!(
            (clip.as_str(), status.as_str(), split.as_str()),
            (name, "ok", want)
        );
        let id = name.trim_end_matches("_v1");
        assert!(
            Path::new(input).ends_with(format!("new_joints/{id}.npy")),
            "{input}"
        );
        // the caption beside the outputs, byte for byte, where musculo_learn::text::caption
        // looks for it (texts/<npz stem>.txt in the npz's folder)
        assert!(out.join(format!("{clip}.npz")).is_file());
        let caption = CAPTIONS.iter().find(|(i, _)| *i == id).unwrap().1;
        assert_eq!(
            std::fs::read_to_string(out.join(format!("texts/{clip}.txt"))).unwrap(),
            caption
        );
    }
    let datasets = &m["run"]["datasets"];
    assert_eq!(datasets.as_array().unwrap().len(), 1, "{datasets}");
    assert_eq!(datasets[0]["motions"], "new_joints");
    assert_eq!(datasets[0]["left_out"], "new_joint_vecs");
    assert_eq!(
        datasets[0]["splits"],
        serde_json::json!([["train", 1], ["val", 0], ["test", 1]])
    );
    let _ = std::fs::remove_dir_all(&out);

    // sharded and merged: the same clips, splits and dataset description
    let sharded = temp_dir("root-sharded");
    for shard in ["0/2", "1/2"] {
        let (ok, _, stderr) = run_musculo(&[
            "augment".as_ref(),
            "--input".as_ref(),
            root.as_os_str(),
            "--shard".as_ref(),
            shard.as_ref(),
            "--out".as_ref(),
            sharded.as_os_str(),
        ]);
        assert!(ok, "{stderr}");
    }
    let (ok, _, stderr) = run_musculo(&["merge".as_ref(), sharded.as_os_str()]);
    assert!(ok, "{stderr}");
    let merged = manifest(&sharded);
    let splits: Vec<(&str, &str)> = (merged["clips"].as_array().unwrap().iter())
        .map(|c| (c["clip"].as_str().unwrap(), c["split"].as_str().unwrap()))
        .collect();
    assert_eq!(splits, [("012314", "train"), ("M012314", "test")]);
    assert_eq!(merged["run"]["datasets"], *datasets);
    assert!(sharded.join("texts/M012314.txt").is_file());
    let _ = std::fs::remove_dir_all(&sharded);
    let _ = std::fs::remove_dir_all(&root);
}

/// Listing only (no chain): which files of a root become clips, named how, in which format.
fn listed(input: &Path, format: Option<Format>) -> Vec<(String, String, Format)> {
    let (clips, _) = runner::list_dataset(&[input.to_path_buf()], format).unwrap();
    clips
        .into_iter()
        .map(|c| match c.source {
            ClipSource::File { path, format } => {
                let rel = path.strip_prefix(input.parent().unwrap()).unwrap();
                (c.name, rel.display().to_string(), format)
            }
            ClipSource::Motion(_) => panic!("{}: not a file", c.name),
        })
        .collect()
}

#[test]
fn a_root_without_joints_uses_its_features_and_a_motion_folder_given_uses_its_root() {
    let root = temp_dir("features");
    if humanml3d_root(&root).is_none() {
        return;
    }
    let name = root.file_name().unwrap().to_string_lossy().into_owned();
    // the features folder given itself: its clips, the root's captions and splits
    let vecs = root.join("new_joint_vecs");
    let (clips, roots) = runner::list_dataset(std::slice::from_ref(&vecs), None).unwrap();
    assert_eq!(clips.len(), 2);
    assert_eq!(roots.len(), 1);
    assert_eq!(roots[0].motions, vecs);
    assert_eq!(roots[0].split_of("M012314").as_deref(), Some("test"));
    assert_eq!(
        roots[0].text_of("012314"),
        Some(root.join("texts/012314.txt"))
    );
    // without new_joints/ the root's clips are the features
    std::fs::remove_dir_all(root.join("new_joints")).unwrap();
    assert_eq!(
        listed(&root, None),
        [
            (
                "012314".to_string(),
                format!("{name}/new_joint_vecs/012314.npy"),
                Format::HumanMl3d
            ),
            (
                "M012314".to_string(),
                format!("{name}/new_joint_vecs/M012314.npy"),
                Format::HumanMl3d
            ),
        ]
    );
    let _ = std::fs::remove_dir_all(&root);
}

/// KIT-ML's root: the same layout with 21 joints (T×21×3, here in millimetres as KIT-ML's
/// files are) — the joints folder chosen, each file read as KIT-ML.
#[test]
fn a_kit_ml_root_gives_its_joint_clips() {
    let root = temp_dir("kit");
    std::fs::create_dir_all(root.join("new_joints")).unwrap();
    std::fs::create_dir_all(root.join("new_joint_vecs")).unwrap();
    let joints = ndarray::ArrayD::<f32>::zeros(ndarray::IxDyn(&[10, 21, 3]));
    let features = ndarray::ArrayD::<f32>::zeros(ndarray::IxDyn(&[10, 251]));
    musculo::motion::npy::write_npy(&root.join("new_joints/00001.npy"), joints.view()).unwrap();
    musculo::motion::npy::write_npy(&root.join("new_joint_vecs/00001.npy"), features.view())
        .unwrap();
    std::fs::write(root.join("train.txt"), "00001\n").unwrap();
    let name = root.file_name().unwrap().to_string_lossy().into_owned();
    assert_eq!(
        listed(&root, None),
        [(
            "00001".to_string(),
            format!("{name}/new_joints/00001.npy"),
            Format::Kit
        )]
    );
    let _ = std::fs::remove_dir_all(&root);
}

/// A folder of loose HumanML3D files (the reference sample's own folder: both forms of one
/// clip and the dataset's Mean/Std): the statistics are not clips, with or without --format.
#[test]
fn statistics_beside_loose_clips_are_not_clips() {
    let Some(folder) = reference_file("humanml3d") else {
        return;
    };
    for format in [None, Some(Format::HumanMl3d)] {
        let names: Vec<String> = listed(&folder, format).into_iter().map(|c| c.0).collect();
        assert_eq!(
            names,
            ["new_joint_vecs_012314", "new_joints_012314"],
            "{format:?}"
        );
    }
}
