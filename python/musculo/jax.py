"""JAX wrappers of musculo's Euler–Lagrange and muscle losses (jax is optional; import this
module only where jax is installed).

    from musculo.jax import physics_loss
    loss_fn = physics_loss(musculo.Model.default(), contacts="model")
    value, grads = jax.value_and_grad(loss_fn, argnums=(0, 1, 2, 3, 4))(q, qd, qdd, tau, lam)

A ``jax.custom_vjp`` function: the forward and backward passes run in musculo through
``jax.pure_callback`` on the host (float64 arrays; enable ``jax_enable_x64`` for exact
gradients), so it composes with ``jax.grad`` and ``jax.jit`` but not with ``vmap`` over
its arguments or higher-order derivatives.
"""

import jax
import numpy as np

from . import EulerLagrangeLoss, MuscleLoss


def physics_loss(model, contacts=None, weights=None):
    """L(q, qd, qdd, tau, lam) = Σ_t Σ_j w_j r_tj² with its VJP; arguments as
    :class:`musculo.EulerLagrangeLoss` (lam of shape (..., P, 3); an empty (..., 0, 3) array
    without contacts)."""
    loss = EulerLagrangeLoss(model, contacts=contacts, weights=weights)
    n_contacts = len(loss.contact_names)

    def host(q, qd, qdd, tau, lam):
        arrays = [np.asarray(x, dtype=np.float64) for x in (q, qd, qdd, tau, lam)]
        out = loss(*arrays[:4], arrays[4] if n_contacts else None, gradients=True)
        grads = [out[k] for k in ("grad_q", "grad_qd", "grad_qdd", "grad_tau")]
        grads.append(out["grad_lambda"] if n_contacts else np.zeros_like(arrays[4]))
        return (np.asarray(out["loss"], dtype=np.float64), *grads)

    def call(q, qd, qdd, tau, lam):
        shapes = (jax.ShapeDtypeStruct((), q.dtype),
                  *(jax.ShapeDtypeStruct(x.shape, x.dtype) for x in (q, qd, qdd, tau, lam)))
        result = jax.pure_callback(host, shapes, q, qd, qdd, tau, lam)
        return result[0], result[1:]

    @jax.custom_vjp
    def f(q, qd, qdd, tau, lam):
        return call(q, qd, qdd, tau, lam)[0]

    def fwd(q, qd, qdd, tau, lam):
        value, grads = call(q, qd, qdd, tau, lam)
        return value, grads

    def bwd(grads, g):
        return tuple(g * d for d in grads)

    f.defvjp(fwd, bwd)
    return f


def muscle_loss(model, weights=None, beta=0.0, bound_weight=1.0):
    """L(q, qdd, a) = Σ_t [Σ_j w_j (q̈ − M⁻¹ R F_max a)_tj² + β‖a‖² + bound penalty] with its
    VJP; arguments as :class:`musculo.MuscleLoss`."""
    loss = MuscleLoss(model, weights=weights, beta=beta, bound_weight=bound_weight)

    def host(q, qdd, a):
        arrays = [np.asarray(x, dtype=np.float64) for x in (q, qdd, a)]
        out = loss(*arrays, gradients=True)
        return (np.asarray(out["loss"], dtype=np.float64),
                *(out[k] for k in ("grad_q", "grad_qdd", "grad_a")))

    def call(q, qdd, a):
        shapes = (jax.ShapeDtypeStruct((), q.dtype),
                  *(jax.ShapeDtypeStruct(x.shape, x.dtype) for x in (q, qdd, a)))
        result = jax.pure_callback(host, shapes, q, qdd, a)
        return result[0], result[1:]

    @jax.custom_vjp
    def f(q, qdd, a):
        return call(q, qdd, a)[0]

    def fwd(q, qdd, a):
        return call(q, qdd, a)

    def bwd(grads, g):
        return tuple(g * d for d in grads)

    f.defvjp(fwd, bwd)
    return f


__all__ = ["physics_loss", "muscle_loss"]
