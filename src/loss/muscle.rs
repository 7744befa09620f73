//! The muscle loss (FlexMotion eqs. 7 and 18, after Lee et al. 2019) and its gradients.
//!
//! Per frame t, with the model's independent coordinates q (n), the activations a of its m
//! muscles, the moment arms R(q) (n × m, [`crate::muscle::path`]'s convention
//! R_jk = −∂ℓ_k/∂q_j: a tension F_k ≥ 0 produces the generalized force R_jk F_k), the maximum
//! isometric forces F = diag(F_max), per-coordinate weights w_j ≥ 0, β ≥ 0 and γ ≥ 0:
//!
//! ```text
//! z_t = M(q)⁻¹ R(q) F a                      (the accelerations the muscles alone would give)
//! e_t = q̈ − z_t
//! L_t = Σ_j w_j e_tj² + β Σ_k a_k² + γ Σ_k (max(0, a_k − 1)² + max(0, −a_k)²),   L = Σ_t L_t
//! ```
//!
//! As FlexMotion defines it, z holds neither gravity nor velocity terms (use
//! [`super::EulerLagrange`] for the full equations of motion). With g = 2 W e and
//! v = M⁻¹ g (M symmetric):
//!
//! ```text
//! ∂L_t/∂q̈ = g
//! ∂L_t/∂a_k = −F_k (Rᵀ v)_k + 2β a_k + 2γ (max(0, a_k − 1) − max(0, −a_k))
//! ∂L_t/∂q = ∂(vᵀ M(q) z)/∂q − ∂(vᵀ R(q) F a)/∂q
//!         = vᵀ ∂τ_ID(q, 0, z)/∂q − vᵀ ∂τ_ID(q, 0, 0)/∂q − Σ_k F_k a_k ṙ_k(q, q̇ = v)
//! ```
//!
//! (de = M⁻¹(dM z − d(R F a)), so dL = vᵀ dM z − vᵀ d(R F a)). The first two terms are
//! vector–Jacobian products of inverse dynamics ([`crate::dynamics::RneaVjp`], the second
//! removing gravity); the last uses ∂(vᵀ r_k)/∂q = −∇²ℓ_k v = ṙ_k at q̇ = v, the exact rate of
//! the moment arms ([`crate::muscle::path::MomentArmRates`]: wrap surfaces, interacting wraps
//! and moving points included). No finite differences anywhere.

use crate::dynamics::{Data, PointForces, RneaVjp, crba, forward_kinematics_velocity};
use crate::linalg::{cholesky_in_place, cholesky_solve_in_place};
use crate::model::Model;
use crate::muscle::MuscleSet;
use crate::muscle::path::{MomentArmRates, PathData, PathSet, compute_paths};
use rayon::prelude::*;

/// The loss's settings and the model's muscles.
#[derive(Clone, Debug)]
pub struct MuscleLoss {
    /// The muscles' paths, in `Model::forces` order (the order of a's entries).
    pub paths: PathSet,
    /// F_max of each muscle (N).
    pub max_isometric_force: Vec<f64>,
    /// w_j ≥ 0 per independent coordinate; empty means all 1.
    pub weights: Vec<f64>,
    /// β ≥ 0, the weight of ‖a‖² (0 unless set).
    pub beta: f64,
    /// γ ≥ 0, the weight of the bound penalty on a ∉ [0, 1] (1 unless set).
    pub bound_weight: f64,
}

/// One batch of frames, row-major, one row per frame.
#[derive(Clone, Copy, Debug)]
pub struct MuscleBatch<'a> {
    pub frames: usize,
    /// q, q̈: frames × n each.
    pub q: &'a [f64],
    pub qdd: &'a [f64],
    /// a: frames × m (muscles in `MuscleLoss::paths` order).
    pub a: &'a [f64],
}

/// The loss, the residuals e = q̈ − M⁻¹RFa and (when asked for) the gradients of one batch.
#[derive(Clone, Debug, Default)]
pub struct MuscleLossOutput {
    /// L = Σ_t L_t.
    pub loss: f64,
    /// L_t per frame.
    pub per_frame: Vec<f64>,
    /// e_t (frames × n).
    pub residual: Vec<f64>,
    /// ∂L/∂q, ∂L/∂q̈ (frames × n) and ∂L/∂a (frames × m); empty without gradients.
    pub grad_q: Vec<f64>,
    pub grad_qdd: Vec<f64>,
    pub grad_a: Vec<f64>,
}

impl MuscleLoss {
    /// Every muscle of `model`, unit weights, β = 0, γ = 1.
    pub fn new(model: &Model) -> crate::Result<MuscleLoss> {
        let set = MuscleSet::new(model)?;
        let max_isometric_force = set
            .muscles
            .iter()
            .map(|m| m.params().max_isometric_force)
            .collect();
        Ok(MuscleLoss {
            paths: set.paths,
            max_isometric_force,
            weights: Vec::new(),
            beta: 0.0,
            bound_weight: 1.0,
        })
    }

    /// The number of muscles m (a's width).
    pub fn muscles(&self) -> usize {
        self.paths.len()
    }

    /// Errors unless the settings fit `model`.
    pub fn validate(&self, model: &Model) -> crate::Result<()> {
        let n = model.nq();
        super::validate_weights(&self.weights, n)?;
        for (name, v) in [("beta", self.beta), ("bound_weight", self.bound_weight)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(crate::Error::invalid(
                    name,
                    format!("{v} (must be finite and ≥ 0)"),
                ));
            }
        }
        if self.max_isometric_force.len() != self.paths.len() {
            return Err(crate::Error::invalid(
                "max_isometric_force",
                format!(
                    "{} forces for {} muscles",
                    self.max_isometric_force.len(),
                    self.paths.len()
                ),
            ));
        }
        if let Some(p) = self
            .paths
            .paths
            .iter()
            .find(|p| p.force >= model.forces.len())
        {
            return Err(crate::Error::invalid(
                "paths",
                format!("path {} belongs to another model", p.name),
            ));
        }
        Ok(())
    }

    /// L, e and, when `gradients` is true, every gradient for `batch` into `out` (resized).
    pub fn evaluate(
        &self,
        model: &Model,
        batch: &MuscleBatch,
        gradients: bool,
        out: &mut MuscleLossOutput,
    ) -> crate::Result<()> {
        self.validate(model)?;
        let (n, m, t) = (model.nq(), self.muscles(), batch.frames);
        for (name, a, width) in [("q", batch.q, n), ("qdd", batch.qdd, n), ("a", batch.a, m)] {
            if a.len() != t * width {
                return Err(crate::Error::invalid(
                    name,
                    format!(
                        "expected {t} frames × {width} values = {}, got {}",
                        t * width,
                        a.len()
                    ),
                ));
            }
            if let Some(i) = a.iter().position(|v| !v.is_finite()) {
                return Err(crate::Error::invalid(
                    name,
                    format!("frame {}: value {} is not finite", i / width, i % width),
                ));
            }
        }
        // One row per frame: [L_t, e (n), then with gradients ∂q (n), ∂q̈ (n), ∂a (m)]
        let width = 1 + n + if gradients { 2 * n + m } else { 0 };
        let mut rows = vec![0.0; t * width];
        rows.par_chunks_mut(width).enumerate().try_for_each_init(
            || Workspace::new(model, &self.paths),
            |ws, (f, row)| {
                let frame = Frame {
                    q: &batch.q[f * n..(f + 1) * n],
                    qdd: &batch.qdd[f * n..(f + 1) * n],
                    a: &batch.a[f * m..(f + 1) * m],
                };
                self.frame(model, &frame, gradients, ws, row)
                    .map_err(|e| crate::Error::invalid("batch", format!("frame {f}: {e}")))
            },
        )?;
        out.per_frame.clear();
        out.residual.clear();
        out.grad_q.clear();
        out.grad_qdd.clear();
        out.grad_a.clear();
        for row in rows.chunks(width) {
            out.per_frame.push(row[0]);
            out.residual.extend_from_slice(&row[1..1 + n]);
            if gradients {
                let g = &row[1 + n..];
                out.grad_q.extend_from_slice(&g[..n]);
                out.grad_qdd.extend_from_slice(&g[n..2 * n]);
                out.grad_a.extend_from_slice(&g[2 * n..]);
            }
        }
        out.loss = out.per_frame.iter().sum();
        Ok(())
    }

    fn frame(
        &self,
        model: &Model,
        frame: &Frame,
        gradients: bool,
        ws: &mut Workspace,
        row: &mut [f64],
    ) -> crate::Result<()> {
        let (n, m) = (model.nq(), self.muscles());
        // M = L Lᵀ, R, f = F a, z = M⁻¹ R f, e = q̈ − z
        crba(model, &mut ws.data, frame.q)?;
        ws.chol.copy_from_slice(ws.data.mass_matrix().as_slice());
        if !cholesky_in_place(&mut ws.chol, n) {
            return Err(crate::Error::invalid(
                "q",
                "the mass matrix is not positive definite at this pose",
            ));
        }
        compute_paths(model, &ws.data, &self.paths, &mut ws.paths)?;
        for ((f, a), fmax) in ws.f.iter_mut().zip(frame.a).zip(&self.max_isometric_force) {
            *f = fmax * a;
        }
        let r = &ws.paths.moment_arms;
        for (j, z) in ws.z.iter_mut().enumerate() {
            *z = (0..m).map(|k| r[(j, k)] * ws.f[k]).sum();
        }
        cholesky_solve_in_place(&ws.chol, n, &mut ws.z);
        let (head, rest) = row.split_at_mut(1 + n);
        let mut loss = 0.0;
        for j in 0..n {
            let e = frame.qdd[j] - ws.z[j];
            let w = self.weights.get(j).copied().unwrap_or(1.0);
            head[1 + j] = e;
            ws.v[j] = 2.0 * w * e;
            loss += w * e * e;
        }
        let (beta, gamma) = (self.beta, self.bound_weight);
        for &a in frame.a {
            let (over, under) = ((a - 1.0).max(0.0), (-a).max(0.0));
            loss += beta * a * a + gamma * (over * over + under * under);
        }
        head[0] = loss;
        if !gradients {
            return Ok(());
        }
        let (gq, rest) = rest.split_at_mut(n);
        let (gqdd, ga) = rest.split_at_mut(n);
        // ∂L/∂q̈ = g;  v = M⁻¹ g
        gqdd.copy_from_slice(&ws.v);
        cholesky_solve_in_place(&ws.chol, n, &mut ws.v);
        // ∂L/∂a_k = −F_k (Rᵀv)_k + 2β a_k + 2γ (max(0, a − 1) − max(0, −a))
        for k in 0..m {
            let rv: f64 = (0..n).map(|j| r[(j, k)] * ws.v[j]).sum();
            let a = frame.a[k];
            ga[k] = -self.max_isometric_force[k] * rv
                + 2.0 * beta * a
                + 2.0 * gamma * ((a - 1.0).max(0.0) - (-a).max(0.0));
        }
        // ∂L/∂q = vᵀ∂τ_ID(q, 0, z)/∂q − vᵀ∂τ_ID(q, 0, 0)/∂q − Σ_k f_k ṙ_k(q̇ = v)
        let none = PointForces::default();
        ws.vjp
            .forward(model, &mut ws.data_vjp, frame.q, &ws.zeros, &ws.z, &none)?;
        ws.vjp.backward(model, &ws.data_vjp, &ws.v)?;
        gq.copy_from_slice(ws.vjp.dq.as_slice());
        ws.vjp.forward(
            model,
            &mut ws.data_vjp,
            frame.q,
            &ws.zeros,
            &ws.zeros,
            &none,
        )?;
        ws.vjp.backward(model, &ws.data_vjp, &ws.v)?;
        for (g, d) in gq.iter_mut().zip(ws.vjp.dq.iter()) {
            *g -= d;
        }
        forward_kinematics_velocity(model, &mut ws.data, frame.q, &ws.v)?;
        ws.rates
            .compute(model, &ws.data, &self.paths, &ws.f, &mut ws.rate)?;
        for (g, d) in gq.iter_mut().zip(&ws.rate) {
            *g -= d;
        }
        Ok(())
    }
}

struct Frame<'a> {
    q: &'a [f64],
    qdd: &'a [f64],
    a: &'a [f64],
}

/// One worker's arrays, allocated once per worker.
struct Workspace {
    data: Data,
    data_vjp: Data,
    vjp: RneaVjp,
    paths: PathData,
    rates: MomentArmRates,
    chol: Vec<f64>,
    f: Vec<f64>,
    z: Vec<f64>,
    v: Vec<f64>,
    zeros: Vec<f64>,
    rate: Vec<f64>,
}

impl Workspace {
    fn new(model: &Model, paths: &PathSet) -> Workspace {
        let n = model.nq();
        Workspace {
            data: Data::new(model),
            data_vjp: Data::new(model),
            vjp: RneaVjp::new(model),
            paths: PathData::new(model, paths),
            rates: MomentArmRates::new(model, paths),
            chol: vec![0.0; n * n],
            f: vec![0.0; paths.len()],
            z: vec![0.0; n],
            v: vec![0.0; n],
            zeros: vec![0.0; n],
            rate: vec![0.0; n],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::SplitMix64;

    fn random_frame(
        model: &Model,
        m: usize,
        rng: &mut SplitMix64,
    ) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let q = crate::reference::random_q(model, rng, 0.05);
        let qdd = (0..model.nq()).map(|_| rng.uniform(-10.0, 10.0)).collect();
        let a = (0..m).map(|_| rng.uniform(-0.1, 1.1)).collect();
        (q, qdd, a)
    }

    /// The losses of frames (q, q̈, a) ± h·e_i for every input i, as one batch (value only).
    fn perturbed_losses(
        model: &Model,
        loss: &MuscleLoss,
        frame: &(Vec<f64>, Vec<f64>, Vec<f64>),
        h: f64,
    ) -> Vec<f64> {
        let (q, qdd, a) = frame;
        let (n, m) = (q.len(), a.len());
        let inputs = 2 * n + m;
        let (mut bq, mut bqdd, mut ba) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..inputs {
            for s in [h, -h] {
                let (mut q1, mut qdd1, mut a1) = (q.clone(), qdd.clone(), a.clone());
                match i {
                    i if i < n => q1[i] += s,
                    i if i < 2 * n => qdd1[i - n] += s,
                    i => a1[i - 2 * n] += s,
                }
                bq.extend(q1);
                bqdd.extend(qdd1);
                ba.extend(a1);
            }
        }
        let batch = MuscleBatch {
            frames: 2 * inputs,
            q: &bq,
            qdd: &bqdd,
            a: &ba,
        };
        let mut out = MuscleLossOutput::default();
        loss.evaluate(model, &batch, false, &mut out).unwrap();
        (0..inputs)
            .map(|i| (out.per_frame[2 * i] - out.per_frame[2 * i + 1]) / (2.0 * h))
            .collect()
    }

    /// ∂L/∂q, ∂L/∂q̈ and ∂L/∂a equal central differences of L (Richardson-extrapolated from the
    /// steps h and 2h) to 1e-6 of the gradient's largest entry, at random states of the default
    /// model, gait2392 and Rajagopal2016 with β and per-coordinate weights set and activations
    /// on both sides of the bounds. States where a wrap engages or a conditional point switches
    /// inside the stencil (the two steps then disagree) are skipped and counted.
    #[test]
    fn muscle_loss_gradients_match_central_differences() {
        let h = 1e-6;
        for (name, model) in crate::reference::test_models() {
            let mut loss = MuscleLoss::new(&model).unwrap();
            loss.beta = 0.3;
            loss.bound_weight = 2.0;
            loss.weights = (0..model.nq())
                .map(|j| 0.5 + (j % 3) as f64 * 0.25)
                .collect();
            let (n, m) = (model.nq(), loss.muscles());
            let mut rng = SplitMix64(11);
            let (mut checked, mut skipped) = (0, 0);
            let mut worst = 0.0f64;
            for _ in 0..3 {
                let frame = random_frame(&model, m, &mut rng);
                let batch = MuscleBatch {
                    frames: 1,
                    q: &frame.0,
                    qdd: &frame.1,
                    a: &frame.2,
                };
                let mut out = MuscleLossOutput::default();
                loss.evaluate(&model, &batch, true, &mut out).unwrap();
                let ours: Vec<f64> = out
                    .grad_q
                    .iter()
                    .chain(&out.grad_qdd)
                    .chain(&out.grad_a)
                    .copied()
                    .collect();
                let fd = perturbed_losses(&model, &loss, &frame, h);
                let fd2 = perturbed_losses(&model, &loss, &frame, 2.0 * h);
                let scale = ours.iter().fold(1e-12f64, |s, v| s.max(v.abs()));
                let jump = fd
                    .iter()
                    .zip(&fd2)
                    .fold(0.0f64, |s, (a, b)| s.max((a - b).abs()));
                if jump > 1e-4 * scale {
                    skipped += 1;
                    continue;
                }
                checked += 1;
                for (i, (g, (a, b))) in ours.iter().zip(fd.iter().zip(&fd2)).enumerate() {
                    let rich = (4.0 * a - b) / 3.0;
                    let what = if i < n {
                        format!("∂L/∂q[{i}]")
                    } else if i < 2 * n {
                        format!("∂L/∂q̈[{}]", i - n)
                    } else {
                        format!(
                            "∂L/∂a[{}] ({})",
                            i - 2 * n,
                            loss.paths.paths[i - 2 * n].name
                        )
                    };
                    worst = worst.max((g - rich).abs() / scale);
                    assert!(
                        (g - rich).abs() <= 1e-6 * scale,
                        "{name}: {what} = {g}, central differences {rich} (scale {scale})"
                    );
                }
            }
            eprintln!(
                "{name}: {checked} states checked ({n} + {n} + {m} gradient entries each), {skipped} \
                 not smooth over the stencil; worst error {worst:.1e} of the gradient's largest entry"
            );
            assert!(checked >= 2, "{name}: only {checked} smooth states");
        }
    }

    /// With a = 0 and β = 0 the loss is Σ w q̈² exactly, its a-gradient is −F_k (Rᵀ M⁻¹ 2Wq̈)_k
    /// and its q-gradient vanishes (nothing but q̈ is left); e = q̈.
    #[test]
    fn muscle_loss_of_zero_activation_is_the_weighted_acceleration_norm() {
        let model = Model::default_fullbody();
        let loss = MuscleLoss::new(&model).unwrap();
        let (n, m) = (model.nq(), loss.muscles());
        let mut rng = SplitMix64(5);
        let (q, qdd, _) = random_frame(&model, m, &mut rng);
        let a = vec![0.0; m];
        let batch = MuscleBatch {
            frames: 1,
            q: &q,
            qdd: &qdd,
            a: &a,
        };
        let mut out = MuscleLossOutput::default();
        loss.evaluate(&model, &batch, true, &mut out).unwrap();
        let expected: f64 = qdd.iter().map(|v| v * v).sum();
        assert!((out.loss - expected).abs() <= 1e-12 * expected);
        assert_eq!(out.residual, qdd);
        assert!(
            out.grad_q.iter().all(|g| g.abs() <= 1e-9 * expected),
            "{:?}",
            out.grad_q
        );
        assert_eq!(out.grad_a.len(), m);
        assert_eq!(out.grad_q.len(), n);
    }

    /// Bad input is an error naming it, never a panic.
    #[test]
    fn muscle_loss_rejects_bad_input() {
        let model = Model::default_fullbody();
        let mut loss = MuscleLoss::new(&model).unwrap();
        let (n, m) = (model.nq(), loss.muscles());
        let q = vec![0.0; n];
        let mut a = vec![0.5; m];
        let mut out = MuscleLossOutput::default();
        let short = MuscleBatch {
            frames: 1,
            q: &q,
            qdd: &q[..n - 1],
            a: &a,
        };
        let e = loss.evaluate(&model, &short, true, &mut out).unwrap_err();
        assert!(e.to_string().contains("qdd"), "{e}");
        a[3] = f64::NAN;
        let nan = MuscleBatch {
            frames: 1,
            q: &q,
            qdd: &q,
            a: &a,
        };
        let e = loss.evaluate(&model, &nan, true, &mut out).unwrap_err();
        assert!(e.to_string().contains("not finite"), "{e}");
        loss.beta = -1.0;
        a[3] = 0.5;
        let ok = MuscleBatch {
            frames: 1,
            q: &q,
            qdd: &q,
            a: &a,
        };
        let e = loss.evaluate(&model, &ok, false, &mut out).unwrap_err();
        assert!(e.to_string().contains("beta"), "{e}");
    }
}
