//! Running the chain over a dataset: listing the clips, the deterministic shard split, resume,
//! clips in parallel, a failing clip recorded with its reason while the run goes on.
//!
//! The work list is every (clip, variant) pair, clips in the byte order of their output
//! names. Shard k of N (0 ≤ k < N) takes the clips whose position in that order is ≡ k
//! (mod N), all variants of a clip in the same shard — a split that depends only on the
//! list of inputs, so any scheduler (a Slurm array, a Kubernetes Indexed Job, Dask, Ray) can
//! run the shards anywhere and `musculo merge` puts them together.

use super::chain::{Chain, ChainOptions, ClipOutput, MeasuredLoads, OPENSIM_SUFFIXES};
use super::dataset::{self, DatasetRoot};
use super::output::{
    self, ClipRecord, ClipStatus, LayoutDescription, Manifest, RunDescription, SHARDS,
};
use super::perturb::{PerturbationRanges, Variant};
use crate::error::Error;
use crate::motion::skeleton::SkeletonMap;
use crate::motion::{self, Format, Motion, ReadOptions};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Where a clip comes from.
#[derive(Clone, Debug)]
pub enum ClipSource {
    /// A motion file in one of the formats of [`Format`].
    File { path: PathBuf, format: Format },
    /// A motion already in memory (the demo clips), matched to the model's markers by name.
    Motion(Box<Motion>),
}

/// One input clip.
#[derive(Clone, Debug)]
pub struct ClipInput {
    /// Output name: the path relative to the input root without extension, `/`-separated.
    pub name: String,
    /// The input as the manifest shows it.
    pub input: String,
    pub source: ClipSource,
}

/// Options of a run.
#[derive(Clone, Debug)]
pub struct RunOptions {
    pub out: PathBuf,
    /// Variants per clip (≥ 1; variant 0 is the clip as recorded).
    pub variants: usize,
    pub seed: u64,
    pub perturbation: PerturbationRanges,
    /// (k, N): run shard k of N.
    pub shard: Option<(usize, usize)>,
    /// Skip clips whose record exists.
    pub resume: bool,
    /// Skeleton map for every input (None: each format's built-in map).
    pub map: Option<SkeletonMap>,
    pub read: ReadOptions,
    /// Measured ground reactions (an OpenSim ExternalLoads file) for a run of one clip, used
    /// instead of the contact estimate (see [`Chain::run_with_loads`]).
    pub external_loads: Option<PathBuf>,
    /// Use each C3D input's own force plates as measured ground reactions.
    pub force_plates: bool,
    /// The HumanML3D / KIT-ML roots the clips came from ([`list_dataset`]): their captions
    /// are copied beside the outputs, their splits go into the records, their layout into
    /// the run's description.
    pub datasets: Vec<DatasetRoot>,
}

impl RunOptions {
    /// One variant per clip, seed 0, the default perturbation ranges, no shard, no resume,
    /// each format's built-in map, default reading, contacts estimated.
    pub fn new(out: impl Into<PathBuf>) -> RunOptions {
        RunOptions {
            out: out.into(),
            variants: 1,
            seed: 0,
            perturbation: PerturbationRanges::default(),
            shard: None,
            resume: false,
            map: None,
            read: ReadOptions::default(),
            external_loads: None,
            force_plates: false,
            datasets: Vec::new(),
        }
    }
}

/// Progress after each clip.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    pub done: usize,
    pub total: usize,
    pub failed: usize,
    pub skipped: usize,
    pub frames: usize,
}

/// What a run did.
#[derive(Clone, Debug)]
pub struct RunReport {
    /// Records of this run's items (computed or resumed), in work-list order, without the
    /// feature sums (those stay in the record files).
    pub records: Vec<ClipRecord>,
    /// The manifest, when this run wrote it (unsharded runs).
    pub manifest: Option<Manifest>,
    pub computed: usize,
    pub resumed: usize,
    pub temporaries_removed: usize,
}

impl RunReport {
    /// Frames of the clips that produced output (computed or resumed).
    pub fn frames(&self) -> usize {
        self.records
            .iter()
            .filter_map(|r| r.quality.as_ref())
            .map(|q| q.frames)
            .sum()
    }
}

/// The clips under `inputs`: files as given, folders searched recursively for the motion
/// formats (`.npy`, `.bvh`, `.c3d`, `.trc`; a dataset's `Mean.npy`/`Std.npy` are not clips),
/// names relative to the folder. Sorted by name; two inputs with one output name are an
/// error. A HumanML3D / KIT-ML root gives the clips of one of its motion folders
/// ([`dataset`]); [`list_dataset`] also returns the roots.
pub fn list_inputs(inputs: &[PathBuf], format: Option<Format>) -> crate::Result<Vec<ClipInput>> {
    Ok(list_dataset(inputs, format)?.0)
}

/// [`list_inputs`], and the HumanML3D / KIT-ML roots among the folders (for
/// [`RunOptions::datasets`]).
pub fn list_dataset(
    inputs: &[PathBuf],
    format: Option<Format>,
) -> crate::Result<(Vec<ClipInput>, Vec<DatasetRoot>)> {
    let mut clips = Vec::new();
    let mut roots = Vec::new();
    for input in inputs {
        let meta = std::fs::metadata(input).map_err(|source| Error::Io {
            path: input.clone(),
            source,
        })?;
        if meta.is_dir() {
            let root = DatasetRoot::find(input)?;
            let folder = root
                .as_ref()
                .map_or(input.as_path(), |r| r.motions.as_path());
            let files = crate::io::folder::files_below(folder, false)?;
            roots.extend(root.clone());
            for path in files {
                let ext = path
                    .extension()
                    .map(|e| e.to_string_lossy().to_ascii_lowercase())
                    .unwrap_or_default();
                if !matches!(ext.as_str(), "npy" | "bvh" | "c3d" | "trc")
                    || dataset::is_statistics(&path)
                {
                    continue;
                }
                let rel = path
                    .strip_prefix(folder)
                    .unwrap_or(&path)
                    .with_extension("");
                let name = rel
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy())
                    .collect::<Vec<_>>()
                    .join("/");
                let format = match format {
                    Some(f) => f,
                    None => Format::detect(&path)?,
                };
                clips.push(ClipInput {
                    name,
                    input: path.display().to_string(),
                    source: ClipSource::File { path, format },
                });
            }
        } else {
            let name = input
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let format = match format {
                Some(f) => f,
                None => Format::detect(input)?,
            };
            clips.push(ClipInput {
                name,
                input: input.display().to_string(),
                source: ClipSource::File {
                    path: input.clone(),
                    format,
                },
            });
        }
    }
    clips.sort_by(|a, b| a.name.cmp(&b.name));
    if let Some(w) = clips.windows(2).find(|w| w[0].name == w[1].name) {
        return Err(Error::invalid(
            "--input",
            format!(
                "{} and {} would both be written as {}.npz",
                w[0].input, w[1].input, w[0].name
            ),
        ));
    }
    if clips.is_empty() {
        return Err(Error::invalid(
            "--input",
            "no motion file (.npy, .bvh, .c3d, .trc) found",
        ));
    }
    Ok((clips, roots))
}

/// The dataset root `clip` was read from and its id there.
fn dataset_of<'a>(options: &'a RunOptions, clip: &ClipInput) -> Option<(&'a DatasetRoot, String)> {
    let ClipSource::File { path, .. } = &clip.source else {
        return None;
    };
    (options.datasets.iter()).find_map(|d| d.id_of(path).map(|id| (d, id)))
}

/// The output name of variant `v` of clip `name`.
pub fn variant_name(name: &str, v: usize) -> String {
    if v == 0 {
        name.to_string()
    } else {
        format!("{name}_v{v}")
    }
}

/// Every output name of the dataset (all clips, not only a shard's, with their variants) is
/// its own and none is the statistics' `stats`: clip `a_v1` and variant 1 of clip `a` would
/// write the same files (which of the two survived depended on the threads), and a clip named
/// `stats` was overwritten by the dataset's `stats.npz` at the end of the run.
fn check_output_names(clips: &[ClipInput], variants: usize) -> crate::Result<()> {
    let mut seen: std::collections::HashMap<String, (&ClipInput, usize)> =
        std::collections::HashMap::with_capacity(clips.len() * variants);
    let describe = |c: &ClipInput, v: usize| {
        if v == 0 {
            c.input.clone()
        } else {
            format!("variant {v} of {}", c.input)
        }
    };
    for c in clips {
        for v in 0..variants {
            let name = variant_name(&c.name, v);
            if name == "stats" {
                return Err(Error::invalid(
                    "--input",
                    format!(
                        "{} would be written as stats.npz, the file of the dataset's \
                         statistics: rename it",
                        describe(c, v)
                    ),
                ));
            }
            if let Some((other, w)) = seen.insert(name.clone(), (c, v)) {
                return Err(Error::invalid(
                    "--input",
                    format!(
                        "{} and {} would both be written as {name}.npz: rename one, or run \
                         them into separate output folders",
                        describe(other, w),
                        describe(c, v)
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// The clips of shard k of N (all clips without a shard).
pub fn shard_clips(clips: &[ClipInput], shard: Option<(usize, usize)>) -> Vec<&ClipInput> {
    clips
        .iter()
        .enumerate()
        .filter(|(i, _)| shard.is_none_or(|(k, n)| i % n == k))
        .map(|(_, c)| c)
        .collect()
}

/// The most variants per clip: every variant is a full run of the chain and a set of output
/// files, and the list of work items is allocated up front.
pub const MAX_VARIANTS: usize = 100_000;

/// Runs `chain` on `clips` (the whole dataset's list: the shard is taken from it), in
/// parallel on the current rayon pool. Unsharded, writes the manifest and statistics at the
/// end; sharded, writes the shard's list for `musculo merge`.
pub fn run(
    chain: &Chain,
    layout: &LayoutDescription,
    clips: &[ClipInput],
    options: &RunOptions,
    progress: &(dyn Fn(Progress) + Sync),
) -> crate::Result<RunReport> {
    check_run_options(clips, options)?;
    std::fs::create_dir_all(&options.out).map_err(|source| Error::Io {
        path: options.out.clone(),
        source,
    })?;
    let mine = shard_clips(clips, options.shard);
    let items: Vec<(&ClipInput, usize)> = mine
        .iter()
        .flat_map(|c| (0..options.variants).map(move |v| (*c, v)))
        .collect();
    let temporaries_removed = remove_own_temporaries(options, &items)?;
    if !options.resume {
        refuse_earlier_results(options, &items)?;
    }
    let settings = run_settings(chain, options);
    output::claim_settings(&options.out, &settings)?;
    let tally = Tally::new(items.len(), progress);
    let results = compute_and_write(chain, options, &items, &tally)?;
    let mut records = Vec::with_capacity(results.len());
    let (mut computed, mut resumed) = (0, 0);
    for r in results {
        let (record, was_resumed) = r?;
        if was_resumed {
            resumed += 1;
        } else {
            computed += 1;
        }
        records.push(record);
    }
    let manifest = write_run_index(clips, options, &settings, layout, &records)?;
    Ok(RunReport {
        records,
        manifest,
        computed,
        resumed,
        temporaries_removed,
    })
}

/// The run's options checked before anything is written: variants, shard, perturbation
/// ranges, clip and output names, measured loads (one trial, no variants, the file
/// present) and an output path that is not a file.
fn check_run_options(clips: &[ClipInput], options: &RunOptions) -> crate::Result<()> {
    if !(1..=MAX_VARIANTS).contains(&options.variants) {
        return Err(Error::invalid(
            "--variants",
            format!("{}: must be from 1 to {MAX_VARIANTS}", options.variants),
        ));
    }
    if let Some((k, n)) = options.shard
        && (n == 0 || k >= n)
    {
        return Err(Error::invalid(
            "--shard",
            format!("{k}/{n}: K must satisfy 0 ≤ K < N"),
        ));
    }
    options.perturbation.validate()?;
    // the names come from the input tree (plain by construction) or from a library caller
    for c in clips {
        output::check_clip_name(&c.name, &c.input)?;
    }
    check_output_names(clips, options.variants)?;
    if options.force_plates && options.variants != 1 {
        return Err(Error::invalid(
            "--force-plates",
            "measured loads belong to the recorded trial: no variants with --force-plates",
        ));
    }
    if options.external_loads.is_some() && (clips.len() != 1 || options.variants != 1) {
        return Err(Error::invalid(
            "--external-loads",
            format!(
                "measured loads belong to one trial: give one input and no variants (got {} \
                 input(s), {} variant(s))",
                clips.len(),
                options.variants
            ),
        ));
    }
    // a missing loads file is the run's error, before an output folder is made
    if let Some(p) = &options.external_loads {
        std::fs::metadata(p).map_err(|source| Error::Io {
            path: p.clone(),
            source,
        })?;
    }
    if options.out.exists() && !options.out.is_dir() {
        return Err(Error::invalid(
            "--out",
            format!(
                "{} is a file, not a folder: give the folder to write the clips into",
                options.out.display()
            ),
        ));
    }
    Ok(())
}

/// Removes stale temporaries of this run's own files only (other shards write beside it);
/// returns how many were removed.
fn remove_own_temporaries(
    options: &RunOptions,
    items: &[(&ClipInput, usize)],
) -> crate::Result<usize> {
    let mut own: std::collections::HashSet<String> = items
        .iter()
        .flat_map(|(c, v)| output::clip_files(&variant_name(&c.name, *v), &OPENSIM_SUFFIXES))
        .collect();
    own.extend(items.iter().map(|(c, v)| {
        let text = dataset::text_path(Path::new(""), &variant_name(&c.name, *v));
        text.to_string_lossy().replace('\\', "/")
    }));
    own.insert(output::SETTINGS.to_string());
    match options.shard {
        None => own.extend(["manifest.json".to_string(), "stats.npz".to_string()]),
        Some((k, n)) => {
            own.insert(format!("{SHARDS}/{k}-of-{n}.json"));
        }
    }
    output::remove_temporaries(&options.out, |f| own.contains(f))
}

/// Without --resume, a folder that already holds a record of one of the run's clips is
/// refused.
fn refuse_earlier_results(
    options: &RunOptions,
    items: &[(&ClipInput, usize)],
) -> crate::Result<()> {
    if let Some((c, v)) = items
        .iter()
        .find(|(c, v)| output::record_path(&options.out, &variant_name(&c.name, *v)).exists())
    {
        return Err(Error::invalid(
            "--out",
            format!(
                "{} already holds results (e.g. {}); use --resume to finish that run, or \
                 another folder",
                options.out.display(),
                variant_name(&c.name, *v)
            ),
        ));
    }
    Ok(())
}

/// The run's progress, counted by workers and writers alike and reported after each clip.
struct Tally<'a> {
    total: usize,
    done: AtomicUsize,
    failed: AtomicUsize,
    skipped: AtomicUsize,
    frames: AtomicUsize,
    progress: &'a (dyn Fn(Progress) + Sync),
}

impl<'a> Tally<'a> {
    fn new(total: usize, progress: &'a (dyn Fn(Progress) + Sync)) -> Tally<'a> {
        Tally {
            total,
            done: AtomicUsize::new(0),
            failed: AtomicUsize::new(0),
            skipped: AtomicUsize::new(0),
            frames: AtomicUsize::new(0),
            progress,
        }
    }

    /// One clip finished: `f` frames, failed or skipped (resumed).
    fn report(&self, f: usize, fail: bool, skip: bool) {
        self.frames.fetch_add(f, Ordering::Relaxed);
        if fail {
            self.failed.fetch_add(1, Ordering::Relaxed);
        }
        if skip {
            self.skipped.fetch_add(1, Ordering::Relaxed);
        }
        let d = self.done.fetch_add(1, Ordering::Relaxed) + 1;
        (self.progress)(Progress {
            done: d,
            total: self.total,
            failed: self.failed.load(Ordering::Relaxed),
            skipped: self.skipped.load(Ordering::Relaxed),
            frames: self.frames.load(Ordering::Relaxed),
        });
    }
}

/// Computes the work items in parallel and writes each clip's files on writer threads;
/// returns each item's summary record and whether it was resumed.
///
/// Writing a clip (its `.npz`, OpenSim files and record, each synced to disk before it is
/// renamed into place) waits mostly on the disk: it is handed to writer threads, one per
/// worker, so the workers go on computing. A bounded queue (one clip per worker) keeps
/// memory independent of the dataset; a clip's files, record included, are named
/// together, so a run killed before that recomputes the clip on --resume.
fn compute_and_write(
    chain: &Chain,
    options: &RunOptions,
    items: &[(&ClipInput, usize)],
    tally: &Tally,
) -> crate::Result<Vec<crate::Result<(ClipRecord, bool)>>> {
    let writers = rayon::current_num_threads().max(1);
    let (queue, jobs) = std::sync::mpsc::sync_channel::<WriteJob>(writers);
    let jobs = std::sync::Mutex::new(jobs);
    let write_error: std::sync::Mutex<Option<Error>> = std::sync::Mutex::new(None);
    let results: Vec<crate::Result<(ClipRecord, bool)>> = std::thread::scope(|scope| {
        for _ in 0..writers {
            scope.spawn(|| write_queued(&jobs, &write_error, &options.out, tally));
        }
        let results = items
            .par_iter()
            .map(|(clip, v)| compute_item(chain, options, tally, &queue, clip, *v))
            .collect();
        // closing the queue ends the writers once it is empty; the scope waits for them
        drop(queue);
        results
    });
    if let Some(e) = write_error.into_inner().unwrap_or_else(|e| e.into_inner()) {
        return Err(e);
    }
    Ok(results)
}

/// A writer thread: writes the queued clips until the queue closes, keeping the first
/// error in `write_error`.
fn write_queued(
    jobs: &std::sync::Mutex<std::sync::mpsc::Receiver<WriteJob>>,
    write_error: &std::sync::Mutex<Option<Error>>,
    out: &Path,
    tally: &Tally,
) {
    let write = |job: WriteJob| -> crate::Result<()> {
        output::write_clip_files(out, &job.record, job.output.as_ref(), job.text.as_deref())?;
        let f = job.record.quality.as_ref().map_or(0, |q| q.frames);
        tally.report(f, job.record.status == ClipStatus::Failed, false);
        Ok(())
    };
    loop {
        // a poisoned lock still holds the receiver (nothing panics while held)
        let job = match jobs.lock().unwrap_or_else(|e| e.into_inner()).recv() {
            Ok(job) => job,
            Err(_) => break, // queue closed: every clip handed over
        };
        // A panic here (none is expected) must not leave the workers blocked on
        // a full queue: it ends this clip's write as an error and the loop goes on.
        let written = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| write(job)))
            .unwrap_or_else(|_| Err(Error::invalid("augment", "writing a clip's files panicked")));
        if let Err(e) = written {
            let mut first = write_error.lock().unwrap_or_else(|e| e.into_inner());
            first.get_or_insert(e);
        }
    }
}

/// One work item (clip, variant): its record read back on --resume when it succeeded
/// before, otherwise the chain run on it and its files queued for the writers. Returns the
/// record without its sums, and whether it was resumed.
fn compute_item(
    chain: &Chain,
    options: &RunOptions,
    tally: &Tally,
    queue: &std::sync::mpsc::SyncSender<WriteJob>,
    clip: &ClipInput,
    v: usize,
) -> crate::Result<(ClipRecord, bool)> {
    let name = variant_name(&clip.name, v);
    if options.resume
        && let Some(record) = output::read_record(&options.out, &name)?
        && record.status == ClipStatus::Ok
    {
        let f = record.quality.as_ref().map_or(0, |q| q.frames);
        tally.report(f, false, true);
        return Ok((without_sums(record), true));
    }
    let variant = Variant::draw(options.seed, &clip.name, v, &options.perturbation);
    let source = dataset_of(options, clip);
    let split = source.as_ref().and_then(|(d, id)| d.split_of(id));
    let text = source.as_ref().and_then(|(d, id)| d.text_of(id));
    let (record, output) = match process(chain, clip, &variant, options) {
        Ok(mut out) => {
            let (x_sum, x_sum_sq) = output::feature_sums(&out.arrays);
            let record = ClipRecord {
                clip: name,
                input: clip.input.clone(),
                status: ClipStatus::Ok,
                reason: None,
                variant,
                quality: Some(out.quality.clone()),
                warnings: std::mem::take(&mut out.warnings),
                x_sum,
                x_sum_sq,
                split,
            };
            (record, Some(out))
        }
        Err(e) => (
            ClipRecord {
                clip: name,
                input: clip.input.clone(),
                status: ClipStatus::Failed,
                reason: Some(e.to_string()),
                variant,
                quality: None,
                warnings: Vec::new(),
                x_sum: Vec::new(),
                x_sum_sq: Vec::new(),
                split,
            },
            None,
        ),
    };
    let summary = without_sums(record.clone());
    queue
        .send(WriteJob {
            record,
            output,
            text,
        })
        .map_err(|_| {
            Error::invalid("augment", "the writer threads stopped before the run ended")
        })?;
    Ok((summary, false))
}

/// The run's index: unsharded, the manifest and statistics; sharded, the shard's list for
/// `musculo merge` (and no manifest).
fn write_run_index(
    clips: &[ClipInput],
    options: &RunOptions,
    settings: &output::RunSettings,
    layout: &LayoutDescription,
    records: &[ClipRecord],
) -> crate::Result<Option<Manifest>> {
    match options.shard {
        None => {
            let names: Vec<String> = records.iter().map(|r| r.clip.clone()).collect();
            Ok(Some(output::write_manifest(
                &options.out,
                &settings.run,
                Some(layout),
                &names,
            )?))
        }
        Some((k, n)) => {
            write_shard_list(
                &options.out,
                k,
                n,
                clips,
                settings,
                layout,
                options.variants,
            )?;
            Ok(None)
        }
    }
}

/// A computed clip for the writer threads: its record and, when it succeeded, its outputs.
struct WriteJob {
    record: ClipRecord,
    output: Option<ClipOutput>,
    /// The clip's caption file, copied beside its outputs.
    text: Option<PathBuf>,
}

fn without_sums(mut record: ClipRecord) -> ClipRecord {
    record.x_sum = Vec::new();
    record.x_sum_sq = Vec::new();
    record
}

/// The run's settings as the manifest shows them.
pub fn run_description(chain: &Chain, options: &RunOptions) -> RunDescription {
    RunDescription {
        musculo_version: env!("CARGO_PKG_VERSION").to_string(),
        model: chain.model.name.clone(),
        model_hash: output::fnv1a_hex(&chain.xml),
        variants: options.variants,
        seed: options.seed,
        perturbation: options.perturbation.clone(),
        lowpass_hz: chain.options.lowpass_hz,
        scale_to_clip: chain.options.scale_to_clip,
        muscle_strength: chain.options.muscle_strength,
        datasets: options.datasets.iter().map(DatasetRoot::describe).collect(),
        base_model: Some(chain.base.clone()),
    }
}

/// What the run's outputs depend on besides its clips (see [`output::RunSettings`]).
pub fn run_settings(chain: &Chain, options: &RunOptions) -> output::RunSettings {
    output::RunSettings {
        run: run_description(chain, options),
        // (without the options named on their own)
        chain: format!(
            "{:?}",
            ChainOptions {
                lowpass_hz: None,
                scale_to_clip: true,
                muscle_strength: 1.0,
                opensim_files: false,
                ..chain.options.clone()
            }
        ),
        opensim_files: chain.options.opensim_files,
        map: options.map.as_ref().map(|m| {
            format!(
                "{:?}",
                SkeletonMap {
                    source: String::new(),
                    ..m.clone()
                }
            )
        }),
        read: format!("{:?}", options.read),
        external_loads: options
            .external_loads
            .as_ref()
            .map(|p| p.display().to_string()),
        force_plates: options.force_plates,
    }
}

fn process(
    chain: &Chain,
    clip: &ClipInput,
    variant: &Variant,
    options: &RunOptions,
) -> crate::Result<ClipOutput> {
    match &clip.source {
        ClipSource::File { path, format } => {
            let (motion, read_warnings) =
                motion::read_with_warnings(path, Some(*format), &options.read)?;
            let builtin;
            let map = match (&options.map, format.default_map()) {
                (Some(m), _) => Some(m),
                (None, Some(name)) => {
                    builtin = SkeletonMap::builtin(name)?;
                    Some(&builtin)
                }
                // a marker file naming few of the model's markers, that a built-in map
                // reads whole (C3D's joint-centre gait sets): that map
                (None, None) => match SkeletonMap::builtin_matching(&motion) {
                    Some(m)
                        if m.targets.len()
                            > crate::solve::ik::tasks_by_name(&chain.model, &motion)
                                .markers
                                .len() =>
                    {
                        builtin = m;
                        Some(&builtin)
                    }
                    _ => None,
                },
            };
            let loads = match (&options.external_loads, options.force_plates) {
                (Some(p), _) => Some(MeasuredLoads::ExternalLoads(p.clone())),
                (None, true) if *format == Format::C3d => {
                    Some(MeasuredLoads::ForcePlates(path.clone()))
                }
                _ => None,
            };
            let mut output = chain.run_with_loads(&motion, map, variant, loads.as_ref())?;
            let read = read_warnings.iter().map(|w| w.to_string());
            output.warnings.splice(0..0, read);
            if options.force_plates && loads.is_none() {
                output.warnings.push(format!(
                    "{}: --force-plates: only C3D files carry force plates; this clip's ground \
                     reactions are estimated from its kinematics",
                    path.display()
                ));
            }
            Ok(output)
        }
        ClipSource::Motion(motion) => {
            let loads = options
                .external_loads
                .clone()
                .map(MeasuredLoads::ExternalLoads);
            chain.run_with_loads(motion, None, variant, loads.as_ref())
        }
    }
}

/// What a shard leaves for `musculo merge`: the whole dataset's clip names and the run's
/// settings, so the merge can tell whether every shard has finished.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ShardList {
    pub shard: usize,
    pub shards: usize,
    pub run: RunDescription,
    pub layout: LayoutDescription,
    /// Every output name of the dataset (all shards), in order.
    pub all: Vec<(String, String)>,
    /// Everything else the outputs depend on (absent from lists written before it was
    /// kept): shards started at the same moment with different settings both find the
    /// folder without any, and the merge is where they meet.
    #[serde(default)]
    pub settings: Option<output::RunSettings>,
}

fn write_shard_list(
    out: &Path,
    k: usize,
    n: usize,
    clips: &[ClipInput],
    settings: &output::RunSettings,
    layout: &LayoutDescription,
    variants: usize,
) -> crate::Result<()> {
    let list = ShardList {
        shard: k,
        shards: n,
        run: settings.run.clone(),
        settings: Some(settings.clone()),
        layout: layout.clone(),
        all: clips
            .iter()
            .flat_map(|c| (0..variants).map(move |v| (variant_name(&c.name, v), c.input.clone())))
            .collect(),
    };
    let path = out.join(SHARDS).join(format!("{k}-of-{n}.json"));
    std::fs::create_dir_all(out.join(SHARDS)).map_err(|source| Error::Io {
        path: out.join(SHARDS),
        source,
    })?;
    let text =
        serde_json::to_string(&list).map_err(|e| Error::invalid("shard list", e.to_string()))?;
    crate::motion::npy::write_file_atomic(&path, text.as_bytes())
}

/// `musculo merge OUT`: checks that every shard of the run in `out` has finished and
/// writes the manifest and statistics from the records — the same files an unsharded run
/// writes.
///
/// The shard lists and records are files anyone may have edited or damaged, so nothing in
/// them is taken on trust: every list must be a shard K of N with 0 ≤ K < N, all lists of
/// one run (same N, settings and clips), the clip names unique and inside `out`; and every
/// clip recorded ok must have its `.npz` ([`output::check_clip_output`]).
pub fn merge(out: &Path) -> crate::Result<Manifest> {
    let dir = out.join(SHARDS);
    let entries = std::fs::read_dir(&dir).map_err(|source| Error::Io {
        path: dir.clone(),
        source,
    })?;
    let mut lists = Vec::new();
    for entry in entries {
        let path = entry
            .map_err(|source| Error::Io {
                path: dir.clone(),
                source,
            })?
            .path();
        if path.extension().is_some_and(|e| e == "json") {
            let text = crate::text::read_text(&path)?;
            let list: ShardList = serde_json::from_str(&text).map_err(|e| Error::Motion {
                file: path.display().to_string(),
                location: format!("line {}", e.line()),
                message: format!("not a shard list: {e}"),
            })?;
            lists.push((path, list));
        }
    }
    // the directory's order is the file system's: errors name the same files every time
    lists.sort_by(|a, b| a.0.cmp(&b.0));
    let Some((first_path, first)) = lists.first() else {
        return Err(Error::invalid(
            "OUT",
            format!(
                "{} holds no shard list: run the shards first",
                dir.display()
            ),
        ));
    };
    let n = first.shards;
    for (path, l) in &lists {
        if l.shard >= l.shards {
            return Err(Error::invalid(
                "OUT",
                format!(
                    "{}: shard {} of {}: a shard list must be shard K of N with 0 ≤ K < N",
                    path.display(),
                    l.shard,
                    l.shards
                ),
            ));
        }
        if l.shards != n {
            return Err(Error::invalid(
                "OUT",
                format!(
                    "{} is shard {} of {}, {} shard {} of {}: the shard lists disagree on the \
                     number of shards, so they belong to different runs",
                    first_path.display(),
                    first.shard,
                    n,
                    path.display(),
                    l.shard,
                    l.shards
                ),
            ));
        }
        if l.run != first.run || l.all != first.all || l.settings != first.settings {
            return Err(Error::invalid(
                "OUT",
                format!(
                    "{}: shard {} of {} belongs to another run than shard {} of {} ({})",
                    out.display(),
                    l.shard,
                    l.shards,
                    first.shard,
                    n,
                    path.display()
                ),
            ));
        }
    }
    // Only the first few missing shards are named; N comes from a file, so 0..N is walked
    // lazily and stops there (at most `lists.len()` + SHOWN steps, whatever N says).
    const SHOWN: usize = 10;
    let present = |k: usize| lists.iter().any(|(_, l)| l.shard == k);
    let missing: Vec<String> = (0..n)
        .filter(|k| !present(*k))
        .take(SHOWN)
        .map(|k| k.to_string())
        .collect();
    if !missing.is_empty() {
        let mut distinct: Vec<usize> = lists.iter().map(|(_, l)| l.shard).collect();
        distinct.sort_unstable();
        distinct.dedup();
        let absent = n - distinct.len();
        let more = if absent > missing.len() {
            format!(" and {} more", absent - missing.len())
        } else {
            String::new()
        };
        return Err(Error::invalid(
            "OUT",
            format!(
                "shard(s) {}{more} of {n} have not finished ({} holds the lists of {} shard(s))",
                missing.join(", "),
                dir.display(),
                distinct.len()
            ),
        ));
    }
    let source = first_path.display().to_string();
    let mut seen = std::collections::HashSet::with_capacity(first.all.len());
    for (name, _) in &first.all {
        output::check_clip_name(name, &source)?;
        if !seen.insert(name.as_str()) {
            return Err(Error::invalid(
                "OUT",
                format!("{source}: clip \"{name}\" is listed twice"),
            ));
        }
    }
    // A record says ok only after the clip's `.npz` was written; one deleted or damaged
    // since would otherwise be counted in the manifest as a clip of the dataset.
    let mut broken = Vec::new();
    for (name, _) in &first.all {
        if let Some(record) = output::read_record(out, name)?
            && record.status == ClipStatus::Ok
            && let Err(e) = output::check_clip_output(out, &record)
        {
            broken.push(format!("{name} ({e})"));
        }
    }
    if !broken.is_empty() {
        let count = broken.len();
        let more = if count > SHOWN {
            format!("; and {} more", count - SHOWN)
        } else {
            String::new()
        };
        broken.truncate(SHOWN);
        return Err(Error::invalid(
            "OUT",
            format!(
                "{count} clip(s) recorded ok have a missing or unreadable output: {}{more}; \
                 remove their records from {} and run their shards again with --resume",
                broken.join("; "),
                out.join(output::RECORDS).display()
            ),
        ));
    }
    let names: Vec<String> = first.all.iter().map(|(n, _)| n.clone()).collect();
    output::write_manifest(out, &first.run, Some(&first.layout), &names)
}
