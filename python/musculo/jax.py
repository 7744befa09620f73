"""JAX wrappers of musculo's Euler–Lagrange and muscle losses (jax is optional; import this
module only where jax is installed).

    from musculo.jax import physics_loss
    loss_fn = physics_loss(musculo.Model.default(), contacts="model")
    value, grads = jax.value_and_grad(loss_fn, argnums=(0, 1, 2, 3, 4))(q, qd, qdd, tau, lam)
    layout_fn = layout_physics_loss(musculo.Model.default(), fps=20)   # a clip in the layout
    grads = jax.grad(layout_fn, argnums=range(6))(pos, rot, vel, acc, torque, contact_force)

A ``jax.custom_vjp`` function: the forward and backward passes run in musculo through
``jax.pure_callback`` on the host (float64 arrays; enable ``jax_enable_x64`` for exact
gradients), so it composes with ``jax.grad`` and ``jax.jit`` but not with ``vmap`` over
its arguments or higher-order derivatives.
"""

import jax
import numpy as np

from . import EulerLagrangeLoss, LayoutEulerLagrangeLoss, MuscleLoss


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


def layout_physics_loss(model, fps, couples="model", weights=None):
    """L_euler of one clip in the per-joint layout, as a function of its blocks
    (joint_pos, joint_rot, joint_vel, joint_acc, joint_torque, contact_force; each T × J × 3):
    the coordinates fitted from the layout (:meth:`musculo.Model.coordinates_from_layout`), the
    contact forces at the joint centres with the best couple on each foot
    (:class:`musculo.LayoutEulerLagrangeLoss`), and its VJP with respect to every block
    (:meth:`musculo.Model.coordinates_from_layout_vjp`)."""
    loss = LayoutEulerLagrangeLoss(model, couples=couples, weights=weights)

    def host(*blocks):
        b = [np.asarray(x, dtype=np.float64) for x in blocks]
        c = model.coordinates_from_layout(*b[:5], fps=fps)
        out = loss(c["q"], c["qd"], c["qdd"], c["tau"], b[5], gradients=True)
        g = model.coordinates_from_layout_vjp(*b[:5], fps, out["grad_q"], out["grad_qd"],
                                              out["grad_qdd"], out["grad_tau"])
        grads = [g[k] for k in ("grad_joint_pos", "grad_joint_rot", "grad_joint_vel",
                                "grad_joint_acc", "grad_joint_torque")]
        return (np.asarray(out["loss"], dtype=np.float64), *grads, out["grad_contact_force"])

    def call(*blocks):
        shapes = (jax.ShapeDtypeStruct((), blocks[0].dtype),
                  *(jax.ShapeDtypeStruct(x.shape, x.dtype) for x in blocks))
        result = jax.pure_callback(host, shapes, *blocks)
        return result[0], result[1:]

    @jax.custom_vjp
    def f(joint_pos, joint_rot, joint_vel, joint_acc, joint_torque, contact_force):
        return call(joint_pos, joint_rot, joint_vel, joint_acc, joint_torque, contact_force)[0]

    def fwd(*blocks):
        return call(*blocks)

    def bwd(grads, g):
        return tuple(g * d for d in grads)

    f.defvjp(fwd, bwd)
    return f


__all__ = ["physics_loss", "muscle_loss", "layout_physics_loss"]
