//! The Euler–Lagrange residual loss (FlexMotion eq. 6) and its gradients.
//!
//! Per frame t, with the model's independent coordinates q (n of them), contact forces λ_i
//! (ground axes, N) at the contact points p_i and per-coordinate weights w_j ≥ 0:
//!
//! ```text
//! r_t = τ_ID(q, q̇, q̈) − τ − Σ_i J_i(q)ᵀ λ_i          (τ_ID = M q̈ + C q̇ + G, `dynamics::rnea`)
//! L_t = Σ_j w_j r_tj²,   L = Σ_t L_t
//! ```
//!
//! and with u = 2 W r (W = diag w):
//!
//! ```text
//! ∂L_t/∂q  = uᵀ ∂(τ_ID − Q)/∂q            (Q = Σ_i J_iᵀ λ_i)
//! ∂L_t/∂q̇  = uᵀ ∂τ_ID/∂q̇
//! ∂L_t/∂q̈  = M u
//! ∂L_t/∂τ  = −u
//! ∂L_t/∂λ_i = −J_i u
//! ```
//!
//! each a vector–Jacobian product of [`crate::dynamics::RneaVjp`]: one forward pass (which
//! gives r) and one backward pass per frame, O(n), without forming a Jacobian.
//!
//! A contact point is a carrier point fixed in a body plus an offset fixed in ground
//! ([`LossContact`]): for a contact sphere of radius ρ on a floor with upward normal n the
//! carrier is its centre and the offset −ρ n, so the force acts at the sphere's lowest point
//! whatever the foot's orientation (as `solve::contact` places it).

use crate::dynamics::{Data, PointForces, RneaVjp};
use crate::model::Model;
use crate::solve::contact::ContactSet;
use crate::spatial::Vec3;
use rayon::prelude::*;

/// Where a contact force acts: c + g, with c fixed in `body` and g fixed in ground.
#[derive(Clone, Debug, PartialEq)]
pub struct LossContact {
    pub name: String,
    /// Index into `Model::bodies`.
    pub body: usize,
    /// The carrier point c in body coordinates (m).
    pub location_in_body: Vec3,
    /// The offset g in ground (m).
    pub offset_in_ground: Vec3,
}

/// The loss's settings: contact points and per-coordinate weights.
#[derive(Clone, Debug, Default)]
pub struct EulerLagrange {
    /// Contact points, in the order of λ's rows.
    pub contacts: Vec<LossContact>,
    /// w_j ≥ 0 per independent coordinate; empty means all 1.
    pub weights: Vec<f64>,
}

/// One batch of frames, each array row-major with one row per frame.
#[derive(Clone, Copy, Debug)]
pub struct EulerLagrangeBatch<'a> {
    pub frames: usize,
    /// q, q̇, q̈, τ: frames × n each.
    pub q: &'a [f64],
    pub qd: &'a [f64],
    pub qdd: &'a [f64],
    pub tau: &'a [f64],
    /// λ: frames × contacts × 3 (ground axes, N); may be empty when there are no contacts.
    pub lambda: &'a [f64],
}

/// The loss, the residuals and (when asked for) the gradients of one batch.
#[derive(Clone, Debug, Default)]
pub struct EulerLagrangeOutput {
    /// L = Σ_t L_t.
    pub loss: f64,
    /// L_t per frame.
    pub per_frame: Vec<f64>,
    /// r_t (frames × n).
    pub residual: Vec<f64>,
    /// ‖τ_ID,t‖ per frame (the scale of r_t).
    pub tau_id_norm: Vec<f64>,
    /// ∂L/∂q, ∂L/∂q̇, ∂L/∂q̈, ∂L/∂τ (frames × n) and ∂L/∂λ (frames × contacts × 3); empty
    /// without gradients.
    pub grad_q: Vec<f64>,
    pub grad_qd: Vec<f64>,
    pub grad_qdd: Vec<f64>,
    pub grad_tau: Vec<f64>,
    pub grad_lambda: Vec<f64>,
}

impl EulerLagrange {
    /// No contacts, unit weights.
    pub fn new() -> EulerLagrange {
        EulerLagrange::default()
    }

    /// The contact spheres of `set` (a model's contact set), each loaded at its lowest point on
    /// the set's floor.
    pub fn with_contact_set(mut self, set: &ContactSet) -> EulerLagrange {
        self.contacts = set
            .points
            .iter()
            .map(|p| LossContact {
                name: p.name.clone(),
                body: p.body,
                location_in_body: p.location_in_body,
                offset_in_ground: -set.floor_normal * p.radius,
            })
            .collect();
        self
    }

    /// Errors unless the contacts and weights fit `model`.
    pub fn validate(&self, model: &Model) -> crate::Result<()> {
        let n = model.nq();
        super::validate_weights(&self.weights, n)?;
        for c in &self.contacts {
            if c.body == 0 || c.body >= model.bodies.len() {
                return Err(crate::Error::invalid(
                    "contacts",
                    format!("{}: body index {} is not a moving body", c.name, c.body),
                ));
            }
        }
        Ok(())
    }

    /// L, r and, when `gradients` is true, every gradient for `batch` into `out` (resized).
    pub fn evaluate(
        &self,
        model: &Model,
        batch: &EulerLagrangeBatch,
        gradients: bool,
        out: &mut EulerLagrangeOutput,
    ) -> crate::Result<()> {
        self.validate(model)?;
        let (n, p, t) = (model.nq(), self.contacts.len(), batch.frames);
        for (name, a, width) in [
            ("q", batch.q, n),
            ("qd", batch.qd, n),
            ("qdd", batch.qdd, n),
            ("tau", batch.tau, n),
            ("lambda", batch.lambda, 3 * p),
        ] {
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
        }
        // One row per frame: [L_t, ‖τ_ID‖, r (n), then with gradients ∂q, ∂q̇, ∂q̈, ∂τ (n each),
        // ∂λ (3p)]
        let width = 2 + n + if gradients { 4 * n + 3 * p } else { 0 };
        let mut rows = vec![0.0; t * width];
        let carriers: Vec<(usize, Vec3)> = self
            .contacts
            .iter()
            .map(|c| (c.body, c.location_in_body))
            .collect();
        let offsets: Vec<Vec3> = self.contacts.iter().map(|c| c.offset_in_ground).collect();
        rows.par_chunks_mut(width).enumerate().try_for_each_init(
            || Workspace::new(model, p),
            |ws, (f, row)| {
                let frame = Frame {
                    q: &batch.q[f * n..(f + 1) * n],
                    qd: &batch.qd[f * n..(f + 1) * n],
                    qdd: &batch.qdd[f * n..(f + 1) * n],
                    tau: &batch.tau[f * n..(f + 1) * n],
                    lambda: &batch.lambda[f * 3 * p..(f + 1) * 3 * p],
                };
                self.frame(model, &carriers, &offsets, &frame, gradients, ws, row)
                    .map_err(|e| crate::Error::invalid("batch", format!("frame {f}: {e}")))
            },
        )?;
        out.per_frame.clear();
        out.residual.clear();
        out.tau_id_norm.clear();
        for v in [
            &mut out.grad_q,
            &mut out.grad_qd,
            &mut out.grad_qdd,
            &mut out.grad_tau,
            &mut out.grad_lambda,
        ] {
            v.clear();
        }
        for row in rows.chunks(width) {
            out.per_frame.push(row[0]);
            out.tau_id_norm.push(row[1]);
            out.residual.extend_from_slice(&row[2..2 + n]);
            if gradients {
                let g = &row[2 + n..];
                out.grad_q.extend_from_slice(&g[..n]);
                out.grad_qd.extend_from_slice(&g[n..2 * n]);
                out.grad_qdd.extend_from_slice(&g[2 * n..3 * n]);
                out.grad_tau.extend_from_slice(&g[3 * n..4 * n]);
                out.grad_lambda.extend_from_slice(&g[4 * n..]);
            }
        }
        out.loss = out.per_frame.iter().sum();
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    fn frame(
        &self,
        model: &Model,
        carriers: &[(usize, Vec3)],
        offsets: &[Vec3],
        frame: &Frame,
        gradients: bool,
        ws: &mut Workspace,
        row: &mut [f64],
    ) -> crate::Result<()> {
        let n = model.nq();
        for (c, f) in ws.forces.iter_mut().zip(frame.lambda.chunks(3)) {
            *c = Vec3::new(f[0], f[1], f[2]);
        }
        let external = PointForces {
            carriers,
            offsets_in_ground: offsets,
            forces: &ws.forces,
        };
        // τ_ID − J_cᵀλ, then r = that − τ,  u = 2 W r,  L_t = rᵀ W r
        let tau_net =
            ws.vjp
                .forward(model, &mut ws.data, frame.q, frame.qd, frame.qdd, &external)?;
        let (head, rest) = row.split_at_mut(2 + n);
        let mut loss = 0.0;
        for j in 0..n {
            let r = tau_net[j] - frame.tau[j];
            let w = self.weights.get(j).copied().unwrap_or(1.0);
            head[2 + j] = r;
            ws.u[j] = 2.0 * w * r;
            loss += w * r * r;
        }
        head[0] = loss;
        head[1] = ws.vjp.tau_id.norm();
        if gradients {
            ws.vjp.backward(model, &ws.data, &ws.u)?;
            let (gq, rest) = rest.split_at_mut(n);
            let (gqd, rest) = rest.split_at_mut(n);
            let (gqdd, rest) = rest.split_at_mut(n);
            let (gtau, glambda) = rest.split_at_mut(n);
            // ∂L/∂q = uᵀ∂(τ_ID − J_cᵀλ)/∂q, likewise q̇, q̈;  ∂L/∂τ = −u;  ∂L/∂λ_i = −J_i u
            gq.copy_from_slice(ws.vjp.dq.as_slice());
            gqd.copy_from_slice(ws.vjp.dqd.as_slice());
            gqdd.copy_from_slice(ws.vjp.dqdd.as_slice());
            for (g, u) in gtau.iter_mut().zip(&ws.u) {
                *g = -u;
            }
            for (g, d) in glambda.chunks_mut(3).zip(&ws.vjp.dforces) {
                g.copy_from_slice(d.as_slice());
            }
        }
        Ok(())
    }
}

struct Frame<'a> {
    q: &'a [f64],
    qd: &'a [f64],
    qdd: &'a [f64],
    tau: &'a [f64],
    lambda: &'a [f64],
}

/// One worker's arrays, allocated once per worker.
struct Workspace {
    data: Data,
    vjp: RneaVjp,
    forces: Vec<Vec3>,
    u: Vec<f64>,
}

impl Workspace {
    fn new(model: &Model, contacts: usize) -> Workspace {
        Workspace {
            data: Data::new(model),
            vjp: RneaVjp::new(model),
            forces: vec![Vec3::zeros(); contacts],
            u: vec![0.0; model.nq()],
        }
    }
}
