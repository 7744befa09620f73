//! The physics terms of the training loss as one custom operation of burn's autodiff: its value
//! and its backward pass come from musculo's `loss` module (exact derivatives of inverse
//! dynamics and of the muscle mapping), not from burn tracing a re-implementation of the
//! dynamics.
//!
//! For a batch of decoded, standardized frames z (B × T × D; y = σ ⊙ z + μ in SI units,
//! [`crate::data`]) and the subset S of sequences whose body is the model's own:
//!
//! ```text
//! L_phys = w_E · (1 / (|S|·T·n)) Σ_{s∈S} Σ_t Σ_j (r_stj / σ_τ)²         r = M q̈ + C q̇ + G − τ − J_cᵀλ
//!        + w_M · (1 / (|S|·T'·n)) Σ_{s∈S} Σ_{t∈T'} Σ_j (e_stj / σ_q̈)²   e = q̈ − M⁻¹ R F_max a
//! ```
//!
//! with σ_τ, σ_q̈ the mean over the coordinates of the training set's standard deviations of
//! τ_j and q̈_j: one scale per term, so that each term is a mean square in about the units the
//! reconstruction loss uses while every coordinate's residual counts alike (per-coordinate
//! scales would let a coordinate that never moves in the data, such as a locked joint or a
//! floating-base force the contacts always balance, weigh its residual by thousands, and
//! discount the residual of the joints that move most),
//! and T' every k-th frame (`muscle_stride`:
//! the muscle term costs ~1.5 ms per frame on the default model). Both sums are the
//! per-coordinate-weighted losses of [`musculo::loss::EulerLagrange`] and
//! [`musculo::loss::MuscleLoss`] with w_j = 1/(σ² · count). The gradient with respect to z is
//! the chain rule through the standardization, ∂L/∂z = σ ⊙ ∂L/∂y, with ∂L/∂y from those
//! modules' vector–Jacobian products (∂L/∂q, ∂L/∂q̇, ∂L/∂q̈, ∂L/∂τ, ∂L/∂λ, ∂L/∂a).
//!
//! The operation ([`PhysicsBackend::physics_loss`]) takes z and returns L_phys as a tensor of
//! shape 1 × 1 × 1. The forward pass computes L_phys and ∂L_phys/∂z on the host (rayon over
//! frames) and keeps the gradient as the op's state; the backward pass multiplies it by the
//! incoming scalar gradient. Implemented for burn's Flex backend (pure-Rust CPU) and, with the
//! `wgpu` or `cuda` feature, its CubeCL backend (GPU: z is read back to the host, the value
//! and gradient written to the device), value only, and for `Autodiff<B>` over either (value
//! and gradient).

use crate::data::{FeatureLayout, Normalizer, Result};
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind, unary};
use burn::backend::tensor::FloatTensor;
use burn::backend::{Autodiff, Backend, Dispatch, Flex, TensorMetadata, backend_extension};
use burn::tensor::{Tensor, TensorData};
use musculo::augment::chain::contact_set;
use musculo::loss::{
    EulerLagrange, EulerLagrangeBatch, EulerLagrangeOutput, MuscleBatch, MuscleLoss,
    MuscleLossOutput,
};
use musculo::model::Model;
use std::sync::{Arc, Mutex};

/// The weights of the physics terms (0 switches a term off).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PhysicsWeights {
    /// w_E, the Euler–Lagrange term.
    pub euler: f64,
    /// w_M, the muscle term.
    pub muscle: f64,
    /// k: the muscle term is evaluated on every k-th frame of a sequence.
    pub muscle_stride: usize,
}

impl Default for PhysicsWeights {
    fn default() -> Self {
        PhysicsWeights {
            euler: 1.0,
            muscle: 0.0,
            muscle_stride: 4,
        }
    }
}

/// Everything the physics terms need: the model, its contact points and muscles, the feature
/// layout and the standardization.
pub struct Physics {
    pub model: Model,
    pub layout: FeatureLayout,
    pub normalizer: Normalizer,
    pub weights: PhysicsWeights,
    euler: EulerLagrange,
    muscle: Option<MuscleLoss>,
}

/// The value of the physics terms for one batch and, when asked, ∂L/∂z (B × T × D).
#[derive(Clone, Debug, Default)]
pub struct PhysicsValue {
    pub loss: f64,
    /// The Euler–Lagrange part (before w_E) and the muscle part (before w_M).
    pub euler: f64,
    pub muscle: f64,
    pub grad: Vec<f32>,
}

impl Physics {
    /// The terms for `model` (its contact set gives the points of λ; its muscles the columns of
    /// a) on data of `layout`, standardized by `normalizer`.
    pub fn new(
        model: Model,
        layout: FeatureLayout,
        normalizer: Normalizer,
        weights: PhysicsWeights,
    ) -> Result<Physics> {
        use crate::data::LearnError;
        if layout.coordinates != model.nq() {
            return Err(LearnError::invalid(
                "physics",
                format!(
                    "the data have {} coordinates, the model {}",
                    layout.coordinates,
                    model.nq()
                ),
            ));
        }
        let contacts = if layout.contacts > 0 {
            let set = contact_set(&model)?;
            if set.points.len() != layout.contacts {
                return Err(LearnError::invalid(
                    "physics",
                    format!(
                        "the data have {} contact points, the model's contact set {}",
                        layout.contacts,
                        set.points.len()
                    ),
                ));
            }
            EulerLagrange::new().with_contact_set(&set)
        } else {
            EulerLagrange::new()
        };
        let muscle = if weights.muscle > 0.0 {
            let loss = MuscleLoss::new(&model)?;
            if loss.muscles() != layout.muscles {
                return Err(LearnError::invalid(
                    "physics",
                    format!(
                        "the data have {} muscles, the model {}",
                        layout.muscles,
                        loss.muscles()
                    ),
                ));
            }
            Some(loss)
        } else {
            None
        };
        if weights.muscle > 0.0 && weights.muscle_stride == 0 {
            return Err(LearnError::invalid("physics", "muscle_stride must be ≥ 1"));
        }
        Ok(Physics {
            model,
            layout,
            normalizer,
            weights,
            euler: contacts,
            muscle,
        })
    }

    /// L_phys of standardized frames `z` (`sequences` × `frames` × D) over the sequences with
    /// `include[s]`, and ∂L_phys/∂z when `gradient`.
    pub fn evaluate(
        &self,
        z: &[f32],
        sequences: usize,
        frames: usize,
        include: &[bool],
        gradient: bool,
    ) -> Result<PhysicsValue> {
        let d = self.layout.width();
        let (n, p) = (self.layout.coordinates, 3 * self.layout.contacts);
        let mut value = PhysicsValue {
            grad: if gradient {
                vec![0.0; z.len()]
            } else {
                Vec::new()
            },
            ..PhysicsValue::default()
        };
        if z.len() != sequences * frames * d || include.len() != sequences {
            return Err(crate::data::LearnError::invalid(
                "physics",
                format!(
                    "{} values and {} inclusion flags for {sequences} sequences × {frames} frames × {d} features",
                    z.len(),
                    include.len()
                ),
            ));
        }
        let chosen: Vec<usize> = (0..sequences).filter(|s| include[*s]).collect();
        if chosen.is_empty() {
            return Ok(value);
        }
        // y = σ ⊙ z + μ for the chosen sequences' frames, split into the loss's arrays
        let block = |name: &str| self.layout.block(name);
        let (bq, bqd, bqdd, btau, blam, ba) = (
            block("q"),
            block("qd"),
            block("qdd"),
            block("tau"),
            block("contact_point_force"),
            block("muscle_act"),
        );
        let rows: Vec<usize> = chosen
            .iter()
            .flat_map(|s| (0..frames).map(move |t| s * frames + t))
            .collect();
        let si = |row: usize, range: &std::ops::Range<usize>| {
            let base = row * d;
            range.clone().map(move |i| {
                (z[base + i] * self.normalizer.std[i] + self.normalizer.mean[i]) as f64
            })
        };
        let gather = |range: &std::ops::Range<usize>, rows: &[usize]| -> Vec<f64> {
            rows.iter().flat_map(|r| si(*r, range)).collect()
        };
        let q = gather(&bq, &rows);
        let qdd = gather(&bqdd, &rows);
        // one scale per term: the mean of the block's σ_j (module docs)
        let sigma = |range: &std::ops::Range<usize>| -> Vec<f64> {
            let mean = range
                .clone()
                .map(|i| self.normalizer.std[i] as f64)
                .sum::<f64>()
                / range.len().max(1) as f64;
            vec![mean; range.len()]
        };
        // ∂L/∂z_i = σ_i ∂L/∂y_i, scattered back to the batch's rows
        let scatter = |grad: &mut Vec<f32>,
                       g: &[f64],
                       range: &std::ops::Range<usize>,
                       rows: &[usize],
                       scale: f64| {
            let w = range.len();
            for (k, row) in rows.iter().enumerate() {
                for (c, i) in range.clone().enumerate() {
                    grad[row * d + i] +=
                        (scale * g[k * w + c] * self.normalizer.std[i] as f64) as f32;
                }
            }
        };
        if self.weights.euler > 0.0 {
            let qd = gather(&bqd, &rows);
            let tau = gather(&btau, &rows);
            let lambda = if p > 0 {
                gather(&blam, &rows)
            } else {
                Vec::new()
            };
            let count = (rows.len() * n) as f64;
            let mut euler = self.euler.clone();
            euler.weights = sigma(&btau).iter().map(|s| 1.0 / (s * s * count)).collect();
            let batch = EulerLagrangeBatch {
                frames: rows.len(),
                q: &q,
                qd: &qd,
                qdd: &qdd,
                tau: &tau,
                lambda: &lambda,
            };
            let mut out = EulerLagrangeOutput::default();
            euler.evaluate(&self.model, &batch, gradient, &mut out)?;
            value.euler = out.loss;
            value.loss += self.weights.euler * out.loss;
            if gradient {
                let w = self.weights.euler;
                for (g, range) in [
                    (&out.grad_q, &bq),
                    (&out.grad_qd, &bqd),
                    (&out.grad_qdd, &bqdd),
                    (&out.grad_tau, &btau),
                    (&out.grad_lambda, &blam),
                ] {
                    if !range.is_empty() {
                        scatter(&mut value.grad, g, range, &rows, w);
                    }
                }
            }
        }
        if let Some(muscle) = &self.muscle {
            let stride = self.weights.muscle_stride;
            let picked: Vec<usize> = (0..rows.len())
                .filter(|k| (k % frames).is_multiple_of(stride))
                .collect();
            let sub_rows: Vec<usize> = picked.iter().map(|k| rows[*k]).collect();
            let pick = |a: &[f64], w: usize| -> Vec<f64> {
                picked
                    .iter()
                    .flat_map(|k| a[k * w..(k + 1) * w].iter().copied())
                    .collect()
            };
            let (q_m, qdd_m) = (pick(&q, n), pick(&qdd, n));
            let a = gather(&ba, &sub_rows);
            let count = (sub_rows.len() * n) as f64;
            let mut loss = muscle.clone();
            loss.weights = sigma(&bqdd).iter().map(|s| 1.0 / (s * s * count)).collect();
            loss.beta = 0.0;
            loss.bound_weight = 0.0;
            let batch = MuscleBatch {
                frames: sub_rows.len(),
                q: &q_m,
                qdd: &qdd_m,
                a: &a,
            };
            let mut out = MuscleLossOutput::default();
            loss.evaluate(&self.model, &batch, gradient, &mut out)?;
            value.muscle = out.loss;
            value.loss += self.weights.muscle * out.loss;
            if gradient {
                let w = self.weights.muscle;
                scatter(&mut value.grad, &out.grad_q, &bq, &sub_rows, w);
                scatter(&mut value.grad, &out.grad_qdd, &bqdd, &sub_rows, w);
                scatter(&mut value.grad, &out.grad_a, &ba, &sub_rows, w);
            }
        }
        Ok(value)
    }
}

/// One call of the physics op: the terms, which sequences of the batch they apply to, and
/// where the forward pass leaves its outcome (the terms' parts for a log, or the error).
#[derive(Clone)]
pub struct PhysicsCall {
    pub physics: Arc<Physics>,
    pub include: Arc<Vec<bool>>,
    pub outcome: Arc<Mutex<Option<Result<PhysicsParts>>>>,
}

/// The physics terms' parts of one forward pass, before their weights.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhysicsParts {
    pub euler: f64,
    pub muscle: f64,
}

impl PhysicsCall {
    /// A call of `physics` on the sequences with `include[s]`.
    pub fn new(physics: Arc<Physics>, include: Vec<bool>) -> PhysicsCall {
        PhysicsCall {
            physics,
            include: Arc::new(include),
            outcome: Arc::new(Mutex::new(None)),
        }
    }

    /// The last forward pass's parts, or its error (the op itself returns NaN then).
    pub fn outcome(&self) -> Result<PhysicsParts> {
        let taken = self.outcome.lock().ok().and_then(|mut o| o.take());
        taken.unwrap_or_else(|| {
            Err(crate::data::LearnError::invalid(
                "physics",
                "the op has not run",
            ))
        })
    }
}

/// burn's backend extension for the physics op (module docs).
#[backend_extension(Autodiff, Flex, Cube: cfg(any(feature = "wgpu", feature = "cuda")))]
pub trait PhysicsBackend: Backend {
    /// L_phys of z (B × T × D) as a 1 × 1 × 1 tensor.
    fn physics_loss(z: FloatTensor<Self>, call: PhysicsCall) -> FloatTensor<Self>;
}

/// z's values on the host with its batch and frame counts; the value and, when `gradient`, the
/// gradient of the physics terms. The outcome goes to `call.outcome`; on an error (a batch that
/// does not fit the model) the op's value is NaN and [`PhysicsCall::outcome`] holds the error.
fn host_value<B: Backend>(z: FloatTensor<B>, call: &PhysicsCall, gradient: bool) -> PhysicsValue {
    let dims = z.shape().dims::<3>();
    let values = burn::tensor::read_sync(B::float_into_data(z))
        .map_err(|e| crate::data::LearnError::invalid("physics", format!("{e:?}")))
        .and_then(|d| {
            d.try_to_vec::<f32>()
                .map_err(|e| crate::data::LearnError::invalid("physics", format!("{e:?}")))
        });
    let value = values.and_then(|v| {
        call.physics
            .evaluate(&v, dims[0], dims[1], &call.include, gradient)
    });
    let (value, outcome) = match value {
        Ok(v) => {
            let parts = PhysicsParts {
                euler: v.euler,
                muscle: v.muscle,
            };
            (v, Ok(parts))
        }
        Err(e) => (
            PhysicsValue {
                loss: f64::NAN,
                ..PhysicsValue::default()
            },
            Err(e),
        ),
    };
    if let Ok(mut slot) = call.outcome.lock() {
        *slot = Some(outcome);
    }
    value
}

/// The value alone (no autodiff), on any backend: computed on the host, written to z's device.
fn value_only<B: Backend>(z: FloatTensor<B>, call: &PhysicsCall) -> FloatTensor<B> {
    let device = z.device();
    let value = host_value::<B>(z, call, false);
    B::float_from_data(TensorData::new(vec![value.loss as f32], [1, 1, 1]), &device)
}

impl PhysicsBackend for Flex {
    fn physics_loss(z: FloatTensor<Self>, call: PhysicsCall) -> FloatTensor<Self> {
        value_only::<Self>(z, &call)
    }
}

#[cfg(any(feature = "wgpu", feature = "cuda"))]
impl PhysicsBackend for burn::backend::Cube {
    fn physics_loss(z: FloatTensor<Self>, call: PhysicsCall) -> FloatTensor<Self> {
        value_only::<Self>(z, &call)
    }
}

impl<B: PhysicsBackend, C: CheckpointStrategy> PhysicsBackend for Autodiff<B, C> {
    fn physics_loss(z: FloatTensor<Self>, call: PhysicsCall) -> FloatTensor<Self> {
        // backward: ∂L/∂z = (incoming scalar gradient) · g, g computed in the forward pass
        #[derive(Debug)]
        struct PhysicsBackward;
        impl<B: Backend> Backward<B, 1> for PhysicsBackward {
            type State = B::FloatTensorPrimitive;
            fn backward(
                self,
                ops: Ops<Self::State, 1>,
                grads: &mut Gradients,
                _checkpointer: &mut Checkpointer,
            ) {
                let g = ops.state;
                unary::<B, _>(ops.parents, ops.node, grads, |grad| B::float_mul(g, grad));
            }
        }
        let (primitive, node) = z.into_parts();
        let device = primitive.device();
        let shape = primitive.shape();
        let value = host_value::<B>(primitive, &call, true);
        let out = B::float_from_data(TensorData::new(vec![value.loss as f32], [1, 1, 1]), &device);
        match PhysicsBackward
            .prepare::<C>([node])
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(prep) => {
                let grad = if value.grad.is_empty() {
                    vec![0.0f32; shape.num_elements()]
                } else {
                    value.grad
                };
                prep.finish(
                    B::float_from_data(TensorData::new(grad, shape), &device),
                    out,
                )
            }
            OpsKind::UnTracked(prep) => prep.finish(out),
        }
    }
}

/// L_phys of `z` as a differentiable tensor (1 × 1 × 1) on z's device.
pub fn physics_loss(z: Tensor<3>, call: PhysicsCall) -> Tensor<3> {
    Tensor::<3>::from_dispatch(<Dispatch as PhysicsBackend>::physics_loss(
        z.into_dispatch(),
        call,
    ))
}
