//! Dataset roots that `augment --input` understands: HumanML3D's and KIT-ML's.
//!
//! Both datasets ship one folder of the form
//!
//! ```text
//! HumanML3D/                          KIT-ML/ (the same, 21 joints, 251 features)
//!   new_joints/<id>.npy               T×22×3 joint centres (m)
//!   new_joint_vecs/<id>.npy           T×263 features of the same motions
//!   texts/<id>.txt                    captions, one a line: "caption#tokens#start#end"
//!   Mean.npy, Std.npy                 feature statistics (263,)
//!   train.txt, val.txt, test.txt      ids of the splits, one a line
//!   train_val.txt, all.txt            unions of those
//! ```
//!
//! A folder given to `--input` that holds `new_joints/` or `new_joint_vecs/` is such a root
//! (so is one of those two folders given itself, inside a root). Its clips are the files of
//! one motion folder, named by their id: `new_joints/` when it holds any `.npy` file — joint
//! positions are what inverse kinematics fits, and the features are the same motions again —
//! otherwise `new_joint_vecs/`, never both. The statistics, split lists and any other entry of
//! the root are not clips. Each clip's caption file (`texts/<id>.txt`) is copied beside its
//! outputs as `texts/<output name>.txt` — for every variant too, which performs the same
//! motion — where the learned module looks for captions (`musculo_learn::text::caption`).
//! The split a clip's id is listed in (`train`, `val` or `test`; names joined by `+` when
//! the lists disagree) goes into its record, and the root's layout into the run's
//! description ([`DatasetDescription`]).

use crate::error::Error;
use std::collections::HashSet;
use std::path::{Path, PathBuf};

/// The motion folders of a root, in order of preference.
pub const MOTION_FOLDERS: [&str; 2] = ["new_joints", "new_joint_vecs"];
/// The split lists read, in this order (`train_val.txt`, `all.txt` are their unions).
pub const SPLITS: [&str; 3] = ["train", "val", "test"];
/// The feature statistics HumanML3D and KIT-ML ship beside their clips: never clips.
pub const STATISTICS: [&str; 2] = ["Mean.npy", "Std.npy"];

/// Whether `path` is a dataset's feature statistics (`Mean.npy`, `Std.npy`, any letter case).
pub fn is_statistics(path: &Path) -> bool {
    path.file_name()
        .map(|n| n.to_string_lossy())
        .is_some_and(|n| STATISTICS.iter().any(|s| s.eq_ignore_ascii_case(&n)))
}

/// A HumanML3D / KIT-ML root found at an input (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct DatasetRoot {
    pub root: PathBuf,
    /// The motion folder the clips come from.
    pub motions: PathBuf,
    /// The other motion folder, when it holds clips too: left out.
    pub left_out: Option<PathBuf>,
    /// The captions' folder, when present.
    pub texts: Option<PathBuf>,
    /// The split lists present, in [`SPLITS`] order: (name, ids).
    pub splits: Vec<(String, HashSet<String>)>,
}

/// A dataset root as the manifest's run describes it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DatasetDescription {
    pub root: String,
    /// The motion folder the clips came from (`new_joints` or `new_joint_vecs`).
    pub motions: String,
    /// The other motion folder, left out.
    pub left_out: Option<String>,
    /// The captions' folder, copied beside the outputs.
    pub texts: Option<String>,
    /// The split lists read: (name, number of ids listed).
    pub splits: Vec<(String, usize)>,
}

fn holds_npy(folder: &Path) -> crate::Result<bool> {
    Ok(crate::io::folder::files_below(folder, true)?
        .iter()
        .any(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy"))))
}

impl DatasetRoot {
    /// The root at `input` (a folder): the folder itself when it holds a motion folder, or
    /// its parent when `input` is one; None otherwise. Split lists that cannot be read are
    /// an error naming the file.
    pub fn find(input: &Path) -> crate::Result<Option<DatasetRoot>> {
        let name = input.file_name().map(|n| n.to_string_lossy().into_owned());
        let (root, given) = match name {
            Some(n) if MOTION_FOLDERS.contains(&n.as_str()) => match input.parent() {
                Some(parent) => (parent.to_path_buf(), Some(input.to_path_buf())),
                None => return Ok(None),
            },
            _ => (input.to_path_buf(), None),
        };
        let present: Vec<PathBuf> = MOTION_FOLDERS
            .iter()
            .map(|f| root.join(f))
            .filter(|p| p.is_dir())
            .collect();
        if present.is_empty() {
            return Ok(None);
        }
        let motions = match given {
            Some(g) => g,
            None => {
                let mut chosen = present[0].clone();
                for p in &present {
                    if holds_npy(p)? {
                        chosen = p.clone();
                        break;
                    }
                }
                chosen
            }
        };
        let mut left_out = None;
        for p in present.into_iter().filter(|p| *p != motions) {
            if holds_npy(&p)? {
                left_out = Some(p);
            }
        }
        let texts = Some(root.join("texts")).filter(|p| p.is_dir());
        let mut splits = Vec::new();
        for split in SPLITS {
            let path = root.join(format!("{split}.txt"));
            if !path.is_file() {
                continue;
            }
            let text = crate::text::read_text(&path)?;
            let ids = text
                .lines()
                .map(str::trim)
                .filter(|l| !l.is_empty())
                .map(str::to_string)
                .collect();
            splits.push((split.to_string(), ids));
        }
        Ok(Some(DatasetRoot {
            root,
            motions,
            left_out,
            texts,
            splits,
        }))
    }

    /// The split(s) listing clip `id` (joined by `+` when several do), None when none does.
    pub fn split_of(&self, id: &str) -> Option<String> {
        let names: Vec<&str> = (self.splits.iter())
            .filter(|(_, ids)| ids.contains(id))
            .map(|(n, _)| n.as_str())
            .collect();
        (!names.is_empty()).then(|| names.join("+"))
    }

    /// The caption file of clip `id`, when it exists.
    pub fn text_of(&self, id: &str) -> Option<PathBuf> {
        let path = self.texts.as_ref()?.join(format!("{id}.txt"));
        path.is_file().then_some(path)
    }

    /// The id of the clip read from `path` when it lies in this root's motion folder: its
    /// path there without extension, `/`-separated.
    pub fn id_of(&self, path: &Path) -> Option<String> {
        let rel = path.strip_prefix(&self.motions).ok()?.with_extension("");
        Some(
            rel.components()
                .map(|c| c.as_os_str().to_string_lossy())
                .collect::<Vec<_>>()
                .join("/"),
        )
    }

    pub fn describe(&self) -> DatasetDescription {
        let folder = |p: &Path| {
            p.file_name().map_or_else(
                || p.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            )
        };
        DatasetDescription {
            root: self.root.display().to_string(),
            motions: folder(&self.motions),
            left_out: self.left_out.as_deref().map(folder),
            texts: self.texts.as_ref().map(|p| p.display().to_string()),
            splits: (self.splits.iter())
                .map(|(n, ids)| (n.clone(), ids.len()))
                .collect(),
        }
    }
}

/// Where the caption of output clip `clip` goes: `texts/<stem>.txt` in the clip's folder,
/// where `musculo_learn::text::caption` looks beside a clip's `.npz`.
pub fn text_path(out: &Path, clip: &str) -> PathBuf {
    let path = Path::new(clip);
    let folder = path.parent().map_or_else(PathBuf::new, Path::to_path_buf);
    let stem = path
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    out.join(folder).join("texts").join(format!("{stem}.txt"))
}

/// Copies `source` (a caption file) to `target`, atomically.
pub fn copy_text(source: &Path, target: &Path) -> crate::Result<()> {
    let bytes = crate::limits::read_text_file_bytes(source)?;
    if let Some(parent) = target.parent() {
        std::fs::create_dir_all(parent).map_err(|source| Error::Io {
            path: parent.to_path_buf(),
            source,
        })?;
    }
    crate::motion::npy::write_file_atomic(target, &bytes)
}
