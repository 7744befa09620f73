//! Gradients through [`super::layout_inverse::coordinates_from_layout`]: given ∂L/∂q, ∂L/∂q̇,
//! ∂L/∂q̈ and ∂L/∂τ of a loss on the fitted coordinates (from [`crate::loss`]), the gradient
//! of L with respect to the per-joint layout itself (`joint_pos`, `joint_rot`, `joint_vel`,
//! `joint_acc`, `joint_torque`) — what a trainer that predicts FlexMotion's layout needs.
//! Exact for any layout, also one whose blocks disagree with each other (a generated motion),
//! where the fit leaves residuals.
//!
//! Notation of [`super::layout_inverse`]: per frame the stacked rows A(q) (A_j of every joint,
//! then w_p J_p of the root centres), the fit's residual e(q, x) (e_j = log(exp(r_j) R_j(q)ᵀ),
//! then w_p (p_j − p_j(q))), N = AᵀA. Per frame, in reverse order of the forward map:
//!
//! - **q̈** = N⁻¹Aᵀy₂ with y₂ = [ẇ_j; w_p p̈_j] − B(q, q̇), B = Ȧq̇ = ∂(A q̇)/∂q · q̇ (the
//!   joint accelerations at q̈ = 0). With z₂ = N⁻¹ ∂L/∂q̈, ρ₂ = y₂ − A q̈:
//!   ∂L/∂y₂ = A z₂ (→ `joint_acc` and, through the second differences, `joint_pos`);
//!   ∂L/∂q_k += ρ₂ᵀ ∂_k A z₂ − (A z₂)ᵀ ∂_k A q̈ − (A z₂)ᵀ ∂_k B;
//!   ∂L/∂q̇ −= (A z₂)ᵀ ∂B/∂q̇ with ∂B/∂q̇_k = ∂_k A q̇ + (∂A/∂q · q̇) e_k.
//! - **q̇** = N⁻¹Aᵀy₁, y₁ = [w_j; w_p ṗ_j]: likewise with z₁ = N⁻¹ ∂L/∂q̇ (all of it, the
//!   share through B included) and ρ₁ = y₁ − A q̇.
//! - **τ_K** = Σ_j A_j,Kᵀ m_j: ∂L/∂m_j = A_j,K ∂L/∂τ_K; ∂L/∂q_k += Σ_j m_jᵀ ∂_k A_j,K ∂L/∂τ_K.
//! - **q** solves the fit's stationarity F(q, x) = −Aᵀe = 0 (the gradient of ½‖e‖²: with
//!   ∂e_j/∂q = −J_r⁻¹(e_j) A_j and J_r⁻ᵀ(e) e = e, the Gauss–Newton fixed point is the exact
//!   minimizer's). By the implicit-function theorem, with the Hessian
//!   H = ∂F/∂q = Aᵀ W A − S, W = diag(J_r⁻¹(e_j), I) and S_lk = eᵀ ∂_k A e_l, and λ = H⁻ᵀ ∂L/∂q:
//!   ∂L/∂r_j = (J_l⁻¹(e_j) J_l(r_j))ᵀ A_j λ (from exp(r + δ) = exp(J_l(r) δ) exp(r) and
//!   log(exp(ξ) exp(e)) = e + J_l⁻¹(e) ξ to first order) and ∂L/∂p_j = w_p² J_p,j λ.
//! - the root centres' differences are linear: their adjoints go to `joint_pos` through the
//!   stencils' transposes.
//!
//! Every derivative of A, B and the root centres is that of a joint's own kinematics: A_j
//! depends only on the joint's full coordinates θ_j = φ_j(q). They are evaluated exactly on
//! hyper-dual numbers with three infinitesimals (ε_i² = 0): with q + ε₁u + ε₂v + ε₃w, the
//! relative rotation R_j, times the same rotation without ε₁ transposed, has as vee of its
//! ε₁, ε₁ε₂, ε₁ε₃ and ε₁ε₂ε₃ parts A_j u, ∂(A_j u)·v, ∂(A_j u)·w and ∂²(A_j u)[v, w] (the
//! root centres likewise from their positions). Coordinate functions enter with their first
//! three derivatives (for several arguments: value, gradient, Hessian and the third
//! derivative along the three infinitesimal directions).
//!
//! The joint positions of joints other than the roots are not read by the fit and get a zero
//! gradient; so do the torques of coordinates outside K.

use super::layout::JointLayout;
use super::layout_inverse::{LayoutClip, LayoutCoordinates, POSITION_WEIGHT, Solver, root_stencil};
use crate::dynamics;
use crate::linalg::lu_solve_in_place;
use crate::model::reduction::NodeKind;
use crate::model::{DofKind, JointStep, Model};
use crate::spatial::{Mat3, Vec3};
use rayon::prelude::*;
use std::cell::RefCell;
use std::ops::{Add, Mul, Sub};

/// The gradient of a loss with respect to a layout clip: arrays shaped as those of
/// [`LayoutClip`] (T × J × 3, row-major).
#[derive(Clone, Debug, Default)]
pub struct LayoutGradient {
    pub joint_pos: Vec<f64>,
    pub joint_rot: Vec<f64>,
    pub joint_vel: Vec<f64>,
    pub joint_acc: Vec<f64>,
    pub joint_torque: Vec<f64>,
}

/// The gradient of a loss with respect to the coordinates fitted from a layout: ∂L/∂q, ∂L/∂q̇,
/// ∂L/∂q̈ and ∂L/∂τ, each T × n row-major.
#[derive(Clone, Copy, Debug)]
pub struct CoordinateGradient<'a> {
    pub q: &'a [f64],
    pub qd: &'a [f64],
    pub qdd: &'a [f64],
    pub tau: &'a [f64],
}

/// The gradient of a loss with respect to the layout `clip`, from its gradient `bar` with
/// respect to the fitted coordinates `coords` (the result of
/// [`super::layout_inverse::coordinates_from_layout`] on the same clip). See the module
/// documentation.
pub fn coordinates_from_layout_vjp(
    model: &Model,
    layout: &JointLayout,
    clip: &LayoutClip,
    coords: &LayoutCoordinates,
    bar: &CoordinateGradient,
) -> crate::Result<LayoutGradient> {
    let (q_bar, qd_bar, qdd_bar, tau_bar) = (bar.q, bar.qd, bar.qdd, bar.tau);
    let (n, nj, t) = (model.nq(), model.joints.len(), clip.frames);
    if layout.n_joints() != nj {
        return Err(crate::Error::invalid(
            "layout",
            format!(
                "the layout has {} joints, the model \"{}\" {nj}",
                layout.n_joints(),
                model.name
            ),
        ));
    }
    for (name, a, len) in [
        ("joint_pos", clip.joint_pos, t * nj * 3),
        ("joint_rot", clip.joint_rot, t * nj * 3),
        ("joint_vel", clip.joint_vel, t * nj * 3),
        ("joint_acc", clip.joint_acc, t * nj * 3),
        ("joint_torque", clip.joint_torque, t * nj * 3),
        ("q", &coords.q, t * n),
        ("qd", &coords.qd, t * n),
        ("qdd", &coords.qdd, t * n),
        ("q_bar", q_bar, t * n),
        ("qd_bar", qd_bar, t * n),
        ("qdd_bar", qdd_bar, t * n),
        ("tau_bar", tau_bar, t * n),
    ] {
        if a.len() != len {
            return Err(crate::Error::invalid(
                name,
                format!("expected {len} values ({t} frames), got {}", a.len()),
            ));
        }
        if let Some(i) = a.iter().position(|v| !v.is_finite()) {
            return Err(crate::Error::invalid(
                name,
                format!("value {i} is not finite"),
            ));
        }
    }
    if !(clip.rate_hz > 0.0 && clip.rate_hz.is_finite()) {
        return Err(crate::Error::invalid(
            "rate_hz",
            format!("{} (must be positive)", clip.rate_hz),
        ));
    }
    let roots: Vec<usize> = (0..nj)
        .filter(|&j| model.joints[j].parent_body == 0)
        .collect();
    let rows = 3 * nj + 3 * roots.len();
    let mut angular = vec![false; n];
    for c in layout.angular_coordinates() {
        angular[c] = true;
    }
    // Per frame, one block of the buffer: the gradients of joint_acc, joint_vel,
    // joint_torque, joint_rot and (through the fit) joint_pos, 3J each, then the adjoints of
    // the root centres' first and second differences, 3 per root each.
    let nr = roots.len();
    let stride = 15 * nj + 6 * nr;
    let mut buffer = vec![0.0; t * stride];
    let ctx = Frames {
        model,
        layout,
        clip,
        coords,
        q_bar,
        qd_bar,
        qdd_bar,
        tau_bar,
        roots: &roots,
        angular: &angular,
    };
    // frames are independent: in parallel, each thread with its own workspaces
    buffer
        .par_chunks_mut(stride.max(1))
        .enumerate()
        .try_for_each_init(
            || {
                let kin = JointKinematics::new(model, &roots);
                let scratch = Scratch::new(model, rows, &kin);
                (Solver::new(model, rows), kin, scratch)
            },
            |(ws, kin, scratch), (f, block)| ctx.frame(f, ws, kin, scratch, block),
        )?;
    let dt = 1.0 / clip.rate_hz;
    let mut out = LayoutGradient::default();
    for (part, target) in [
        &mut out.joint_acc,
        &mut out.joint_vel,
        &mut out.joint_torque,
        &mut out.joint_rot,
        &mut out.joint_pos,
    ]
    .into_iter()
    .enumerate()
    {
        *target = buffer
            .chunks(stride.max(1))
            .flat_map(|b| &b[3 * nj * part..3 * nj * (part + 1)])
            .copied()
            .collect();
        target.resize(t * nj * 3, 0.0);
    }
    // the root centres' differences, transposed
    for f in 0..t {
        let [first, second] = root_stencil(f, t, dt);
        for (r, &j) in roots.iter().enumerate() {
            let b = &buffer[f * stride + 15 * nj..(f + 1) * stride];
            let gv = Vec3::from_column_slice(&b[3 * r..3 * r + 3]);
            let ga = Vec3::from_column_slice(&b[3 * nr + 3 * r..3 * nr + 3 * r + 3]);
            for ((g1, c1), (g2, c2)) in first.into_iter().zip(second) {
                for k in 0..3 {
                    out.joint_pos[(g1 * nj + j) * 3 + k] += c1 * gv[k];
                    out.joint_pos[(g2 * nj + j) * 3 + k] += c2 * ga[k];
                }
            }
        }
    }
    Ok(out)
}

/// What every frame of the reverse pass reads.
struct Frames<'a> {
    model: &'a Model,
    layout: &'a JointLayout,
    clip: &'a LayoutClip<'a>,
    coords: &'a LayoutCoordinates,
    q_bar: &'a [f64],
    qd_bar: &'a [f64],
    qdd_bar: &'a [f64],
    tau_bar: &'a [f64],
    roots: &'a [usize],
    /// Per coordinate, whether it is one of the layout's angular coordinates K.
    angular: &'a [bool],
}

impl Frames<'_> {
    fn vec3(&self, a: &[f64], f: usize, j: usize) -> Vec3 {
        let i = (f * self.model.joints.len() + j) * 3;
        Vec3::new(a[i], a[i + 1], a[i + 2])
    }

    /// The root centres' first and second differences at frame `f` (see `root_stencil`).
    fn root_rates(&self, f: usize, r: usize) -> (Vec3, Vec3) {
        let [first, second] = root_stencil(f, self.clip.frames, 1.0 / self.clip.rate_hz);
        let p = |(g, c): (usize, f64)| self.vec3(self.clip.joint_pos, g, self.roots[r]) * c;
        (
            first.into_iter().map(p).sum(),
            second.into_iter().map(p).sum(),
        )
    }

    /// The reverse pass of frame `f` into its `block` of the buffer (see
    /// [`coordinates_from_layout_vjp`]): the fit linearized at the frame's q, the adjoints of
    /// q̈ = N⁻¹Aᵀy₂, q̇ = N⁻¹Aᵀy₁ and τ_K, then that of q through the fit's stationarity.
    fn frame(
        &self,
        f: usize,
        ws: &mut Solver,
        kin: &JointKinematics,
        scratch: &mut Scratch,
        block: &mut [f64],
    ) -> crate::Result<()> {
        let n = self.model.nq();
        let frame = f * n..(f + 1) * n;
        let state = FrameState {
            f,
            q: &self.coords.q[frame.clone()],
            qd: &self.coords.qd[frame.clone()],
            qdd: &self.coords.qdd[frame.clone()],
        };
        let mut bars = BlockBars::split(block, self.model.joints.len(), self.roots.len());
        self.linearize(&state, ws, kin, scratch)?;
        self.residuals(&state, ws, kin, scratch);
        scratch.q_bar.copy_from_slice(&self.q_bar[frame.clone()]);
        scratch.qd_bar.copy_from_slice(&self.qd_bar[frame]);
        self.acceleration_adjoint(&state, ws, kin, scratch, &mut bars);
        self.velocity_adjoint(&state, ws, kin, scratch, &mut bars);
        self.torque_adjoint(&state, ws, kin, scratch, &mut bars);
        self.position_adjoint(&state, ws, kin, scratch, &mut bars)
    }

    /// The fit at the frame's q: kinematics, the rows' Jacobian A, the errors e, the normal
    /// matrix N factored, and each joint's table over its coordinates l, k:
    /// ∂(A e_l)·e_k and ∂²(A e_l)[e_k, q̇].
    fn linearize(
        &self,
        s: &FrameState,
        ws: &mut Solver,
        kin: &JointKinematics,
        scratch: &mut Scratch,
    ) -> crate::Result<()> {
        let model = self.model;
        let (n, nj) = (model.nq(), model.joints.len());
        let rows = 3 * nj + 3 * self.roots.len();
        dynamics::forward_kinematics(model, &mut ws.data, s.q)?;
        ws.jacobians(model, self.layout, self.roots)?;
        ws.errors(model, self.clip, s.f, self.roots);
        ws.factor(n, rows)?;
        scratch.e.copy_from_slice(&ws.e);
        for j in 0..nj {
            let deps = &kin.deps[j];
            for (li, &l) in deps.iter().enumerate() {
                for (ki, &k) in deps.iter().enumerate() {
                    let g = kin.eval(model, j, s.q, Dir::Unit(l), Dir::Unit(k), Dir::Vec(s.qd));
                    scratch.table[kin.offset[j] + li * deps.len() + ki] = [g.part(1), g.part(3)];
                }
            }
        }
        Ok(())
    }

    /// The right-hand sides less the fit: ρ₁ = y₁ − A q̇ and ρ₂ = y₂ − A q̈ with
    /// y₂ = joint accelerations − B, B = ∂(A q̇)·q̇; and the joint torques m.
    fn residuals(&self, s: &FrameState, ws: &Solver, kin: &JointKinematics, scratch: &mut Scratch) {
        let (clip, f) = (self.clip, s.f);
        let (n, nj) = (self.model.nq(), self.model.joints.len());
        let rows = 3 * nj + 3 * self.roots.len();
        let Scratch {
            rho1,
            rho2,
            m,
            table,
            ..
        } = scratch;
        let t = JointTables {
            kin,
            table: table.as_slice(),
        };
        for j in 0..nj {
            let mut b = (Vec3::zeros(), Vec3::zeros());
            for (li, &l) in kin.deps[j].iter().enumerate() {
                let r = t.contract_k(j, li, s.qd);
                b.0 += r.0 * s.qd[l];
                b.1 += r.1 * s.qd[l];
            }
            let w = self.vec3(clip.joint_vel, f, j);
            let acc = self.vec3(clip.joint_acc, f, j) - b.0;
            rho1[3 * j..3 * j + 3].copy_from_slice(w.as_slice());
            rho2[3 * j..3 * j + 3].copy_from_slice(acc.as_slice());
            m[3 * j..3 * j + 3].copy_from_slice(self.vec3(clip.joint_torque, f, j).as_slice());
            if let Some(r) = kin.root_of[j] {
                let (v, a) = self.root_rates(f, r);
                let i = 3 * nj + 3 * r;
                rho1[i..i + 3].copy_from_slice((v * POSITION_WEIGHT).as_slice());
                rho2[i..i + 3].copy_from_slice((a * POSITION_WEIGHT - b.1).as_slice());
            }
        }
        for row in 0..rows {
            let a = &ws.a[row * n..(row + 1) * n];
            rho1[row] -= dot(a, s.qd);
            rho2[row] -= dot(a, s.qdd);
        }
    }

    /// The adjoint of q̈ = N⁻¹Aᵀy₂: the joint and root accelerations' gradients, and what
    /// q̈'s dependence on q and q̇ adds to theirs.
    fn acceleration_adjoint(
        &self,
        s: &FrameState,
        ws: &mut Solver,
        kin: &JointKinematics,
        scratch: &mut Scratch,
        bars: &mut BlockBars,
    ) {
        let (n, nj) = (self.model.nq(), self.model.joints.len());
        let Scratch {
            rho2,
            az,
            q_bar: qb,
            qd_bar: qdb,
            z,
            table,
            ..
        } = scratch;
        let t = JointTables {
            kin,
            table: table.as_slice(),
        };
        let qd = s.qd;
        z.copy_from_slice(&self.qdd_bar[s.f * n..(s.f + 1) * n]);
        ws.solve_normal(z);
        multiply(&ws.a, n, z, az);
        bars.acc.copy_from_slice(&az[..3 * nj]);
        for (d, a) in bars.pdd.iter_mut().zip(&az[3 * nj..]) {
            *d = a * POSITION_WEIGHT;
        }
        for j in 0..nj {
            for (ki, &k) in kin.deps[j].iter().enumerate() {
                // ∂_k B = ∂²(A q̇)[q̇, e_k];  ∂B/∂q̇_k = ∂_k(A q̇) + ∂(A e_k)·q̇
                qb[k] -= kin.dot_rows(j, az, &t.contract_l(j, ki, qd, 1));
                qdb[k] -= kin.dot_rows(j, az, &t.contract_l(j, ki, qd, 0));
                qdb[k] -= kin.dot_rows(j, az, &t.contract_k(j, ki, qd));
                qb[k] += kin.dot_rows(j, rho2, &t.contract_l(j, ki, z, 0));
                qb[k] -= kin.dot_rows(j, az, &t.contract_l(j, ki, s.qdd, 0));
            }
        }
    }

    /// The adjoint of q̇ = N⁻¹Aᵀy₁: the joint and root velocities' gradients, and what q̇'s
    /// dependence on q adds to its.
    fn velocity_adjoint(
        &self,
        s: &FrameState,
        ws: &mut Solver,
        kin: &JointKinematics,
        scratch: &mut Scratch,
        bars: &mut BlockBars,
    ) {
        let (n, nj) = (self.model.nq(), self.model.joints.len());
        let Scratch {
            rho1,
            az,
            q_bar: qb,
            qd_bar: qdb,
            z,
            table,
            ..
        } = scratch;
        let t = JointTables {
            kin,
            table: table.as_slice(),
        };
        z.copy_from_slice(qdb);
        ws.solve_normal(z);
        multiply(&ws.a, n, z, az);
        bars.vel.copy_from_slice(&az[..3 * nj]);
        for (d, a) in bars.pd.iter_mut().zip(&az[3 * nj..]) {
            *d = a * POSITION_WEIGHT;
        }
        for j in 0..nj {
            for (ki, &k) in kin.deps[j].iter().enumerate() {
                qb[k] += kin.dot_rows(j, rho1, &t.contract_l(j, ki, z, 0));
                qb[k] -= kin.dot_rows(j, az, &t.contract_l(j, ki, s.qd, 0));
            }
        }
    }

    /// The adjoint of τ_K = Σ_j A_j,Kᵀ m_j: the joint torques' gradients, and what τ_K's
    /// dependence on q adds to its.
    fn torque_adjoint(
        &self,
        s: &FrameState,
        ws: &Solver,
        kin: &JointKinematics,
        scratch: &mut Scratch,
        bars: &mut BlockBars,
    ) {
        let (n, nj) = (self.model.nq(), self.model.joints.len());
        let Scratch {
            az,
            m,
            q_bar: qb,
            z,
            table,
            ..
        } = scratch;
        let t = JointTables {
            kin,
            table: table.as_slice(),
        };
        for (c, zc) in z.iter_mut().enumerate() {
            *zc = if self.angular[c] {
                self.tau_bar[s.f * n + c]
            } else {
                0.0
            };
        }
        multiply(&ws.a, n, z, az);
        bars.torque.copy_from_slice(&az[..3 * nj]);
        for j in 0..nj {
            for (ki, &k) in kin.deps[j].iter().enumerate() {
                qb[k] +=
                    Vec3::from_column_slice(&m[3 * j..3 * j + 3]).dot(&t.contract_l(j, ki, z, 0).0);
            }
        }
    }

    /// The adjoint of q, by the implicit-function theorem on the fit's stationarity:
    /// λ = H⁻ᵀ ∂L/∂q, and from it the joint rotations' and root positions' gradients.
    fn position_adjoint(
        &self,
        s: &FrameState,
        ws: &Solver,
        kin: &JointKinematics,
        scratch: &mut Scratch,
        bars: &mut BlockBars,
    ) -> crate::Result<()> {
        let (n, nj) = (self.model.nq(), self.model.joints.len());
        let Scratch {
            e,
            az,
            q_bar: qb,
            table,
            ht,
            ..
        } = scratch;
        let t = JointTables {
            kin,
            table: table.as_slice(),
        };
        // Hᵀ, row-major (ht[k·n + l] = H_lk), solved in place for λ = H⁻ᵀ ∂L/∂q
        ht.fill(0.0);
        for j in 0..nj {
            // (Aᵀ W A) over this joint's rows: W = J_r⁻¹(e_j) on the rotation rows
            let ej = Vec3::from_column_slice(&e[3 * j..3 * j + 3]);
            let w = right_jacobian_inverse(&ej);
            let deps = &kin.deps[j];
            for &l in deps {
                let al = column(&ws.a, n, 3 * j, l);
                for &k in deps {
                    let ak = column(&ws.a, n, 3 * j, k);
                    ht[k * n + l] += al.dot(&(w * ak));
                }
            }
            if let Some(r) = kin.root_of[j] {
                for &l in deps {
                    let al = column(&ws.a, n, 3 * nj + 3 * r, l);
                    for &k in deps {
                        ht[k * n + l] += al.dot(&column(&ws.a, n, 3 * nj + 3 * r, k));
                    }
                }
            }
            // − S: S_lk = eᵀ ∂_k A e_l
            for (li, &l) in deps.iter().enumerate() {
                for (ki, &k) in deps.iter().enumerate() {
                    ht[k * n + l] -= kin.dot_rows(j, e, &t.at(j, li, ki)[0]);
                }
            }
        }
        if !lu_solve_in_place(ht, n, qb) {
            return Err(crate::Error::invalid(
                "layout",
                format!(
                    "frame {}: the fit's Hessian is singular (its q is not determined)",
                    s.f
                ),
            ));
        }
        let lambda = &*qb;
        multiply(&ws.a, n, lambda, az);
        for j in 0..nj {
            let ej = Vec3::from_column_slice(&e[3 * j..3 * j + 3]);
            let rj = self.vec3(self.clip.joint_rot, s.f, j);
            let de = left_jacobian_inverse(&ej) * left_jacobian(&rj);
            let g = de.transpose() * Vec3::from_column_slice(&az[3 * j..3 * j + 3]);
            bars.rot[3 * j..3 * j + 3].copy_from_slice(g.as_slice());
            if let Some(r) = kin.root_of[j] {
                let k = 3 * nj + 3 * r;
                for i in 0..3 {
                    bars.pos[3 * j + i] = az[k + i] * POSITION_WEIGHT;
                }
            }
        }
        Ok(())
    }
}

/// One frame's coordinates, as the reverse pass reads them.
struct FrameState<'a> {
    f: usize,
    q: &'a [f64],
    qd: &'a [f64],
    qdd: &'a [f64],
}

/// A frame's block of the gradient buffer, by layout array: per joint (3 each) the
/// accelerations, velocities, torques, rotations and positions; per root (3 each) the
/// first and second differences of its centre.
struct BlockBars<'a> {
    acc: &'a mut [f64],
    vel: &'a mut [f64],
    torque: &'a mut [f64],
    rot: &'a mut [f64],
    pos: &'a mut [f64],
    pd: &'a mut [f64],
    pdd: &'a mut [f64],
}

impl<'a> BlockBars<'a> {
    /// `block` split for `nj` joints and `nr` roots.
    fn split(block: &'a mut [f64], nj: usize, nr: usize) -> BlockBars<'a> {
        let (acc, rest) = block.split_at_mut(3 * nj);
        let (vel, rest) = rest.split_at_mut(3 * nj);
        let (torque, rest) = rest.split_at_mut(3 * nj);
        let (rot, rest) = rest.split_at_mut(3 * nj);
        let (pos, rest) = rest.split_at_mut(3 * nj);
        let (pd, pdd) = rest.split_at_mut(3 * nr);
        BlockBars {
            acc,
            vel,
            torque,
            rot,
            pos,
            pd,
            pdd,
        }
    }
}

/// A frame's per-joint tables ([`Scratch::table`]) and the contractions the reverse pass
/// takes of them.
struct JointTables<'a> {
    kin: &'a JointKinematics,
    table: &'a [[(Vec3, Vec3); 2]],
}

impl JointTables<'_> {
    /// Joint `j`'s entry for its coordinates `li`, `ki` (in `deps` order).
    fn at(&self, j: usize, li: usize, ki: usize) -> &[(Vec3, Vec3); 2] {
        &self.table[self.kin.offset[j] + li * self.kin.deps[j].len() + ki]
    }

    /// Σ_l u_l T[l][k] (part 0: ∂(A u)·e_k; part 1: ∂²(A u)[e_k, q̇])
    fn contract_l(&self, j: usize, ki: usize, u: &[f64], part: usize) -> (Vec3, Vec3) {
        let mut s = (Vec3::zeros(), Vec3::zeros());
        for (li, &l) in self.kin.deps[j].iter().enumerate() {
            let t = &self.at(j, li, ki)[part];
            s.0 += t.0 * u[l];
            s.1 += t.1 * u[l];
        }
        s
    }

    /// Σ_k v_k T[l][k] (part 0): ∂(A e_l)·v
    fn contract_k(&self, j: usize, li: usize, v: &[f64]) -> (Vec3, Vec3) {
        let mut s = (Vec3::zeros(), Vec3::zeros());
        for (ki, &k) in self.kin.deps[j].iter().enumerate() {
            let t = &self.at(j, li, ki)[0];
            s.0 += t.0 * v[k];
            s.1 += t.1 * v[k];
        }
        s
    }
}

/// Per-frame vectors of the reverse pass, allocated once.
struct Scratch {
    e: Vec<f64>,
    rho1: Vec<f64>,
    rho2: Vec<f64>,
    az: Vec<f64>,
    m: Vec<f64>,
    q_bar: Vec<f64>,
    qd_bar: Vec<f64>,
    z: Vec<f64>,
    /// Per joint, its table (see [`JointKinematics::offset`]).
    table: Vec<[(Vec3, Vec3); 2]>,
    /// The fit's Hessian, transposed (n × n).
    ht: Vec<f64>,
}

impl Scratch {
    fn new(model: &Model, rows: usize, kin: &JointKinematics) -> Scratch {
        let n = model.nq();
        Scratch {
            e: vec![0.0; rows],
            rho1: vec![0.0; rows],
            rho2: vec![0.0; rows],
            az: vec![0.0; rows],
            m: vec![0.0; 3 * model.joints.len()],
            q_bar: vec![0.0; n],
            qd_bar: vec![0.0; n],
            z: vec![0.0; n],
            table: vec![[(Vec3::zeros(), Vec3::zeros()); 2]; kin.table_len],
            ht: vec![0.0; n * n],
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// out = A x for A row-major with `n` columns.
fn multiply(a: &[f64], n: usize, x: &[f64], out: &mut [f64]) {
    for (row, o) in out.iter_mut().enumerate() {
        *o = dot(&a[row * n..(row + 1) * n], x);
    }
}

/// Column `c` of the three rows of A starting at `row`.
fn column(a: &[f64], n: usize, row: usize, c: usize) -> Vec3 {
    Vec3::new(a[row * n + c], a[(row + 1) * n + c], a[(row + 2) * n + c])
}

fn hat(v: &Vec3) -> Mat3 {
    Mat3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// The coefficients of J_l(φ) = I + a[φ]× + b[φ]×² and of J_l⁻¹(φ) = I − ½[φ]× + c[φ]×²:
/// a = (1 − cos θ)/θ², b = (θ − sin θ)/θ³, c = 1/θ² − (1 + cos θ)/(2θ sin θ), θ = |φ|
/// (Taylor series below θ = 1e-3).
fn so3_coefficients(phi: &Vec3) -> (f64, f64, f64) {
    let th = phi.norm();
    let t2 = th * th;
    if th < 1e-3 {
        return (
            0.5 - t2 / 24.0 + t2 * t2 / 720.0,
            1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0,
            1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0,
        );
    }
    let (s, c) = th.sin_cos();
    (
        (1.0 - c) / t2,
        (th - s) / (t2 * th),
        1.0 / t2 - (1.0 + c) / (2.0 * th * s),
    )
}

/// The left Jacobian of SO(3): exp(φ + δ) = exp(J_l(φ) δ) exp(φ) to first order.
fn left_jacobian(phi: &Vec3) -> Mat3 {
    let (a, b, _) = so3_coefficients(phi);
    let k = hat(phi);
    Mat3::identity() + k * a + k * k * b
}

/// J_l⁻¹(φ): log(exp(ξ) exp(φ)) = φ + J_l⁻¹(φ) ξ to first order.
fn left_jacobian_inverse(phi: &Vec3) -> Mat3 {
    let (_, _, c) = so3_coefficients(phi);
    let k = hat(phi);
    Mat3::identity() - k * 0.5 + k * k * c
}

/// J_r⁻¹(φ) = J_l⁻¹(−φ): log(exp(φ) exp(ξ)) = φ + J_r⁻¹(φ) ξ to first order.
fn right_jacobian_inverse(phi: &Vec3) -> Mat3 {
    left_jacobian_inverse(&-phi)
}

/// A hyper-dual number with three infinitesimals ε₁, ε₂, ε₃ (ε_i² = 0): component `m` (a bit
/// mask, bit i for ε_{i+1}) is the coefficient of the product of the ε's in `m`.
#[derive(Clone, Copy, Debug, Default)]
struct Hyper([f64; 8]);

impl Hyper {
    fn cst(v: f64) -> Hyper {
        let mut c = [0.0; 8];
        c[0] = v;
        Hyper(c)
    }

    /// f(self) from f and its first three derivatives `d` at the real part a₀: with
    /// h = self − a₀ (h⁴ = 0), f(a₀ + h) = f + f′h + f″h²/2 + f‴h³/6.
    fn apply(self, d: [f64; 4]) -> Hyper {
        let mut h = self;
        h.0[0] = 0.0;
        let h2 = h * h;
        let h3 = h2 * h;
        let mut out = h * d[1] + h2 * (0.5 * d[2]) + h3 * (d[3] / 6.0);
        out.0[0] = d[0];
        out
    }
}

impl Add for Hyper {
    type Output = Hyper;
    fn add(mut self, o: Hyper) -> Hyper {
        for (a, b) in self.0.iter_mut().zip(o.0) {
            *a += b;
        }
        self
    }
}

impl Sub for Hyper {
    type Output = Hyper;
    fn sub(mut self, o: Hyper) -> Hyper {
        for (a, b) in self.0.iter_mut().zip(o.0) {
            *a -= b;
        }
        self
    }
}

impl Mul for Hyper {
    type Output = Hyper;
    /// (Σ a_m ε_m)(Σ b_n ε_n) = Σ_{m ∩ n = ∅} a_m b_n ε_{m ∪ n}.
    fn mul(self, o: Hyper) -> Hyper {
        let mut c = [0.0; 8];
        for (i, &a) in self.0.iter().enumerate() {
            if a == 0.0 {
                continue;
            }
            for (j, &b) in o.0.iter().enumerate() {
                if i & j == 0 {
                    c[i | j] += a * b;
                }
            }
        }
        Hyper(c)
    }
}

impl Mul<f64> for Hyper {
    type Output = Hyper;
    fn mul(mut self, s: f64) -> Hyper {
        self.0.iter_mut().for_each(|a| *a *= s);
        self
    }
}

type HMat = [[Hyper; 3]; 3];
type HVec = [Hyper; 3];

fn hmat_identity() -> HMat {
    let mut m = [[Hyper::default(); 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        row[i] = Hyper::cst(1.0);
    }
    m
}

fn hmat_mul(a: &HMat, b: &HMat) -> HMat {
    let mut c = [[Hyper::default(); 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    c
}

fn hmat_mul_f64(a: &HMat, b: &Mat3) -> HMat {
    let mut c = [[Hyper::default(); 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[i][0] * b[(0, j)] + a[i][1] * b[(1, j)] + a[i][2] * b[(2, j)];
        }
    }
    c
}

fn hmat_vec(a: &HMat, v: &Vec3) -> HVec {
    [0, 1, 2].map(|i| a[i][0] * v.x + a[i][1] * v.y + a[i][2] * v.z)
}

/// Rodrigues' formula R = cos θ I + sin θ [a]× + (1 − cos θ) a aᵀ for a unit axis a.
fn hrotation(axis: &Vec3, th: Hyper) -> HMat {
    let (s0, c0) = th.0[0].sin_cos();
    let s = th.apply([s0, c0, -s0, -c0]);
    let c = th.apply([c0, -s0, -c0, s0]);
    let one_c = Hyper::cst(1.0) - c;
    let k = hat(axis);
    let mut m = [[Hyper::default(); 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = s * k[(i, j)] + one_c * (axis[i] * axis[j]);
        }
        m[i][i] = m[i][i] + c;
    }
    m
}

/// A direction of q: a full vector or a unit vector e_k.
#[derive(Clone, Copy)]
enum Dir<'a> {
    Vec(&'a [f64]),
    Unit(usize),
}

impl Dir<'_> {
    fn at(&self, k: usize) -> f64 {
        match *self {
            Dir::Vec(v) => v[k],
            Dir::Unit(u) => f64::from(u == k),
        }
    }
}

/// One joint's rows of A along the directions (u, v, w): index 0 = A u, 1 = ∂(A u)·v,
/// 2 = ∂(A u)·w, 3 = ∂²(A u)[v, w]; the rotation rows, and the root centre's rows (w_p J_p)
/// for a root joint.
struct JointRates {
    rot: [Vec3; 4],
    pos: [Vec3; 4],
}

impl JointRates {
    /// The rows' part `i` as one slice-like pair (rotation, position).
    fn part(&self, i: usize) -> (Vec3, Vec3) {
        (self.rot[i], self.pos[i])
    }
}

/// The kinematics of each joint alone on hyper-dual numbers: the coordinate nodes its full
/// coordinates need and the q it depends on.
struct JointKinematics {
    /// Per joint: the reduction nodes to evaluate, arguments first.
    nodes: Vec<Vec<usize>>,
    /// Per joint: the independent coordinates its rows depend on.
    deps: Vec<Vec<usize>>,
    /// Per joint: its index among the root joints.
    root_of: Vec<Option<usize>>,
    /// Per joint: where its table starts in [`Scratch::table`]: for its coordinates l, k (in
    /// `deps` order) at l · |deps| + k the rows ∂(A e_l)·e_k and ∂²(A e_l)[e_k, q̇]. Every
    /// derivative of A the reverse pass needs is a contraction of these.
    offset: Vec<usize>,
    table_len: usize,
    /// Scratch: the nodes' hyper-dual values, and the arguments, gradient, Hessian and the
    /// three infinitesimal directions of a function of several arguments.
    value: RefCell<Vec<Hyper>>,
    args: RefCell<Vec<f64>>,
}

impl JointKinematics {
    fn new(model: &Model, roots: &[usize]) -> JointKinematics {
        let r = &model.reduction;
        let nc = r.n_coordinates;
        // position of each node in the evaluation order (coordinates, then full coordinates)
        let mut rank = vec![usize::MAX; r.nodes.len()];
        for (i, &node) in r
            .order
            .iter()
            .chain(&(nc..r.nodes.len()).collect::<Vec<_>>())
            .enumerate()
        {
            rank[node] = i;
        }
        let mut nodes = Vec::new();
        let mut deps = Vec::new();
        for joint in &model.joints {
            let mut seen = vec![false; r.nodes.len()];
            let mut stack: Vec<usize> = joint.dof_range.clone().map(|d| nc + d).collect();
            let mut list = Vec::new();
            let mut q = Vec::new();
            while let Some(i) = stack.pop() {
                if std::mem::replace(&mut seen[i], true) {
                    continue;
                }
                list.push(i);
                match &r.nodes[i] {
                    NodeKind::Independent(j) => q.push(*j),
                    NodeKind::Constant(_) => {}
                    NodeKind::Affine { arg, .. } => stack.push(*arg),
                    NodeKind::Function { args, .. } => stack.extend(args),
                }
            }
            list.sort_by_key(|&i| rank[i]);
            q.sort_unstable();
            nodes.push(list);
            deps.push(q);
        }
        let mut root_of = vec![None; model.joints.len()];
        for (k, &j) in roots.iter().enumerate() {
            root_of[j] = Some(k);
        }
        let k = r.max_args;
        let mut offset = Vec::with_capacity(deps.len());
        let mut table_len = 0;
        for d in &deps {
            offset.push(table_len);
            table_len += d.len() * d.len();
        }
        JointKinematics {
            nodes,
            deps,
            root_of,
            offset,
            table_len,
            value: RefCell::new(vec![Hyper::default(); r.nodes.len()]),
            args: RefCell::new(vec![0.0; 5 * k + k * k]),
        }
    }

    /// sᵀ of joint `j`'s rows (its rotation rows, then its root centre rows) times `rows`.
    fn dot_rows(&self, j: usize, s: &[f64], rows: &(Vec3, Vec3)) -> f64 {
        let mut v = Vec3::from_column_slice(&s[3 * j..3 * j + 3]).dot(&rows.0);
        if let Some(r) = self.root_of[j] {
            let i = 3 * self.root_of.len() + 3 * r;
            v += Vec3::from_column_slice(&s[i..i + 3]).dot(&rows.1);
        }
        v
    }

    /// Joint `j`'s rows at q + ε₁u + ε₂v + ε₃w (see [`JointRates`]).
    fn eval(&self, model: &Model, j: usize, q: &[f64], u: Dir, v: Dir, w: Dir) -> JointRates {
        let r = &model.reduction;
        let nc = r.n_coordinates;
        let mut value = self.value.borrow_mut();
        for &i in &self.nodes[j] {
            value[i] = match &r.nodes[i] {
                NodeKind::Independent(k) => {
                    let mut h = [0.0; 8];
                    h[0] = q[*k];
                    h[1] = u.at(*k);
                    h[2] = v.at(*k);
                    h[4] = w.at(*k);
                    Hyper(h)
                }
                NodeKind::Constant(c) => Hyper::cst(*c),
                NodeKind::Affine {
                    arg,
                    slope,
                    intercept,
                } => value[*arg] * *slope + Hyper::cst(*intercept),
                NodeKind::Function {
                    function,
                    args,
                    scale,
                } => {
                    if args.len() == 1 {
                        let x = value[args[0]].0[0];
                        let (f0, f1, f2) = function.eval1(x);
                        let f3 = function.third_derivative1(x);
                        value[args[0]].apply([f0, f1, f2, f3]) * *scale
                    } else {
                        // functions of several arguments: with h_a the argument's
                        // infinitesimal part, f(x + h) = f + Σ_a f_a h_a + ½ Σ_ab f_ab h_a h_b
                        // + ⅙ Σ_abc f_abc h_a h_b h_c; each factor of the cubic term gives one
                        // of ε₁, ε₂, ε₃ (ε_i² = 0), so it is D³f[h¹, h², h³] ε₁ε₂ε₃ with h^m
                        // the ε_m parts of the arguments.
                        let k = args.len();
                        let mut args_scratch = self.args.borrow_mut();
                        let (x, rest) = args_scratch.split_at_mut(k);
                        let (g, rest) = rest.split_at_mut(k);
                        let (hs, rest) = rest.split_at_mut(k * k);
                        let (h1, rest) = rest.split_at_mut(k);
                        let (h2, rest) = rest.split_at_mut(k);
                        let h3 = &mut rest[..k];
                        for (xa, &a) in x.iter_mut().zip(args) {
                            *xa = value[a].0[0];
                        }
                        let f0 = function.eval(x, g, hs);
                        let mut out = Hyper::cst(f0);
                        for a in 0..k {
                            let mut ha = value[args[a]];
                            ha.0[0] = 0.0;
                            out = out + ha * g[a];
                            for b in 0..k {
                                let mut hb = value[args[b]];
                                hb.0[0] = 0.0;
                                out = out + ha * hb * (0.5 * hs[a * k + b]);
                            }
                        }
                        if !function.third_order_vanishes() {
                            for (a, &arg) in args.iter().enumerate() {
                                let h = value[arg].0;
                                (h1[a], h2[a], h3[a]) = (h[1], h[2], h[4]);
                            }
                            out.0[7] += function.third_directional(x, h1, h2, h3);
                        }
                        out * *scale
                    }
                }
            };
        }
        // R_j = Π steps, the joint centre in F (translations along the preceding frame)
        let joint = &model.joints[j];
        let mut rot = hmat_identity();
        let mut pos = [Hyper::default(); 3];
        for step in &joint.steps {
            match step {
                JointStep::Fixed(x) => {
                    let d = hmat_vec(&rot, &x.pos);
                    pos = [0, 1, 2].map(|i| pos[i] + d[i]);
                    rot = hmat_mul_f64(&rot, &x.rot);
                }
                JointStep::Dof(d) => {
                    let dof = &model.dofs[*d];
                    let th = value[nc + d];
                    match dof.kind {
                        DofKind::Slide => {
                            let a = hmat_vec(&rot, &dof.axis);
                            pos = [0, 1, 2].map(|i| pos[i] + a[i] * th);
                        }
                        DofKind::Hinge => rot = hmat_mul(&rot, &hrotation(&dof.axis, th)),
                    }
                }
            }
        }
        // vee of the skew part of R · R|ε₁=0 ᵀ
        let mut r0 = rot;
        for row in r0.iter_mut() {
            for x in row.iter_mut() {
                for m in [1, 3, 5, 7] {
                    x.0[m] = 0.0;
                }
            }
        }
        let mut prod = [[Hyper::default(); 3]; 3];
        for i in 0..3 {
            for k in 0..3 {
                prod[i][k] = rot[i][0] * r0[k][0] + rot[i][1] * r0[k][1] + rot[i][2] * r0[k][2];
            }
        }
        let vee = |m: usize| {
            Vec3::new(
                prod[2][1].0[m] - prod[1][2].0[m],
                prod[0][2].0[m] - prod[2][0].0[m],
                prod[1][0].0[m] - prod[0][1].0[m],
            ) * 0.5
        };
        let parts = [1, 3, 5, 7];
        let rot_rows = parts.map(vee);
        let pos_rows = if self.root_of[j].is_some() {
            let x = &joint.parent_offset;
            parts.map(|m| {
                let local = Vec3::new(pos[0].0[m], pos[1].0[m], pos[2].0[m]);
                x.rot * local * POSITION_WEIGHT
            })
        } else {
            [Vec3::zeros(); 4]
        };
        JointRates {
            rot: rot_rows,
            pos: pos_rows,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::augment::layout_inverse::coordinates_from_layout;
    use crate::random::SplitMix64;
    use crate::reference::layout_clip;

    /// On an inconsistent layout (the fit leaves residuals), the gradient of a random linear
    /// functional of the fitted q, q̇, q̈ and τ equals central differences of the forward map,
    /// block by block, on the default model, gait2392 and Rajagopal2016.
    #[test]
    fn layout_gradient_matches_finite_differences() {
        for (name, model) in crate::reference::test_models() {
            check_layout_gradient(name, &model);
        }
    }

    /// The same on a shoulder whose translations follow a coordinate coupled to two
    /// coordinates by a cubic multivariate polynomial (third derivatives of a function of
    /// several arguments in the hyper-dual kinematics).
    #[test]
    fn layout_gradient_matches_finite_differences_with_a_multivariate_coupler() {
        let xml = include_str!("../../tests/data/multivariate_coupler.osim");
        let model = Model::from_osim_str(xml, "multivariate_coupler.osim").unwrap();
        check_layout_gradient("multivariate_coupler", &model);
    }

    fn check_layout_gradient(name: &str, model: &Model) {
        let n = model.nq();
        let layout = JointLayout::new(model, 0);
        let (t, rate) = (6, 20.0);
        let x = crate::reference::layout_motion(model, t, rate, &[], 1.0)
            .0
            .to_vec();
        let base = coordinates_from_layout(model, &layout, &layout_clip(t, rate, &x)).unwrap();
        let misfit = base.rotation_error.iter().fold(0.0f64, |m, v| m.max(*v));
        assert!(
            misfit > 1e-3,
            "{name}: the disturbed layout is consistent ({misfit})"
        );
        let mut rng = SplitMix64(11);
        let cot: Vec<Vec<f64>> = (0..4)
            .map(|_| (0..t * n).map(|_| rng.uniform(-1.0, 1.0)).collect())
            .collect();
        let functional = |c: &LayoutCoordinates| -> f64 {
            [&c.q, &c.qd, &c.qdd, &c.tau]
                .iter()
                .zip(&cot)
                .map(|(v, g)| dot(v, g))
                .sum()
        };
        let grad = coordinates_from_layout_vjp(
            model,
            &layout,
            &layout_clip(t, rate, &x),
            &base,
            &CoordinateGradient {
                q: &cot[0],
                qd: &cot[1],
                qdd: &cot[2],
                tau: &cot[3],
            },
        )
        .unwrap();
        let blocks = [
            ("joint_pos", &grad.joint_pos),
            ("joint_rot", &grad.joint_rot),
            ("joint_vel", &grad.joint_vel),
            ("joint_acc", &grad.joint_acc),
            ("joint_torque", &grad.joint_torque),
        ];
        for (b, (block, g)) in blocks.iter().enumerate() {
            let dir: Vec<f64> = (0..g.len()).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let h = 1e-5;
            let at = |s: f64| {
                let mut y = x.clone();
                for (v, d) in y[b].iter_mut().zip(&dir) {
                    *v += s * d;
                }
                functional(
                    &coordinates_from_layout(model, &layout, &layout_clip(t, rate, &y)).unwrap(),
                )
            };
            let fd = (at(h) - at(-h)) / (2.0 * h);
            let exact = dot(g, &dir);
            let rel = (fd - exact).abs() / exact.abs().max(1e-300);
            eprintln!("{name} {block}: {exact:.9e} vs differences {fd:.9e} ({rel:.1e})");
            assert!(rel < 1e-6, "{name} {block}: {exact} vs {fd} ({rel:.1e})");
        }
    }
}
