//! The first frame of a clip (or a static trial) from several starts: multi-start local
//! search, keeping the start whose solution has the lowest objective.
//!
//! A frame after the first starts from its predecessors' solutions (warm start). The first
//! has none, and Levenberg–Marquardt from the default pose reaches the nearest local minimum
//! of f — with an upper arm rolled 90° the wrong way, or a hip turned so that a thigh's
//! markers fit from the wrong side, f has minima far from the global one. The starts:
//!
//! 1. **default pose**: the model's default coordinates, the floating base translated onto
//!    the targets' centroid (as every clip started before);
//! 2. **limbs in turn**: from the same pose, first the floating base alone (a rigid fit of the
//!    whole body, every other coordinate held), then, parents before children, each joint of
//!    two or more rotational coordinates whose subtree carries targets (hips, lumbar spine,
//!    shoulders, wrists): its subtree's coordinates fitted alone, the rest held, from its
//!    current value and from the best points of a grid over the joint's own coordinates
//!    (each at 1/6, 1/2 and 5/6 of its range), keeping the lowest f.
//!
//! Each start is then solved whole, all coordinates free, and the lowest f is kept:
//!
//!   q₀* = argmin over starts s of f(LM(s)),
//!
//! so the chosen first frame is never worse than the default pose's. The starts and their
//! objectives are in [`super::IkSolution::first_frame_starts`].

use super::{Frame, IkTasks, IkWorkspace, objective, solve_frame};
use crate::model::{Model, MotionType};

/// One start of the first frame and the objective its solution reached.
#[derive(Clone, Debug, PartialEq)]
pub struct StartOutcome {
    /// `"default pose"` (or `"previous frames"` where earlier frames were solved),
    /// `"limbs in turn"`.
    pub name: &'static str,
    /// f at the solution from this start.
    pub objective: f64,
    /// Whether this start's solution is the frame's.
    pub chosen: bool,
}

/// Grid points per coordinate of a joint (fractions of its range).
const GRID: [f64; 3] = [1.0 / 6.0, 0.5, 5.0 / 6.0];
/// Grid points (besides the current value) from which a joint's subtree is fitted.
const GRID_STARTS: usize = 2;
/// Iterations of each partial fit (the whole fit afterwards has the first frame's own).
const PARTIAL_ITERATIONS: usize = 60;

/// Solves the first frame from each start, leaves the best solution in `ws.q` (and its body
/// poses in `ws.data`) and returns its f, the iterations of the chosen solve and every
/// start's outcome.
#[allow(clippy::too_many_arguments)] // solve_frame's arguments and the given start's name
pub(super) fn best_of_starts(
    model: &Model,
    ws: &mut IkWorkspace,
    given: &'static str,
    tasks: &IkTasks,
    frame: &Frame,
    max_iterations: usize,
    tolerance: f64,
    relative_decrease: f64,
) -> crate::Result<(f64, u32, Vec<StartOutcome>)> {
    // each start solved whole, every coordinate free (evaluations of f accumulate in ws)
    let whole = |ws: &mut IkWorkspace| {
        solve_frame(
            model,
            ws,
            tasks,
            frame,
            max_iterations,
            tolerance,
            relative_decrease,
        )
    };
    let q0 = ws.q.clone();
    let mu0 = ws.mu;
    let (f_default, it_default) = whole(ws)?;
    let (q_default, mu_default) = (ws.q.clone(), ws.mu);

    ws.q.copy_from_slice(&q0);
    ws.mu = mu0;
    limbs_in_turn(model, ws, tasks, frame, tolerance, relative_decrease)?;
    let (f_limbs, it_limbs) = whole(ws)?;
    // ties keep the default pose (as every first frame was solved before)
    let limbs_better = f_limbs < f_default;
    let outcomes = vec![
        StartOutcome {
            name: given,
            objective: f_default,
            chosen: !limbs_better,
        },
        StartOutcome {
            name: "limbs in turn",
            objective: f_limbs,
            chosen: limbs_better,
        },
    ];
    if limbs_better {
        return Ok((f_limbs, it_limbs, outcomes));
    }
    ws.q.copy_from_slice(&q_default);
    ws.mu = mu_default;
    // the caller reads the solution's marker positions from the body poses
    let f = objective(model, &mut ws.data, tasks, frame, &ws.q, &ws.q_prev)?;
    Ok((f, it_default, outcomes))
}

/// The "limbs in turn" start (see the module's documentation), left in `ws.q`.
fn limbs_in_turn(
    model: &Model,
    ws: &mut IkWorkspace,
    tasks: &IkTasks,
    frame: &Frame,
    tolerance: f64,
    relative_decrease: f64,
) -> crate::Result<()> {
    let n = model.nq();
    // per q index: the joint the coordinate belongs to
    let joint_of: Vec<usize> = (model.reduction.independent.iter())
        .map(|&c| model.coordinates[c].joint)
        .collect();
    // per body: whether a task's target present in this frame is on it or below it
    let mut carries = vec![false; model.bodies.len()];
    for t in tasks.markers.iter().filter(|t| t.weight > 0.0) {
        if !frame.targets[t.target].x.is_nan() {
            carries[model.markers[t.marker].body] = true;
        }
    }
    for joint in model.joints.iter().rev() {
        if carries[joint.child_body] {
            carries[joint.parent_body] = true;
        }
    }
    // per joint: whether it lies in the subtree of joint k (parents precede children)
    let below = |k: usize| -> Vec<bool> {
        let mut inside = vec![false; model.bodies.len()];
        inside[model.joints[k].child_body] = true;
        let mut joints = vec![false; model.joints.len()];
        joints[k] = true;
        for (i, joint) in model.joints.iter().enumerate().skip(k + 1) {
            if inside[joint.parent_body] {
                inside[joint.child_body] = true;
                joints[i] = true;
            }
        }
        joints
    };

    // the floating base alone: every coordinate of a joint to ground
    let base: Vec<bool> = (0..n)
        .map(|j| model.joints[joint_of[j]].parent_body == 0)
        .collect();
    if base.iter().any(|&b| b) {
        partial_fit(model, ws, tasks, frame, &base, tolerance, relative_decrease)?;
    }

    for (k, joint) in model.joints.iter().enumerate() {
        if joint.parent_body == 0 || !carries[joint.child_body] {
            continue;
        }
        // the joint's own rotational coordinates that may move
        let own: Vec<(usize, f64, f64)> = (0..n)
            .filter(|&j| joint_of[j] == k)
            .filter_map(|j| {
                let c = &model.coordinates[model.reduction.independent[j]];
                if c.motion_type != MotionType::Rotational || c.locked {
                    return None;
                }
                let (lo, hi) = grid_range(ws.lo[j], ws.hi[j], c.range);
                (hi > lo).then_some((j, lo, hi))
            })
            .collect();
        if own.len() < 2 {
            continue;
        }
        let in_subtree = below(k);
        let free: Vec<bool> = (0..n).map(|j| in_subtree[joint_of[j]]).collect();
        // the grid over the joint's coordinates, its other coordinates as they are
        let current = ws.q.clone();
        let mut grid: Vec<(f64, Vec<f64>)> = Vec::new();
        let points = GRID.len().pow(own.len() as u32);
        for index in 0..points {
            let mut q = current.clone();
            let mut rest = index;
            for &(j, lo, hi) in &own {
                let fraction = GRID[rest % GRID.len()];
                rest /= GRID.len();
                q[j] = (lo + fraction * (hi - lo)).clamp(ws.lo[j], ws.hi[j]);
            }
            let f = objective(model, &mut ws.data, tasks, frame, &q, &ws.q_prev)?;
            grid.push((f, q));
        }
        grid.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut best: Option<(f64, Vec<f64>)> = None;
        let candidates = std::iter::once(current).chain(
            grid.into_iter()
                .take(GRID_STARTS)
                .filter(|(f, _)| f.is_finite())
                .map(|(_, q)| q),
        );
        for start in candidates {
            ws.q.copy_from_slice(&start);
            let f = partial_fit(model, ws, tasks, frame, &free, tolerance, relative_decrease)?;
            if best.as_ref().is_none_or(|(b, _)| f < *b) {
                best = Some((f, ws.q.clone()));
            }
        }
        if let Some((_, q)) = best {
            ws.q.copy_from_slice(&q);
        }
    }
    Ok(())
}

/// The interval a coordinate's grid spans: its bounds where they are finite, else its range
/// in the model where that is a proper interval, else one turn.
fn grid_range(lo: f64, hi: f64, range: [f64; 2]) -> (f64, f64) {
    let (lo, hi) = if lo.is_finite() && hi.is_finite() {
        (lo, hi)
    } else if range[0].is_finite() && range[1].is_finite() && range[0] < range[1] {
        (range[0], range[1])
    } else {
        (-std::f64::consts::PI, std::f64::consts::PI)
    };
    // no grid wider than one turn
    let span = (hi - lo).min(2.0 * std::f64::consts::PI);
    (lo, lo + span)
}

/// Levenberg–Marquardt over the coordinates `free` only (the others held at their values in
/// `ws.q` by bounds that pin them), at most [`PARTIAL_ITERATIONS`]; returns f.
fn partial_fit(
    model: &Model,
    ws: &mut IkWorkspace,
    tasks: &IkTasks,
    frame: &Frame,
    free: &[bool],
    tolerance: f64,
    relative_decrease: f64,
) -> crate::Result<f64> {
    let (lo, hi) = (ws.lo.clone(), ws.hi.clone());
    for (j, &f) in free.iter().enumerate() {
        if !f {
            ws.lo[j] = ws.q[j];
            ws.hi[j] = ws.q[j];
        }
    }
    let result = solve_frame(
        model,
        ws,
        tasks,
        frame,
        PARTIAL_ITERATIONS,
        tolerance,
        relative_decrease,
    );
    ws.lo = lo;
    ws.hi = hi;
    Ok(result?.0)
}

/// The starts in words, for a log line: `default pose f = 1.925e-4, limbs in turn
/// f = 1.687e-4 (kept)`.
pub fn describe(starts: &[StartOutcome]) -> String {
    starts
        .iter()
        .map(|s| {
            format!(
                "{} f = {:.4e}{}",
                s.name,
                s.objective,
                if s.chosen { " (kept)" } else { "" }
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}
