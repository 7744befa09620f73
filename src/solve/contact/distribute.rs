//! Per-frame distribution of the floating-base rows over the contact points: a small QP.
//!
//! Unknowns: per point p, coordinates x_p,e along directions d_e in ground — without friction
//! d = (n, t₁, t₂) with x_n ≥ 0 and the tangential ones free; with friction μ the edges of the
//! inscribed pyramid d = (n ± μ t₁, n ± μ t₂) with every x ≥ 0 — so f_p = Σ_e x_p,e d_e; and
//! one slack s_r per floating-base row. With J_p the 3 × n Jacobian of the point's contact
//! location (sphere centre − r n) and B the floating-base rows:
//!
//!   minimise   Σ_p (1/φ_p) Σ_e c_e x_p,e²  +  Σ_r w_r s_r²
//!   subject to Σ_p Σ_e (J_p,Bᵀ d_e) x_p,e + s = τ_B,
//!
//! φ_p the contact factor, c_e = 1 for the normal and the pyramid's edges and the
//! `tangential_weight` for free tangential coordinates (a point with φ_p = 0 has its coordinates fixed at 0). The slack makes
//! the problem always feasible; with w_r large (`residual_weight` on translation rows,
//! `residual_moment_weight` on rotation rows) it is the unexplained residual, reported per row.
//! The weights 1/φ_p move load smoothly as the factors ramp (METHOD.md §4). Solved by
//! [`crate::solve::qp`] (p = 2), warm-started from the previous frame.

use super::{ContactOptions, ContactSet};
use crate::dynamics::{Data, Stage, check_len, contact_jacobian};
use crate::error::Error;
use crate::model::Model;
use crate::solve::qp::{QpMatrix, QpProblem, QpStatus, QpWorkspace};
use crate::spatial::Vec3;
use nalgebra::DMatrix;

/// The contact forces of one frame.
#[derive(Clone, Debug)]
pub struct ContactFrame {
    /// Force of the ground on each point, in ground (N), P entries.
    pub forces: Vec<Vec3>,
    /// Where each force acts, in ground: the sphere centre minus its radius along the normal.
    pub points: Vec<Vec3>,
    /// J_cᵀλ: the generalized forces of the contact forces (length nq).
    pub generalized: Vec<f64>,
    /// τ_B − (J_cᵀλ)_B: what the contacts leave unexplained on the floating-base rows (in
    /// `ContactSet::floating_base` order; N for translations, N·m for rotations).
    pub residual: Vec<f64>,
    /// How the QP ended (`Solved` unless something went wrong numerically).
    pub status: QpStatus,
    /// Newton iterations of the QP (0 when no point was in contact).
    pub iterations: usize,
}

impl ContactFrame {
    /// A frame sized for `model` and `set`.
    pub fn new(model: &Model, set: &ContactSet) -> ContactFrame {
        let np = set.points.len();
        ContactFrame {
            forces: vec![Vec3::zeros(); np],
            points: vec![Vec3::zeros(); np],
            generalized: vec![0.0; model.nq()],
            residual: vec![0.0; set.floating_base.len()],
            status: QpStatus::Solved,
            iterations: 0,
        }
    }
}

/// The memory of [`ContactWorkspace::distribute`] for one model and contact set: everything a
/// frame writes, allocated once. One per thread.
#[derive(Clone, Debug)]
pub struct ContactWorkspace {
    nq: usize,
    np: usize,
    nb: usize,
    /// Each point's contact location in its body (changes with the body's orientation).
    local: Vec<(usize, Vec3)>,
    /// J_c (3P × nq).
    jacobian: DMatrix<f64>,
    /// Directions of the force coordinates (4 per point at most).
    directions: Vec<Vec3>,
    /// A (nb × m), b, weights and bounds, sized for the friction pyramid (m = 4P + nb).
    a: DMatrix<f64>,
    b: Vec<f64>,
    weights: Vec<f64>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    /// Solvers without friction (m = 3P + nb) and with the pyramid (m = 4P + nb).
    qp_free: QpWorkspace,
    qp_cone: QpWorkspace,
}

impl ContactWorkspace {
    pub fn new(model: &Model, set: &ContactSet) -> Self {
        let (nq, np, nb) = (model.nq(), set.points.len(), set.floating_base.len());
        let m = 4 * np + nb;
        ContactWorkspace {
            nq,
            np,
            nb,
            local: vec![(0, Vec3::zeros()); np],
            jacobian: DMatrix::zeros(3 * np, nq),
            directions: vec![Vec3::zeros(); 4 * np],
            a: DMatrix::zeros(nb, m),
            b: vec![0.0; nb],
            weights: vec![1.0; m],
            lower: vec![0.0; m],
            upper: vec![0.0; m],
            qp_free: QpWorkspace::new(nb, 3 * np + nb),
            qp_cone: QpWorkspace::new(nb, 4 * np + nb),
        }
    }

    /// Forgets the previous frame's multipliers (e.g. at the start of another clip).
    pub fn clear_warm_start(&mut self) {
        self.qp_free.clear_warm_start();
        self.qp_cone.clear_warm_start();
    }

    /// Distributes the floating-base rows of `tau` (inverse dynamics without contact, length
    /// nq) over the points with factor > 0 (`factor`: this frame's P factors in [0, 1]).
    /// `data` holds the frame's kinematics (position stage at least: after
    /// `forward_kinematics`, `forward_kinematics_velocity` or `rnea`). Writes the forces,
    /// their points, J_cᵀλ and the residual into `out` (from [`ContactFrame::new`]).
    /// Allocates nothing.
    #[allow(clippy::too_many_arguments)]
    pub fn distribute(
        &mut self,
        model: &Model,
        data: &Data,
        set: &ContactSet,
        options: &ContactOptions,
        factor: &[f64],
        tau: &[f64],
        out: &mut ContactFrame,
    ) -> crate::Result<()> {
        self.check_inputs(model, set, options, factor, tau, out)?;
        data.require(model, Stage::Position, "ContactWorkspace::distribute")?;
        self.place_points(data, set, tau, out);
        if factor.iter().all(|&f| f == 0.0) {
            out.residual.copy_from_slice(&self.b);
            return Ok(());
        }
        contact_jacobian(model, data, &self.local, &mut self.jacobian)?;
        let k = self.build_problem(set, options, factor);
        let m = k * self.np + self.nb;
        let problem = QpProblem {
            a: QpMatrix::Dense(self.a.columns(0, m)),
            b: &self.b,
            weights: &self.weights[..m],
            lower: &self.lower[..m],
            upper: &self.upper[..m],
        };
        let qp = if k == 4 {
            &mut self.qp_cone
        } else {
            &mut self.qp_free
        };
        let solution = qp
            .solve(&problem, &options.qp)
            .map_err(|e| Error::invalid("contact QP", e.to_string()))?;
        out.status = solution.status;
        out.iterations = solution.iterations;
        for p in 0..self.np {
            // f_p = Σ_e x_p,e d_e
            out.forces[p] = (0..k)
                .map(|e| self.directions[k * p + e] * solution.x[k * p + e])
                .sum();
        }
        self.write_generalized(set, out);
        Ok(())
    }

    /// Checks that the workspace, `set`, the options and the arrays fit together.
    fn check_inputs(
        &self,
        model: &Model,
        set: &ContactSet,
        options: &ContactOptions,
        factor: &[f64],
        tau: &[f64],
        out: &ContactFrame,
    ) -> crate::Result<()> {
        let (nq, np, nb) = (self.nq, self.np, self.nb);
        if model.nq() != nq || set.points.len() != np || set.floating_base.len() != nb {
            return Err(Error::invalid(
                "set",
                format!(
                    "this workspace was built for nq = {nq}, {np} points, {nb} floating-base \
                     rows; got nq = {}, {} points, {} rows",
                    model.nq(),
                    set.points.len(),
                    set.floating_base.len()
                ),
            ));
        }
        options.validate()?;
        check_len("tau", tau, nq)?;
        check_len("factor", factor, np)?;
        if let Some(i) = factor.iter().position(|f| !(0.0..=1.0).contains(f)) {
            return Err(Error::invalid(
                "factor",
                format!("element {i} is {}, must be in [0, 1]", factor[i]),
            ));
        }
        if out.forces.len() != np
            || out.points.len() != np
            || out.generalized.len() != nq
            || out.residual.len() != nb
        {
            return Err(Error::invalid(
                "out",
                "sized for another model or set (use ContactFrame::new)",
            ));
        }
        Ok(())
    }

    /// The contact locations b = c − r n (in their bodies, and in ground into `out.points`),
    /// b = τ_B, and `out` cleared of the previous frame's forces.
    fn place_points(&mut self, data: &Data, set: &ContactSet, tau: &[f64], out: &mut ContactFrame) {
        let n = set.floor_normal;
        for (p, point) in set.points.iter().enumerate() {
            let (rot, _) = data.body_pose(point.body);
            // contact location b = c − r n, in the body
            let local = point.location_in_body - rot.transpose() * n * point.radius;
            self.local[p] = (point.body, local);
            out.points[p] = data.point_position(point.body, &local);
        }
        for (r, &j) in set.floating_base.iter().enumerate() {
            self.b[r] = tau[j];
        }
        out.forces.iter_mut().for_each(|f| *f = Vec3::zeros());
        out.generalized.iter_mut().for_each(|g| *g = 0.0);
        out.status = QpStatus::Solved;
        out.iterations = 0;
    }

    /// The QP's A, weights and bounds from the Jacobian: k force coordinates per point (3
    /// without friction, 4 pyramid edges with it), then one slack per floating-base row.
    /// Returns k.
    fn build_problem(
        &mut self,
        set: &ContactSet,
        options: &ContactOptions,
        factor: &[f64],
    ) -> usize {
        let (np, nb) = (self.np, self.nb);
        let n = set.floor_normal;
        let (t1, t2) = set.floor_tangents();
        let k = if options.friction.is_some() { 4 } else { 3 };
        for p in 0..np {
            let d = &mut self.directions[k * p..k * (p + 1)];
            match options.friction {
                None => d.copy_from_slice(&[n, t1, t2]),
                Some(mu) => {
                    d.copy_from_slice(&[n + t1 * mu, n - t1 * mu, n + t2 * mu, n - t2 * mu])
                }
            }
            for e in 0..k {
                let c = k * p + e;
                // A_rc = (J_p,B ᵀ d_e)_r
                let dir = self.directions[c];
                for (r, &j) in set.floating_base.iter().enumerate() {
                    self.a[(r, c)] = (0..3).map(|x| self.jacobian[(3 * p + x, j)] * dir[x]).sum();
                }
                let free_tangent = options.friction.is_none() && e > 0;
                if factor[p] > 0.0 {
                    let tangential = if free_tangent {
                        options.tangential_weight
                    } else {
                        1.0
                    };
                    self.weights[c] = tangential / factor[p];
                    self.lower[c] = if free_tangent { f64::NEG_INFINITY } else { 0.0 };
                    self.upper[c] = f64::INFINITY;
                } else {
                    self.weights[c] = 1.0;
                    self.lower[c] = 0.0;
                    self.upper[c] = 0.0;
                }
            }
        }
        for r in 0..nb {
            let c = k * np + r;
            for rr in 0..nb {
                self.a[(rr, c)] = if rr == r { 1.0 } else { 0.0 };
            }
            self.weights[c] = if set.floating_base_rotational[r] {
                options.residual_moment_weight
            } else {
                options.residual_weight
            };
            self.lower[c] = f64::NEG_INFINITY;
            self.upper[c] = f64::INFINITY;
        }
        k
    }

    /// J_cᵀλ of the forces in `out`, and the residual τ_B − (J_cᵀλ)_B.
    fn write_generalized(&self, set: &ContactSet, out: &mut ContactFrame) {
        // J_cᵀ λ
        for j in 0..self.nq {
            let mut g = 0.0;
            for (p, f) in out.forces.iter().enumerate() {
                for x in 0..3 {
                    g += self.jacobian[(3 * p + x, j)] * f[x];
                }
            }
            out.generalized[j] = g;
        }
        for (r, &j) in set.floating_base.iter().enumerate() {
            out.residual[r] = self.b[r] - out.generalized[j];
        }
    }
}
