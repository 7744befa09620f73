//! Evaluating the coordinate reduction θ = φ(q) with Φ = ∂φ/∂q and Φ̇q̇ (see
//! [`crate::model::Reduction`] for the chain rule implemented here).

use super::Data;
use crate::model::Model;
use crate::model::reduction::NodeKind;
use nalgebra::DMatrix;

/// Nodes in evaluation order: coordinates (arguments first), then full coordinates.
#[inline]
fn eval_order(model: &Model) -> impl Iterator<Item = usize> + '_ {
    let r = &model.reduction;
    r.order
        .iter()
        .copied()
        .chain(r.n_coordinates..r.nodes.len())
}

/// Values and q-gradients of every node at q.
pub(crate) fn evaluate_position(model: &Model, data: &mut Data, q: &[f64]) {
    let r = &model.reduction;
    let Data {
        node_value,
        node_grad,
        node_g1,
        node_g2,
        arg_scratch,
        ..
    } = data;
    for i in eval_order(model) {
        let g = r.dep_start[i]..r.dep_start[i + 1];
        match &r.nodes[i] {
            NodeKind::Independent(j) => {
                node_value[i] = q[*j];
                node_grad[g.start] = 1.0;
            }
            NodeKind::Constant(v) => node_value[i] = *v,
            NodeKind::Affine {
                arg,
                slope,
                intercept,
            } => {
                node_value[i] = slope * node_value[*arg] + intercept;
                let a0 = r.arg_start[i];
                node_g1[a0] = *slope;
                // ∂n/∂q = slope · ∂c/∂q (node_g2 stays 0); an affine node depends on exactly
                // the q's its argument depends on, in the same order.
                let src = r.dep_start[*arg];
                for (t, e) in g.enumerate() {
                    node_grad[e] = slope * node_grad[src + t];
                }
            }
            NodeKind::Function {
                function,
                args,
                scale,
            } => {
                let k = args.len();
                let a0 = r.arg_start[i];
                let h0 = r.hess_start[i];
                let g1 = &mut node_g1[a0..a0 + k];
                let g2 = &mut node_g2[h0..h0 + k * k];
                let v = if k == 1 {
                    // g(c) = s·f(c): g' = s f', g'' = s f''.
                    let (f, d1, d2) = function.eval1(node_value[args[0]]);
                    g1[0] = scale * d1;
                    g2[0] = scale * d2;
                    scale * f
                } else {
                    let x = &mut arg_scratch[..k];
                    for (xa, &a) in x.iter_mut().zip(args) {
                        *xa = node_value[a];
                    }
                    let f = function.eval(x, g1, g2);
                    g1.iter_mut().for_each(|v| *v *= scale);
                    g2.iter_mut().for_each(|v| *v *= scale);
                    scale * f
                };
                node_value[i] = v;
                // ∂n/∂q = Σ_a g_a ∂c_a/∂q
                for e in g {
                    node_grad[e] = 0.0;
                }
                for s in &r.scatter[r.scatter_start[i]..r.scatter_start[i + 1]] {
                    node_grad[s.dst] += node_g1[a0 + s.arg] * node_grad[s.src];
                }
            }
        }
    }
}

/// Rates ṅ = (∂n/∂q) q̇ and the q̈-free accelerations (Φ̇q̇)_n of every node; needs
/// [`evaluate_position`] at the same q.
pub(crate) fn evaluate_velocity(model: &Model, data: &mut Data, qd: &[f64]) {
    let r = &model.reduction;
    let Data {
        node_vel,
        node_acc_bias,
        node_grad,
        node_g1,
        node_g2,
        ..
    } = data;
    for i in eval_order(model) {
        let mut v = 0.0;
        for e in r.dep_start[i]..r.dep_start[i + 1] {
            v += node_grad[e] * qd[r.dep_index[e]];
        }
        node_vel[i] = v;
        node_acc_bias[i] = match &r.nodes[i] {
            NodeKind::Affine { arg, slope, .. } => slope * node_acc_bias[*arg],
            NodeKind::Function { args, .. } => {
                // (Φ̇q̇)_n = Σ_a g_a (Φ̇q̇)_a + Σ_ab g_ab ċ_a ċ_b
                let k = args.len();
                let a0 = r.arg_start[i];
                let h0 = r.hess_start[i];
                let mut acc = 0.0;
                for (ai, &a) in args.iter().enumerate() {
                    acc += node_g1[a0 + ai] * node_acc_bias[a];
                    for (bi, &b) in args.iter().enumerate() {
                        acc += node_g2[h0 + ai * k + bi] * node_vel[a] * node_vel[b];
                    }
                }
                acc
            }
            _ => 0.0,
        };
    }
}

/// θ̈ = Φ q̈ + Φ̇ q̇ into `data.theta_acc`; `qdd = None` means q̈ = 0.
pub(crate) fn theta_acceleration(model: &Model, data: &mut Data, qdd: Option<&[f64]>) {
    let r = &model.reduction;
    let nc = r.n_coordinates;
    for d in 0..model.dofs.len() {
        let mut a = data.node_acc_bias[nc + d];
        if let Some(qdd) = qdd {
            for e in r.phi_row(d) {
                a += data.node_grad[e] * qdd[r.dep_index[e]];
            }
        }
        data.theta_acc[d] = a;
    }
}

/// Derivatives of θ̇ = Φq̇, θ̈ = Φq̈ + Φ̇q̇ and Φ with respect to q and q̇, by one forward
/// (tangent) pass through the node graph per independent coordinate k. With a node
/// n = g(c) of its arguments c, and t(·) = ∂(·)/∂q_k:
///
/// ```text
/// t(n)    = Σ_a g_a t(c_a)
/// t(ṅ)    = Σ_a g_a t(ċ_a) + Σ_ab g_ab t(c_b) ċ_a
/// t(n̈)    = Σ_a g_a t(c̈_a) + Σ_ab g_ab (t(c_b) c̈_a + t(ċ_a) ċ_b + ċ_a t(ċ_b))
///           + Σ_abc g_abc t(c_c) ċ_a ċ_b
/// t(∂n/∂q) = Σ_a (g_a t(∂c_a/∂q) + Σ_b g_ab t(c_b) ∂c_a/∂q)
/// ```
///
/// and with respect to q̇_k (u(·) = ∂(·)/∂q̇_k): u(ṅ) = ∂n/∂q_k and
/// u(n̈) = Σ_a g_a u(c̈_a) + 2 Σ_ab g_ab u(ċ_a) ċ_b. For a one-argument function the
/// third-order term is g‴ t(c) ċ² with g‴ = s f‴; for several arguments it is
/// s D³f[ċ, ċ, t(c)], the function's third derivative along the argument rates (twice) and
/// tangents, zero unless the function has third derivatives (a multivariate polynomial of
/// order ≥ 3).
#[derive(Clone, Debug)]
pub(crate) struct ReductionTangents {
    /// Φ (n_full × n), ∂θ̇/∂q, ∂θ̈/∂q and ∂θ̈/∂q̇.
    pub phi: DMatrix<f64>,
    pub theta_dot_q: DMatrix<f64>,
    pub theta_ddot_q: DMatrix<f64>,
    pub theta_ddot_qd: DMatrix<f64>,
    /// ∂²θ/∂q∂q_k in the layout of the node-gradient array, for every k (k-major): the
    /// entries of the full-coordinate nodes are the ∂Φ/∂q_k.
    pub grad_q: Vec<f64>,
    node_acc: Vec<f64>,
    /// g‴ = s f‴ of each one-argument function node at the current state.
    node_g3: Vec<f64>,
    t_val: Vec<f64>,
    t_vel: Vec<f64>,
    t_acc: Vec<f64>,
    /// Arguments, rates and tangents of one function of several arguments (3 × max_args).
    scratch: Vec<f64>,
    /// The nodes that depend on q_k, in evaluation order:
    /// `k_nodes[k_nodes_start[k]..k_nodes_start[k + 1]]`; all other tangents of direction k
    /// are zero. Likewise the full coordinates that depend on q_k.
    k_nodes_start: Vec<usize>,
    k_nodes: Vec<usize>,
    k_full_start: Vec<usize>,
    k_full: Vec<usize>,
}

impl ReductionTangents {
    pub fn new(model: &Model) -> ReductionTangents {
        let r = &model.reduction;
        let (nf, n, nodes) = (model.n_full(), model.nq(), r.nodes.len());
        let depends =
            |i: usize, k: usize| r.dep_index[r.dep_start[i]..r.dep_start[i + 1]].contains(&k);
        let (mut k_nodes_start, mut k_nodes) = (vec![0], Vec::new());
        let (mut k_full_start, mut k_full) = (vec![0], Vec::new());
        for k in 0..n {
            k_nodes.extend(eval_order(model).filter(|&i| depends(i, k)));
            k_nodes_start.push(k_nodes.len());
            k_full.extend((0..nf).filter(|&d| depends(r.n_coordinates + d, k)));
            k_full_start.push(k_full.len());
        }
        ReductionTangents {
            phi: DMatrix::zeros(nf, n),
            theta_dot_q: DMatrix::zeros(nf, n),
            theta_ddot_q: DMatrix::zeros(nf, n),
            theta_ddot_qd: DMatrix::zeros(nf, n),
            grad_q: vec![0.0; n * r.dep_index.len()],
            node_acc: vec![0.0; nodes],
            node_g3: vec![0.0; nodes],
            t_val: vec![0.0; nodes],
            t_vel: vec![0.0; nodes],
            t_acc: vec![0.0; nodes],
            scratch: vec![0.0; 3 * r.max_args],
            k_nodes_start,
            k_nodes,
            k_full_start,
            k_full,
        }
    }

    /// The full coordinates that depend on q_k (the rows where column k of Φ, ∂θ̇/∂q, ∂θ̈/∂q
    /// and ∂θ̈/∂q̇ can be non-zero).
    pub fn full_of(&self, k: usize) -> &[usize] {
        &self.k_full[self.k_full_start[k]..self.k_full_start[k + 1]]
    }

    /// Σ_d w_d ∂²θ_d/∂q_j∂q_k into `out[(j, k)]` (added), from the last [`Self::compute`].
    pub fn add_weighted_hessian(&self, model: &Model, w: &[f64], out: &mut DMatrix<f64>) {
        let r = &model.reduction;
        let ne = r.dep_index.len();
        for k in 0..model.nq() {
            let g = &self.grad_q[k * ne..(k + 1) * ne];
            for (d, &wd) in w.iter().enumerate() {
                if wd == 0.0 {
                    continue;
                }
                for e in r.phi_row(d) {
                    out[(r.dep_index[e], k)] += wd * g[e];
                }
            }
        }
    }

    /// The tangents at the state of the last [`evaluate_position`] and [`evaluate_velocity`]
    /// in `data`, with accelerations q̈.
    ///
    /// Steps: n̈ of every node; Φ; g‴ of the one-argument functions; then per direction k the
    /// forward-mode tangents along q_k (giving ∂θ̇/∂q, ∂θ̈/∂q and ∂Φ/∂q_k) and along q̇_k
    /// (giving ∂θ̈/∂q̇), over only the nodes that depend on q_k.
    pub fn compute(&mut self, model: &Model, data: &Data, qdd: &[f64]) {
        let r = &model.reduction;
        let nc = r.n_coordinates;
        let ne = r.dep_index.len();
        node_accelerations(model, data, qdd, &mut self.node_acc);
        // Φ's sparsity is fixed: only its non-zero pattern is written.
        for d in 0..model.n_full() {
            for e in r.phi_row(d) {
                self.phi[(d, r.dep_index[e])] = data.node_grad[e];
            }
        }
        third_derivatives(model, data, &mut self.node_g3);
        let ReductionTangents {
            theta_dot_q,
            theta_ddot_q,
            theta_ddot_qd,
            grad_q,
            node_acc,
            node_g3,
            t_val,
            t_vel,
            t_acc,
            scratch,
            k_nodes_start,
            k_nodes,
            k_full_start,
            k_full,
            ..
        } = self;
        let nd = NodeDerivatives {
            val: &data.node_value,
            vel: &data.node_vel,
            acc: node_acc,
            grad: &data.node_grad,
            g1: &data.node_g1,
            g2: &data.node_g2,
            g3: node_g3,
        };
        let mut t = Tangent {
            val: t_val,
            vel: t_vel,
            acc: t_acc,
            scratch,
        };
        for k in 0..model.nq() {
            let t_grad = &mut grad_q[k * ne..(k + 1) * ne];
            let nodes_k = &k_nodes[k_nodes_start[k]..k_nodes_start[k + 1]];
            let full_k = &k_full[k_full_start[k]..k_full_start[k + 1]];
            // --- direction q_k (tangents of nodes that do not depend on q_k stay 0) ---
            tangents_along_q(model, &nd, k, nodes_k, &mut t, t_grad);
            for &d in full_k {
                theta_dot_q[(d, k)] = t.vel[nc + d];
                theta_ddot_q[(d, k)] = t.acc[nc + d];
            }
            for &i in nodes_k {
                t.val[i] = 0.0;
            }
            // --- direction q̇_k ---
            tangents_along_qd(model, &nd, k, nodes_k, &mut t);
            for &d in full_k {
                theta_ddot_qd[(d, k)] = t.acc[nc + d];
            }
            for &i in nodes_k {
                t.vel[i] = 0.0;
                t.acc[i] = 0.0;
            }
        }
    }
}

/// n̈ of every node: (∂n/∂q) q̈ + (Φ̇q̇)_n.
#[inline]
fn node_accelerations(model: &Model, data: &Data, qdd: &[f64], node_acc: &mut [f64]) {
    let r = &model.reduction;
    for i in 0..r.nodes.len() {
        let mut a = data.node_acc_bias[i];
        for e in r.dep_start[i]..r.dep_start[i + 1] {
            a += data.node_grad[e] * qdd[r.dep_index[e]];
        }
        node_acc[i] = a;
    }
}

/// g‴ = s f‴ of each one-argument function node at the current state.
#[inline]
fn third_derivatives(model: &Model, data: &Data, node_g3: &mut [f64]) {
    for (i, node) in model.reduction.nodes.iter().enumerate() {
        if let NodeKind::Function {
            function,
            args,
            scale,
        } = node
            && args.len() == 1
        {
            node_g3[i] = scale * function.third_derivative1(data.node_value[args[0]]);
        }
    }
}

/// Every node's ṅ, n̈, ∂n/∂q and its function's derivatives g_a, g_ab, g‴ at the current state.
struct NodeDerivatives<'a> {
    val: &'a [f64],
    vel: &'a [f64],
    acc: &'a [f64],
    grad: &'a [f64],
    g1: &'a [f64],
    g2: &'a [f64],
    g3: &'a [f64],
}

/// Tangents t(n), t(ṅ), t(n̈) of every node along one direction (zero off the direction's
/// nodes between directions).
struct Tangent<'a> {
    val: &'a mut [f64],
    vel: &'a mut [f64],
    acc: &'a mut [f64],
    /// Scratch for the third-order term of a function of several arguments.
    scratch: &'a mut [f64],
}

/// Direction q_k: t(n), t(ṅ), t(n̈) and t(∂n/∂q) (into `t_grad`) of the nodes that depend on
/// q_k, in evaluation order.
#[inline]
fn tangents_along_q(
    model: &Model,
    nd: &NodeDerivatives,
    k: usize,
    nodes_k: &[usize],
    t: &mut Tangent,
    t_grad: &mut [f64],
) {
    let r = &model.reduction;
    for &i in nodes_k {
        let g = r.dep_start[i]..r.dep_start[i + 1];
        match &r.nodes[i] {
            NodeKind::Independent(j) => {
                t.val[i] = if *j == k { 1.0 } else { 0.0 };
                t.vel[i] = 0.0;
                t.acc[i] = 0.0;
                t_grad[g].fill(0.0);
            }
            NodeKind::Constant(_) => {
                t.val[i] = 0.0;
                t.vel[i] = 0.0;
                t.acc[i] = 0.0;
            }
            NodeKind::Affine { arg, slope, .. } => {
                t.val[i] = slope * t.val[*arg];
                t.vel[i] = slope * t.vel[*arg];
                t.acc[i] = slope * t.acc[*arg];
                let src = r.dep_start[*arg];
                for (s, e) in g.enumerate() {
                    t_grad[e] = slope * t_grad[src + s];
                }
            }
            NodeKind::Function { args, .. } => {
                function_tangent_along_q(model, nd, i, args, t, t_grad);
            }
        }
    }
}

/// Direction q_k at function node i (type-level formulas above [`ReductionTangents`]):
/// t(n) = Σ_a g_a t(c_a), t(ṅ) = Σ_a g_a t(ċ_a) + Σ_ab g_ab t(c_b) ċ_a,
/// t(n̈) = Σ_a g_a t(c̈_a) + Σ_ab g_ab (t(c_b) c̈_a + t(ċ_a) ċ_b + ċ_a t(ċ_b)) + g‴ t(c) ċ²
/// (one argument) or + s D³f[ċ, ċ, t(c)] (several),
/// t(∂n/∂q) = Σ_a (g_a t(∂c_a/∂q) + Σ_b g_ab t(c_b) ∂c_a/∂q) through the scatter plan.
#[inline]
fn function_tangent_along_q(
    model: &Model,
    nd: &NodeDerivatives,
    i: usize,
    args: &[usize],
    t: &mut Tangent,
    t_grad: &mut [f64],
) {
    let r = &model.reduction;
    let (node_vel, node_acc) = (nd.vel, nd.acc);
    let nargs = args.len();
    let g1 = &nd.g1[r.arg_start[i]..r.arg_start[i] + nargs];
    let g2 = &nd.g2[r.hess_start[i]..r.hess_start[i] + nargs * nargs];
    let (mut tv, mut tvel, mut tacc) = (0.0, 0.0, 0.0);
    for (ai, &a) in args.iter().enumerate() {
        tv += g1[ai] * t.val[a];
        tvel += g1[ai] * t.vel[a];
        tacc += g1[ai] * t.acc[a];
        for (bi, &b) in args.iter().enumerate() {
            let gab = g2[ai * nargs + bi];
            tvel += gab * t.val[b] * node_vel[a];
            tacc +=
                gab * (t.val[b] * node_acc[a] + t.vel[a] * node_vel[b] + node_vel[a] * t.vel[b]);
        }
    }
    if nargs == 1 {
        let c = args[0];
        tacc += nd.g3[i] * t.val[c] * node_vel[c] * node_vel[c];
    } else if let NodeKind::Function {
        function, scale, ..
    } = &r.nodes[i]
        && !function.third_order_vanishes()
    {
        let (x, rest) = t.scratch.split_at_mut(nargs);
        let (rate, rest) = rest.split_at_mut(nargs);
        let tangent = &mut rest[..nargs];
        for (ai, &a) in args.iter().enumerate() {
            x[ai] = nd.val[a];
            rate[ai] = node_vel[a];
            tangent[ai] = t.val[a];
        }
        tacc += scale * function.third_directional(x, rate, rate, tangent);
    }
    t.val[i] = tv;
    t.vel[i] = tvel;
    t.acc[i] = tacc;
    for e in r.dep_start[i]..r.dep_start[i + 1] {
        t_grad[e] = 0.0;
    }
    for s in &r.scatter[r.scatter_start[i]..r.scatter_start[i + 1]] {
        let mut w = 0.0;
        for (bi, &b) in args.iter().enumerate() {
            w += g2[s.arg * nargs + bi] * t.val[b];
        }
        t_grad[s.dst] += g1[s.arg] * t_grad[s.src] + w * nd.grad[s.src];
    }
}

/// Direction q̇_k: u(ṅ) = ∂n/∂q_k and u(n̈) = Σ_a g_a u(c̈_a) + 2 Σ_ab g_ab u(ċ_a) ċ_b of the
/// nodes that depend on q_k, in evaluation order.
#[inline]
fn tangents_along_qd(
    model: &Model,
    nd: &NodeDerivatives,
    k: usize,
    nodes_k: &[usize],
    t: &mut Tangent,
) {
    let r = &model.reduction;
    for &i in nodes_k {
        match &r.nodes[i] {
            NodeKind::Independent(j) => {
                t.vel[i] = if *j == k { 1.0 } else { 0.0 };
                t.acc[i] = 0.0;
            }
            NodeKind::Constant(_) => {
                t.vel[i] = 0.0;
                t.acc[i] = 0.0;
            }
            NodeKind::Affine { arg, slope, .. } => {
                t.vel[i] = slope * t.vel[*arg];
                t.acc[i] = slope * t.acc[*arg];
            }
            NodeKind::Function { args, .. } => {
                let nargs = args.len();
                let g1 = &nd.g1[r.arg_start[i]..r.arg_start[i] + nargs];
                let g2 = &nd.g2[r.hess_start[i]..r.hess_start[i] + nargs * nargs];
                let (mut tvel, mut tacc) = (0.0, 0.0);
                for (ai, &a) in args.iter().enumerate() {
                    tvel += g1[ai] * t.vel[a];
                    tacc += g1[ai] * t.acc[a];
                    for (bi, &b) in args.iter().enumerate() {
                        tacc += 2.0 * g2[ai * nargs + bi] * t.vel[a] * nd.vel[b];
                    }
                }
                t.vel[i] = tvel;
                t.acc[i] = tacc;
            }
        }
    }
}
