//! Reduction to independent coordinates: the plan for evaluating every coordinate and every
//! full coordinate (movable axis) as a function of the independent coordinates q,
//! θ = φ(q), together with Φ = ∂φ/∂q and Φ̇q̇.
//!
//! Coordinates and full coordinates are *nodes* of one expression graph:
//! - an independent coordinate is q_j;
//! - a locked coordinate is its default value;
//! - a coupler's dependent coordinate is s·f(c_a, c_b, …) of other coordinates;
//! - a full coordinate is f(c_a, …) of its joint's coordinates.
//!
//! Node derivatives follow the chain rule. With g the node's function of its arguments
//! (already scaled) and c its arguments,
//!   ∂n/∂q = Σ_a g_a ∂c_a/∂q,
//!   ṅ = Σ_a g_a ċ_a,
//!   n̈ = (∂n/∂q) q̈ + Σ_a g_a (Ċq̇)_a + Σ_ab g_ab ċ_a ċ_b,   the last two terms being (Φ̇q̇)_n.
//! The sparsity of ∂n/∂q (which q's each node depends on) is fixed when the model is built.

use super::{CoordinateRole, Function, Model};

/// How one node is evaluated.
#[derive(Clone, Debug)]
pub(crate) enum NodeKind {
    /// q_j.
    Independent(usize),
    /// A constant (locked coordinate).
    Constant(f64),
    /// slope · (value of node `arg`) + intercept: a one-argument LinearFunction (the common
    /// case of an axis driven directly by its coordinate), evaluated without dispatch.
    Affine {
        arg: usize,
        slope: f64,
        intercept: f64,
    },
    /// scale · f(node values of `args`).
    Function {
        function: Function,
        args: Vec<usize>,
        scale: f64,
    },
}

/// One chain-rule term: grad[dst] += g_arg · grad[src] (flat indices into the node-gradient
/// array).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Scatter {
    /// Index of the argument within the node (into the node's g_a slots).
    pub arg: usize,
    pub src: usize,
    pub dst: usize,
}

/// The evaluation plan for θ = φ(q). Built once with the model.
#[derive(Clone, Debug, Default)]
pub struct Reduction {
    /// For each independent coordinate q_j, its index in `Model::coordinates`.
    pub independent: Vec<usize>,
    /// Number of coordinate nodes; full-coordinate node i is node `n_coordinates + i`.
    pub n_coordinates: usize,
    pub(crate) nodes: Vec<NodeKind>,
    /// Order in which coordinate nodes are evaluated (arguments before the nodes using them);
    /// full-coordinate nodes follow in index order.
    pub(crate) order: Vec<usize>,
    /// Dependencies of node i on q: `dep_index[dep_start[i]..dep_start[i + 1]]` (sorted).
    pub dep_start: Vec<usize>,
    pub dep_index: Vec<usize>,
    /// Offsets of each node's first-derivative slots (one per argument).
    pub(crate) arg_start: Vec<usize>,
    /// Offsets of each node's second-derivative slots (arguments², row-major).
    pub(crate) hess_start: Vec<usize>,
    /// Chain-rule terms of node i: `scatter[scatter_start[i]..scatter_start[i + 1]]`.
    pub(crate) scatter_start: Vec<usize>,
    pub(crate) scatter: Vec<Scatter>,
    /// Largest number of arguments of any node.
    pub(crate) max_args: usize,
    /// The reduced motion subspace: one column per (joint, independent coordinate the
    /// joint's axes depend on), S̃_c = Σ_{d ∈ joint} Φ_dj s_d. Columns are in tree order.
    pub(crate) columns: Columns,
}

/// Columns of the reduced motion subspace, in tree order (joint by joint).
///
/// Because the full coordinates of one joint move the same child body, the joint's block of
/// M_full is S_Jᵀ I^c S_J, and Φᵀ M_full Φ can be accumulated over these columns instead of
/// over full coordinates: M_jk += S̃_eᵀ I^c S̃_c for each column c and each column e on the
/// path from c to ground. A knee whose rotation and two spline-driven translations all depend
/// on the knee angle contributes one column instead of three.
#[derive(Clone, Debug, Default)]
pub(crate) struct Columns {
    /// Independent coordinate of column c.
    pub q: Vec<usize>,
    /// Body moved by column c (its joint's child).
    pub body: Vec<usize>,
    /// The preceding column towards ground, or `NONE`.
    pub parent: Vec<usize>,
    /// Terms of column c: `terms[start[c]..start[c + 1]]` = (full coordinate d, index of
    /// Φ_dj in the node-gradient array).
    pub start: Vec<usize>,
    pub terms: Vec<(usize, usize)>,
    /// The last column on the path from ground to each body, or `NONE`.
    pub body_last: Vec<usize>,
}

/// Marks an absent index in `Columns`.
pub(crate) const NONE: usize = usize::MAX;

impl Columns {
    fn build(model: &Model, dep_start: &[usize], dep_index: &[usize], nc: usize) -> Columns {
        let mut c = Columns {
            body_last: vec![NONE; model.bodies.len()],
            ..Default::default()
        };
        for joint in &model.joints {
            let mut last = c.body_last[joint.parent_body];
            let mut qs: Vec<usize> = joint
                .dof_range
                .clone()
                .flat_map(|d| {
                    dep_index[dep_start[nc + d]..dep_start[nc + d + 1]]
                        .iter()
                        .copied()
                })
                .collect();
            qs.sort_unstable();
            qs.dedup();
            for j in qs {
                c.q.push(j);
                c.body.push(joint.child_body);
                c.parent.push(last);
                c.start.push(c.terms.len());
                for d in joint.dof_range.clone() {
                    for e in dep_start[nc + d]..dep_start[nc + d + 1] {
                        if dep_index[e] == j {
                            c.terms.push((d, e));
                        }
                    }
                }
                last = c.q.len() - 1;
            }
            c.body_last[joint.child_body] = last;
        }
        c.start.push(c.terms.len());
        c
    }

    pub fn len(&self) -> usize {
        self.q.len()
    }
}

impl Reduction {
    /// Builds the plan. Errors name a coupler (index) whose dependencies form a cycle.
    ///
    /// Steps: the graph's nodes (coordinates, then full coordinates); the evaluation order of
    /// the coordinate nodes; each node's dependency set on q (Φ's sparsity); the offsets of
    /// each node's argument gradients and Hessians; the chain-rule scatter plan; the
    /// motion-subspace columns.
    pub(crate) fn build(model: &Model) -> Result<Reduction, (usize, String)> {
        let nc = model.coordinates.len();
        let (nodes, roles, independent) = graph_nodes(model);
        let order = coordinate_evaluation_order(model, &nodes, &roles)?;

        let deps = dependency_sets(&nodes, &order, nc);
        let mut dep_start = Vec::with_capacity(nodes.len() + 1);
        let mut dep_index = Vec::new();
        for d in &deps {
            dep_start.push(dep_index.len());
            dep_index.extend_from_slice(d);
        }
        dep_start.push(dep_index.len());

        let (arg_start, hess_start, max_args) = argument_offsets(&nodes);
        let (scatter_start, scatter) = scatter_plan(&nodes, &deps, &dep_start, &dep_index);
        let columns = Columns::build(model, &dep_start, &dep_index, nc);
        Ok(Reduction {
            independent,
            n_coordinates: nc,
            nodes,
            order,
            dep_start,
            dep_index,
            arg_start,
            hess_start,
            scatter_start,
            columns,
            scatter,
            max_args,
        })
    }

    /// The independent coordinates full coordinate `dof` depends on, with the positions of
    /// its Φ entries (indices into `Data`'s node gradient array).
    pub fn phi_row(&self, dof: usize) -> std::ops::Range<usize> {
        let n = self.n_coordinates + dof;
        self.dep_start[n]..self.dep_start[n + 1]
    }
}

/// The graph's nodes: one per coordinate (constant, independent, or its coupler's function)
/// then one per full coordinate (its function); single-argument linear functions become
/// affine nodes. Also returns each coordinate's role and the independent coordinates in q
/// order.
fn graph_nodes(model: &Model) -> (Vec<NodeKind>, Vec<CoordinateRole>, Vec<usize>) {
    let mut independent = Vec::new();
    let mut nodes = Vec::with_capacity(model.coordinates.len() + model.dofs.len());
    for c in &model.coordinates {
        nodes.push(NodeKind::Constant(c.default_value));
    }
    // Roles: dependents were marked while reading couplers; the rest are locked or
    // independent.
    let mut roles: Vec<CoordinateRole> = model.coordinates.iter().map(|c| c.role).collect();
    for (i, c) in model.coordinates.iter().enumerate() {
        if let CoordinateRole::Dependent(k) = roles[i] {
            let cp = &model.couplers[k];
            nodes[i] = NodeKind::Function {
                function: cp.function.clone(),
                args: cp.independents.clone(),
                scale: cp.scale,
            };
        } else if c.locked {
            roles[i] = CoordinateRole::Locked;
        } else {
            roles[i] = CoordinateRole::Independent(independent.len());
            nodes[i] = NodeKind::Independent(independent.len());
            independent.push(i);
        }
    }
    for d in &model.dofs {
        nodes.push(NodeKind::Function {
            function: d.function.clone(),
            args: d.args.clone(),
            scale: 1.0,
        });
    }
    for n in nodes.iter_mut() {
        if let NodeKind::Function {
            function: Function::Linear(c),
            args,
            scale,
        } = n
        {
            if args.len() == 1 && c.len() == 2 {
                // scale·(c₀ x + c₁) = slope x + intercept
                *n = NodeKind::Affine {
                    arg: args[0],
                    slope: *scale * c[0],
                    intercept: *scale * c[1],
                };
            }
        }
    }
    (nodes, roles, independent)
}

/// Topological order of the coordinate nodes (depth-first), to evaluate couplers of
/// couplers; a cycle is an error naming its coupler.
fn coordinate_evaluation_order(
    model: &Model,
    nodes: &[NodeKind],
    roles: &[CoordinateRole],
) -> Result<Vec<usize>, (usize, String)> {
    let nc = model.coordinates.len();
    let mut order = Vec::with_capacity(nc);
    let mut state = vec![0u8; nc]; // 0 new, 1 visiting, 2 done
    for i in 0..nc {
        let mut stack = Vec::new();
        if let Err(cycle) = visit_node(i, nodes, &mut state, &mut order, &mut stack) {
            let names: Vec<&str> = cycle
                .iter()
                .map(|&c| model.coordinates[c].name.as_str())
                .collect();
            let coupler = match roles[cycle[0]] {
                CoordinateRole::Dependent(k) => k,
                _ => 0,
            };
            return Err((
                coupler,
                format!("coupler constraints form a cycle: {}", names.join(" → ")),
            ));
        }
    }
    Ok(order)
}

/// Depth-first visit of node `i` for the evaluation order: its arguments first. Err(the
/// cycle) when `i` is on the current `stack`.
fn visit_node(
    i: usize,
    nodes: &[NodeKind],
    state: &mut [u8],
    order: &mut Vec<usize>,
    stack: &mut Vec<usize>,
) -> Result<(), Vec<usize>> {
    match state[i] {
        2 => return Ok(()),
        1 => {
            let pos = stack.iter().position(|&s| s == i).unwrap_or(0);
            return Err(stack[pos..].to_vec());
        }
        _ => {}
    }
    state[i] = 1;
    stack.push(i);
    for a in node_args(&nodes[i]) {
        visit_node(a, nodes, state, order, stack)?;
    }
    stack.pop();
    state[i] = 2;
    order.push(i);
    Ok(())
}

/// Per node, the sorted independent coordinates (indices into q) it depends on, computed in
/// evaluation order (coordinates in `order`, then the full coordinates); a constant function
/// or a zero slope depends on none.
fn dependency_sets(nodes: &[NodeKind], order: &[usize], nc: usize) -> Vec<Vec<usize>> {
    let n_nodes = nodes.len();
    let mut deps: Vec<Vec<usize>> = vec![Vec::new(); n_nodes];
    let eval_order: Vec<usize> = order.iter().copied().chain(nc..n_nodes).collect();
    for &i in &eval_order {
        deps[i] = match &nodes[i] {
            NodeKind::Independent(j) => vec![*j],
            NodeKind::Constant(_) => vec![],
            NodeKind::Affine { arg, slope, .. } => {
                if *slope == 0.0 {
                    vec![]
                } else {
                    deps[*arg].clone()
                }
            }
            NodeKind::Function { args, function, .. } => {
                if function.is_constant() {
                    vec![]
                } else {
                    let mut d: Vec<usize> =
                        args.iter().flat_map(|&a| deps[a].iter().copied()).collect();
                    d.sort_unstable();
                    d.dedup();
                    d
                }
            }
        };
    }
    deps
}

/// (arg_start, hess_start, max_args): per node, the offsets of its k argument gradients and
/// its k² Hessian entries in flat arrays, and the largest k.
fn argument_offsets(nodes: &[NodeKind]) -> (Vec<usize>, Vec<usize>, usize) {
    let mut arg_start = Vec::with_capacity(nodes.len() + 1);
    let mut hess_start = Vec::with_capacity(nodes.len() + 1);
    let (mut na, mut nh, mut max_args) = (0, 0, 0);
    for n in nodes {
        arg_start.push(na);
        hess_start.push(nh);
        let k = node_args(n).len();
        na += k;
        nh += k * k;
        max_args = max_args.max(k);
    }
    arg_start.push(na);
    hess_start.push(nh);
    (arg_start, hess_start, max_args)
}

/// The chain rule ∂node_i/∂q_j = Σ_a ∂f_i/∂arg_a · ∂arg_a/∂q_j as a list of (argument, source
/// entry, destination entry) per node: (scatter_start, scatter).
fn scatter_plan(
    nodes: &[NodeKind],
    deps: &[Vec<usize>],
    dep_start: &[usize],
    dep_index: &[usize],
) -> (Vec<usize>, Vec<Scatter>) {
    let n_nodes = nodes.len();
    let mut scatter_start = Vec::with_capacity(n_nodes + 1);
    let mut scatter = Vec::new();
    for i in 0..n_nodes {
        scatter_start.push(scatter.len());
        for (ai, a) in node_args(&nodes[i]).into_iter().enumerate() {
            for src in dep_start[a]..dep_start[a + 1] {
                let j = dep_index[src];
                if let Some(p) = deps[i].iter().position(|&x| x == j) {
                    scatter.push(Scatter {
                        arg: ai,
                        src,
                        dst: dep_start[i] + p,
                    });
                }
            }
        }
    }
    scatter_start.push(scatter.len());
    (scatter_start, scatter)
}
/// The arguments of a node.
fn node_args(n: &NodeKind) -> Vec<usize> {
    match n {
        NodeKind::Affine { arg, .. } => vec![*arg],
        NodeKind::Function { args, .. } => args.clone(),
        _ => vec![],
    }
}
