//! The backward sweep of a clip: every frame solved again from the solution kept for the
//! frame after it, keeping whichever of its two solutions fits its targets better.
//!
//! Tracking forwards, each frame starts from its predecessors' solutions, so a frame that ends
//! in another local minimum of f — a limb in the other angle branch after passing near a
//! gimbal lock, or held at a bound with the true pose on the far side — hands that minimum on,
//! and the forward pass stays there until the motion leaves its basin. Sweeping back from the
//! frames after such a stretch enters it from the other side. With q⁺ frame t's forward
//! solution and q⁻ its solution started from the kept solutions of t + 1 and t + 2
//! (extrapolated at constant velocity, as the forward pass does), frame t keeps
//!
//!   q_t = q⁻  if f₀(q⁻) < (1 − ε) f₀(q⁺),  else q⁺,
//!
//! with f₀ the frame's f without the smoothness term (the two solutions come from different
//! neighbours) and ε = 10⁻⁶, a hundred times the relative decrease at which a frame's solve
//! stops ([`super::RELATIVE_DECREASE`]), so that two solutions of one minimum are never told
//! apart. The sweep goes on from the kept solution, so a stretch left by the forward pass in
//! a worse minimum is replaced from its end back to where the two passes meet. A backward
//! solve that comes within [`super::JOIN_RADIUS`] of q⁺ (in every coordinate) is converging
//! to q⁺ and stops there, keeping q⁺: where the two passes agree, the sweep costs a few
//! evaluations of f per frame instead of a whole solve.

use super::{
    Frame, IkSettings, IkSolution, IkTasks, IkWorkspace, Observed, objective, solve_frame_joining,
};
use crate::model::Model;

/// How much lower f₀ of the backward solution must be (relative) for it to be kept.
const EPSILON: f64 = 1e-6;

/// Runs the sweep over `out` (every frame solved forwards), replacing the coordinates,
/// objective and iterations of the frames whose backward solution fits better and adding
/// the sweep's evaluations to every frame's. The fit figures are left to the caller.
pub(super) fn sweep(
    model: &Model,
    ws: &mut IkWorkspace,
    tasks: &IkTasks,
    observed: &Observed,
    settings: &IkSettings,
    out: &mut IkSolution,
) -> crate::Result<()> {
    let (n, frames) = (out.nq, out.n_frames());
    let time = &observed.targets.time;
    for f in (0..frames.saturating_sub(1)).rev() {
        if !observed.has_data(f) {
            continue;
        }
        // the start: the kept solutions of f + 1 and f + 2, extrapolated to t_f
        let after = f + 1;
        let after2 = (f + 2).min(frames - 1);
        ws.q_prev.copy_from_slice(out.frame(after));
        ws.q_prev2.copy_from_slice(out.frame(after2));
        let ratio = if after2 > after {
            (time[f] - time[after]) / (time[after] - time[after2])
        } else {
            0.0
        };
        for j in 0..n {
            ws.q[j] =
                (ws.q_prev[j] + ratio * (ws.q_prev[j] - ws.q_prev2[j])).clamp(ws.lo[j], ws.hi[j]);
        }
        let frame = observed.frame(f, settings);
        ws.evaluations = 0;
        let (value, iterations, joined) = solve_frame_joining(
            model,
            ws,
            tasks,
            &frame,
            settings.max_iterations,
            settings.tolerance,
            settings.relative_decrease,
            Some(out.frame(f)),
        )?;
        out.evaluations[f] += ws.evaluations;

        if joined {
            continue;
        }
        // without a smoothness term the two solves' own f are f₀
        let (backward, forward) = if frame.smoothness == 0.0 {
            (value, out.objective[f])
        } else {
            let fit = Frame {
                smoothness: 0.0,
                ..frame
            };
            (
                objective(model, &mut ws.data, tasks, &fit, &ws.q, &ws.q_prev)?,
                objective(model, &mut ws.data, tasks, &fit, out.frame(f), &ws.q_prev)?,
            )
        };
        if backward < (1.0 - EPSILON) * forward {
            out.q[f * n..(f + 1) * n].copy_from_slice(&ws.q);
            out.objective[f] = value;
            out.iterations[f] = iterations;
        }
    }
    Ok(())
}
