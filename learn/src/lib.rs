//! musculo's learned module (ARCHITECTURE.md: `learn/`, a workspace member kept out of the
//! default build), on burn: a physics-aware motion autoencoder trained on the tensors of
//! `musculo augment`, with the Euler–Lagrange and muscle losses of musculo's `loss` module
//! joined to burn's autodiff as a custom backward operation; a latent diffusion model over its
//! latents conditioned on captions and spatial controls; and the composition of concepts
//! (conjunction, negation) at sampling time.
//!
//! - [`data`]: tensor files → per-frame feature vectors, and their standardization;
//! - [`autoencoder`]: the Transformer autoencoder with a temporally downsampled latent;
//! - [`physics`]: the physics terms as burn's custom op (value and gradient from musculo);
//! - [`train`]: the training loop, reconstruction and its quality figures;
//! - [`diffusion`]: latent diffusion (DDPM training, DDIM sampling) conditioned on captions and
//!   spatial controls, and the composition of concepts (conjunction, negation);
//! - [`text`]: caption vectors (a built-in bag of words, or precomputed embeddings);
//! - [`checkpoint`]: saving and loading trained networks, and snapshots a run continues from;
//! - [`device`]: where the networks run (CPU, or a GPU with the `wgpu` / `cuda` features).
//!
//! Backend: burn's Flex (pure-Rust CPU) with autodiff, or its CubeCL backend on a GPU; every
//! tensor lives on a `Device` (`Device::flex()`, `.autodiff()` for training).

pub mod autoencoder;
pub mod checkpoint;
pub mod data;
pub mod device;
pub mod diffusion;
pub mod error;
pub mod physics;
pub mod text;
pub mod train;

pub use data::ClipSet;
pub use error::{LearnError, Result};

/// burn seeds a device's random generator globally (`Device::seed`), so two trainings that
/// initialize their networks at once on one device would interleave their draws. Every seeded
/// initialization here holds this lock from the seed to the last parameter drawn, which keeps a
/// seed's network the same whatever else runs (tests in parallel threads, say).
pub(crate) static INITIALIZATION: std::sync::Mutex<()> = std::sync::Mutex::new(());
