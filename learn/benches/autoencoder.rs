//! The autoencoder's cost on this CPU (burn's Flex backend), side by side in one process:
//! a training step (B = 8 windows of T = 64 frames) on the reconstruction alone, with the
//! Euler–Lagrange term and with the muscle term too (every 4th frame), as ratios to the plain
//! step; the time to encode and decode one 64-frame sequence; the parameter count; the latent
//! diffusion model's training step and the time to sample one 64-frame motion.
//!
//! `cargo bench -p musculo-learn --bench autoencoder`

use burn::module::Module;
use burn::tensor::{Device, Tensor, TensorData};
use musculo::model::Model;
use musculo_learn::autoencoder::AutoencoderConfig;
use musculo_learn::data::ClipSet;
use musculo_learn::diffusion::{self, Concept, Control, DenoiserConfig, DiffusionTrainConfig};
use musculo_learn::physics::PhysicsWeights;
use musculo_learn::train::{self, TrainConfig};
use std::time::Instant;

fn main() {
    let dir = std::env::temp_dir().join(format!("musculo-learn-bench-{}", std::process::id()));
    musculo_learn::data::augment_demo(&dir).expect("augment the demo clips");
    let model = Model::default_fullbody();
    let set = ClipSet::read(std::slice::from_ref(&dir), &model).expect("tensor files");
    let config = AutoencoderConfig::new(set.layout.width());
    let steps = 20;
    let step_time = |euler: f64, muscle: f64| -> (f64, usize) {
        let train = TrainConfig {
            steps,
            batch: 8,
            window: 64,
            physics: PhysicsWeights {
                euler,
                muscle,
                muscle_stride: 4,
            },
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
        .expect("training");
        // the first steps warm the allocator; time the second half
        let log = &trained.log;
        let half = steps / 2;
        let t = (log[steps - 1].seconds - log[half - 1].seconds) / (steps - half) as f64;
        (t, train::parameters(&trained.model))
    };
    let (plain, params) = step_time(0.0, 0.0);
    let (euler, _) = step_time(1.0, 0.0);
    let (muscle, _) = step_time(1.0, 1.0);
    println!(
        "autoencoder: {params} parameters (d = {}, {} + {} layers, k = {}, latent {}), {} features per frame",
        config.d_model,
        config.layers,
        config.layers,
        config.downsample,
        config.latent,
        set.layout.width()
    );
    println!("training step, B = 8 × T = 64 frames:");
    println!(
        "  reconstruction only        {:8.1} ms   1.00×",
        plain * 1e3
    );
    println!(
        "  + Euler–Lagrange term      {:8.1} ms   {:.2}×",
        euler * 1e3,
        euler / plain
    );
    println!(
        "  + muscle term (every 4th)  {:8.1} ms   {:.2}×",
        muscle * 1e3,
        muscle / plain
    );
    // inference: encode + decode one 64-frame sequence
    let device = Device::flex();
    let net = config.init(&device);
    let d = set.layout.width();
    let z = TensorData::new(vec![0.1f32; 64 * d], [1, 64, d]);
    let runs = 20;
    let start = Instant::now();
    for _ in 0..runs {
        let out = net.forward(Tensor::<3>::from_data(z.clone(), &device));
        let _ = out.into_data();
    }
    let per = start.elapsed().as_secs_f64() / runs as f64;
    println!(
        "encode + decode of one 64-frame sequence: {:.2} ms ({:.0} frames/s)",
        per * 1e3,
        64.0 / per
    );
    // latent diffusion: a training step (B = 16 windows of 64 frames) and DDIM sampling
    let texts: Vec<Vec<f32>> = set
        .clips
        .iter()
        .map(|c| musculo_learn::text::bag_of_words(&c.caption))
        .collect();
    let normalizer = musculo_learn::data::Normalizer::of(&set);
    let dconfig = DenoiserConfig::new(
        config.latent,
        d,
        config.downsample,
        musculo_learn::text::BUCKETS,
    );
    let dtrain = DiffusionTrainConfig {
        steps,
        ..DiffusionTrainConfig::default()
    };
    let denoiser = diffusion::train_denoiser(
        &set,
        &net,
        &normalizer,
        &texts,
        &dconfig,
        &dtrain,
        &Device::flex().autodiff(),
        &mut |_| {},
    )
    .expect("diffusion training");
    let half = steps / 2;
    let step = (denoiser.log[steps - 1].2 - denoiser.log[half - 1].2) / (steps - half) as f64;
    let concept = [Concept {
        text: texts[0].clone(),
        weight: 2.5,
    }];
    let time_sampling = |control: &Control, guidance: usize| -> f64 {
        let start = Instant::now();
        diffusion::sample(
            &denoiser,
            &net,
            &normalizer,
            &concept,
            control,
            64,
            1,
            30,
            guidance,
            0,
            &Device::flex(),
        )
        .expect("sampling");
        start.elapsed().as_secs_f64()
    };
    let free = time_sampling(&Control::none(64, d), 0);
    let mut control = Control::none(64, d);
    control.set_block(&set.layout, "joint_pos", 0..64, &set.clips[0].y);
    let guided = time_sampling(&control, 5);
    println!(
        "denoiser: {} parameters; training step (B = 16 × 64 frames) {:.1} ms",
        denoiser.model.num_params(),
        step * 1e3
    );
    println!(
        "sampling one 64-frame motion (30 DDIM steps, caption guidance): {:.0} ms; with joint-position control and 5 guidance steps per DDIM step: {:.0} ms",
        free * 1e3,
        guided * 1e3
    );
    let _ = std::fs::remove_dir_all(&dir);
}
