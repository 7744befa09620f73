//! The physics-aware multimodal motion autoencoder (FlexMotion §3.1, in our sizes).
//!
//! ```text
//! encode:  z (B × T × D) ─Linear→ d ─+PE→ Transformer encoder (L layers)
//!          ─group k frames: B × T/k × k·d ─Linear→ latent  h (B × T/k × c)
//! decode:  h ─Linear→ k·d ─ungroup: B × T × d ─+PE→ Transformer encoder (L layers) ─Linear→ D
//! ```
//!
//! z are the standardized per-frame modality vectors of [`crate::data`]; PE the sinusoidal
//! position encoding; k the temporal downsampling (T must be a multiple of k). The latent
//! sequence h (T/k steps of c values) is what the latent diffusion model samples. Every
//! modality is decoded; the training loss ([`crate::train`]) is the reconstruction's mean square
//! in standardized units plus the physics terms of [`crate::physics`] on the decoded frames.

use burn::config::Config;
use burn::module::Module;
use burn::nn::transformer::{
    TransformerEncoder, TransformerEncoderConfig, TransformerEncoderInput,
};
use burn::nn::{Linear, LinearConfig, PositionalEncoding, PositionalEncodingConfig};
use burn::tensor::{Device, Tensor};

/// The autoencoder's sizes.
#[derive(Config, Debug)]
pub struct AutoencoderConfig {
    /// D, the width of a frame's feature vector.
    pub features: usize,
    /// d, the Transformer width.
    #[config(default = 128)]
    pub d_model: usize,
    /// Attention heads (d must be a multiple).
    #[config(default = 4)]
    pub heads: usize,
    /// L, the layers of the encoder and of the decoder.
    #[config(default = 2)]
    pub layers: usize,
    /// The feed-forward width.
    #[config(default = 256)]
    pub d_ff: usize,
    /// c, the latent width per latent step.
    #[config(default = 32)]
    pub latent: usize,
    /// k, frames per latent step.
    #[config(default = 4)]
    pub downsample: usize,
    /// The longest sequence the position encoding covers.
    #[config(default = 512)]
    pub max_frames: usize,
}

/// The autoencoder (module docs).
#[derive(Module, Debug)]
pub struct Autoencoder {
    input: Linear,
    position: PositionalEncoding,
    encoder: TransformerEncoder,
    to_latent: Linear,
    from_latent: Linear,
    decoder: TransformerEncoder,
    output: Linear,
    d_model: usize,
    downsample: usize,
}

impl AutoencoderConfig {
    /// A freshly initialized autoencoder on `device`.
    pub fn init(&self, device: &Device) -> Autoencoder {
        let transformer =
            TransformerEncoderConfig::new(self.d_model, self.d_ff, self.heads, self.layers)
                .with_norm_first(true)
                .with_dropout(0.0);
        let k = self.downsample;
        Autoencoder {
            input: LinearConfig::new(self.features, self.d_model).init(device),
            position: PositionalEncodingConfig::new(self.d_model)
                .with_max_sequence_size(self.max_frames)
                .init(device),
            encoder: transformer.init(device),
            to_latent: LinearConfig::new(k * self.d_model, self.latent).init(device),
            from_latent: LinearConfig::new(self.latent, k * self.d_model).init(device),
            decoder: transformer.init(device),
            output: LinearConfig::new(self.d_model, self.features).init(device),
            d_model: self.d_model,
            downsample: k,
        }
    }
}

impl Autoencoder {
    /// h = E(z): B × T × D → B × T/k × c.
    pub fn encode(&self, z: Tensor<3>) -> Tensor<3> {
        let [b, t, _] = z.dims();
        let x = self.position.forward(self.input.forward(z));
        let x = self.encoder.forward(TransformerEncoderInput::new(x));
        let k = self.downsample;
        self.to_latent
            .forward(x.reshape([b, t / k, k * self.d_model]))
    }

    /// ẑ = D(h): B × T/k × c → B × T × D.
    pub fn decode(&self, h: Tensor<3>) -> Tensor<3> {
        let [b, steps, _] = h.dims();
        let k = self.downsample;
        let x = self
            .from_latent
            .forward(h)
            .reshape([b, steps * k, self.d_model]);
        let x = self.position.forward(x);
        let x = self.decoder.forward(TransformerEncoderInput::new(x));
        self.output.forward(x)
    }

    /// ẑ = D(E(z)).
    pub fn forward(&self, z: Tensor<3>) -> Tensor<3> {
        self.decode(self.encode(z))
    }

    /// k, frames per latent step.
    pub fn downsample(&self) -> usize {
        self.downsample
    }
}
