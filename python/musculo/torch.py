"""PyTorch wrappers of musculo's Euler–Lagrange and muscle losses (torch is optional; import
this module only where torch is installed).

    from musculo.torch import PhysicsLoss, MuscleLoss
    physics = PhysicsLoss(musculo.Model.default(), contacts="model")
    loss = loss + weight * physics(q, qd, qdd, tau, lam)     # differentiable in every input
    muscle = MuscleLoss(musculo.Model.default(), beta=1e-3)
    loss = loss + weight * muscle(q, qdd, a)
    layout = LayoutCoordinates(musculo.Model.default(), fps=20)   # FlexMotion's per-joint layout
    q, qd, qdd, tau = layout(joint_pos, joint_rot, joint_vel, joint_acc, joint_torque)
    layout_physics = LayoutPhysicsLoss(musculo.Model.default())    # its contact forces, per joint
    loss = loss + weight * layout_physics(q, qd, qdd, tau, contact_force)

The forward and backward passes run in musculo (exact gradients, vector–Jacobian products of
inverse dynamics); tensors are moved to the CPU as float64 and the gradients come back in each
input's dtype and device.
"""

import numpy as np
import torch

from . import EulerLagrangeLoss
from . import LayoutEulerLagrangeLoss
from . import MuscleLoss as _MuscleLoss


class _EulerLagrangeFunction(torch.autograd.Function):
    @staticmethod
    def forward(ctx, loss, q, qd, qdd, tau, lam):
        def cpu(x):
            return None if x is None else x.detach().to("cpu", torch.float64).numpy()

        out = loss(cpu(q), cpu(qd), cpu(qdd), cpu(tau), cpu(lam), gradients=True)
        grads = [out["grad_q"], out["grad_qd"], out["grad_qdd"], out["grad_tau"],
                 out["grad_lambda"] if lam is not None else None]
        ctx.grads = [None if g is None else torch.from_numpy(g).to(x.device, x.dtype)
                     for g, x in zip(grads, (q, qd, qdd, tau, lam))]
        return q.new_tensor(out["loss"])

    @staticmethod
    def backward(ctx, grad_output):
        scaled = [None if g is None else grad_output * g for g in ctx.grads]
        return (None, *scaled)


class PhysicsLoss(torch.nn.Module):
    """L_euler = Σ_t Σ_j w_j r_tj², r = M q̈ + C q̇ + G − τ − Σ_i J_iᵀ λ_i, summed over every
    frame of the batch; arguments as :class:`musculo.EulerLagrangeLoss`."""

    def __init__(self, model, contacts=None, weights=None):
        super().__init__()
        self.loss = EulerLagrangeLoss(model, contacts=contacts, weights=weights)

    def forward(self, q, qd, qdd, tau, lam=None):
        return _EulerLagrangeFunction.apply(self.loss, q, qd, qdd, tau, lam)


class _MuscleFunction(torch.autograd.Function):
    @staticmethod
    def forward(ctx, loss, q, qdd, a):
        def cpu(x):
            return x.detach().to("cpu", torch.float64).numpy()

        out = loss(cpu(q), cpu(qdd), cpu(a), gradients=True)
        ctx.grads = [torch.from_numpy(out[k]).to(x.device, x.dtype)
                     for k, x in zip(("grad_q", "grad_qdd", "grad_a"), (q, qdd, a))]
        return q.new_tensor(out["loss"])

    @staticmethod
    def backward(ctx, grad_output):
        return (None, *(grad_output * g for g in ctx.grads))


class MuscleLoss(torch.nn.Module):
    """L_muscle = Σ_t [Σ_j w_j (q̈ − M⁻¹ R F_max a)_tj² + β‖a‖² + bound penalty], summed over
    every frame of the batch, differentiable in q, q̈ and a; arguments as
    :class:`musculo.MuscleLoss`."""

    def __init__(self, model, weights=None, beta=0.0, bound_weight=1.0):
        super().__init__()
        self.loss = _MuscleLoss(model, weights=weights, beta=beta, bound_weight=bound_weight)

    def forward(self, q, qdd, a):
        return _MuscleFunction.apply(self.loss, q, qdd, a)


_LAYOUT = ("joint_pos", "joint_rot", "joint_vel", "joint_acc", "joint_torque")


class _LayoutFunction(torch.autograd.Function):
    @staticmethod
    def forward(ctx, model, fps, *blocks):
        like = blocks[0]
        # one clip (T × J × 3) or a batch of clips (B × T × J × 3), fitted clip by clip
        batched = like.dim() == 4
        cpu = [b.detach().to("cpu", torch.float64).numpy() for b in blocks]
        clips = [list(c) for c in zip(*cpu)] if batched else [cpu]
        fits = [model.coordinates_from_layout(*c, fps=fps) for c in clips]
        ctx.model, ctx.fps, ctx.clips, ctx.batched = model, fps, clips, batched
        ctx.like = [(b.device, b.dtype) for b in blocks]
        outs = []
        for key in ("q", "qd", "qdd", "tau"):
            arrays = [f[key] for f in fits]
            a = torch.from_numpy(np.stack(arrays) if batched else arrays[0])
            outs.append(a.to(like.device, like.dtype))
        return tuple(outs)

    @staticmethod
    def backward(ctx, *grads):
        per_clip = []
        for i, clip in enumerate(ctx.clips):
            bars = []
            for g in grads:
                g = g.detach().to("cpu", torch.float64).numpy()
                bars.append(g[i] if ctx.batched else g)
            out = ctx.model.coordinates_from_layout_vjp(*clip, ctx.fps, *bars)
            per_clip.append([out["grad_" + k] for k in _LAYOUT])
        result = []
        for k, (device, dtype) in enumerate(ctx.like):
            arrays = [p[k] for p in per_clip]
            a = torch.from_numpy(np.stack(arrays) if ctx.batched else arrays[0])
            result.append(a.to(device, dtype))
        return (None, None, *result)


class LayoutCoordinates(torch.nn.Module):
    """The coordinates q, q̇, q̈ and τ (T × n) of a clip in FlexMotion's per-joint layout
    (`joint_pos`, `joint_rot`, `joint_vel`, `joint_acc`, `joint_torque`: T × J × 3, or
    B × T × J × 3 for a batch of clips) at `fps`, as :meth:`musculo.Model.coordinates_from_layout`
    fits them, differentiable in every block (:meth:`musculo.Model.coordinates_from_layout_vjp`):
    a trainer that predicts the layout feeds them to :class:`PhysicsLoss` or :class:`MuscleLoss`.
    """

    def __init__(self, model, fps):
        super().__init__()
        self.model, self.fps = model, float(fps)

    def forward(self, joint_pos, joint_rot, joint_vel, joint_acc, joint_torque):
        return _LayoutFunction.apply(self.model, self.fps, joint_pos, joint_rot, joint_vel,
                                     joint_acc, joint_torque)


class _LayoutEulerLagrangeFunction(torch.autograd.Function):
    @staticmethod
    def forward(ctx, loss, q, qd, qdd, tau, contact_force):
        def cpu(x):
            return x.detach().to("cpu", torch.float64).numpy()

        out = loss(cpu(q), cpu(qd), cpu(qdd), cpu(tau), cpu(contact_force), gradients=True)
        keys = ("grad_q", "grad_qd", "grad_qdd", "grad_tau", "grad_contact_force")
        ctx.grads = [torch.from_numpy(out[k]).to(x.device, x.dtype)
                     for k, x in zip(keys, (q, qd, qdd, tau, contact_force))]
        return q.new_tensor(out["loss"])

    @staticmethod
    def backward(ctx, grad_output):
        return (None, *(grad_output * g for g in ctx.grads))


class LayoutPhysicsLoss(torch.nn.Module):
    """L_euler of motions in the per-joint layout: q, q̇, q̈, τ (..., T, n; from
    :class:`LayoutCoordinates`) and the layout's contact forces (..., T, J, 3), which act at the
    joint centres with the couple on each foot that best explains the motion; arguments as
    :class:`musculo.LayoutEulerLagrangeLoss`."""

    def __init__(self, model, couples="model", weights=None):
        super().__init__()
        self.loss = LayoutEulerLagrangeLoss(model, couples=couples, weights=weights)

    def forward(self, q, qd, qdd, tau, contact_force):
        return _LayoutEulerLagrangeFunction.apply(self.loss, q, qd, qdd, tau, contact_force)
