//! Training the autoencoder: Adam on random windows of the set's clips, the loss
//!
//! ```text
//! L = (1 / (B·T·D)) Σ (ẑ − z)²                       reconstruction, standardized units
//!   + L_phys(ẑ)                                       crate::physics (w_E, w_M inside)
//!   + w_a · (1 / (B·T·m)) Σ (max(0, −â) + max(0, â − 1))² / σ_a²      activation bounds
//! ```
//!
//! with â the decoded activations in SI units. The learning rate follows a cosine from its
//! initial value to a tenth of it at the last step. Each step draws B windows of T frames: a clip
//! with probability proportional to its frames, a start uniform over the clip — from the
//! SplitMix64 stream of the seed, so that a seed fixes the run (with the network's
//! initialization seeded from the same number).
//!
//! [`reconstruct`] runs a trained model over whole clips (windows of T frames; a clip's last
//! window is aligned to its end) and [`Reconstruction`] measures what came back: the joint
//! position error (m) and the Euler–Lagrange residual of the decoded q, q̇, q̈, τ, λ.

use crate::autoencoder::{Autoencoder, AutoencoderConfig};
use crate::data::{ClipSet, FeatureLayout, LearnError, Normalizer, Result};
use crate::physics::{Physics, PhysicsCall, PhysicsWeights, physics_loss};
use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::activation::relu;
use burn::tensor::{Device, Tensor, TensorData};
use musculo::loss::{EulerLagrange, EulerLagrangeBatch, EulerLagrangeOutput};
use musculo::model::Model;
use musculo::random::SplitMix64;
use std::sync::Arc;
use std::time::Instant;

/// The training run's settings.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct TrainConfig {
    pub steps: usize,
    /// B, windows per step.
    pub batch: usize,
    /// T, frames per window (a multiple of the autoencoder's k).
    pub window: usize,
    pub learning_rate: f64,
    pub seed: u64,
    /// The physics terms; both weights 0 trains on the reconstruction alone.
    pub physics: PhysicsWeights,
    /// w_a, the activation-bound penalty.
    pub bound_weight: f64,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            steps: 2000,
            batch: 8,
            window: 64,
            learning_rate: 1e-3,
            seed: 0,
            physics: PhysicsWeights::default(),
            bound_weight: 1.0,
        }
    }
}

/// One step's losses (the weighted terms' values before weighting) and the time so far.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StepLog {
    pub step: usize,
    pub total: f64,
    pub reconstruction: f64,
    pub euler: f64,
    pub muscle: f64,
    pub bounds: f64,
    pub seconds: f64,
}

impl StepLog {
    /// The CSV header of [`Self::csv_row`].
    pub const CSV_HEADER: &'static str = "step,total,reconstruction,euler,muscle,bounds,seconds";

    /// One CSV row.
    pub fn csv_row(&self) -> String {
        format!(
            "{},{:e},{:e},{:e},{:e},{:e},{:.3}",
            self.step,
            self.total,
            self.reconstruction,
            self.euler,
            self.muscle,
            self.bounds,
            self.seconds
        )
    }
}

/// A trained autoencoder with what it needs to be used: its sizes and the standardization.
#[derive(Debug)]
pub struct Trained {
    pub model: Autoencoder,
    pub config: AutoencoderConfig,
    pub normalizer: Normalizer,
    pub layout: FeatureLayout,
    pub log: Vec<StepLog>,
}

/// Where a training run stands after its last finished step: enough to continue it exactly as
/// an uninterrupted run would have (the network, Adam's moments, the window generator's state
/// and the log so far).
pub struct TrainState {
    /// The network on the training (autodiff) device.
    pub net: Autoencoder,
    pub optimizer: ModuleOptimizer,
    /// The SplitMix64 state of the window draws.
    pub rng: u64,
    /// The steps done (the next step's index).
    pub step: usize,
    /// One entry per step done.
    pub log: Vec<StepLog>,
}

impl TrainState {
    /// A fresh run of `config` under `train` on `device`: the seeded initialization, Adam
    /// without moments, the window generator at the seed.
    pub fn new(config: &AutoencoderConfig, train: &TrainConfig, device: &Device) -> TrainState {
        let net = {
            let _held = crate::INITIALIZATION.lock();
            device.seed(train.seed);
            config.init(device)
        };
        TrainState {
            net,
            optimizer: AdamConfig::new().init(),
            rng: SplitMix64(musculo::random::mix(train.seed)).0,
            step: 0,
            log: Vec::new(),
        }
    }
}

/// Trains an autoencoder of `config` on `set` (`model`: the musculoskeletal model the clips
/// were augmented with, the physics terms' body 0; the other bodies of the set,
/// [`ClipSet::bodies`], the clips' own) on `device` (an autodiff device), calling
/// `progress` after each step with the run's state (its log ends with that step's losses; to
/// show progress and save snapshots a run can continue from, [`continue_training`]).
pub fn train_autoencoder(
    set: &ClipSet,
    model: &Model,
    config: &AutoencoderConfig,
    train: &TrainConfig,
    device: &Device,
    progress: &mut dyn FnMut(&TrainState),
) -> Result<Trained> {
    validate(set, config, train)?;
    let state = TrainState::new(config, train, device);
    continue_training(set, model, config, train, device, state, progress)
}

/// Runs the steps of `train` that `state` has not done yet (see [`train_autoencoder`]); for a
/// state saved by an interrupted run with the same set, model and settings, the result is the
/// uninterrupted run's.
pub fn continue_training(
    set: &ClipSet,
    model: &Model,
    config: &AutoencoderConfig,
    train: &TrainConfig,
    device: &Device,
    mut state: TrainState,
    progress: &mut dyn FnMut(&TrainState),
) -> Result<Trained> {
    validate(set, config, train)?;
    if state.step > train.steps || state.log.len() != state.step {
        return Err(LearnError::invalid(
            "training",
            format!(
                "the state has done {} steps with {} log entries, the run has {}",
                state.step,
                state.log.len(),
                train.steps
            ),
        ));
    }
    let d = set.layout.width();
    let normalizer = Normalizer::of(set);
    let physics = if train.physics.euler > 0.0 || train.physics.muscle > 0.0 {
        Some(Arc::new(Physics::with_bodies(
            &bodies(set, model),
            set.layout.clone(),
            normalizer.clone(),
            train.physics,
        )?))
    } else {
        None
    };
    let mut rng = SplitMix64(state.rng);
    let total_frames = set.frames();
    let (b, t) = (train.batch, train.window);
    let acts = set.layout.block("muscle_act");
    let (a_mean, a_std): (Vec<f32>, Vec<f32>) = acts
        .clone()
        .map(|i| (normalizer.mean[i], normalizer.std[i]))
        .unzip();
    let a_mean = Tensor::<1>::from_floats(a_mean.as_slice(), device).reshape([1, 1, acts.len()]);
    let a_std = Tensor::<1>::from_floats(a_std.as_slice(), device).reshape([1, 1, acts.len()]);
    let start = Instant::now();
    let earlier = state.log.last().map_or(0.0, |s| s.seconds);
    for step in state.step..train.steps {
        let mut batch = Vec::with_capacity(b * t * d);
        let mut bodies = Vec::with_capacity(b);
        for _ in 0..b {
            let mut pick = (rng.unit() * total_frames as f64) as usize;
            let mut c = 0;
            while pick >= set.clips[c].frames {
                pick -= set.clips[c].frames;
                c += 1;
            }
            let clip = &set.clips[c];
            let s = (rng.unit() * (clip.frames - t + 1) as f64) as usize;
            batch.extend_from_slice(&clip.y[s * d..(s + t) * d]);
            bodies.push(clip.body);
        }
        // standardized per batch: the set is held once, in SI units
        normalizer.normalize(&mut batch);
        let z = Tensor::<3>::from_data(TensorData::new(batch, [b, t, d]), device);
        let z_hat = state.net.forward(z.clone());
        let reconstruction = (z_hat.clone() - z).powf_scalar(2.0).mean();
        let mut loss = reconstruction.clone();
        let (mut euler, mut muscle) = (0.0, 0.0);
        if let Some(physics) = &physics {
            let call = PhysicsCall::new(physics.clone(), bodies.clone());
            loss = loss + physics_loss(z_hat.clone(), call.clone()).reshape([1]);
            let parts = call.outcome()?;
            euler = parts.euler;
            muscle = parts.muscle;
        }
        let a = z_hat.slice([0..b, 0..t, acts.clone()]) * a_std.clone() + a_mean.clone();
        let outside = relu(-a.clone()) + relu(a - 1.0);
        let bounds = (outside / a_std.clone()).powf_scalar(2.0).mean();
        if train.bound_weight > 0.0 {
            loss = loss + bounds.clone() * train.bound_weight;
        }
        let total: f64 = loss.clone().into_scalar::<f32>() as f64;
        if !total.is_finite() {
            return Err(LearnError::invalid(
                "training",
                format!("step {step}: the loss is {total} (lower the learning rate)"),
            ));
        }
        let grads = GradientsParams::from_grads(loss.backward(), &state.net);
        let lr = cosine_learning_rate(train.learning_rate, step, train.steps);
        state.net = state.optimizer.step(lr, state.net.clone(), grads);
        let entry = StepLog {
            step,
            total,
            reconstruction: reconstruction.into_scalar::<f32>() as f64,
            euler,
            muscle,
            bounds: bounds.into_scalar::<f32>() as f64,
            seconds: earlier + start.elapsed().as_secs_f64(),
        };
        state.log.push(entry);
        state.step = step + 1;
        state.rng = rng.0;
        progress(&state);
    }
    Ok(Trained {
        model: state.net.valid(),
        config: AutoencoderConfig { ..config.clone() },
        normalizer,
        layout: set.layout.clone(),
        log: state.log,
    })
}

/// The learning rate at `step` of `steps`: a cosine from `initial` to a tenth of it,
/// lr = initial · (0.1 + 0.9 · (1 + cos(π step / steps)) / 2).
pub fn cosine_learning_rate(initial: f64, step: usize, steps: usize) -> f64 {
    let fraction = step as f64 / steps.max(1) as f64;
    initial * (0.1 + 0.45 * (1.0 + (std::f64::consts::PI * fraction).cos()))
}

fn validate(set: &ClipSet, config: &AutoencoderConfig, train: &TrainConfig) -> Result<()> {
    let bad = |m: String| Err(LearnError::invalid("training settings", m));
    if config.features != set.layout.width() {
        return bad(format!(
            "the autoencoder takes {} features, the data have {}",
            config.features,
            set.layout.width()
        ));
    }
    if train.window == 0
        || config.downsample == 0
        || !train.window.is_multiple_of(config.downsample)
    {
        return bad(format!(
            "window {} must be a positive multiple of the downsampling {}",
            train.window, config.downsample
        ));
    }
    if train.window > config.max_frames {
        return bad(format!(
            "window {} is longer than the position encoding's {} frames",
            train.window, config.max_frames
        ));
    }
    if train.batch == 0 || train.steps == 0 {
        return bad("batch and steps must be ≥ 1".into());
    }
    if !(train.learning_rate > 0.0 && train.learning_rate.is_finite()) {
        return bad(format!("learning rate {}", train.learning_rate));
    }
    if let Some(c) = set.clips.iter().find(|c| c.frames < train.window) {
        return bad(format!(
            "clip {} has {} frames, fewer than the window of {} (shorten --window)",
            c.name, c.frames, train.window
        ));
    }
    if config.heads == 0 || !config.d_model.is_multiple_of(config.heads) {
        return bad(format!(
            "d_model {} is not a multiple of {} heads",
            config.d_model, config.heads
        ));
    }
    Ok(())
}

/// A clip's frames decoded by a trained autoencoder, in SI units (T × D).
#[derive(Clone, Debug)]
pub struct Reconstruction {
    pub name: String,
    pub frames: usize,
    pub y: Vec<f32>,
}

/// Every clip of `set` through `trained` (inference device `device`), in windows of `window`
/// frames (a multiple of k, at most the shortest clip); overlapping frames of a clip's last
/// window take that window's values.
pub fn reconstruct(
    trained: &Trained,
    set: &ClipSet,
    window: usize,
    device: &Device,
) -> Result<Vec<Reconstruction>> {
    let d = set.layout.width();
    let k = trained.model.downsample();
    if set.layout != trained.layout {
        return Err(LearnError::invalid(
            "reconstruction",
            "the data's layout differs from the model's",
        ));
    }
    if window == 0 || !window.is_multiple_of(k) {
        return Err(LearnError::invalid(
            "reconstruction",
            format!("window {window} is not a positive multiple of {k}"),
        ));
    }
    let mut out = Vec::new();
    for clip in &set.clips {
        if clip.frames < window {
            return Err(LearnError::invalid(
                "reconstruction",
                format!("clip {} is shorter than the window {window}", clip.name),
            ));
        }
        let mut z = clip.y.clone();
        trained.normalizer.normalize(&mut z);
        let mut starts: Vec<usize> = (0..=clip.frames - window).step_by(window).collect();
        if starts.last() != Some(&(clip.frames - window)) {
            starts.push(clip.frames - window);
        }
        let mut batch = Vec::with_capacity(starts.len() * window * d);
        for s in &starts {
            batch.extend_from_slice(&z[s * d..(s + window) * d]);
        }
        let input =
            Tensor::<3>::from_data(TensorData::new(batch, [starts.len(), window, d]), device);
        let decoded: Vec<f32> = trained
            .model
            .forward(input)
            .into_data()
            .try_to_vec::<f32>()
            .map_err(|e| LearnError::invalid("reconstruction", format!("{e:?}")))?;
        let mut y = vec![0.0f32; clip.frames * d];
        for (w, s) in starts.iter().enumerate() {
            let src = &decoded[w * window * d..(w + 1) * window * d];
            y[s * d..(s + window) * d].copy_from_slice(src);
        }
        trained.normalizer.denormalize(&mut y);
        out.push(Reconstruction {
            name: clip.name.clone(),
            frames: clip.frames,
            y,
        });
    }
    Ok(out)
}

/// What a reconstruction kept: errors against the clip and its physics.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ReconstructionQuality {
    /// Mean over frames and joints of ‖p̂ − p‖ (m).
    pub joint_pos_error: f64,
    /// Root mean square of the decoded frames' Euler–Lagrange residual r (N·m or N per
    /// coordinate, all coordinates and frames).
    pub residual_rms: f64,
    /// The same of the original frames (≈ 0 for `musculo augment` output).
    pub residual_rms_data: f64,
    /// RMS of the original τ, the scale residuals are read against.
    pub tau_rms: f64,
}

/// The models of `set`'s bodies, body 0 (the model the set was read for) being `model`.
fn bodies(set: &ClipSet, model: &Model) -> Vec<Arc<Model>> {
    let mut models = set.body_models();
    if let Some(first) = models.first_mut() {
        *first = Arc::new(model.clone());
    }
    models
}

/// Joint-position error and residuals of `recon` against `set` (clips in the same order), each
/// clip's residual on its own body with its contact set (body 0 `model`, the others
/// [`ClipSet::bodies`]); clips without a body ([`crate::data::Clip::body`]) are left out.
pub fn quality(
    set: &ClipSet,
    recon: &[Reconstruction],
    model: &Model,
) -> Result<ReconstructionQuality> {
    let layout = &set.layout;
    let d = layout.width();
    let pos = layout.block("joint_pos");
    let (mut err, mut count) = (0.0, 0usize);
    for (clip, rec) in set.clips.iter().zip(recon) {
        for f in 0..clip.frames {
            for j in 0..layout.joints {
                let i = f * d + pos.start + 3 * j;
                let e: f64 = (0..3)
                    .map(|c| (clip.y[i + c] - rec.y[i + c]) as f64)
                    .map(|v| v * v)
                    .sum();
                err += e.sqrt();
                count += 1;
            }
        }
    }
    let models = bodies(set, model);
    let mut eulers = Vec::with_capacity(models.len());
    for body in &models {
        eulers.push(if layout.contacts > 0 {
            EulerLagrange::new().with_contact_set(&musculo::augment::chain::contact_set(body)?)
        } else {
            EulerLagrange::new()
        });
    }
    let residual_rms = |frames: &[(&[f32], usize, usize)]| -> Result<(f64, f64)> {
        let (mut sum, mut tau_sum, mut n_values) = (0.0, 0.0, 0usize);
        for (y, t, body) in frames {
            let get = |name: &str| -> Vec<f64> {
                let r = layout.block(name);
                (0..*t)
                    .flat_map(|f| r.clone().map(move |i| y[f * d + i] as f64))
                    .collect()
            };
            let (q, qd, qdd, tau, lambda) = (
                get("q"),
                get("qd"),
                get("qdd"),
                get("tau"),
                get("contact_point_force"),
            );
            let batch = EulerLagrangeBatch {
                frames: *t,
                q: &q,
                qd: &qd,
                qdd: &qdd,
                tau: &tau,
                lambda: &lambda,
            };
            let mut out = EulerLagrangeOutput::default();
            eulers[*body].evaluate(&models[*body], &batch, false, &mut out)?;
            sum += out.residual.iter().map(|r| r * r).sum::<f64>();
            tau_sum += tau.iter().map(|v| v * v).sum::<f64>();
            n_values += out.residual.len();
        }
        let n = n_values.max(1) as f64;
        Ok(((sum / n).sqrt(), (tau_sum / n).sqrt()))
    };
    let own: Vec<(&[f32], usize, usize)> = set
        .clips
        .iter()
        .filter_map(|c| Some((c.y.as_slice(), c.frames, c.body?)))
        .collect();
    let decoded: Vec<(&[f32], usize, usize)> = set
        .clips
        .iter()
        .zip(recon)
        .filter_map(|(c, r)| Some((r.y.as_slice(), r.frames, c.body?)))
        .collect();
    let (residual_rms_data, tau_rms) = residual_rms(&own)?;
    let (residual_rms, _) = residual_rms(&decoded)?;
    Ok(ReconstructionQuality {
        joint_pos_error: err / count.max(1) as f64,
        residual_rms,
        residual_rms_data,
        tau_rms,
    })
}

/// The autoencoder's parameter count.
pub fn parameters(model: &Autoencoder) -> usize {
    model.num_params()
}
