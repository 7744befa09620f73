//! Speed of `musculo::evaluate` beside the augmentation that made its input, on the same
//! clips and one thread each: the HumanML3D sample (../shared/reference, when present) and the
//! demo clips, copied up to N clips (default 1,000; `MUSCULO_BENCH_CLIPS`), augmented by
//! `augment::runner`, then evaluated with the default joint strength curves and, on the first
//! 30 clips, with capacities per frame. Reported: frames/s of each and the ratio.
//!
//! Run: `cargo bench --bench evaluate` (the augmentation of 1,000 clips takes minutes).

use musculo::augment::chain::{Chain, ChainOptions};
use musculo::augment::runner::{self, ClipInput, ClipSource, RunOptions};
use musculo::augment::{demo, describe};
use musculo::evaluate::{self, EvaluateOptions, SetOptions};
use musculo::motion::Format;
use std::path::PathBuf;
use std::time::Instant;

fn reference_dir() -> PathBuf {
    std::env::var_os("MUSCULO_REFERENCE")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/reference"))
        })
}

fn main() {
    let n: usize = std::env::var("MUSCULO_BENCH_CLIPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1000);
    let chain = Chain::new(
        musculo::DEFAULT_MODEL_OSIM.to_string(),
        "models/musculo_fullbody.osim".into(),
        ChainOptions::default(),
    )
    .expect("default model");
    let layout = describe(&chain).expect("layout");
    let mut base: Vec<ClipInput> = Vec::new();
    let sample = reference_dir().join("humanml3d/new_joints_012314.npy");
    if sample.exists() {
        base.push(ClipInput {
            name: "012314".into(),
            input: sample.display().to_string(),
            source: ClipSource::File {
                path: sample.clone(),
                format: Format::HumanMl3d,
            },
        });
    }
    for (name, m) in demo::clips(&chain.model).expect("demo") {
        base.push(ClipInput {
            input: format!("demo:{name}"),
            name,
            source: ClipSource::Motion(Box::new(m)),
        });
    }
    let clips: Vec<ClipInput> = (0..n)
        .map(|i| {
            let c = &base[i % base.len()];
            ClipInput {
                name: format!("{}_{i:04}", c.name),
                ..c.clone()
            }
        })
        .collect();
    let out = std::env::temp_dir().join(format!("musculo-bench-evaluate-{n}"));
    let _ = std::fs::remove_dir_all(&out);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let start = Instant::now();
    let report = pool
        .install(|| runner::run(&chain, &layout, &clips, &RunOptions::new(&out), &|_| {}))
        .expect("augment");
    let augment_s = start.elapsed().as_secs_f64();
    let frames = report.frames();
    let files = evaluate::collect(std::slice::from_ref(&out), None).expect("clips");
    let run = |files: &[evaluate::ClipFile], per_frame: bool| {
        let options = SetOptions {
            metrics: EvaluateOptions {
                muscles_per_frame: per_frame,
                ..EvaluateOptions::default()
            },
            ..SetOptions::default()
        };
        let start = Instant::now();
        let r = pool
            .install(|| evaluate::evaluate_set(files, &options, &|_, _| {}))
            .expect("evaluate");
        assert!(r.failed.is_empty(), "{:?}", r.failed);
        (start.elapsed().as_secs_f64(), r.summary.frames)
    };
    let (curves_s, curves_frames) = run(&files, false);
    let few = &files[..files.len().min(30)];
    let (exact_s, exact_frames) = run(few, true);
    let augment_rate = frames as f64 / augment_s;
    let curves_rate = curves_frames as f64 / curves_s;
    let exact_rate = exact_frames as f64 / exact_s;
    println!("{n} clips, {frames} frames, one thread:");
    println!("  augment:                          {augment_s:8.2} s, {augment_rate:8.0} frames/s");
    println!(
        "  evaluate (strength curves):       {curves_s:8.2} s, {curves_rate:8.0} frames/s = {:.1} × augment",
        curves_rate / augment_rate
    );
    println!(
        "  evaluate --muscles-per-frame ({} clips, {exact_frames} frames): {exact_s:.2} s, {exact_rate:.0} frames/s = {:.1} × augment",
        few.len(),
        exact_rate / augment_rate
    );
    let _ = std::fs::remove_dir_all(&out);
}
