//! The learned module at tiny scale: the physics op's gradient against finite differences, the
//! autoencoder overfitting the demo clips, the physics terms' effect on the reconstruction's
//! Euler–Lagrange residual (FlexMotion's ablation, on our data), checkpoints and bad input.

use burn::tensor::{Device, Tensor, TensorData};
use musculo::model::Model;
use musculo_learn::autoencoder::AutoencoderConfig;
use musculo_learn::checkpoint;
use musculo_learn::data::{ClipSet, Normalizer};
use musculo_learn::physics::{Physics, PhysicsCall, PhysicsWeights, physics_loss};
use musculo_learn::train::{self, TrainConfig};
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

/// burn's CPU backend splits its reductions over the shared thread pool as the pool is free, so
/// trainings running beside each other round differently and long runs drift apart; the tests of
/// this file take turns so that each figure is the one a run alone gives.
fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static TURN: std::sync::Mutex<()> = std::sync::Mutex::new(());
    TURN.lock().unwrap_or_else(|e| e.into_inner())
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("musculo-learn-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The demo clips augmented once per test binary (3 clips, 330 frames at 30 Hz).
fn demo_data() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = temp_dir("demo");
        musculo_learn::data::augment_demo(&dir).unwrap();
        dir
    })
}

fn model() -> Model {
    Model::default_fullbody()
}

#[test]
fn physics_op_gradient_equals_finite_differences() {
    let _turn = one_at_a_time();
    let model = model();
    let set = ClipSet::read(&[demo_data().to_path_buf()], &model).unwrap();
    let normalizer = Normalizer::of(&set);
    let d = set.layout.width();
    let physics = Arc::new(
        Physics::new(
            model,
            set.layout.clone(),
            normalizer.clone(),
            PhysicsWeights {
                euler: 1.0,
                muscle: 0.5,
                muscle_stride: 3,
            },
        )
        .unwrap(),
    );
    // two sequences of 6 frames from the squat, perturbed so that the residual is not zero;
    // the second is left out of the terms
    let (b, t) = (2, 6);
    let squat = set.clips.iter().find(|c| c.name == "squat").unwrap();
    let mut z: Vec<f32> = squat.y[30 * d..(30 + b * t) * d].to_vec();
    normalizer.normalize(&mut z);
    let mut state = 7u64;
    for v in &mut z {
        state = musculo::random::mix(state);
        *v += 0.3 * ((state >> 11) as f32 / (1u64 << 53) as f32 - 0.5);
    }
    let include = vec![Some(0), None];
    let device = Device::flex().autodiff();
    let input =
        Tensor::<3>::from_data(TensorData::new(z.clone(), [b, t, d]), &device).require_grad();
    let call = PhysicsCall::new(physics.clone(), include.clone());
    let value = physics_loss(input.clone(), call.clone()).sum();
    let loss: f32 = value.clone().into_scalar();
    let grads = value.backward();
    let grad: Vec<f32> = input
        .grad(&grads)
        .unwrap()
        .into_data()
        .try_to_vec::<f32>()
        .unwrap();
    let parts = call.outcome().unwrap();
    let direct = physics.evaluate(&z, b, t, &include, true).unwrap();
    assert_eq!((parts.euler, parts.muscle), (direct.euler, direct.muscle));
    assert!((loss as f64 - direct.loss).abs() <= 1e-6 * direct.loss);
    assert!(direct.euler > 0.0 && direct.muscle > 0.0);
    // nothing flows into the excluded sequence
    assert!(grad[t * d..].iter().all(|g| *g == 0.0));
    // a batch that does not fit the layout: NaN from the op and the error from the call
    let narrow = Tensor::<3>::from_data(TensorData::new(vec![0.0f32; 2 * 5], [1, 2, 5]), &device);
    let bad = PhysicsCall::new(physics.clone(), vec![Some(0)]);
    let v: f32 = physics_loss(narrow, bad.clone()).sum().into_scalar();
    assert!(v.is_nan());
    let err = bad.outcome().err().unwrap().to_string();
    assert!(err.contains("10 values"), "{err}");
    // directional derivatives along random directions, central differences of the f64 value
    for trial in 0..3 {
        let dir: Vec<f32> = (0..z.len())
            .map(|i| {
                let r = musculo::random::mix((trial * 1_000_003 + i) as u64);
                (r >> 11) as f32 / (1u64 << 53) as f32 - 0.5
            })
            .collect();
        let h = 1e-2f32;
        let at = |s: f32| -> f64 {
            let zz: Vec<f32> = z.iter().zip(&dir).map(|(a, v)| a + s * v).collect();
            physics.evaluate(&zz, b, t, &include, false).unwrap().loss
        };
        let fd = (at(h) - at(-h)) / (2.0 * h as f64);
        let analytic: f64 = grad
            .iter()
            .zip(&dir)
            .map(|(g, v)| *g as f64 * *v as f64)
            .sum();
        let rel = (fd - analytic).abs() / fd.abs().max(1e-12);
        assert!(
            rel < 2e-3,
            "trial {trial}: finite difference {fd}, op gradient {analytic} (relative {rel})"
        );
    }
}

fn tiny(set: &ClipSet) -> AutoencoderConfig {
    AutoencoderConfig::new(set.layout.width())
        .with_d_model(64)
        .with_d_ff(128)
        .with_layers(2)
        .with_latent(32)
        .with_downsample(4)
}

#[test]
fn autoencoder_overfits_the_demo_clips_and_the_physics_terms_lower_the_residual() {
    let _turn = one_at_a_time();
    let model = model();
    let set = ClipSet::read(&[demo_data().to_path_buf()], &model).unwrap();
    // the default sizes (d = 128, 2 + 2 layers, k = 4, 32 latent values per 4 frames)
    let config = AutoencoderConfig::new(set.layout.width());
    let steps = 2500;
    let run = |euler: f64| {
        let train = TrainConfig {
            steps,
            batch: 8,
            window: 32,
            learning_rate: 2e-3,
            seed: 3,
            physics: PhysicsWeights {
                euler,
                muscle: 0.0,
                muscle_stride: 4,
            },
            bound_weight: 1.0,
        };
        let device = Device::flex().autodiff();
        let trained =
            train::train_autoencoder(&set, &model, &config, &train, &device, &mut |_| {}).unwrap();
        let recon = train::reconstruct(&trained, &set, 32, &Device::flex()).unwrap();
        let quality = train::quality(&set, &recon, &model).unwrap();
        eprintln!(
            "w_E = {euler}: {} steps in {:.1} s, final loss {:.5}: {quality:?}",
            steps,
            trained.log.last().unwrap().seconds,
            trained.log.last().unwrap().total
        );
        quality
    };
    let plain = run(0.0);
    let physical = run(1.0);
    // the data themselves satisfy the equations of motion (musculo augment's τ)
    assert!(plain.residual_rms_data < 1e-3 * plain.tau_rms);
    for q in [&plain, &physical] {
        assert!(
            q.joint_pos_error < 0.01,
            "joint positions reconstructed to {} m",
            q.joint_pos_error
        );
    }
    // measured: joint positions 2.3 mm and 8.5 mm, residual RMS 2.91 → 0.57 N·m (5.1×) at
    // commit 0c856f5; 2.2 mm and 7.7 mm, 1.82 → 0.62 N·m (2.9×) at 27c9eab, whose demo clips
    // differ only in their activations (by up to 0.07, within static optimization's
    // tolerance; q by 1e-11). The factor is a training outcome that such noise moves by 2×:
    // the bound asks for a clear lowering, not a particular one.
    let factor = plain.residual_rms / physical.residual_rms;
    assert!(
        factor > 2.0,
        "the physics terms lowered the residual only {factor}× ({} → {} N·m)",
        plain.residual_rms,
        physical.residual_rms
    );
}

#[test]
fn a_checkpoint_reads_back_to_the_same_reconstruction() {
    let _turn = one_at_a_time();
    let model = model();
    let set = ClipSet::read(&[demo_data().to_path_buf()], &model).unwrap();
    let config = tiny(&set);
    let train = TrainConfig {
        steps: 5,
        batch: 2,
        window: 32,
        ..TrainConfig::default()
    };
    let trained = train::train_autoencoder(
        &set,
        &model,
        &config,
        &train,
        &Device::flex().autodiff(),
        &mut |_| {},
    )
    .unwrap();
    let dir = temp_dir("checkpoint");
    checkpoint::save(&trained, &train, "hash", &dir).unwrap();
    let csv = std::fs::read_to_string(dir.join("loss.csv")).unwrap();
    assert_eq!(csv.lines().count(), 6);
    let device = Device::flex();
    let loaded = checkpoint::load(&dir, &device).unwrap();
    assert_eq!(loaded.model_hash, "hash");
    let a = train::reconstruct(&trained, &set, 32, &device).unwrap();
    let b = train::reconstruct(&loaded.trained, &set, 32, &device).unwrap();
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.y, y.y, "clip {}", x.name);
    }
    // a damaged checkpoint is an error naming the file
    std::fs::write(dir.join("autoencoder.bpk"), b"not a record").unwrap();
    let err = checkpoint::load(&dir, &device).err().unwrap().to_string();
    assert!(err.contains("autoencoder.bpk"), "{err}");
}

/// The losses of a log without its times.
fn losses(log: &[train::StepLog]) -> Vec<[f64; 5]> {
    log.iter()
        .map(|s| [s.total, s.reconstruction, s.euler, s.muscle, s.bounds])
        .collect()
}

#[test]
fn an_interrupted_run_continues_to_the_uninterrupted_result() {
    // a run of 10 steps that saves its state after steps 4 and 7; continuing from the step-7
    // snapshot must give the uninterrupted run's losses and network, which a continuation
    // with Adam's moments reset does not
    let _turn = one_at_a_time();
    let model = model();
    let set = ClipSet::read(&[demo_data().to_path_buf()], &model).unwrap();
    let config = tiny(&set);
    let train = TrainConfig {
        steps: 10,
        batch: 2,
        window: 32,
        ..TrainConfig::default()
    };
    let normalizer = Normalizer::of(&set);
    let run = checkpoint::RunIdentity {
        config: &config,
        train: &train,
        normalizer: &normalizer,
        model_hash: "hash",
    };
    let device = Device::flex().autodiff();
    let dir = temp_dir("resume");
    assert!(
        checkpoint::load_state(&dir, &run, &device)
            .unwrap()
            .is_none()
    );
    let whole = train::train_autoencoder(&set, &model, &config, &train, &device, &mut |state| {
        if state.step == 4 || state.step == 7 {
            checkpoint::save_state(state, &run, &dir).unwrap();
        }
    })
    .unwrap();
    // only the latest snapshot's files are kept
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    assert_eq!(files, ["optimizer-7.bpk", "resume-7.bpk", "resume.json"]);
    let state = checkpoint::load_state(&dir, &run, &device)
        .unwrap()
        .unwrap();
    assert_eq!((state.step, state.log.len()), (7, 7));
    let resumed =
        train::continue_training(&set, &model, &config, &train, &device, state, &mut |_| {})
            .unwrap();
    assert_eq!(losses(&resumed.log), losses(&whole.log));
    let plain = Device::flex();
    let a = train::reconstruct(&whole, &set, 32, &plain).unwrap();
    let b = train::reconstruct(&resumed, &set, 32, &plain).unwrap();
    let mut diff = 0.0f32;
    for (x, y) in a.iter().zip(&b) {
        for (u, v) in x.y.iter().zip(&y.y) {
            diff = diff.max((u - v).abs());
        }
    }
    assert!(diff <= 1e-6, "resumed vs uninterrupted: {diff}");
    // the same continuation without Adam's moments lands elsewhere
    let mut reset = checkpoint::load_state(&dir, &run, &device)
        .unwrap()
        .unwrap();
    reset.optimizer = burn::optim::AdamConfig::new().init();
    let restarted =
        train::continue_training(&set, &model, &config, &train, &device, reset, &mut |_| {})
            .unwrap();
    let c = train::reconstruct(&restarted, &set, 32, &plain).unwrap();
    let mut moved = 0.0f32;
    for (x, y) in a.iter().zip(&c) {
        for (u, v) in x.y.iter().zip(&y.y) {
            moved = moved.max((u - v).abs());
        }
    }
    eprintln!("resumed vs uninterrupted: max |Δ| {diff}; with Adam's moments reset: {moved}");
    assert!(
        moved > 100.0 * diff.max(1e-6),
        "reset moments changed only {moved}"
    );
    // a snapshot of another run is refused, naming what differs
    let longer = TrainConfig {
        steps: 11,
        ..train.clone()
    };
    let other = checkpoint::RunIdentity {
        train: &longer,
        ..run
    };
    let err = checkpoint::load_state(&dir, &other, &device)
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("training settings"), "{err}");
}

#[test]
fn bad_training_input_is_an_error_not_a_panic() {
    let _turn = one_at_a_time();
    let model = model();
    let missing = ClipSet::read(&[PathBuf::from("/nonexistent/clips")], &model)
        .err()
        .unwrap()
        .to_string();
    assert!(missing.contains("/nonexistent/clips"), "{missing}");
    let empty = temp_dir("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let none = ClipSet::read(std::slice::from_ref(&empty), &model)
        .err()
        .unwrap()
        .to_string();
    assert!(none.contains("no tensor files"), "{none}");
    let set = ClipSet::read(&[demo_data().to_path_buf()], &model).unwrap();
    let device = Device::flex().autodiff();
    for (window, expect) in [(30, "multiple"), (200, "fewer than the window")] {
        let train = TrainConfig {
            window,
            steps: 1,
            ..TrainConfig::default()
        };
        let err = train::train_autoencoder(&set, &model, &tiny(&set), &train, &device, &mut |_| {})
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains(expect), "window {window}: {err}");
    }
}
