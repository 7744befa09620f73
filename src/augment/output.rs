//! What `musculo augment` writes, and how an interrupted or sharded run is put together.
//!
//! Output tree (mirrors the input tree; `<clip>` is the input's path relative to the input
//! root without its extension, `<clip>_v<k>` for variant k ≥ 1):
//! - `<clip>.npz` — the clip's float32 arrays (see [`super::chain`]);
//! - `.musculo/records/<clip>.json` — the clip's record: status, reason, variant, quality
//!   figures and the per-feature sums of `x` for the statistics; written after the `.npz`,
//!   so a record means the clip is complete;
//! - `.musculo/settings.json` — what the clips' outputs depend on besides the clips
//!   ([`RunSettings`]), written by the first run into the folder: every later run there (a
//!   resumed one, another shard) must have the same, so that a folder never mixes results of
//!   different settings;
//! - `manifest.json` and `stats.npz` — written at the end of an unsharded run, or by
//!   `musculo merge` from the records once every shard has finished. Both are computed from
//!   the records in clip order only, so the same clips give the same bytes whatever the
//!   number of threads, shards or interruptions.
//!
//! Every file is written atomically (temporary file, sync, rename), and a clip's files
//! together ([`write_clip_files`]): a clip has all its files under their names, record
//! included, or none. A process killed mid-write leaves hidden temporary files
//! (`.<name>.tmp-…`), which a later run removes once their writer has certainly ended
//! ([`remove_temporaries`]).

use super::chain::{Array, ClipOutput};
pub use super::identity::fnv1a_hex;
use super::layout::BlockRange;
use super::perturb::{PerturbationRanges, Variant};
use super::verdict::{ClipQuality, ClipVerdict, Verdict};
use crate::error::Error;
use crate::motion::npy;
use ndarray::{ArrayD, IxDyn};
use std::path::{Path, PathBuf};

/// Folder of the per-clip records, inside the output folder.
pub const RECORDS: &str = ".musculo/records";
/// Folder of the shard lists, inside the output folder.
pub const SHARDS: &str = ".musculo/shards";
/// The settings of the run the output folder holds ([`RunSettings`]).
pub const SETTINGS: &str = ".musculo/settings.json";

/// The manifest's description of the tensors (same for every clip of a run).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LayoutDescription {
    pub joints: Vec<String>,
    pub muscles: Vec<String>,
    pub coordinates: Vec<String>,
    /// The floating-base coordinates (the columns of `residual`).
    pub floating_base: Vec<String>,
    pub contact_points: Vec<String>,
    pub contact_groups: Vec<String>,
    /// Blocks of `x` with their index ranges.
    pub x: Vec<BlockRange>,
    /// Units of every array.
    pub units: Vec<(String, String)>,
}

/// Settings that decide the results (the manifest's `run`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunDescription {
    pub musculo_version: String,
    pub model: String,
    /// FNV-1a 64-bit hash of the model file's text.
    pub model_hash: String,
    pub variants: usize,
    pub seed: u64,
    pub perturbation: PerturbationRanges,
    pub lowpass_hz: Option<f64>,
    pub scale_to_clip: bool,
    /// Factor on every muscle's maximum isometric force (1 in manifests written before it
    /// existed).
    #[serde(default = "unit_strength")]
    pub muscle_strength: f64,
    /// The HumanML3D / KIT-ML roots the clips came from (none for files and plain folders).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub datasets: Vec<super::dataset::DatasetDescription>,
    /// The model file the clips' bodies are made from: its source, absolute path (none for
    /// the built-in model) and hashes (None in manifests written before it existed). Each
    /// clip's `.npz` records its own body beside it ([`super::identity`]).
    #[serde(default)]
    pub base_model: Option<super::identity::BaseModel>,
}

fn unit_strength() -> f64 {
    1.0
}

/// What a run's outputs depend on besides its clips, kept in the output folder
/// ([`SETTINGS`]) by the first run there and required of every later one ([`claim_settings`]):
/// a resumed run that changed `--lowpass` would otherwise finish a dataset half of which was
/// filtered at one cutoff and half at another, under a manifest that names only the second.
/// The number of variants may differ: variant k of a clip depends on the seed, the clip and k
/// only, so a resumed run may add variants.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunSettings {
    pub run: RunDescription,
    /// The chain's options but those `run` holds and `opensim_files` (IK, contacts, static
    /// optimization, reserves), as Rust's `Debug` prints them.
    pub chain: String,
    /// Whether each clip also has its OpenSim files (`--opensim-files`, or `--report`).
    pub opensim_files: bool,
    /// The skeleton map given for every input (without the path it was read from); None:
    /// each format's built-in map.
    pub map: Option<String>,
    /// How the inputs are read (length unit).
    pub read: String,
    /// An ExternalLoads file for the run's single trial.
    pub external_loads: Option<String>,
    /// Each C3D input's force plates as measured loads.
    pub force_plates: bool,
}

impl RunSettings {
    /// The settings in which `now` differs from `self` (but for the number of variants), each
    /// as `name: value then → value now` where the values are short.
    pub fn differences(&self, now: &RunSettings) -> Vec<String> {
        let (a, b) = (&self.run, &now.run);
        let mut out = Vec::new();
        let mut short = |name: &str, then: String, now: String| {
            if then != now {
                out.push(format!("{name}: {then} then → {now} now"));
            }
        };
        short(
            "musculo version",
            a.musculo_version.clone(),
            b.musculo_version.clone(),
        );
        short(
            "model",
            format!("{} (hash {})", a.model, a.model_hash),
            format!("{} (hash {})", b.model, b.model_hash),
        );
        let hz = |v: Option<f64>| v.map_or("none".to_string(), |v| format!("{v} Hz"));
        short("--lowpass", hz(a.lowpass_hz), hz(b.lowpass_hz));
        short(
            "--muscle-strength",
            a.muscle_strength.to_string(),
            b.muscle_strength.to_string(),
        );
        short(
            "scaling to each clip (--no-scale)",
            a.scale_to_clip.to_string(),
            b.scale_to_clip.to_string(),
        );
        short("--seed", a.seed.to_string(), b.seed.to_string());
        short(
            "perturbation ranges",
            format!("{:?}", a.perturbation),
            format!("{:?}", b.perturbation),
        );
        short(
            "--opensim-files (or --report, which implies it)",
            self.opensim_files.to_string(),
            now.opensim_files.to_string(),
        );
        short(
            "--force-plates",
            self.force_plates.to_string(),
            now.force_plates.to_string(),
        );
        for (name, then, now) in [
            (
                "the chain's other options (IK, contacts, --treadmill, static optimization, \
                 reserves, or --keep-calibration-frames)",
                Some(&self.chain),
                Some(&now.chain),
            ),
            ("--map", self.map.as_ref(), now.map.as_ref()),
            ("--length-unit", Some(&self.read), Some(&now.read)),
            (
                "--external-loads",
                self.external_loads.as_ref(),
                now.external_loads.as_ref(),
            ),
        ] {
            if then != now {
                out.push(name.to_string());
            }
        }
        out
    }
}

/// Writes `settings` into the output folder when it holds none; when it does, requires them
/// to be the same (but for the number of variants), and otherwise refuses the run, naming
/// what differs. Run before any clip is computed.
pub fn claim_settings(out: &Path, settings: &RunSettings) -> crate::Result<()> {
    let path = out.join(SETTINGS);
    match std::fs::read_to_string(&path) {
        Ok(text) => {
            let held: RunSettings = serde_json::from_str(&text).map_err(|e| Error::Motion {
                file: path.display().to_string(),
                location: format!("line {}", e.line()),
                message: format!("not a run's settings: {e}"),
            })?;
            let differences = held.differences(settings);
            if differences.is_empty() {
                Ok(())
            } else {
                Err(Error::invalid(
                    "--out",
                    format!(
                        "{} holds results of a run with other settings ({}): finish that run \
                         with the settings it started with, or use another folder",
                        out.display(),
                        differences.join("; ")
                    ),
                ))
            }
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            create_parent(&path)?;
            let text = serde_json::to_string_pretty(settings)
                .map_err(|e| Error::invalid("settings", e.to_string()))?;
            npy::write_file_atomic(&path, text.as_bytes())
        }
        Err(source) => Err(Error::Io { path, source }),
    }
}

/// One clip's record.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClipRecord {
    /// Output name (relative path without extension).
    pub clip: String,
    /// Input file, relative to the input root.
    pub input: String,
    pub status: ClipStatus,
    /// Why the clip failed.
    pub reason: Option<String>,
    pub variant: Variant,
    pub quality: Option<ClipQuality>,
    pub warnings: Vec<String>,
    /// Σ x and Σ x² per feature of `x` over the clip's frames (f64), for `stats.npz`.
    pub x_sum: Vec<f64>,
    pub x_sum_sq: Vec<f64>,
    /// The dataset split (`train`, `val`, `test`) the clip's id is listed in, for a clip of a
    /// HumanML3D / KIT-ML root with split lists ([`super::dataset`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub split: Option<String>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ClipStatus {
    Ok,
    Failed,
}

/// The whole run's manifest.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Manifest {
    pub run: RunDescription,
    pub layout: Option<LayoutDescription>,
    pub clips: Vec<ClipRecordSummary>,
    pub summary: Summary,
}

/// A clip in the manifest: its record without the sums.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClipRecordSummary {
    pub clip: String,
    pub input: String,
    pub status: ClipStatus,
    pub reason: Option<String>,
    pub variant: Variant,
    pub quality: Option<ClipQuality>,
    pub warnings: Vec<String>,
    /// The clip's dataset split ([`ClipRecord::split`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub split: Option<String>,
}

/// Totals over the clips.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Summary {
    /// Clips the chain computed (whatever their verdict), and clips it could not compute.
    pub clips_ok: usize,
    pub clips_failed: usize,
    pub frames: usize,
    /// The clips with the largest unexplained residual force (× body weight), worst first
    /// (at most 5).
    pub worst_residuals: Vec<(String, f64)>,
    /// Largest reserve share of any clip.
    pub reserve_share_max: f64,
    /// The clips grouped by verdict ([`super::verdict`]); absent from manifests written
    /// before verdicts existed.
    #[serde(default)]
    pub verdicts: VerdictSummary,
}

/// The clips of a run grouped by verdict: the counts of how many clips, and each suspect or
/// failed clip with the one reason that decided it.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VerdictSummary {
    /// All clips (variants included): the "of how many" of the counts.
    pub clips: usize,
    pub ok: usize,
    pub suspect: usize,
    /// Clips judged `failed`, and clips the chain could not compute.
    pub failed: usize,
    /// Clips whose record holds no verdict (recorded before verdicts existed).
    pub unjudged: usize,
    /// (clip, reason), in clip order.
    pub suspect_clips: Vec<(String, String)>,
    pub failed_clips: Vec<(String, String)>,
}

impl VerdictSummary {
    /// Counts one clip with its verdict (None: unjudged).
    pub fn add(&mut self, clip: &str, verdict: Option<&ClipVerdict>) {
        self.clips += 1;
        let Some(v) = verdict else {
            self.unjudged += 1;
            return;
        };
        let reason = || (clip.to_string(), v.reason.clone().unwrap_or_default());
        match v.verdict {
            Verdict::Ok => self.ok += 1,
            Verdict::Suspect => {
                self.suspect += 1;
                self.suspect_clips.push(reason());
            }
            Verdict::Failed => {
                self.failed += 1;
                self.failed_clips.push(reason());
            }
        }
    }

    /// The number of clips at `level` or worse (`suspect`: suspect and failed).
    pub fn at_least(&self, level: Verdict) -> usize {
        match level {
            Verdict::Ok => self.clips - self.unjudged,
            Verdict::Suspect => self.suspect + self.failed,
            Verdict::Failed => self.failed,
        }
    }
}

/// The verdict of a clip from its record's fields: its quality's verdict when the chain
/// computed it, `failed` with the error when it could not (None for a computed clip recorded
/// before verdicts existed).
pub fn clip_verdict(
    status: ClipStatus,
    reason: Option<&str>,
    quality: Option<&ClipQuality>,
) -> Option<ClipVerdict> {
    match (status, quality) {
        (ClipStatus::Ok, Some(q)) => q.verdict.clone(),
        _ => Some(ClipVerdict::not_computed(
            reason.unwrap_or("no quality figures"),
        )),
    }
}

/// Refuses a clip name that would put its files outside the output folder: every file of a
/// clip is `out/<name>…`, so the name must be a relative, `/`-separated path of plain
/// components (no empty one, no `.` or `..`, no root or drive). `source` names where the
/// name came from in the error.
pub fn check_clip_name(name: &str, source: &str) -> crate::Result<()> {
    let plain = !name.is_empty()
        && name
            .split(['/', '\\'])
            .all(|c| !c.is_empty() && c != "." && c != "..")
        && Path::new(name)
            .components()
            .all(|c| matches!(c, std::path::Component::Normal(_)));
    if plain {
        Ok(())
    } else {
        Err(Error::invalid(
            "clip name",
            format!(
                "{source}: clip name \"{name}\" is not a relative path inside the output folder \
                 (empty, absolute, or with a `.`, `..` or empty component)"
            ),
        ))
    }
}

/// Checks that the `.npz` of a clip recorded ok is the archive its record describes: it
/// exists, opens as a zip archive, and holds a `time` array of the record's frame count and,
/// when the record has feature sums, an `x` array. Cheap: the archive's directory and `time`
/// are read, not the other arrays. The error says what is wrong.
pub fn check_clip_output(out: &Path, record: &ClipRecord) -> crate::Result<()> {
    let path = npz_path(out, &record.clip);
    let frames = record.quality.as_ref().map_or(0, |q| q.frames);
    let members = npy::read_npz_some_as_f64(&path, &["time"])?;
    let bad = |message: String| Error::Motion {
        file: path.display().to_string(),
        location: "archive".to_string(),
        message,
    };
    match members.iter().find(|(k, _)| k == "time") {
        Some((_, Some(time))) if time.ndim() == 1 && time.len() == frames => {}
        Some((_, Some(time))) => {
            return Err(bad(format!(
                "`time` has shape {}; the clip's record says {frames} frames",
                npy::shape_text(time.shape())
            )));
        }
        _ => return Err(bad("has no `time` array".to_string())),
    }
    if !record.x_sum.is_empty() && !members.iter().any(|(k, _)| k == "x") {
        return Err(bad("has no `x` array".to_string()));
    }
    Ok(())
}

/// The `.npz` of a clip.
pub fn npz_path(out: &Path, clip: &str) -> PathBuf {
    out.join(format!("{clip}.npz"))
}

/// The record of a clip.
pub fn record_path(out: &Path, clip: &str) -> PathBuf {
    out.join(RECORDS).join(format!("{clip}.json"))
}

fn create_parent(path: &Path) -> crate::Result<()> {
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).map_err(|source| Error::Io {
            path: parent.to_path_buf(),
            source,
        })?;
    }
    Ok(())
}

/// Writes a clip's arrays as `<clip>.npz` (uncompressed, so equal arrays give equal bytes),
/// without a model identity ([`write_clip_output`] writes one).
pub fn write_clip(out: &Path, clip: &str, arrays: &[Array]) -> crate::Result<()> {
    write_clip_with_identity(out, clip, arrays, None)
}

/// Writes a clip's arrays and its model identity ([`super::identity`], the text member
/// `model_identity`) as `<clip>.npz`.
pub fn write_clip_output(out: &Path, clip: &str, output: &ClipOutput) -> crate::Result<()> {
    write_clip_with_identity(out, clip, &output.arrays, Some(&output.identity.to_json()))
}

/// [`write_clip`] with the clip's model identity as JSON text.
pub fn write_clip_with_identity(
    out: &Path,
    clip: &str,
    arrays: &[Array],
    identity: Option<&str>,
) -> crate::Result<()> {
    let path = npz_path(out, clip);
    create_parent(&path)?;
    let owned = owned_arrays(arrays)?;
    let views: Vec<(&str, ndarray::ArrayViewD<'_, f32>)> =
        owned.iter().map(|(n, a)| (*n, a.view())).collect();
    let texts: Vec<(&str, &str)> = identity
        .map(|t| (super::identity::MEMBER, t))
        .into_iter()
        .collect();
    npy::write_npz_with_texts(&path, &views, &texts, false)
}

/// Writes a clip's OpenSim files beside its `.npz`: `<clip><suffix>` for each table, and
/// `<clip>.osim` for the model when given.
pub fn write_opensim_files(
    out: &Path,
    clip: &str,
    tables: &[(&str, crate::io::Table)],
    model_xml: Option<&str>,
) -> crate::Result<()> {
    for (suffix, table) in tables {
        let path = out.join(format!("{clip}{suffix}"));
        npy::write_file_atomic(&path, table.to_file_string()?.as_bytes())?;
    }
    if let Some(xml) = model_xml {
        npy::write_file_atomic(&out.join(format!("{clip}.osim")), xml.as_bytes())?;
    }
    Ok(())
}

/// Writes a clip's record (after its `.npz`).
pub fn write_record(out: &Path, record: &ClipRecord) -> crate::Result<()> {
    let path = record_path(out, &record.clip);
    create_parent(&path)?;
    let text = serde_json::to_string(record)
        .map_err(|e| Error::invalid("record", format!("{}: {e}", record.clip)))?;
    // JSON has no NaN or infinity (serde writes null), and a record that does not read back
    // makes every later `--resume` and `merge` of the folder fail: refuse it here instead.
    if let Err(e) = serde_json::from_str::<ClipRecord>(&text) {
        return Err(Error::invalid(
            "record",
            format!(
                "{}: the clip's record holds a number that is not finite (written as null, \
                 column {} of the record: {e}); it would not read back, so it is not written",
                record.clip,
                e.column()
            ),
        ));
    }
    npy::write_file_atomic(&path, text.as_bytes())
}

/// Reads a clip's record; None when it does not exist (the clip is not finished).
pub fn read_record(out: &Path, clip: &str) -> crate::Result<Option<ClipRecord>> {
    let path = record_path(out, clip);
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(source) => return Err(Error::Io { path, source }),
    };
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|e| Error::Motion {
            file: path.display().to_string(),
            location: format!("line {}", e.line()),
            message: format!("not a clip record: {e}"),
        })
}

/// The files a clip's run may write, as paths relative to the output folder: its `.npz`, its
/// record, and with OpenSim files its tables (`suffixes`) and model.
pub fn clip_files(clip: &str, suffixes: &[&str]) -> Vec<String> {
    let mut files = vec![
        format!("{clip}.npz"),
        format!("{RECORDS}/{clip}.json"),
        format!("{clip}.osim"),
    ];
    files.extend(suffixes.iter().map(|s| format!("{clip}{s}")));
    files
}

/// Removes the temporary files that interrupted runs left in `out` (recursively) for the
/// targets `owns` accepts (paths relative to `out`, `/`-separated), and finishes the commits
/// they left journaled (a clip whose files were all written but not all named); returns how
/// many temporaries were removed. A journal that was still being written when its run was
/// killed is removed whoever owns the clip: its commit never began, so the clip's files are
/// all still temporaries.
///
/// Only a file whose writer has certainly ended is touched
/// ([`npy::abandoned_temporary_target`]: on this host and in this PID namespace, a process
/// that is gone or a zombie; elsewhere, a lease that has run out): shards of one run write
/// into the same folder at the same time, from other hosts and namespaces, and each keeps
/// to its own clips' files.
pub fn remove_temporaries(out: &Path, owns: impl Fn(&str) -> bool) -> crate::Result<usize> {
    let mut removed = 0;
    let mut stack = vec![(out.to_path_buf(), String::new())];
    while let Some((dir, relative)) = stack.pop() {
        let entries = match std::fs::read_dir(&dir) {
            Ok(e) => e,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            Err(source) => return Err(Error::Io { path: dir, source }),
        };
        let mut journals = Vec::new();
        let mut temporaries = Vec::new();
        for entry in entries {
            let entry = entry.map_err(|source| Error::Io {
                path: dir.clone(),
                source,
            })?;
            let path = entry.path();
            let name = entry.file_name().to_string_lossy().into_owned();
            if path.is_dir() {
                stack.push((path, format!("{relative}{name}/")));
            } else if crate::io::output::is_abandoned_journal(&dir, &name) {
                journals.push(path);
            } else if let Some(target) = npy::abandoned_temporary_target(&dir, &name)
                && (crate::io::output::is_journal_name(target)
                    || owns(&format!("{relative}{target}")))
            {
                temporaries.push(path);
            }
        }
        // a journal names complete files: they are given their names, not removed
        for journal in journals {
            crate::io::output::finish_journal(&journal);
        }
        for path in temporaries {
            match std::fs::remove_file(&path) {
                Ok(()) => removed += 1,
                // another run tidied it first, or a journal named it
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(source) => return Err(Error::Io { path, source }),
            }
        }
    }
    Ok(removed)
}

/// Writes every file of a clip — its caption copy, `.npz`, OpenSim files and model (when it
/// was computed) and its record — as one [`crate::io::output::OutputSet`]: all are written
/// to temporaries first and named together, so a clip interrupted by a full disk or a kill
/// leaves none of its files under their names (a run killed during the renames leaves a
/// journal that the next run there finishes).
pub fn write_clip_files(
    out: &Path,
    record: &ClipRecord,
    output: Option<&ClipOutput>,
    caption: Option<&Path>,
) -> crate::Result<()> {
    let mut set = crate::io::output::OutputSet::new_in_tidied_folders();
    if let Some(o) = output {
        if let Some(text) = caption {
            let bytes = crate::limits::read_text_file_bytes(text)?;
            set.add(&super::dataset::text_path(out, &record.clip), &bytes)?;
        }
        set.add(&npz_path(out, &record.clip), &clip_npz_bytes(o)?)?;
        for (suffix, table) in &o.tables {
            let path = out.join(format!("{}{suffix}", record.clip));
            set.add(&path, table.to_file_string()?.as_bytes())?;
        }
        if let Some(xml) = &o.model_xml {
            set.add(&out.join(format!("{}.osim", record.clip)), xml.as_bytes())?;
        }
    }
    let text = serde_json::to_string(record)
        .map_err(|e| Error::invalid("record", format!("{}: {e}", record.clip)))?;
    set.add(&record_path(out, &record.clip), text.as_bytes())?;
    set.commit()?;
    Ok(())
}

/// The bytes of a clip's `.npz` ([`write_clip_output`]).
fn clip_npz_bytes(output: &ClipOutput) -> crate::Result<Vec<u8>> {
    let owned = owned_arrays(&output.arrays)?;
    let views: Vec<(&str, ndarray::ArrayViewD<'_, f32>)> =
        owned.iter().map(|(n, a)| (*n, a.view())).collect();
    let identity = output.identity.to_json();
    npy::npz_bytes(
        &views,
        &[(super::identity::MEMBER, identity.as_str())],
        false,
    )
}

/// The arrays as ndarray arrays, named.
fn owned_arrays(arrays: &[Array]) -> crate::Result<Vec<(&str, ArrayD<f32>)>> {
    arrays
        .iter()
        .map(|a| {
            ArrayD::from_shape_vec(IxDyn(&a.shape), a.values.clone())
                .map(|arr| (a.name, arr))
                .map_err(|e| Error::invalid("arrays", format!("{}: {e}", a.name)))
        })
        .collect()
}

/// Σ x and Σ x² per feature over the frames of the `x` array (f64 accumulation).
pub fn feature_sums(arrays: &[Array]) -> (Vec<f64>, Vec<f64>) {
    let Some(x) = arrays.iter().find(|a| a.name == "x") else {
        return (Vec::new(), Vec::new());
    };
    let width = x.shape[1];
    let mut sum = vec![0.0; width];
    let mut sq = vec![0.0; width];
    for row in x.values.chunks(width) {
        for ((s, q), &v) in sum.iter_mut().zip(&mut sq).zip(row) {
            let v = v as f64;
            *s += v;
            *q += v * v;
        }
    }
    (sum, sq)
}

/// Builds the manifest and `stats.npz` from the records of `clips` (in this order), read
/// from `out` one at a time (memory does not grow with the dataset), and writes both. A clip
/// without a record is an error.
pub fn write_manifest(
    out: &Path,
    run: &RunDescription,
    layout: Option<&LayoutDescription>,
    clips: &[String],
) -> crate::Result<Manifest> {
    let mut summary = Summary::default();
    let width = layout.map_or(0, |l| l.x.last().map_or(0, |b| b.end));
    let (mut sum, mut sq, mut count) = (vec![0.0; width], vec![0.0; width], 0usize);
    let mut residuals = Vec::new();
    let mut verdicts = VerdictSummary::default();
    let mut entries = Vec::with_capacity(clips.len());
    for name in clips {
        let r = read_record(out, name)?.ok_or_else(|| {
            Error::invalid(
                "OUT",
                format!(
                    "clip {name} has no record in {}: it did not finish",
                    out.display()
                ),
            )
        })?;
        match (r.status, &r.quality) {
            (ClipStatus::Ok, Some(q)) => {
                summary.clips_ok += 1;
                summary.frames += q.frames;
                summary.reserve_share_max = summary.reserve_share_max.max(q.reserve_share);
                residuals.push((r.clip.clone(), q.residual_force_max_bw));
                if r.x_sum.len() != width {
                    return Err(Error::invalid(
                        "records",
                        format!(
                            "clip {} has {} features, others {width}: records of different runs \
                             are mixed in {}",
                            r.clip,
                            r.x_sum.len(),
                            out.display()
                        ),
                    ));
                }
                for i in 0..width {
                    sum[i] += r.x_sum[i];
                    sq[i] += r.x_sum_sq[i];
                }
                count += q.frames;
            }
            _ => summary.clips_failed += 1,
        }
        let verdict = clip_verdict(r.status, r.reason.as_deref(), r.quality.as_ref());
        verdicts.add(&r.clip, verdict.as_ref());
        entries.push(ClipRecordSummary {
            clip: r.clip,
            input: r.input,
            status: r.status,
            reason: r.reason,
            variant: r.variant,
            quality: r.quality,
            warnings: r.warnings,
            split: r.split,
        });
    }
    residuals.sort_by(|a, b| b.1.total_cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
    residuals.truncate(5);
    summary.worst_residuals = residuals;
    summary.verdicts = verdicts;
    // mean and (population) standard deviation per feature, as HumanML3D's Mean/Std
    let n = count.max(1) as f64;
    let mean: Vec<f32> = sum.iter().map(|s| (s / n) as f32).collect();
    let std: Vec<f32> = sum
        .iter()
        .zip(&sq)
        .map(|(s, q)| ((q / n - (s / n) * (s / n)).max(0.0)).sqrt() as f32)
        .collect();
    let stats = [
        (
            "mean",
            ArrayD::from_shape_vec(IxDyn(&[width]), mean).expect("length"),
        ),
        (
            "std",
            ArrayD::from_shape_vec(IxDyn(&[width]), std).expect("length"),
        ),
    ];
    let views: Vec<_> = stats.iter().map(|(n, a)| (*n, a.view())).collect();
    npy::write_npz(&out.join("stats.npz"), &views, false)?;
    let manifest = Manifest {
        run: run.clone(),
        layout: layout.cloned(),
        clips: entries,
        summary,
    };
    let text = serde_json::to_string_pretty(&manifest)
        .map_err(|e| Error::invalid("manifest", e.to_string()))?;
    npy::write_file_atomic(&out.join("manifest.json"), text.as_bytes())?;
    Ok(manifest)
}
