//! The physics terms of the training loss as one custom operation of burn's autodiff: its value
//! and its backward pass come from musculo's `loss` module (exact derivatives of inverse
//! dynamics and of the muscle mapping), not from burn tracing a re-implementation of the
//! dynamics.
//!
//! For a batch of decoded, standardized frames z (B × T × D; y = σ ⊙ z + μ in SI units,
//! [`crate::data`]) and the subset S of sequences with a known body (each clip's own model:
//! the base model scaled to the clip's bones, with a variant's mass and load,
//! [`crate::data::ClipSet::bodies`]), each sequence's r and e computed on its own body b(s):
//!
//! ```text
//! L_phys = w_E · (1 / (|S|·T·n)) Σ_{s∈S} Σ_t Σ_j (r_stj / σ_τ)²         r = M q̈ + C q̇ + G − τ − J_cᵀλ
//!        + w_M · (1 / (|S|·T'·n)) Σ_{s∈S} Σ_{t∈T'} Σ_j (e_stj / σ_q̈)²   e = q̈ − M⁻¹ R F_max a
//!
//!          (M, C, G, J_c, R, F_max those of body b(s))
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
//! [`musculo::loss::MuscleLoss`] with w_j = 1/(σ² · count), evaluated once per body on that
//! body's sequences with the count of the whole batch, so that the sum over the bodies is the
//! mean above. The gradient with respect to z is
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

/// One body's share of the physics terms: its model, the Euler–Lagrange term with the model's
/// contact set and, when the muscle term is on, the muscle mapping.
struct Body {
    model: Arc<Model>,
    euler: EulerLagrange,
    muscle: Option<MuscleLoss>,
}

/// Everything the physics terms need: one model per distinct body of the training set (each
/// with its contact points and muscles), the feature layout and the standardization.
pub struct Physics {
    pub layout: FeatureLayout,
    pub normalizer: Normalizer,
    pub weights: PhysicsWeights,
    bodies: Vec<Body>,
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
    /// The terms for the one body `model` (body 0; its contact set gives the points of λ; its
    /// muscles the columns of a) on data of `layout`, standardized by `normalizer`.
    pub fn new(
        model: Model,
        layout: FeatureLayout,
        normalizer: Normalizer,
        weights: PhysicsWeights,
    ) -> Result<Physics> {
        Self::with_bodies(&[Arc::new(model)], layout, normalizer, weights)
    }

    /// The terms for the bodies `models` (body i is `models[i]`, e.g.
    /// [`crate::data::ClipSet::bodies`]), each checked against `layout` as in [`Physics::new`].
    pub fn with_bodies(
        models: &[Arc<Model>],
        layout: FeatureLayout,
        normalizer: Normalizer,
        weights: PhysicsWeights,
    ) -> Result<Physics> {
        use crate::data::LearnError;
        if models.is_empty() {
            return Err(LearnError::invalid("physics", "no body to evaluate on"));
        }
        if weights.muscle > 0.0 && weights.muscle_stride == 0 {
            return Err(LearnError::invalid("physics", "muscle_stride must be ≥ 1"));
        }
        let mut bodies = Vec::with_capacity(models.len());
        for model in models {
            let invalid = |message: String| {
                LearnError::invalid(format!("physics on model \"{}\"", model.name), message)
            };
            if layout.coordinates != model.nq() {
                return Err(invalid(format!(
                    "the data have {} coordinates, the model {}",
                    layout.coordinates,
                    model.nq()
                )));
            }
            let euler = if layout.contacts > 0 {
                let set = contact_set(model)?;
                if set.points.len() != layout.contacts {
                    return Err(invalid(format!(
                        "the data have {} contact points, the model's contact set {}",
                        layout.contacts,
                        set.points.len()
                    )));
                }
                EulerLagrange::new().with_contact_set(&set)
            } else {
                EulerLagrange::new()
            };
            let muscle = if weights.muscle > 0.0 {
                let loss = MuscleLoss::new(model)?;
                if loss.muscles() != layout.muscles {
                    return Err(invalid(format!(
                        "the data have {} muscles, the model {}",
                        layout.muscles,
                        loss.muscles()
                    )));
                }
                Some(loss)
            } else {
                None
            };
            bodies.push(Body {
                model: Arc::clone(model),
                euler,
                muscle,
            });
        }
        Ok(Physics {
            layout,
            normalizer,
            weights,
            bodies,
        })
    }

    /// The number of bodies.
    pub fn bodies(&self) -> usize {
        self.bodies.len()
    }

    /// L_phys of standardized frames `z` (`sequences` × `frames` × D), sequence s evaluated on
    /// body `bodies[s]` and left out when it is None, and ∂L_phys/∂z when `gradient`. The
    /// sequences are grouped by body and each group evaluated on its own model; the weights
    /// count every included frame of the batch, so the sum over the groups is the mean over the
    /// whole batch (module docs).
    pub fn evaluate(
        &self,
        z: &[f32],
        sequences: usize,
        frames: usize,
        bodies: &[Option<usize>],
        gradient: bool,
    ) -> Result<PhysicsValue> {
        let d = self.layout.width();
        let mut value = PhysicsValue {
            grad: if gradient {
                vec![0.0; z.len()]
            } else {
                Vec::new()
            },
            ..PhysicsValue::default()
        };
        if z.len() != sequences * frames * d || bodies.len() != sequences {
            return Err(crate::data::LearnError::invalid(
                "physics",
                format!(
                    "{} values and {} body indices for {sequences} sequences × {frames} frames × {d} features",
                    z.len(),
                    bodies.len()
                ),
            ));
        }
        if let Some(i) = bodies.iter().flatten().find(|i| **i >= self.bodies.len()) {
            return Err(crate::data::LearnError::invalid(
                "physics",
                format!("body {i} of a batch, the terms have {}", self.bodies.len()),
            ));
        }
        let included = bodies.iter().flatten().count();
        if included == 0 {
            return Ok(value);
        }
        let n = self.layout.coordinates;
        let stride = self.weights.muscle_stride.max(1);
        // the counts of the whole batch: |S|·T·n and |S|·T'·n
        let euler_count = (included * frames * n) as f64;
        let muscle_count = (included * frames.div_ceil(stride) * n) as f64;
        for (i, body) in self.bodies.iter().enumerate() {
            let rows: Vec<usize> = (0..sequences)
                .filter(|s| bodies[*s] == Some(i))
                .flat_map(|s| (0..frames).map(move |t| s * frames + t))
                .collect();
            if !rows.is_empty() {
                self.evaluate_body(
                    body,
                    z,
                    frames,
                    &rows,
                    (euler_count, muscle_count),
                    &mut value,
                )?;
            }
        }
        Ok(value)
    }

    /// Adds the terms of the batch's `rows` (whole sequences of `frames`), all of `body`, to
    /// `value`, each term's weights 1/(σ² · count) with `counts` those of the whole batch.
    fn evaluate_body(
        &self,
        body: &Body,
        z: &[f32],
        frames: usize,
        rows: &[usize],
        (euler_count, muscle_count): (f64, f64),
        value: &mut PhysicsValue,
    ) -> Result<()> {
        let d = self.layout.width();
        let (n, p) = (self.layout.coordinates, 3 * self.layout.contacts);
        let gradient = !value.grad.is_empty();
        // y = σ ⊙ z + μ for the rows' frames, split into the loss's arrays
        let block = |name: &str| self.layout.block(name);
        let (bq, bqd, bqdd, btau, blam, ba) = (
            block("q"),
            block("qd"),
            block("qdd"),
            block("tau"),
            block("contact_point_force"),
            block("muscle_act"),
        );
        let si = |row: usize, range: &std::ops::Range<usize>| {
            let base = row * d;
            range.clone().map(move |i| {
                (z[base + i] * self.normalizer.std[i] + self.normalizer.mean[i]) as f64
            })
        };
        let gather = |range: &std::ops::Range<usize>, rows: &[usize]| -> Vec<f64> {
            rows.iter().flat_map(|r| si(*r, range)).collect()
        };
        let q = gather(&bq, rows);
        let qdd = gather(&bqdd, rows);
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
            let qd = gather(&bqd, rows);
            let tau = gather(&btau, rows);
            let lambda = if p > 0 {
                gather(&blam, rows)
            } else {
                Vec::new()
            };
            let mut euler = body.euler.clone();
            euler.weights = sigma(&btau)
                .iter()
                .map(|s| 1.0 / (s * s * euler_count))
                .collect();
            let batch = EulerLagrangeBatch {
                frames: rows.len(),
                q: &q,
                qd: &qd,
                qdd: &qdd,
                tau: &tau,
                lambda: &lambda,
            };
            let mut out = EulerLagrangeOutput::default();
            euler.evaluate(&body.model, &batch, gradient, &mut out)?;
            value.euler += out.loss;
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
                        scatter(&mut value.grad, g, range, rows, w);
                    }
                }
            }
        }
        if let Some(muscle) = &body.muscle {
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
            let mut loss = muscle.clone();
            loss.weights = sigma(&bqdd)
                .iter()
                .map(|s| 1.0 / (s * s * muscle_count))
                .collect();
            loss.beta = 0.0;
            loss.bound_weight = 0.0;
            let batch = MuscleBatch {
                frames: sub_rows.len(),
                q: &q_m,
                qdd: &qdd_m,
                a: &a,
            };
            let mut out = MuscleLossOutput::default();
            loss.evaluate(&body.model, &batch, gradient, &mut out)?;
            value.muscle += out.loss;
            value.loss += self.weights.muscle * out.loss;
            if gradient {
                let w = self.weights.muscle;
                scatter(&mut value.grad, &out.grad_q, &bq, &sub_rows, w);
                scatter(&mut value.grad, &out.grad_qdd, &bqdd, &sub_rows, w);
                scatter(&mut value.grad, &out.grad_a, &ba, &sub_rows, w);
            }
        }
        Ok(())
    }
}

/// One call of the physics op: the terms, the body of each sequence of the batch (None: left
/// out of the terms), and where the forward pass leaves its outcome (the terms' parts for a
/// log, or the error).
#[derive(Clone)]
pub struct PhysicsCall {
    pub physics: Arc<Physics>,
    pub bodies: Arc<Vec<Option<usize>>>,
    pub outcome: Arc<Mutex<Option<Result<PhysicsParts>>>>,
}

/// The physics terms' parts of one forward pass, before their weights.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhysicsParts {
    pub euler: f64,
    pub muscle: f64,
}

impl PhysicsCall {
    /// A call of `physics`, sequence s on body `bodies[s]` (None: left out).
    pub fn new(physics: Arc<Physics>, bodies: Vec<Option<usize>>) -> PhysicsCall {
        PhysicsCall {
            physics,
            bodies: Arc::new(bodies),
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
            .evaluate(&v, dims[0], dims[1], &call.bodies, gradient)
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
