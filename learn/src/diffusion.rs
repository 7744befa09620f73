//! Latent diffusion over the autoencoder's latents, conditioned on text and on spatial controls
//! (FlexMotion §3.2), with DDPM training, DDIM sampling and EnergyMoGen's composition of
//! concepts.
//!
//! **Noise schedule** (Ho et al. 2020, N steps, β linear from β₁ to β_N):
//!
//! ```text
//! ᾱ_t = Π_{s≤t} (1 − β_s)
//! h_t = √ᾱ_t h₀ + √(1 − ᾱ_t) ε,   ε ~ N(0, I)          h₀ = latent / s (s: the set's latent RMS)
//! L = E ‖ε − ε_θ(h_t, t, e, c)‖²                         (the denoiser predicts the noise)
//! ```
//!
//! with N = 100 and β from 10⁻³ to 0.2 (the 1,000-step schedule's 10⁻⁴…0.02 stretched to 100
//! steps). **Sampling** is DDIM (Song et al. 2021) with η = 0 over a strided subset τ₁ > … > τ_S
//! of the steps:
//!
//! ```text
//! ĥ₀ = (h_τ − √(1 − ᾱ_τ) ε̂) / √ᾱ_τ,   h_τ' = √ᾱ_τ' ĥ₀ + √(1 − ᾱ_τ') ε̂
//! ```
//!
//! Training windows (a clip with probability ∝ its frames, a uniform start) are encoded by the
//! frozen autoencoder as they are drawn, so a large set costs no memory beyond its frames; the
//! latent scale s is the latents' RMS over up to 256 windows spread evenly over the set.
//!
//! **Conditions**: e, a caption's vector ([`crate::text`]), enters through a linear layer added
//! to every latent token; c, the spatial controls, are masked targets in the standardized frame
//! features z — per frame the values m ⊙ z and the mask m for any subset of features (joint
//! positions, torques, contact forces, activations…) — grouped k frames per latent token and
//! added through a linear layer. Training drops the caption (e = 0) with probability 0.1 and
//! draws the controls at random: none with probability ½, otherwise one modality block (a random
//! subset of joints for the joint positions) on a random span of frames.
//!
//! **Guidance and composition** (classifier-free guidance, Ho & Salimans 2022; EnergyMoGen's
//! latent-energy composition): with ε_∅ the prediction without caption, the prediction used for a
//! set of concepts {(e_i, w_i)} is
//!
//! ```text
//! ε̂ = ε_∅ + Σ_i w_i (ε(e_i) − ε_∅)
//! ```
//!
//! a sum of the concepts' scores: w_i > 0 for a concept to be present (conjunction, "A and B"),
//! w_i < 0 for one to be absent (negation, "A but not B"). The controls enter every term.
//!
//! **Spatial guidance** (OmniControl's, on the latent): at each DDIM step the clean estimate ĥ₀
//! takes G normalized gradient steps (with a halving line search) on
//! E(ĥ₀) = Σ m ⊙ (D(s ĥ₀) − z*)² / Σ m — the controlled features'
//! mean square error after decoding — before ε̂ is recomputed from it and the step is taken, so
//! the motion meets its controls without leaving what the denoiser considers likely.

use crate::autoencoder::Autoencoder;
use crate::data::{ClipSet, FeatureLayout, LearnError};
use burn::config::Config;
use burn::module::Module;
use burn::nn::transformer::{
    TransformerEncoder, TransformerEncoderConfig, TransformerEncoderInput,
};
use burn::nn::{Linear, LinearConfig, PositionalEncoding, PositionalEncodingConfig};
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::activation::gelu;
use burn::tensor::{Device, Tensor, TensorData};
use musculo::random::SplitMix64;
use std::time::Instant;

/// N, the diffusion steps.
pub const STEPS: usize = 100;

/// The noise schedule: ᾱ_t for t = 0 … N−1.
pub fn alpha_bar() -> Vec<f64> {
    let (b1, bn) = (1e-3, 0.2);
    let mut acc = 1.0;
    (0..STEPS)
        .map(|t| {
            let beta = b1 + (bn - b1) * t as f64 / (STEPS - 1) as f64;
            acc *= 1.0 - beta;
            acc
        })
        .collect()
}

/// The denoiser's sizes.
#[derive(Config, Debug)]
pub struct DenoiserConfig {
    /// c, the latent width per token.
    pub latent: usize,
    /// D, the frame features (for the controls).
    pub features: usize,
    /// k, frames per latent token.
    pub downsample: usize,
    /// E, the caption vector's width.
    pub text: usize,
    #[config(default = 128)]
    pub d_model: usize,
    #[config(default = 4)]
    pub heads: usize,
    #[config(default = 3)]
    pub layers: usize,
    #[config(default = 256)]
    pub d_ff: usize,
    #[config(default = 256)]
    pub max_tokens: usize,
}

/// ε_θ(h_t, t, e, c): a Transformer over the latent tokens (module docs).
#[derive(Module, Debug)]
pub struct Denoiser {
    input: Linear,
    position: PositionalEncoding,
    time_1: Linear,
    time_2: Linear,
    text: Linear,
    control: Linear,
    body: TransformerEncoder,
    output: Linear,
    d_model: usize,
}

impl DenoiserConfig {
    pub fn init(&self, device: &Device) -> Denoiser {
        let d = self.d_model;
        Denoiser {
            input: LinearConfig::new(self.latent, d).init(device),
            position: PositionalEncodingConfig::new(d)
                .with_max_sequence_size(self.max_tokens)
                .init(device),
            time_1: LinearConfig::new(d, d).init(device),
            time_2: LinearConfig::new(d, d).init(device),
            text: LinearConfig::new(self.text, d).init(device),
            control: LinearConfig::new(2 * self.downsample * self.features, d).init(device),
            body: TransformerEncoderConfig::new(d, self.d_ff, self.heads, self.layers)
                .with_norm_first(true)
                .with_dropout(0.0)
                .init(device),
            output: LinearConfig::new(d, self.latent).init(device),
            d_model: d,
        }
    }
}

/// The sinusoidal embedding of diffusion steps `t` (B values) in `d` dimensions.
fn step_embedding(t: &[usize], d: usize, device: &Device) -> Tensor<2> {
    let half = d / 2;
    let mut v = Vec::with_capacity(t.len() * d);
    for &s in t {
        for i in 0..d {
            let f = (-(10_000f64.ln()) * (i % half) as f64 / half as f64).exp();
            let a = s as f64 * f;
            v.push(if i < half { a.sin() } else { a.cos() } as f32);
        }
    }
    Tensor::<2>::from_data(TensorData::new(v, [t.len(), d]), device)
}

impl Denoiser {
    /// ε̂ for noisy latents `h` (B × S × c) at steps `t`, captions `e` (B × E) and controls `c`
    /// (B × S × 2kD).
    pub fn forward(&self, h: Tensor<3>, t: &[usize], e: Tensor<2>, c: Tensor<3>) -> Tensor<3> {
        let [b, _, _] = h.dims();
        let device = h.device();
        let time = self.time_2.forward(gelu(self.time_1.forward(step_embedding(
            t,
            self.d_model,
            &device,
        ))));
        let global = (time + self.text.forward(e)).reshape([b, 1, self.d_model]);
        let x = self.position.forward(self.input.forward(h)) + self.control.forward(c) + global;
        self.output
            .forward(self.body.forward(TransformerEncoderInput::new(x)))
    }
}

/// A spatial control: targets for some features of some frames, in SI units (as the frames of
/// [`crate::data`]).
#[derive(Clone, Debug, Default)]
pub struct Control {
    /// T × D targets (values where `mask` is 0 are ignored).
    pub target: Vec<f32>,
    /// T × D, 1 where a feature of a frame is controlled.
    pub mask: Vec<f32>,
}

impl Control {
    /// No control over `frames` frames of `width` features.
    pub fn none(frames: usize, width: usize) -> Control {
        Control {
            target: vec![0.0; frames * width],
            mask: vec![0.0; frames * width],
        }
    }

    /// Controls `block` of `layout` on `frames` to `values` (the frames' full feature rows).
    pub fn set_block(
        &mut self,
        layout: &FeatureLayout,
        block: &str,
        frames: std::ops::Range<usize>,
        values: &[f32],
    ) {
        let d = layout.width();
        for f in frames {
            for i in layout.block(block) {
                self.target[f * d + i] = values[f * d + i];
                self.mask[f * d + i] = 1.0;
            }
        }
    }
}

/// The control input of the denoiser for `controls` (one per sequence, standardized here with
/// `normalizer`): B × T/k × 2kD, per frame [m ⊙ z, m].
fn control_tensor(
    controls: &[&Control],
    frames: usize,
    k: usize,
    normalizer: &crate::data::Normalizer,
    device: &Device,
) -> Tensor<3> {
    let d = normalizer.mean.len();
    let mut v = Vec::with_capacity(controls.len() * frames * 2 * d);
    for c in controls {
        for f in 0..frames {
            for i in 0..d {
                let m = c.mask[f * d + i];
                let z = (c.target[f * d + i] - normalizer.mean[i]) / normalizer.std[i];
                v.push(m * z);
            }
            v.extend_from_slice(&c.mask[f * d..(f + 1) * d]);
        }
    }
    Tensor::<3>::from_data(
        TensorData::new(v, [controls.len(), frames / k, k * 2 * d]),
        device,
    )
}

/// Training settings of the denoiser.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct DiffusionTrainConfig {
    pub steps: usize,
    pub batch: usize,
    /// Frames per window (a multiple of k).
    pub window: usize,
    pub learning_rate: f64,
    pub seed: u64,
}

impl Default for DiffusionTrainConfig {
    fn default() -> Self {
        DiffusionTrainConfig {
            steps: 3000,
            batch: 16,
            window: 64,
            learning_rate: 1e-3,
            seed: 0,
        }
    }
}

/// A trained denoiser with the latent scale s and the caption width.
#[derive(Debug)]
pub struct TrainedDenoiser {
    pub model: Denoiser,
    pub config: DenoiserConfig,
    pub latent_scale: f32,
    pub log: Vec<(usize, f64, f64)>,
}

/// Where a denoiser's training stands after its last finished step: enough to continue it
/// exactly as an uninterrupted run would have.
pub struct DenoiserState {
    /// The network on the training (autodiff) device.
    pub net: Denoiser,
    pub optimizer: ModuleOptimizer,
    /// The SplitMix64 state of the draws (windows, noise, steps, captions, controls).
    pub rng: u64,
    /// The steps done.
    pub step: usize,
    /// (step, loss, seconds) per step done.
    pub log: Vec<(usize, f64, f64)>,
}

impl DenoiserState {
    /// A fresh run: the seeded initialization, Adam without moments, the generator at the seed.
    pub fn new(
        config: &DenoiserConfig,
        train: &DiffusionTrainConfig,
        device: &Device,
    ) -> DenoiserState {
        let net = {
            let _held = crate::INITIALIZATION.lock();
            device.seed(train.seed);
            config.init(device)
        };
        DenoiserState {
            net,
            optimizer: AdamConfig::new().init(),
            rng: SplitMix64(musculo::random::mix(train.seed ^ 0x5eed)).0,
            step: 0,
            log: Vec::new(),
        }
    }
}

/// One training step of the denoiser, as `progress` sees it.
pub struct DenoiserStep<'a> {
    pub step: usize,
    pub loss: f64,
    /// Seconds since training began (over all the run's sessions).
    pub seconds: f64,
    /// The run after the step (its `net` is the network as it now is).
    pub state: &'a DenoiserState,
    /// s, the latent scale.
    pub latent_scale: f32,
}

/// A normal sample from the generator (Box–Muller).
fn normal(rng: &mut SplitMix64) -> f32 {
    let u1 = rng.unit().max(1e-300);
    let u2 = rng.unit();
    ((-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()) as f32
}

/// The latents of windows `(clip, start)` of `window` frames through the frozen autoencoder
/// `ae` (inference device), from the set's clips standardized by `normalizer`; W × T/k × c
/// values out, windows in order.
fn encode_windows(
    ae: &Autoencoder,
    set: &ClipSet,
    normalizer: &crate::data::Normalizer,
    windows: &[(usize, usize)],
    window: usize,
    device: &Device,
) -> Vec<f32> {
    let d = set.layout.width();
    let mut batch = Vec::with_capacity(windows.len() * window * d);
    for &(ci, s) in windows {
        batch.extend_from_slice(&set.clips[ci].y[s * d..(s + window) * d]);
    }
    normalizer.normalize(&mut batch);
    let x = Tensor::<3>::from_data(TensorData::new(batch, [windows.len(), window, d]), device);
    ae.encode(x)
        .into_data()
        .try_to_vec::<f32>()
        .unwrap_or_default()
}

/// Trains a denoiser on the latents of `set` under the trained autoencoder `ae` (with its
/// standardization `normalizer`), each clip captioned by `texts[clip]` (E values each), calling
/// `progress` after each step ([`DenoiserStep`]: the step, its loss and the run as it now is,
/// to save snapshots a run can continue from, [`continue_denoiser`]).
#[allow(clippy::too_many_arguments)]
pub fn train_denoiser(
    set: &ClipSet,
    ae: &Autoencoder,
    normalizer: &crate::data::Normalizer,
    texts: &[Vec<f32>],
    config: &DenoiserConfig,
    train: &DiffusionTrainConfig,
    device: &Device,
    progress: &mut dyn FnMut(&DenoiserStep),
) -> crate::data::Result<TrainedDenoiser> {
    let state = DenoiserState::new(config, train, device);
    continue_denoiser(
        set, ae, normalizer, texts, config, train, device, state, progress,
    )
}

/// Runs the steps of `train` that `state` has not done yet (see [`train_denoiser`]); from a
/// state saved by an interrupted run with the same inputs and settings, the result is the
/// uninterrupted run's.
#[allow(clippy::too_many_arguments)]
pub fn continue_denoiser(
    set: &ClipSet,
    ae: &Autoencoder,
    normalizer: &crate::data::Normalizer,
    texts: &[Vec<f32>],
    config: &DenoiserConfig,
    train: &DiffusionTrainConfig,
    device: &Device,
    mut state: DenoiserState,
    progress: &mut dyn FnMut(&DenoiserStep),
) -> crate::data::Result<TrainedDenoiser> {
    check_run(set, texts, config, train, &state)?;
    // the frozen autoencoder runs on the training device without autodiff
    let inference = device.clone().inner();
    let ae = &ae.clone().to_device(&inference);
    let rms = latent_scale(ae, set, normalizer, train.window, &inference);
    let source = BatchSource {
        set,
        ae,
        normalizer,
        texts,
        config,
        batch: train.batch,
        window: train.window,
        inference: &inference,
        latent_scale: rms,
        alpha_bar: alpha_bar(),
    };
    let mut rng = SplitMix64(state.rng);
    let start = Instant::now();
    let earlier = state.log.last().map_or(0.0, |s| s.2);
    for step in state.step..train.steps {
        let batch = source.draw(&mut rng);
        let loss = batch.loss(&state.net, &source, device);
        let value = loss.clone().into_scalar::<f32>() as f64;
        if !value.is_finite() {
            return Err(LearnError::invalid(
                "diffusion training",
                format!("step {step}: the loss is {value}"),
            ));
        }
        let grads = GradientsParams::from_grads(loss.backward(), &state.net);
        let lr = crate::train::cosine_learning_rate(train.learning_rate, step, train.steps);
        state.net = state.optimizer.step(lr, state.net.clone(), grads);
        let seconds = earlier + start.elapsed().as_secs_f64();
        state.log.push((step, value, seconds));
        state.step = step + 1;
        state.rng = rng.0;
        progress(&DenoiserStep {
            step,
            loss: value,
            seconds,
            state: &state,
            latent_scale: rms,
        });
    }
    Ok(TrainedDenoiser {
        model: state.net.valid(),
        config: DenoiserConfig { ..config.clone() },
        latent_scale: rms,
        log: state.log,
    })
}

/// Checks that `state` belongs to a run of `train`, that the window fits the denoiser and
/// every clip, and that every clip has its caption.
fn check_run(
    set: &ClipSet,
    texts: &[Vec<f32>],
    config: &DenoiserConfig,
    train: &DiffusionTrainConfig,
    state: &DenoiserState,
) -> crate::data::Result<()> {
    if state.step > train.steps || state.log.len() != state.step {
        return Err(LearnError::invalid(
            "diffusion training",
            format!(
                "the state has done {} steps with {} log entries, the run has {}",
                state.step,
                state.log.len(),
                train.steps
            ),
        ));
    }
    let k = config.downsample;
    let t = train.window;
    if t == 0 || !t.is_multiple_of(k) || t / k > config.max_tokens {
        return Err(LearnError::invalid(
            "diffusion training",
            format!(
                "window {t} must be a positive multiple of {k}, at most {} tokens",
                config.max_tokens
            ),
        ));
    }
    if texts.len() != set.clips.len() || texts.iter().any(|e| e.len() != config.text) {
        return Err(LearnError::invalid(
            "diffusion training",
            format!("need one caption vector of {} values per clip", config.text),
        ));
    }
    if let Some(c) = set.clips.iter().find(|c| c.frames < t) {
        return Err(LearnError::invalid(
            "diffusion training",
            format!(
                "clip {} has {} frames, fewer than the window {t}",
                c.name, c.frames
            ),
        ));
    }
    Ok(())
}

/// s: the latents' RMS over up to 256 windows of `window` frames spread evenly over the set's
/// window starts.
fn latent_scale(
    ae: &Autoencoder,
    set: &ClipSet,
    normalizer: &crate::data::Normalizer,
    window: usize,
    inference: &Device,
) -> f32 {
    let t = window;
    let starts: Vec<(usize, usize)> = set
        .clips
        .iter()
        .enumerate()
        .flat_map(|(ci, clip)| (0..=clip.frames - t).map(move |s| (ci, s)))
        .collect();
    let probe: Vec<(usize, usize)> = (0..starts.len().min(256))
        .map(|i| starts[i * starts.len() / starts.len().min(256)])
        .collect();
    let (mut sum, mut count) = (0.0f64, 0usize);
    for chunk in probe.chunks(32) {
        let h = encode_windows(ae, set, normalizer, chunk, t, inference);
        sum += h.iter().map(|v| (*v as f64).powi(2)).sum::<f64>();
        count += h.len();
    }
    (sum / count.max(1) as f64).sqrt().max(1e-6) as f32
}

/// What a training batch is drawn from: the set, its captions and the frozen autoencoder.
struct BatchSource<'a> {
    set: &'a ClipSet,
    /// The frozen autoencoder, on `inference`.
    ae: &'a Autoencoder,
    normalizer: &'a crate::data::Normalizer,
    texts: &'a [Vec<f32>],
    config: &'a DenoiserConfig,
    /// B windows of T frames per batch.
    batch: usize,
    window: usize,
    inference: &'a Device,
    /// s, the latent scale.
    latent_scale: f32,
    alpha_bar: Vec<f64>,
}

/// One training batch: the noised latents h_t = √ᾱ h₀/s + √(1 − ᾱ) ε, the noise ε, the
/// diffusion steps, the captions (dropped to zeros one time in ten) and the controls.
struct Batch {
    h_t: Vec<f32>,
    eps: Vec<f32>,
    steps: Vec<usize>,
    text: Vec<f32>,
    controls: Vec<Control>,
}

/// The blocks a random training control constrains.
const CONTROL_BLOCKS: [&str; 5] = ["joint_pos", "tau", "contact_point_force", "muscle_act", "q"];

impl BatchSource<'_> {
    /// Draws a batch: B windows (a clip with probability ∝ its frames, a uniform start)
    /// encoded together, then per window a step, the noise, the caption and a control.
    fn draw(&self, rng: &mut SplitMix64) -> Batch {
        let (b, t) = (self.batch, self.window);
        let (set, config) = (self.set, self.config);
        let (tokens, c) = (t / config.downsample, config.latent);
        let mut batch = Batch {
            h_t: Vec::with_capacity(b * tokens * c),
            eps: Vec::with_capacity(b * tokens * c),
            steps: Vec::with_capacity(b),
            text: Vec::with_capacity(b * config.text),
            controls: Vec::with_capacity(b),
        };
        let total_frames = set.frames();
        let picks: Vec<(usize, usize)> = (0..b)
            .map(|_| {
                let mut pick = (rng.unit() * total_frames as f64) as usize;
                let mut ci = 0;
                while pick >= set.clips[ci].frames {
                    pick -= set.clips[ci].frames;
                    ci += 1;
                }
                let s = (rng.unit() * (set.clips[ci].frames - t + 1) as f64) as usize;
                (ci, s)
            })
            .collect();
        let latents = encode_windows(self.ae, set, self.normalizer, &picks, t, self.inference);
        let ab = &self.alpha_bar;
        let rms = self.latent_scale;
        for (w, &(ci, s)) in picks.iter().enumerate() {
            let h0 = &latents[w * tokens * c..(w + 1) * tokens * c];
            let ts = (rng.unit() * STEPS as f64) as usize;
            let (sa, sn) = (ab[ts].sqrt() as f32, (1.0 - ab[ts]).sqrt() as f32);
            for v in h0 {
                let e = normal(rng);
                batch.eps.push(e);
                batch.h_t.push(sa * v / rms + sn * e);
            }
            batch.steps.push(ts);
            if rng.unit() < 0.1 {
                batch.text.extend(std::iter::repeat_n(0.0, config.text));
            } else {
                batch.text.extend_from_slice(&self.texts[ci]);
            }
            batch.controls.push(self.random_control(ci, s, rng));
        }
        batch
    }

    /// A random control for the window of clip `ci` at frame `s`: none (½), or one block on a
    /// random span (for joint positions, a random subset of the joints).
    fn random_control(&self, ci: usize, s: usize, rng: &mut SplitMix64) -> Control {
        let (set, t) = (self.set, self.window);
        let d = set.layout.width();
        let mut control = Control::none(t, d);
        if rng.unit() >= 0.5 {
            let block = CONTROL_BLOCKS[(rng.unit() * CONTROL_BLOCKS.len() as f64) as usize];
            let a = (rng.unit() * t as f64) as usize;
            let len = 1 + (rng.unit() * (t - a) as f64) as usize;
            let clip = &set.clips[ci].y[s * d..(s + t) * d];
            control.set_block(&set.layout, block, a..a + len, clip);
            if block == "joint_pos" {
                // a random subset of the joints
                for j in 0..set.layout.joints {
                    if rng.unit() < 0.5 {
                        for f in a..a + len {
                            for x in 0..3 {
                                control.mask[f * d + 3 * j + x] = 0.0;
                            }
                        }
                    }
                }
            }
        }
        control
    }
}

impl Batch {
    /// The denoiser's loss on the batch, mean ‖ε̂(h_t, t, e, c) − ε‖², on `device`.
    fn loss(self, net: &Denoiser, source: &BatchSource, device: &Device) -> Tensor<1> {
        let config = source.config;
        let (b, t, k) = (source.batch, source.window, config.downsample);
        let (tokens, c) = (t / k, config.latent);
        let refs: Vec<&Control> = self.controls.iter().collect();
        let cond = control_tensor(&refs, t, k, source.normalizer, device);
        let h = Tensor::<3>::from_data(TensorData::new(self.h_t, [b, tokens, c]), device);
        let e = Tensor::<2>::from_data(TensorData::new(self.text, [b, config.text]), device);
        let target = Tensor::<3>::from_data(TensorData::new(self.eps, [b, tokens, c]), device);
        (net.forward(h, &self.steps, e, cond) - target)
            .powf_scalar(2.0)
            .mean()
    }
}

/// Spatial guidance: gradient steps on ĥ₀ that pull the decoded frames onto the controls.
struct Guidance {
    /// The autoencoder on the autodiff device (copied once per sampling run).
    net: Autoencoder,
    /// The sampling device (without autodiff).
    device: Device,
    /// Standardized targets and masks, count × frames × D.
    target: Vec<f32>,
    mask: Vec<f32>,
    controlled: f32,
    steps: usize,
    frames: usize,
}

impl Guidance {
    fn new(
        ae: &Autoencoder,
        device: &Device,
        control: &Control,
        count: usize,
        frames: usize,
        normalizer: &crate::data::Normalizer,
        steps: usize,
    ) -> Option<Guidance> {
        let controlled: f32 = control.mask.iter().sum::<f32>() * count as f32;
        if steps == 0 || controlled == 0.0 {
            return None;
        }
        let d = normalizer.mean.len();
        let mut target = Vec::with_capacity(count * frames * d);
        for _ in 0..count {
            for (i, v) in control.target.iter().enumerate() {
                let k = i % d;
                target.push((v - normalizer.mean[k]) / normalizer.std[k]);
            }
        }
        let mask = control.mask.repeat(count);
        Some(Guidance {
            net: ae.clone().to_device(&device.clone().autodiff()),
            device: device.clone(),
            target,
            mask,
            controlled,
            steps,
            frames,
        })
    }

    /// `steps` steps of normalized gradient descent on E(ĥ₀) = Σ m (D(s ĥ₀) − z*)² / Σ m with a
    /// halving line search: ĥ₀ ← ĥ₀ − α g/rms(g), α from ½ (ĥ₀ has unit scale) halved until E
    /// falls (at most 6 halvings; no step when none does).
    fn apply(
        &self,
        ae: &Autoencoder,
        h0: &mut [f32],
        shape: [usize; 3],
        scale: f32,
    ) -> crate::data::Result<()> {
        let plain = self.device.clone();
        let device = plain.clone().autodiff();
        let net = &self.net;
        let d = self.target.len() / (shape[0] * self.frames);
        let dims = [shape[0], self.frames, d];
        let target = Tensor::<3>::from_data(TensorData::new(self.target.clone(), dims), &device);
        let mask = Tensor::<3>::from_data(TensorData::new(self.mask.clone(), dims), &device);
        let error = |h: &[f32]| -> f32 {
            let x = Tensor::<3>::from_data(TensorData::new(h.to_vec(), shape), &plain);
            let z: Vec<f32> = ae
                .decode(x * scale)
                .into_data()
                .try_to_vec::<f32>()
                .unwrap_or_default();
            z.iter()
                .zip(&self.target)
                .zip(&self.mask)
                .map(|((z, t), m)| m * (z - t) * (z - t))
                .sum::<f32>()
                / self.controlled
        };
        let mut current = error(h0);
        for _ in 0..self.steps {
            let x =
                Tensor::<3>::from_data(TensorData::new(h0.to_vec(), shape), &device).require_grad();
            let z = net.decode(x.clone() * scale);
            let e = ((z - target.clone()) * mask.clone()).powf_scalar(2.0).sum() / self.controlled;
            let grads = e.backward();
            let g: Vec<f32> = x
                .grad(&grads)
                .map(|g| g.into_data().try_to_vec::<f32>().unwrap_or_default())
                .unwrap_or_default();
            if g.len() != h0.len() {
                return Err(LearnError::invalid(
                    "generate",
                    "guidance gradient unavailable",
                ));
            }
            let rms = (g.iter().map(|v| v * v).sum::<f32>() / g.len() as f32).sqrt();
            if !(rms > 0.0 && rms.is_finite()) {
                break;
            }
            let mut alpha = 0.5f32;
            let mut moved = false;
            for _ in 0..7 {
                let trial: Vec<f32> = h0
                    .iter()
                    .zip(&g)
                    .map(|(h, g)| h - alpha * g / rms)
                    .collect();
                let e = error(&trial);
                if e < current {
                    h0.copy_from_slice(&trial);
                    current = e;
                    moved = true;
                    break;
                }
                alpha *= 0.5;
            }
            if !moved {
                break;
            }
        }
        Ok(())
    }
}

/// ε̂ = ε_∅ + Σ_i w_i (ε_i − ε_∅) for `eps` = [ε_∅, ε_1, …] and `weights` = [w_1, …] (module
/// docs).
pub fn compose(eps: &[f32], weights: &[f32]) -> f32 {
    let base = eps[0];
    base + weights
        .iter()
        .zip(&eps[1..])
        .map(|(w, e)| w * (e - base))
        .sum::<f32>()
}

/// One DDIM step (η = 0) from h at ᾱ = `a` to ᾱ' = `a_next` with predicted noise `eps`:
/// ĥ₀ = (h − √(1−ᾱ) ε̂)/√ᾱ, h' = √ᾱ' ĥ₀ + √(1−ᾱ') ε̂ (module docs).
pub fn ddim_step(h: f32, eps: f32, a: f64, a_next: f64) -> f32 {
    let h0 = (h as f64 - (1.0 - a).sqrt() * eps as f64) / a.sqrt();
    (a_next.sqrt() * h0 + (1.0 - a_next).sqrt() * eps as f64) as f32
}

/// One concept of a prompt: a caption vector and its weight (negative: "not").
#[derive(Clone, Debug)]
pub struct Concept {
    pub text: Vec<f32>,
    pub weight: f32,
}

/// Samples `count` latent sequences of `frames` frames by DDIM with `sampling_steps` steps
/// under `concepts` and `control` (with `guidance` gradient steps of spatial guidance per DDIM
/// step, 0 for none), from seed `seed`, on `device` (without autodiff; the networks are copied
/// there); returns their decoded frames (SI units, `count` × frames × D) through `ae` and
/// `normalizer`.
#[allow(clippy::too_many_arguments)]
pub fn sample(
    denoiser: &TrainedDenoiser,
    ae: &Autoencoder,
    normalizer: &crate::data::Normalizer,
    concepts: &[Concept],
    control: &Control,
    frames: usize,
    count: usize,
    sampling_steps: usize,
    guidance: usize,
    seed: u64,
    device: &Device,
) -> crate::data::Result<Vec<f32>> {
    let cfg = &denoiser.config;
    let (k, c, d) = (cfg.downsample, cfg.latent, cfg.features);
    if frames == 0 || !frames.is_multiple_of(k) || frames / k > cfg.max_tokens {
        return Err(LearnError::invalid(
            "generate",
            format!(
                "frames {frames}: a positive multiple of {k}, at most {} tokens",
                cfg.max_tokens
            ),
        ));
    }
    if control.mask.len() != frames * d || control.target.len() != frames * d {
        return Err(LearnError::invalid(
            "generate",
            format!(
                "the control has {} values, expected {frames} × {d}",
                control.mask.len()
            ),
        ));
    }
    if let Some(bad) = concepts.iter().find(|e| e.text.len() != cfg.text) {
        return Err(LearnError::invalid(
            "generate",
            format!(
                "a caption vector has {} values, the model takes {}",
                bad.text.len(),
                cfg.text
            ),
        ));
    }
    if !(1..=STEPS).contains(&sampling_steps) || count == 0 {
        return Err(LearnError::invalid(
            "generate",
            format!("sampling steps {sampling_steps} must be 1 to {STEPS}, count ≥ 1"),
        ));
    }
    let device = device.clone().inner();
    let ae = &ae.clone().to_device(&device);
    let net = denoiser.model.clone().to_device(&device);
    let tokens = frames / k;
    let ab = alpha_bar();
    let mut rng = SplitMix64(musculo::random::mix(seed));
    let mut h: Vec<f32> = (0..count * tokens * c).map(|_| normal(&mut rng)).collect();
    // τ_1 > … > τ_S, evenly spaced from N−1 down
    let schedule: Vec<usize> = (0..sampling_steps)
        .map(|i| (STEPS - 1) - i * (STEPS - 1) / sampling_steps.max(1))
        .collect();
    let refs: Vec<&Control> = vec![control; count];
    let cond = control_tensor(&refs, frames, k, normalizer, &device);
    // the unconditional term and one term per concept, batched: (1 + |concepts|) × count
    let mut texts = vec![0.0f32; count * cfg.text];
    for concept in concepts {
        for _ in 0..count {
            texts.extend_from_slice(&concept.text);
        }
    }
    let guide = Guidance::new(ae, &device, control, count, frames, normalizer, guidance);
    let terms = 1 + concepts.len();
    let weights: Vec<f32> = concepts.iter().map(|c| c.weight).collect();
    let e = Tensor::<2>::from_data(TensorData::new(texts, [terms * count, cfg.text]), &device);
    let cond = Tensor::cat(vec![cond; terms], 0);
    for (i, &tau) in schedule.iter().enumerate() {
        let next = schedule.get(i + 1).copied();
        let x = Tensor::<3>::from_data(TensorData::new(h.clone(), [count, tokens, c]), &device);
        let x = Tensor::cat(vec![x; terms], 0);
        let eps: Vec<f32> = net
            .forward(x, &vec![tau; terms * count], e.clone(), cond.clone())
            .into_data()
            .try_to_vec::<f32>()
            .map_err(|e| LearnError::invalid("generate", format!("{e:?}")))?;
        let n = count * tokens * c;
        let (a, a_next) = (ab[tau], next.map_or(1.0, |s| ab[s]));
        let mut h0: Vec<f32> = (0..n)
            .map(|j| {
                let terms: Vec<f32> = (0..=concepts.len()).map(|ci| eps[ci * n + j]).collect();
                let e_hat = compose(&terms, &weights);
                ((h[j] as f64 - (1.0 - a).sqrt() * e_hat as f64) / a.sqrt()) as f32
            })
            .collect();
        if let Some(g) = &guide {
            g.apply(ae, &mut h0, [count, tokens, c], denoiser.latent_scale)?;
        }
        for j in 0..n {
            // ε̂ consistent with the (guided) ĥ₀, then the DDIM step
            let e_hat = ((h[j] as f64 - a.sqrt() * h0[j] as f64) / (1.0 - a).sqrt()) as f32;
            h[j] = ddim_step(h[j], e_hat, a, a_next);
        }
    }
    let scale = denoiser.latent_scale;
    let latents: Vec<f32> = h.iter().map(|v| v * scale).collect();
    let decoded: Vec<f32> = ae
        .decode(Tensor::<3>::from_data(
            TensorData::new(latents, [count, tokens, c]),
            &device,
        ))
        .into_data()
        .try_to_vec::<f32>()
        .map_err(|e| LearnError::invalid("generate", format!("{e:?}")))?;
    let mut y = decoded;
    normalizer.denormalize(&mut y);
    Ok(y)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_schedule_falls_from_almost_one_to_almost_zero() {
        let ab = alpha_bar();
        assert_eq!(ab.len(), STEPS);
        assert!((ab[0] - (1.0 - 1e-3)).abs() < 1e-12);
        assert!(ab.windows(2).all(|w| w[1] < w[0]));
        assert!(ab[STEPS - 1] < 1e-4, "ᾱ_N = {}", ab[STEPS - 1]);
    }

    #[test]
    fn ddim_with_the_true_noise_lands_on_the_forward_process() {
        // h_t = √ᾱ h₀ + √(1−ᾱ) ε; one step with ε̂ = ε must give √ᾱ' h₀ + √(1−ᾱ') ε, and the
        // last step (ᾱ' = 1) h₀ itself
        let ab = alpha_bar();
        let (h0, eps) = (0.7f64, -1.3f64);
        for (t, next) in [(99usize, 66usize), (66, 33), (33, 0)] {
            let h = ab[t].sqrt() * h0 + (1.0 - ab[t]).sqrt() * eps;
            let got = ddim_step(h as f32, eps as f32, ab[t], ab[next]) as f64;
            let want = ab[next].sqrt() * h0 + (1.0 - ab[next]).sqrt() * eps;
            assert!((got - want).abs() < 1e-5, "{t} → {next}: {got} vs {want}");
        }
        let h = ab[10].sqrt() * h0 + (1.0 - ab[10]).sqrt() * eps;
        assert!((ddim_step(h as f32, eps as f32, ab[10], 1.0) as f64 - h0).abs() < 1e-5);
    }

    #[test]
    fn composition_adds_the_concepts_scores_and_subtracts_the_negated() {
        // one concept with weight 1 is that concept's prediction
        assert_eq!(compose(&[0.5, 2.0], &[1.0]), 2.0);
        // guidance w extrapolates: ε_∅ + w (ε − ε_∅)
        assert_eq!(compose(&[0.5, 2.0], &[3.0]), 0.5 + 3.0 * 1.5);
        // A ∧ ¬B: + (ε_A − ε_∅) − (ε_B − ε_∅)
        assert_eq!(compose(&[1.0, 3.0, 4.0], &[1.0, -1.0]), 1.0 + 2.0 - 3.0);
        // no concept: the unconditional prediction
        assert_eq!(compose(&[0.25], &[]), 0.25);
    }
}
