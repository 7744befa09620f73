"""PyTorch wrappers of musculo's Euler–Lagrange and muscle losses (torch is optional; import
this module only where torch is installed).

    from musculo.torch import PhysicsLoss, MuscleLoss
    physics = PhysicsLoss(musculo.Model.default(), contacts="model")
    loss = loss + weight * physics(q, qd, qdd, tau, lam)     # differentiable in every input
    muscle = MuscleLoss(musculo.Model.default(), beta=1e-3)
    loss = loss + weight * muscle(q, qdd, a)

The forward and backward passes run in musculo (exact gradients, vector–Jacobian products of
inverse dynamics); tensors are moved to the CPU as float64 and the gradients come back in each
input's dtype and device.
"""

import torch

from . import EulerLagrangeLoss
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
