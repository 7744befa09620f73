//! L_euler of a motion given in FlexMotion's per-joint layout (METHOD.md §1), whose contact
//! forces come per joint, without a point of application.
//!
//! The layout's `contact_force` λ_j is the resultant of the ground's forces on joint j's child
//! body (ground axes). It is taken to act at the joint centre p_j(q) — the per-joint forces
//! at the joint locations of FlexMotion's own physics term — together with a free couple μ_b
//! on each body that can touch the ground (the bodies of the model's contact set). Any set
//! of forces on a body is its resultant at one point plus a couple; the layout does not carry
//! the couple, so the loss takes the one that best explains the motion:
//!
//! ```text
//! r(μ) = τ_ID(q, q̇, q̈) − τ − Σ_j J_j(q)ᵀ λ_j − Σ_b J_ω,b(q)ᵀ μ_b
//! μ*   = argmin_μ r(μ)ᵀ W r(μ)        (normal equations (CᵀWC) μ = CᵀW r(0), C = [J_ω,bᵀ])
//! L_t  = r(μ*)ᵀ W r(μ*)
//! ```
//!
//! (J_j the Jacobian of the joint centre, J_ω,b the angular Jacobian of body b, W = diag w).
//! A layout written by `musculo augment` therefore has the residual of its coordinate arrays on
//! every coordinate the couples or the layout's moments reach: its contact forces explain
//! exactly what the contact spheres' forces explained.
//!
//! Gradients: μ* minimizes L at fixed inputs, so ∂L/∂μ = 0 there and every gradient of L is
//! that of the Euler–Lagrange loss at μ = μ* held fixed (the envelope theorem). The couple is
//! handed to [`EulerLagrange`] as four point forces on the body (−Σ_k f_k at the joint centre
//! and f_k = (μ × e_k)/(2d) at the centre plus d e_k, e_k the ground axes, d = 0.1 m: zero net
//! force and Σ_k d e_k × f_k = μ), which gives its generalized force J_ωᵀμ and the exact
//! q-derivative of that force with the loss's other gradients.
//!
//! With [`crate::augment::layout_inverse`] (the layout's q, q̇, q̈ and τ) and
//! [`crate::augment::layout_inverse_vjp`] (gradients back to the layout) this is L_euler of a
//! generated motion and its gradient with respect to every block of the layout.

use super::{EulerLagrange, EulerLagrangeBatch, EulerLagrangeOutput, LossContact};
use crate::dynamics::{self, Data};
use crate::linalg::{cholesky_in_place, cholesky_solve_in_place};
use crate::model::Model;
use crate::solve::contact::ContactSet;
use crate::spatial::Vec3;
use nalgebra::DMatrix;
use rayon::prelude::*;

/// The lever d of the point forces that carry a couple (m); any d > 0 gives the same couple.
const COUPLE_ARM: f64 = 0.1;

/// The layout's Euler–Lagrange loss: its contact points (the joint centres, then four points
/// per couple body) and weights.
#[derive(Clone, Debug)]
pub struct LayoutEulerLagrange {
    inner: EulerLagrange,
    /// Bodies (indices into `Model::bodies`) that carry a free couple.
    couple_bodies: Vec<usize>,
    joints: usize,
}

/// One batch of frames in the layout's form: the coordinates fitted from it and its
/// contact forces.
#[derive(Clone, Copy, Debug)]
pub struct LayoutEulerLagrangeBatch<'a> {
    pub frames: usize,
    /// q, q̇, q̈, τ: frames × n each (e.g. from `coordinates_from_layout`).
    pub q: &'a [f64],
    pub qd: &'a [f64],
    pub qdd: &'a [f64],
    pub tau: &'a [f64],
    /// The layout's `contact_force`: frames × J × 3 (ground axes, N).
    pub contact_force: &'a [f64],
}

/// The loss, the residuals at the best couples and (when asked for) the gradients.
#[derive(Clone, Debug, Default)]
pub struct LayoutEulerLagrangeOutput {
    /// L = Σ_t L_t.
    pub loss: f64,
    /// L_t per frame.
    pub per_frame: Vec<f64>,
    /// r(μ*) per frame (frames × n).
    pub residual: Vec<f64>,
    /// ‖τ_ID,t‖ per frame.
    pub tau_id_norm: Vec<f64>,
    /// μ* per frame and couple body (frames × B × 3, ground axes, N·m).
    pub couple: Vec<f64>,
    /// ∂L/∂q, ∂L/∂q̇, ∂L/∂q̈, ∂L/∂τ (frames × n) and ∂L/∂λ (frames × J × 3); empty without
    /// gradients.
    pub grad_q: Vec<f64>,
    pub grad_qd: Vec<f64>,
    pub grad_qdd: Vec<f64>,
    pub grad_tau: Vec<f64>,
    pub grad_contact_force: Vec<f64>,
}

impl LayoutEulerLagrange {
    /// Joint forces at the joint centres, a free couple on each of `couple_bodies`, weights
    /// w_j (empty: all 1).
    pub fn new(
        model: &Model,
        couple_bodies: &[usize],
        weights: Vec<f64>,
    ) -> crate::Result<LayoutEulerLagrange> {
        super::validate_weights(&weights, model.nq())?;
        let mut contacts: Vec<LossContact> = model
            .joints
            .iter()
            .map(|joint| LossContact {
                name: format!("{}/centre", joint.name),
                body: joint.child_body,
                location_in_body: joint.child_offset.pos,
                offset_in_ground: Vec3::zeros(),
            })
            .collect();
        let mut bodies: Vec<usize> = Vec::new();
        for &b in couple_bodies {
            if b == 0 || b >= model.bodies.len() {
                return Err(crate::Error::invalid(
                    "couple bodies",
                    format!("body index {b} is not a moving body"),
                ));
            }
            if bodies.contains(&b) {
                continue;
            }
            bodies.push(b);
            let joint = model
                .joints
                .iter()
                .find(|j| j.child_body == b)
                .ok_or_else(|| {
                    crate::Error::invalid(
                        "couple bodies",
                        format!("body {} has no joint", model.bodies[b].name),
                    )
                })?;
            for k in 0..4 {
                let mut offset = Vec3::zeros();
                if k > 0 {
                    offset[k - 1] = COUPLE_ARM;
                }
                contacts.push(LossContact {
                    name: format!("{}/couple{k}", model.bodies[b].name),
                    body: b,
                    location_in_body: joint.child_offset.pos,
                    offset_in_ground: offset,
                });
            }
        }
        Ok(LayoutEulerLagrange {
            inner: EulerLagrange { contacts, weights },
            couple_bodies: bodies,
            joints: model.joints.len(),
        })
    }

    /// Free couples on the bodies of a contact set (those that can touch the ground).
    pub fn from_contact_set(
        model: &Model,
        set: &ContactSet,
        weights: Vec<f64>,
    ) -> crate::Result<LayoutEulerLagrange> {
        let bodies: Vec<usize> = set.points.iter().map(|p| p.body).collect();
        Self::new(model, &bodies, weights)
    }

    /// The bodies that carry a free couple, in the order of `couple`.
    pub fn couple_bodies(&self) -> &[usize] {
        &self.couple_bodies
    }

    /// L, r(μ*), μ* and, when `gradients` is true, every gradient for `batch` into `out`.
    pub fn evaluate(
        &self,
        model: &Model,
        batch: &LayoutEulerLagrangeBatch,
        gradients: bool,
        out: &mut LayoutEulerLagrangeOutput,
    ) -> crate::Result<()> {
        self.check_batch(model, batch)?;
        let (t, nj, nb) = (batch.frames, self.joints, self.couple_bodies.len());
        // λ per frame: the joint forces, then the couple bodies' points (zero in the first pass)
        let width = 3 * (nj + 4 * nb);
        let mut lambda = vec![0.0; t * width];
        for (row, f) in lambda
            .chunks_mut(width.max(1))
            .zip(batch.contact_force.chunks(3 * nj.max(1)))
        {
            row[..3 * nj].copy_from_slice(f);
        }
        let mut first = EulerLagrangeOutput::default();
        self.inner
            .evaluate(model, &el_batch(batch, &lambda), false, &mut first)?;
        out.couple = vec![0.0; t * 3 * nb];
        if nb > 0 {
            self.fit_couples(model, batch, &first.residual, &mut lambda, &mut out.couple)?;
        }
        let mut second = EulerLagrangeOutput::default();
        self.inner
            .evaluate(model, &el_batch(batch, &lambda), gradients, &mut second)?;
        out.loss = second.loss;
        out.per_frame = second.per_frame;
        out.residual = second.residual;
        out.tau_id_norm = second.tau_id_norm;
        out.grad_q = second.grad_q;
        out.grad_qd = second.grad_qd;
        out.grad_qdd = second.grad_qdd;
        out.grad_tau = second.grad_tau;
        out.grad_contact_force = if gradients {
            second
                .grad_lambda
                .chunks(width.max(1))
                .flat_map(|g| &g[..3 * nj])
                .copied()
                .collect()
        } else {
            Vec::new()
        };
        Ok(())
    }

    /// The batch checked against the loss: the model's joint count and the size of
    /// `contact_force` (T × joints × 3).
    fn check_batch(&self, model: &Model, batch: &LayoutEulerLagrangeBatch) -> crate::Result<()> {
        let (t, nj) = (batch.frames, self.joints);
        if nj != model.joints.len() {
            return Err(crate::Error::invalid(
                "layout loss",
                format!(
                    "built for {nj} joints, the model \"{}\" has {}",
                    model.name,
                    model.joints.len()
                ),
            ));
        }
        if batch.contact_force.len() != t * nj * 3 {
            return Err(crate::Error::invalid(
                "contact_force",
                format!(
                    "expected {t} frames × {nj} joints × 3 = {}, got {}",
                    t * nj * 3,
                    batch.contact_force.len()
                ),
            ));
        }
        Ok(())
    }

    /// μ* per frame from the first pass's residual r(0) (into `couple`, 3 per couple body),
    /// and its point forces into each frame's row of `lambda`.
    fn fit_couples(
        &self,
        model: &Model,
        batch: &LayoutEulerLagrangeBatch,
        residual: &[f64],
        lambda: &mut [f64],
        couple: &mut [f64],
    ) -> crate::Result<()> {
        let nb = self.couple_bodies.len();
        let width = 3 * (self.joints + 4 * nb);
        lambda
            .par_chunks_mut(width)
            .zip(couple.par_chunks_mut(3 * nb))
            .enumerate()
            .try_for_each_init(
                || CoupleWorkspace::new(model, nb),
                |ws, (f, (row, mu))| {
                    self.couple_moments(model, batch, residual, f, ws, mu)?;
                    self.couple_point_forces(mu, row);
                    Ok::<(), crate::Error>(())
                },
            )
    }

    /// μ* at frame `f`: the least-squares couples, min Σ_j w_j (r_j − (C μ)_j)² with
    /// C = [J_ω,bᵀ] (n × 3B), by the normal equations (regularized by 10⁻¹² of their trace;
    /// zero where no coordinate feels a couple).
    fn couple_moments(
        &self,
        model: &Model,
        batch: &LayoutEulerLagrangeBatch,
        residual: &[f64],
        f: usize,
        ws: &mut CoupleWorkspace,
        mu: &mut [f64],
    ) -> crate::Result<()> {
        let (n, nb) = (model.nq(), self.couple_bodies.len());
        let CoupleWorkspace {
            data,
            jac,
            normal,
            c,
        } = ws;
        dynamics::forward_kinematics(model, data, &batch.q[f * n..(f + 1) * n])?;
        // C = [J_ω,bᵀ] (n × 3B), stored as its rows per coordinate
        for (i, &b) in self.couple_bodies.iter().enumerate() {
            dynamics::body_jacobian(model, data, b, jac)?;
            for j in 0..n {
                for k in 0..3 {
                    c[j * 3 * nb + 3 * i + k] = jac[(k, j)];
                }
            }
        }
        let m = 3 * nb;
        normal.fill(0.0);
        mu.fill(0.0);
        let r = &residual[f * n..(f + 1) * n];
        for j in 0..n {
            let w = self.inner.weights.get(j).copied().unwrap_or(1.0);
            let cj = &c[j * m..(j + 1) * m];
            for a in 0..m {
                mu[a] += w * cj[a] * r[j];
                for b in a..m {
                    normal[a * m + b] += w * cj[a] * cj[b];
                }
            }
        }
        let trace: f64 = (0..m).map(|a| normal[a * m + a]).sum();
        if trace > 0.0 {
            for a in 0..m {
                normal[a * m + a] += 1e-12 * trace;
            }
            if !cholesky_in_place(normal, m) {
                return Err(crate::Error::invalid(
                    "layout loss",
                    format!("frame {f}: the couples' normal equations fail"),
                ));
            }
            cholesky_solve_in_place(normal, m, mu);
        } else {
            mu.fill(0.0);
        }
        Ok(())
    }

    /// The couples `mu` as four point forces per body into a frame's `row` of λ: −Σ f_k at
    /// the centre, f_k = μ × e_k / 2d at + d e_k.
    fn couple_point_forces(&self, mu: &[f64], row: &mut [f64]) {
        let nj = self.joints;
        for i in 0..self.couple_bodies.len() {
            let couple = Vec3::new(mu[3 * i], mu[3 * i + 1], mu[3 * i + 2]);
            let points = &mut row[3 * nj + 12 * i..3 * nj + 12 * (i + 1)];
            let mut sum = Vec3::zeros();
            for k in 0..3 {
                let mut e = Vec3::zeros();
                e[k] = 1.0;
                let fk = couple.cross(&e) / (2.0 * COUPLE_ARM);
                sum += fk;
                points[3 * (k + 1)..3 * (k + 2)].copy_from_slice(fk.as_slice());
            }
            points[..3].copy_from_slice((-sum).as_slice());
        }
    }
}

/// The batch of the joint-space loss for `batch` with contact forces `lambda`.
fn el_batch<'a>(batch: &LayoutEulerLagrangeBatch<'a>, lambda: &'a [f64]) -> EulerLagrangeBatch<'a> {
    EulerLagrangeBatch {
        frames: batch.frames,
        q: batch.q,
        qd: batch.qd,
        qdd: batch.qdd,
        tau: batch.tau,
        lambda,
    }
}

/// Per-thread workspace of the couples' fit.
struct CoupleWorkspace {
    data: Data,
    /// A body's Jacobian (6 × n).
    jac: DMatrix<f64>,
    /// The normal equations (3B × 3B), factored in place.
    normal: Vec<f64>,
    /// C = [J_ω,bᵀ] (n × 3B), by rows.
    c: Vec<f64>,
}

impl CoupleWorkspace {
    fn new(model: &Model, nb: usize) -> CoupleWorkspace {
        let n = model.nq();
        CoupleWorkspace {
            data: Data::new(model),
            jac: DMatrix::zeros(6, n),
            normal: vec![0.0; 9 * nb * nb],
            c: vec![0.0; n * 3 * nb],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::augment::layout::JointLayout;
    use crate::augment::layout_inverse::{LayoutCoordinates, coordinates_from_layout};
    use crate::augment::layout_inverse_vjp::{CoordinateGradient, coordinates_from_layout_vjp};
    use crate::random::SplitMix64;
    use crate::reference::layout_clip;

    fn loss_of(
        model: &Model,
        loss: &LayoutEulerLagrange,
        c: &LayoutCoordinates,
        contact_force: &[f64],
        gradients: bool,
    ) -> LayoutEulerLagrangeOutput {
        let mut out = LayoutEulerLagrangeOutput::default();
        let batch = LayoutEulerLagrangeBatch {
            frames: c.rotation_error.len(),
            q: &c.q,
            qd: &c.qd,
            qdd: &c.qdd,
            tau: &c.tau,
            contact_force,
        };
        loss.evaluate(model, &batch, gradients, &mut out).unwrap();
        out
    }

    fn couple_bodies(contacts: &[LossContact]) -> Vec<usize> {
        contacts.iter().map(|c| c.body).collect()
    }

    /// A layout made from a motion with forces at several points under each foot: its
    /// joint forces at the joint centres plus the best couples explain exactly what the point
    /// forces explained, so the loss is what the layout cannot carry — the generalized forces
    /// of the root's translations (τ_ID − J_cᵀλ there, τ being 0 in the layout) — and without
    /// the couples it is larger by far more than the test's tolerance.
    #[test]
    fn the_layout_loss_of_a_consistent_motion_is_what_the_layout_cannot_carry() {
        for (name, model) in crate::reference::test_models() {
            let n = model.nq();
            let contacts = crate::reference::foot_contacts(&model);
            assert!(contacts.len() >= 4, "{name}: no feet");
            let (t, rate) = (5, 30.0);
            let (x, tau) = crate::reference::layout_motion(&model, t, rate, &contacts, 0.0);
            let layout = JointLayout::new(&model, 0);
            let c = coordinates_from_layout(&model, &layout, &layout_clip(t, rate, &x)).unwrap();
            let angular: Vec<usize> = layout.angular_coordinates().collect();
            let expected: f64 = (0..t * n)
                .filter(|i| !angular.contains(&(i % n)))
                .map(|i| tau[i] * tau[i])
                .sum();
            let loss =
                LayoutEulerLagrange::new(&model, &couple_bodies(&contacts), Vec::new()).unwrap();
            let out = loss_of(&model, &loss, &c, &x[5], false);
            let without = LayoutEulerLagrange::new(&model, &[], Vec::new()).unwrap();
            let plain = loss_of(&model, &without, &c, &x[5], false).loss;
            let rel = (out.loss - expected).abs() / expected;
            eprintln!(
                "{name}: L {:.9e}, Σ τ² of the translations {expected:.9e} ({rel:.1e}); \
                 without couples {plain:.3e}",
                out.loss
            );
            assert!(rel < 1e-8, "{name}: {} vs {expected}", out.loss);
            // the couples' part: what forces at the joint centres alone leave unexplained
            assert!(
                plain - expected > 1e-4 * expected,
                "{name}: the couples change nothing"
            );
        }
    }

    /// On a disturbed layout, the gradient of L_euler with respect to every block of the
    /// layout (through the fit: `coordinates_from_layout_vjp`; the contact forces directly)
    /// equals central differences of the whole map, on the default model, gait2392 and
    /// Rajagopal2016.
    #[test]
    fn the_layout_loss_gradient_matches_finite_differences() {
        for (name, model) in crate::reference::test_models() {
            let n = model.nq();
            let contacts = crate::reference::foot_contacts(&model);
            let (t, rate) = (5, 30.0);
            let x = crate::reference::layout_motion(&model, t, rate, &contacts, 1.0)
                .0
                .to_vec();
            let layout = JointLayout::new(&model, 0);
            let mut rng = SplitMix64(3);
            let weights: Vec<f64> = (0..n).map(|_| rng.uniform(0.5, 2.0)).collect();
            let loss =
                LayoutEulerLagrange::new(&model, &couple_bodies(&contacts), weights).unwrap();
            let value = |x: &[Vec<f64>]| {
                let c = coordinates_from_layout(&model, &layout, &layout_clip(t, rate, x)).unwrap();
                loss_of(&model, &loss, &c, &x[5], false).loss
            };
            let c = coordinates_from_layout(&model, &layout, &layout_clip(t, rate, &x)).unwrap();
            let out = loss_of(&model, &loss, &c, &x[5], true);
            let g = coordinates_from_layout_vjp(
                &model,
                &layout,
                &layout_clip(t, rate, &x),
                &c,
                &CoordinateGradient {
                    q: &out.grad_q,
                    qd: &out.grad_qd,
                    qdd: &out.grad_qdd,
                    tau: &out.grad_tau,
                },
            )
            .unwrap();
            let grads = [
                &g.joint_pos,
                &g.joint_rot,
                &g.joint_vel,
                &g.joint_acc,
                &g.joint_torque,
                &out.grad_contact_force,
            ];
            for (b, grad) in grads.iter().enumerate() {
                let dir: Vec<f64> = (0..grad.len()).map(|_| rng.uniform(-1.0, 1.0)).collect();
                let h = 1e-5;
                let at = |s: f64| {
                    let mut y = x.clone();
                    for (v, d) in y[b].iter_mut().zip(&dir) {
                        *v += s * d;
                    }
                    value(&y)
                };
                let fd = (at(h) - at(-h)) / (2.0 * h);
                let exact: f64 = grad.iter().zip(&dir).map(|(a, d)| a * d).sum();
                let rel = (fd - exact).abs() / exact.abs();
                eprintln!(
                    "{name} block {b}: {exact:.9e} vs differences {fd:.9e} ({rel:.1e}); L {:.3e}",
                    out.loss
                );
                assert!(rel < 1e-6, "{name} block {b}: {exact} vs {fd}");
            }
        }
    }
}
