//! Speed and memory of the whole augmentation chain (`musculo::augment`) on the default
//! model: IK → filtering → inverse dynamics → contacts → static optimization over 324
//! muscles + reserves → excitations → per-joint layout → `.npz` writes, clips in parallel.
//!
//! Clips: the HumanML3D sample (../shared/reference, 170 frames at 20 fps), repeated, and the
//! demo clips; reported: frames/s with 1 and 2 threads, and peak resident memory (VmHWM from
//! /proc/self/status) after the runs — with the number of clips doubled, to show that memory
//! does not grow with the dataset; then the HumanML3D clip alone (8 copies, 2 threads), the
//! kind of clip the 5,000 frames/s goal is stated for. Beside it, the HumanML3D clip through
//! the chain's stages one at a time, so the share of each stage is visible. The chain shares
//! a scaled model between clips of one skeleton (as all HumanML3D clips are), so after the
//! first clip the scaling itself is not in these figures; the last line says what it costs.
//!
//! Run: `cargo bench --bench augment`.

use musculo::augment::chain::{Chain, ChainOptions};
use musculo::augment::output::LayoutDescription;
use musculo::augment::perturb::Variant;
use musculo::augment::runner::{self, ClipInput, ClipSource, RunOptions};
use musculo::augment::{demo, describe};
use musculo::motion::skeleton::SkeletonMap;
use musculo::motion::{self, Format, ReadOptions};
use std::path::PathBuf;
use std::time::Instant;

fn reference_dir() -> PathBuf {
    std::env::var_os("MUSCULO_REFERENCE")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/reference"))
        })
}

fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// `k` copies of each clip, named apart.
fn copies(base: &[ClipInput], k: usize) -> Vec<ClipInput> {
    (0..k)
        .flat_map(|i| {
            base.iter().map(move |c| ClipInput {
                name: format!("{}_{i:03}", c.name),
                ..c.clone()
            })
        })
        .collect()
}

/// One run of `clips` on `threads` threads into a scratch directory: (frames, seconds).
fn timed_run(
    chain: &Chain,
    layout: &LayoutDescription,
    clips: &[ClipInput],
    threads: usize,
    tag: usize,
) -> (usize, f64) {
    let out = std::env::temp_dir().join(format!("musculo-bench-augment-{threads}-{tag}"));
    let _ = std::fs::remove_dir_all(&out);
    let options = RunOptions::new(&out);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool");
    let start = Instant::now();
    let report = pool
        .install(|| runner::run(chain, layout, clips, &options, &|_| {}))
        .expect("run");
    let seconds = start.elapsed().as_secs_f64();
    let frames = report.frames();
    let _ = std::fs::remove_dir_all(&out);
    (frames, seconds)
}

fn main() {
    let chain = Chain::new(
        musculo::DEFAULT_MODEL_OSIM.to_string(),
        "models/musculo_fullbody.osim".into(),
        ChainOptions::default(),
    )
    .expect("default model");
    let layout = describe(&chain).expect("layout");
    let sample = reference_dir().join("humanml3d/new_joints_012314.npy");
    let mut base: Vec<ClipInput> = Vec::new();
    if sample.exists() {
        base.push(ClipInput {
            name: "012314".into(),
            input: sample.display().to_string(),
            source: ClipSource::File {
                path: sample.clone(),
                format: Format::HumanMl3d,
            },
        });
    } else {
        eprintln!(
            "HumanML3D sample not found under {}: demo clips only",
            reference_dir().display()
        );
    }
    for (name, m) in demo::clips(&chain.model).expect("demo") {
        base.push(ClipInput {
            input: format!("demo:{name}"),
            name,
            source: ClipSource::Motion(Box::new(m)),
        });
    }
    println!(
        "augment chain, default model (324 muscles), clips: {}",
        base.len()
    );
    for (threads, k) in [(1usize, 2usize), (2, 2), (2, 4)] {
        let clips = copies(&base, k);
        let (frames, seconds) = timed_run(&chain, &layout, &clips, threads, k);
        println!(
            "{threads} thread(s), {} clips, {frames} frames: {:.2} s, {:.0} frames/s; peak RSS \
             so far {:.0} MiB",
            clips.len(),
            seconds,
            frames as f64 / seconds,
            peak_rss_mib()
        );
    }
    // The dataset the goal is stated for: HumanML3D-like clips only (each scaled to its
    // clip, ~170 frames), where the per-clip scaling weighs more than on the long demo clips.
    if sample.exists() {
        let clips = copies(&base[..1], 8);
        let (frames, seconds) = timed_run(&chain, &layout, &clips, 2, 8);
        println!(
            "2 thread(s), HumanML3D clip only, {} copies, {frames} frames: {:.2} s, {:.0} \
             frames/s",
            clips.len(),
            seconds,
            frames as f64 / seconds
        );
    }
    // the stages of one clip, timed separately (one thread)
    if sample.exists() {
        let clip = motion::read(&sample, Some(Format::HumanMl3d), &ReadOptions::default())
            .expect("sample");
        let map = SkeletonMap::builtin("humanml3d").expect("map");
        let v = Variant::identity();
        // the chain's scaled model is shared with the runs above (same skeleton): what a
        // clip of a new skeleton costs on top is the scaling itself
        let t = Instant::now();
        musculo::solve::scale_from_clip::scale_to_clip(
            &chain.xml,
            &chain.source,
            &chain.model,
            &map,
            &clip,
        )
        .expect("scaling");
        let unshared_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let model = chain.clip_model(&clip, Some(&map), &v).expect("model");
        let model_s = t.elapsed().as_secs_f64();
        let (targets, tasks) = map.apply(&model, &clip).expect("map");
        let t = Instant::now();
        let ik =
            musculo::solve::ik::solve_motion(&model, &targets, &tasks, &chain.options.ik, &|_| {})
                .expect("ik");
        let ik_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let out = chain.run(&clip, Some(&map), &v).expect("chain");
        let all_s = t.elapsed().as_secs_f64();
        let frames = ik.n_frames() as f64;
        println!(
            "HumanML3D 012314 ({frames} frames), one thread: whole chain {:.1} ms ({:.0} frames/s); \
             of which the clip's model (scaled model shared with the clips before: marker \
             placement, reserves) {:.1} ms, IK {:.1} ms ({:.0} frames/s); the rest (filtering, \
             ID, contacts, SO, excitations, layout) {:.1} ms ({:.0} frames/s); IK RMSE median \
             {:.1} mm; for a clip of a new skeleton, the scaling and placement instead \
             (scale_to_clip unshared, as `ik --scale auto`) {:.1} ms",
            all_s * 1e3,
            frames / all_s,
            model_s * 1e3,
            ik_s * 1e3,
            frames / ik_s,
            (all_s - model_s - ik_s) * 1e3,
            frames / (all_s - model_s - ik_s),
            out.quality.ik_rmse_median * 1e3,
            unshared_s * 1e3
        );
    }
}
