//! Evaluating the coordinate reduction θ = φ(q) with Φ = ∂φ/∂q and Φ̇q̇ (see
//! [`crate::model::Reduction`] for the chain rule implemented here).

use super::Data;
use crate::model::Model;
use crate::model::reduction::NodeKind;

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
