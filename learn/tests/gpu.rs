//! The GPU path (features `wgpu` / `cuda`): burn's CubeCL backend with the physics op, against
//! the CPU (Flex) run of the same network. The device comes from `MUSCULO_LEARN_DEVICE`
//! (default `wgpu`, or `cuda` in a build with only that feature); CI runs it on wgpu over
//! Mesa's software Vulkan driver (lavapipe), which exercises every kernel without a GPU.
#![cfg(any(feature = "wgpu", feature = "cuda"))]

use burn::module::Module;
use burn::tensor::{Device, Tensor, TensorData};
use musculo::model::Model;
use musculo_learn::autoencoder::AutoencoderConfig;
use musculo_learn::data::{ClipSet, Normalizer};
use musculo_learn::physics::{Physics, PhysicsCall, PhysicsWeights, physics_loss};
use musculo_learn::train::{self, TrainConfig, TrainState};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

fn gpu() -> Device {
    let default = if cfg!(feature = "wgpu") {
        "wgpu"
    } else {
        "cuda"
    };
    let name = std::env::var("MUSCULO_LEARN_DEVICE").unwrap_or_else(|_| default.into());
    musculo_learn::device::parse(&name).expect("the device")
}

/// One test at a time: they share the GPU and burn's seeded initialization.
fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static TURN: Mutex<()> = Mutex::new(());
    TURN.lock().unwrap_or_else(|e| e.into_inner())
}

fn demo_set(model: &Model) -> ClipSet {
    let dir: PathBuf =
        std::env::temp_dir().join(format!("musculo-learn-gpu-{}", std::process::id()));
    if !dir.join("manifest.json").is_file() {
        musculo_learn::data::augment_demo(&dir).unwrap();
    }
    ClipSet::read(&[dir], model).unwrap()
}

#[test]
fn the_physics_op_gives_the_cpu_value_and_gradient_on_the_gpu() {
    let _turn = one_at_a_time();
    let model = Model::default_fullbody();
    let set = demo_set(&model);
    let normalizer = Normalizer::of(&set);
    let (b, t, d) = (2, 16, set.layout.width());
    let physics = Arc::new(
        Physics::new(
            model,
            set.layout.clone(),
            normalizer.clone(),
            PhysicsWeights {
                euler: 1.0,
                muscle: 0.5,
                muscle_stride: 4,
            },
        )
        .unwrap(),
    );
    // two real windows, standardized, slightly perturbed so that the residual is not ~0
    let mut z = Vec::with_capacity(b * t * d);
    for (s, clip) in set.clips.iter().take(b).enumerate() {
        let mut y = clip.y[..t * d].to_vec();
        normalizer.normalize(&mut y);
        z.extend(
            y.iter()
                .enumerate()
                .map(|(i, v)| v + 0.01 * ((i * 7 + s) % 13) as f32),
        );
    }
    let run = |device: &Device| -> (f32, Vec<f32>) {
        let x =
            Tensor::<3>::from_data(TensorData::new(z.clone(), [b, t, d]), device).require_grad();
        let call = PhysicsCall::new(physics.clone(), vec![Some(0); b]);
        let loss = physics_loss(x.clone(), call.clone());
        call.outcome().expect("the op's parts");
        let value = loss.clone().into_scalar::<f32>();
        let grads = loss.sum().backward();
        let g = x
            .grad(&grads)
            .expect("a gradient")
            .into_data()
            .try_to_vec::<f32>()
            .unwrap();
        (value, g)
    };
    let (cpu_value, cpu_grad) = run(&Device::flex().autodiff());
    let (gpu_value, gpu_grad) = run(&gpu().autodiff());
    assert!(cpu_value > 0.0);
    assert!(
        ((gpu_value - cpu_value) / cpu_value).abs() < 1e-6,
        "{gpu_value} vs {cpu_value}"
    );
    let scale = cpu_grad.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    eprintln!("physics op: value {gpu_value} on the GPU, {cpu_value} on the CPU");
    let worst = cpu_grad
        .iter()
        .zip(&gpu_grad)
        .fold(0.0f32, |m, (a, g)| m.max((a - g).abs()));
    assert!(
        worst <= 1e-6 * scale,
        "gradient differs by {worst} (scale {scale})"
    );
}

#[test]
fn training_on_the_gpu_follows_the_cpu_run() {
    // the same initial network (drawn on the CPU, copied to each device) and the same windows:
    // the losses of 6 steps with the Euler–Lagrange term agree to float rounding
    let _turn = one_at_a_time();
    let model = Model::default_fullbody();
    let set = demo_set(&model);
    let config = AutoencoderConfig::new(set.layout.width())
        .with_d_model(64)
        .with_d_ff(128)
        .with_layers(2)
        .with_latent(32)
        .with_downsample(4);
    let train = TrainConfig {
        steps: 6,
        batch: 2,
        window: 32,
        ..TrainConfig::default()
    };
    let cpu = Device::flex().autodiff();
    let start = TrainState::new(&config, &train, &cpu);
    let log = |device: &Device| {
        let state = TrainState {
            net: start.net.clone().fork(device),
            optimizer: burn::optim::AdamConfig::new().init(),
            rng: start.rng,
            step: 0,
            log: Vec::new(),
        };
        train::continue_training(&set, &model, &config, &train, device, state, &mut |_| {})
            .expect("training")
            .log
    };
    let on_cpu = log(&cpu);
    let on_gpu = log(&gpu().autodiff());
    let mut largest = 0.0f64;
    for (c, g) in on_cpu.iter().zip(&on_gpu) {
        for (name, a, b) in [
            ("total", c.total, g.total),
            ("reconstruction", c.reconstruction, g.reconstruction),
            ("euler", c.euler, g.euler),
        ] {
            largest = largest.max(((a - b) / a).abs());
            assert!(
                ((a - b) / a).abs() < 1e-3,
                "step {}: {name} {b} on the GPU vs {a} on the CPU",
                c.step
            );
        }
    }
    eprintln!(
        "6 steps: losses agree to {largest:.1e} relative; total {:.4} → {:.4} on the GPU",
        on_gpu[0].total, on_gpu[5].total
    );
    assert!(on_gpu[5].total < on_gpu[0].total, "{on_gpu:?}");
}
