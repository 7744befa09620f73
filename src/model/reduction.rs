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
}

impl Reduction {
    /// Builds the plan. Errors name a coupler (index) whose dependencies form a cycle.
    pub(crate) fn build(model: &Model) -> Result<Reduction, (usize, String)> {
        let nc = model.coordinates.len();
        let mut independent = Vec::new();
        let mut nodes = Vec::with_capacity(nc + model.dofs.len());
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

        // Topological order of coordinate nodes (Kahn), to evaluate couplers of couplers.
        let mut order = Vec::with_capacity(nc);
        let mut state = vec![0u8; nc]; // 0 new, 1 visiting, 2 done
        fn visit(
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
            if let NodeKind::Function { args, .. } = &nodes[i] {
                for &a in args {
                    visit(a, nodes, state, order, stack)?;
                }
            }
            stack.pop();
            state[i] = 2;
            order.push(i);
            Ok(())
        }
        for i in 0..nc {
            let mut stack = Vec::new();
            if let Err(cycle) = visit(i, &nodes, &mut state, &mut order, &mut stack) {
                let names: Vec<&str> = cycle.iter().map(|&c| model.coordinates[c].name.as_str()).collect();
                let coupler = match roles[cycle[0]] {
                    CoordinateRole::Dependent(k) => k,
                    _ => 0,
                };
                return Err((coupler, format!("coupler constraints form a cycle: {}", names.join(" → "))));
            }
        }

        // Dependency sets on q, in evaluation order.
        let n_nodes = nodes.len();
        let mut deps: Vec<Vec<usize>> = vec![Vec::new(); n_nodes];
        let eval_order: Vec<usize> = order.iter().copied().chain(nc..n_nodes).collect();
        for &i in &eval_order {
            deps[i] = match &nodes[i] {
                NodeKind::Independent(j) => vec![*j],
                NodeKind::Constant(_) => vec![],
                NodeKind::Function { args, function, .. } => {
                    if function.is_constant() {
                        vec![]
                    } else {
                        let mut d: Vec<usize> = args.iter().flat_map(|&a| deps[a].iter().copied()).collect();
                        d.sort_unstable();
                        d.dedup();
                        d
                    }
                }
            };
        }
        let mut dep_start = Vec::with_capacity(n_nodes + 1);
        let mut dep_index = Vec::new();
        for d in &deps {
            dep_start.push(dep_index.len());
            dep_index.extend_from_slice(d);
        }
        dep_start.push(dep_index.len());

        let mut arg_start = Vec::with_capacity(n_nodes + 1);
        let mut hess_start = Vec::with_capacity(n_nodes + 1);
        let (mut na, mut nh, mut max_args) = (0, 0, 0);
        for n in &nodes {
            arg_start.push(na);
            hess_start.push(nh);
            if let NodeKind::Function { args, .. } = n {
                na += args.len();
                nh += args.len() * args.len();
                max_args = max_args.max(args.len());
            }
        }
        arg_start.push(na);
        hess_start.push(nh);

        let mut scatter_start = Vec::with_capacity(n_nodes + 1);
        let mut scatter = Vec::new();
        for i in 0..n_nodes {
            scatter_start.push(scatter.len());
            if let NodeKind::Function { args, .. } = &nodes[i] {
                for (ai, &a) in args.iter().enumerate() {
                    for src in dep_start[a]..dep_start[a + 1] {
                        let j = dep_index[src];
                        if let Some(p) = deps[i].iter().position(|&x| x == j) {
                            scatter.push(Scatter { arg: ai, src, dst: dep_start[i] + p });
                        }
                    }
                }
            }
        }
        scatter_start.push(scatter.len());

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
