"""The Python package against independent references: M from inverse-dynamics columns,
the loss gradients against central differences of the loss, errors as exceptions, and the
torch wrapper with torch.autograd.gradcheck where torch is installed."""

import os

import numpy as np
import pytest

import musculo

REFERENCE = os.environ.get("MUSCULO_REFERENCE", os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "reference"))
GAIT2392 = os.path.join(REFERENCE, "opensim-models", "Models", "Gait2392_Simbody", "gait2392_thelen2003muscle.osim")


@pytest.fixture(scope="module")
def model():
    return musculo.Model.default()


def state(model, frames, seed):
    rng = np.random.default_rng(seed)
    n = model.nq
    return (rng.uniform(-0.5, 0.5, (frames, n)), rng.uniform(-1, 1, (frames, n)),
            rng.uniform(-5, 5, (frames, n)))


def test_the_default_model(model):
    assert (model.nq, len(model.muscle_names), round(model.total_mass, 6)) == (29, 324, 75.0)
    assert len(model.coordinate_names) == model.nq


def test_mass_matrix_equals_inverse_dynamics_columns_and_batches_keep_their_shape(model):
    q, qd, _ = state(model, 6, 1)
    q = q.reshape(2, 3, model.nq)
    m = model.mass_matrix(q)
    assert m.shape == (2, 3, model.nq, model.nq)
    zero = np.zeros(model.nq)
    g = model.bias(q[1, 2], zero)
    for j in range(model.nq):
        e = np.eye(model.nq)[j]
        col = model.inverse_dynamics(q[1, 2], zero, e) - g
        np.testing.assert_allclose(m[1, 2][:, j], col, rtol=0, atol=1e-10 * np.abs(m).max())
    np.testing.assert_allclose(m, np.swapaxes(m, -1, -2), atol=1e-12)


def test_inverse_dynamics_derivatives_equal_central_differences(model):
    q, qd, qdd = (x[0] for x in state(model, 1, 2))
    dq, dqd, dqdd = model.inverse_dynamics_derivatives(q, qd, qdd)
    h = 1e-6
    for j in (0, 5, 12, 20):
        e = np.zeros(model.nq)
        e[j] = h
        fd = (model.inverse_dynamics(q + e, qd, qdd) - model.inverse_dynamics(q - e, qd, qdd)) / (2 * h)
        np.testing.assert_allclose(dq[:, j], fd, atol=1e-6 * np.abs(dq).max())
        fd = (model.inverse_dynamics(q, qd + e, qdd) - model.inverse_dynamics(q, qd - e, qdd)) / (2 * h)
        np.testing.assert_allclose(dqd[:, j], fd, atol=1e-6 * np.abs(dqd).max())
    np.testing.assert_allclose(dqdd, model.mass_matrix(q), atol=1e-12)


def test_loss_gradients_equal_central_differences(model):
    loss = musculo.EulerLagrangeLoss(model, contacts="model")
    p = len(loss.contact_names)
    assert p == 8
    q, qd, qdd = state(model, 3, 3)
    rng = np.random.default_rng(4)
    tau = rng.uniform(-50, 50, q.shape)
    lam = rng.uniform(-300, 300, (3, p, 3))
    inputs = [q, qd, qdd, tau, lam]
    out = loss(*inputs)
    assert out["residual"].shape == q.shape and out["per_frame"].shape == (3,)
    np.testing.assert_allclose(out["loss"], out["per_frame"].sum(), rtol=1e-12)
    rng = np.random.default_rng(5)
    for k, name in enumerate(["grad_q", "grad_qd", "grad_qdd", "grad_tau", "grad_lambda"]):
        g = out[name]
        assert g.shape == inputs[k].shape
        for _ in range(6):
            idx = tuple(rng.integers(0, s) for s in g.shape)
            x = [a.copy() for a in inputs]
            h = 1e-6 * max(1.0, abs(x[k][idx]))
            x[k][idx] += h
            lp = loss(*x, gradients=False)["loss"]
            x[k][idx] -= 2 * h
            lm = loss(*x, gradients=False)["loss"]
            fd = (lp - lm) / (2 * h)
            assert abs(g[idx] - fd) <= 1e-6 * np.abs(g).max(), (name, idx, g[idx], fd)


def test_a_consistent_motion_has_zero_loss(model):
    loss = musculo.EulerLagrangeLoss(model)
    q, qd, qdd = state(model, 4, 6)
    tau = model.inverse_dynamics(q, qd, qdd)
    out = loss(q, qd, qdd, tau)
    assert out["loss"] < 1e-20 * (tau ** 2).sum()
    tau[2, 7] += 0.5
    np.testing.assert_allclose(loss(q, qd, qdd, tau)["per_frame"][2], 0.25, rtol=1e-9)


def muscle_state(model, frames, seed):
    rng = np.random.default_rng(seed)
    q, _, qdd = state(model, frames, seed)
    return q, qdd, rng.uniform(-0.1, 1.1, (frames, len(model.muscle_names)))


def test_muscle_loss_gradients_equal_central_differences(model):
    loss = musculo.MuscleLoss(model, beta=0.2, bound_weight=3.0)
    assert loss.muscle_names == model.muscle_names and len(loss.max_isometric_force) == 324
    q, qdd, a = muscle_state(model, 2, 12)
    inputs = [q, qdd, a]
    out = loss(*inputs)
    assert out["residual"].shape == q.shape and out["grad_a"].shape == a.shape
    np.testing.assert_allclose(out["loss"], out["per_frame"].sum(), rtol=1e-12)
    rng = np.random.default_rng(13)
    for k, name in enumerate(["grad_q", "grad_qdd", "grad_a"]):
        g = out[name]
        for _ in range(5):
            idx = tuple(rng.integers(0, s) for s in g.shape)
            x = [v.copy() for v in inputs]
            # L is quadratic in q̈ (and piecewise in a): a large step there is exact and keeps
            # round-off of the large loss out of the difference
            h = (1e-6 if k == 0 else 1e-3) * max(1.0, abs(x[k][idx]))
            x[k][idx] += h
            lp = loss(*x, gradients=False)["loss"]
            x[k][idx] -= 2 * h
            lm = loss(*x, gradients=False)["loss"]
            fd = (lp - lm) / (2 * h)
            assert abs(g[idx] - fd) <= 1e-6 * np.abs(g).max(), (name, idx, g[idx], fd)


def test_muscle_loss_residual_is_the_acceleration_the_muscles_miss(model):
    # e = q̈ − M⁻¹ R F a: with q̈ set to the muscles' own acceleration the residual vanishes
    loss = musculo.MuscleLoss(model)
    q, _, a = muscle_state(model, 1, 14)
    a = np.clip(a, 0, 1)
    _, arms = model.muscle_paths(q[0])
    z = np.linalg.solve(model.mass_matrix(q[0]), arms @ (np.asarray(loss.max_isometric_force) * a[0]))
    out = loss(q, z[None, :], a)
    assert np.abs(out["residual"]).max() <= 1e-9 * np.abs(z).max()


def test_muscle_paths_and_forces(model):
    q = model.default_q()
    lengths, arms = model.muscle_paths(q)
    assert lengths.shape == (324,) and arms.shape == (model.nq, 324)
    assert np.all(lengths > 0.01) and np.all(lengths < 1.0)
    f = model.muscle_forces(q, np.zeros(model.nq), np.full(324, 0.5), rigid_tendon=True)
    assert f.shape == (324,) and np.all(f >= 0)


def test_errors_are_exceptions_with_the_library_message(model):
    with pytest.raises(musculo.MusculoError, match="last axis must have 29"):
        model.mass_matrix(np.zeros(5))
    with pytest.raises(ValueError, match="not finite"):
        model.inverse_dynamics(np.full(29, np.nan), np.zeros(29), np.zeros(29))
    with pytest.raises(musculo.MusculoError, match="no body"):
        musculo.EulerLagrangeLoss(model, contacts=[("nowhere", [0, 0, 0], [0, 0, 0])])
    with pytest.raises(musculo.MusculoError):
        musculo.Model.from_osim("/nonexistent/model.osim")
    with pytest.raises(musculo.MusculoError, match="λ"):
        musculo.EulerLagrangeLoss(model, contacts="model")(*state(model, 1, 7), np.zeros((1, 29)))


@pytest.mark.skipif(not os.path.exists(GAIT2392), reason="reference data not found")
def test_an_opensim_model_from_a_file():
    m = musculo.Model.from_osim(GAIT2392)
    assert m.nq == 23 and len(m.muscle_names) == 92


def test_torch_wrapper_passes_gradcheck(model):
    torch = pytest.importorskip("torch")
    from musculo.torch import PhysicsLoss

    physics = PhysicsLoss(model, contacts="model")
    q, qd, qdd = state(model, 2, 8)
    # near a consistent motion (τ ≈ τ_ID, small λ) the loss is small, so central differences
    # of it are not swamped by round-off
    rng = np.random.default_rng(9)
    tau = model.inverse_dynamics(q, qd, qdd) + rng.normal(0, 0.5, q.shape)
    lam = rng.normal(0, 1.0, (2, 8, 3))
    args = tuple(torch.tensor(x, dtype=torch.float64, requires_grad=True) for x in (q, qd, qdd, tau, lam))
    assert torch.autograd.gradcheck(physics, args, eps=1e-6, atol=1e-5, rtol=1e-5)


def test_torch_muscle_loss_passes_gradcheck(model):
    torch = pytest.importorskip("torch")
    from musculo.torch import MuscleLoss

    muscle = MuscleLoss(model, beta=0.1)
    q, qdd, a = muscle_state(model, 1, 15)
    # q̈ near the muscles' own acceleration keeps the loss small against round-off
    _, arms = model.muscle_paths(q[0])
    fmax = np.asarray(muscle.loss.max_isometric_force)
    a = np.clip(a, 0.05, 0.95)
    qdd = np.linalg.solve(model.mass_matrix(q[0]), arms @ (fmax * a[0]))[None, :] + 0.1
    args = tuple(torch.tensor(x, dtype=torch.float64, requires_grad=True) for x in (q, qdd, a))
    assert torch.autograd.gradcheck(muscle, args, eps=1e-7, atol=1e-4, rtol=1e-5)


REPOSITORY = os.path.join(os.path.dirname(__file__), "..", "..")


def documentation_python_blocks():
    """Every ```python block of README.md and of the book (docs/src, in SUMMARY.md's order), as
    (document, line, code); tests/readme.rs checks the same documents' tags and shell blocks."""
    docs = ["README.md"]
    summary = os.path.join(REPOSITORY, "docs", "src", "SUMMARY.md")
    if os.path.exists(summary):
        for line in open(summary, encoding="utf-8"):
            if "](" in line:
                docs.append(os.path.join("docs", "src", line.split("](", 1)[1].split(")", 1)[0]))
    out = []
    for doc in docs:
        path = os.path.join(REPOSITORY, doc)
        if not os.path.exists(path):
            continue
        block, start = None, 0
        for k, line in enumerate(open(path, encoding="utf-8"), start=1):
            fence = line.strip().startswith("```")
            if block is None and fence and line.strip()[3:].strip() == "python":
                block, start = [], k
            elif block is not None and fence:
                out.append((doc, start, "".join(block)))
                block = None
            elif block is not None:
                block.append(line)
    return out


def test_documentation_examples(monkeypatch):
    """Runs every Python example of the README and the book as written, from the repository
    root, the blocks of one document in one namespace. A block that imports torch or
    musculo.torch is skipped without torch; one that reads ../shared/reference without the reference data; one that reads
    out/demo (the README's main command, `musculo augment --demo --out out/demo`) runs it first
    with the built binary when out/demo is missing, and is skipped without one."""
    blocks = documentation_python_blocks()
    if not blocks:
        pytest.skip("README.md and docs/ not beside the tests")
    assert any(doc == "README.md" for doc, _, _ in blocks)
    monkeypatch.chdir(REPOSITORY)
    try:
        import torch  # noqa: F401
        have_torch = True
    except ImportError:
        have_torch = False
    namespaces, ran, skipped = {}, 0, []
    for doc, line, code in blocks:
        where = f"{doc}:{line}"
        if ("import torch" in code or "musculo.torch" in code) and not have_torch:
            skipped.append(f"{where} (torch)")
            continue
        needs = [p for p in code.split('"') if p.startswith("../shared/reference/")]
        if any(not os.path.exists(p) for p in needs):
            skipped.append(f"{where} (reference data)")
            continue
        if "out/demo/" in code and not os.path.exists(os.path.join("out", "demo", "manifest.json")):
            binary = os.path.join("target", "release", "musculo")
            if not os.path.exists(binary):
                skipped.append(f"{where} (out/demo and no target/release/musculo to make it)")
                continue
            import subprocess
            subprocess.run([binary, "augment", "--demo", "--out", "out/demo"], check=True,
                           capture_output=True)
        namespace = namespaces.setdefault(doc, {})
        try:
            exec(compile(code, where, "exec"), namespace)
        except Exception as e:  # name the block, not this test's line
            raise AssertionError(f"{where}: the example fails: {e!r}") from e
        ran += 1
        check_documented_results(doc, code, namespace)
    print(f"{ran} documentation examples ran; skipped: {skipped}")
    assert ran >= 2


def check_documented_results(doc, code, namespace):
    """What the Python chapter's examples promise, checked once each has run."""
    if not doc.endswith("python.md"):
        return
    out = namespace.get("out")
    if "EulerLagrangeLoss(" in code:
        assert out["grad_q"].shape == (16, 196, namespace["model"].nq)
    if "augment_file(" in code:
        assert namespace["m"]["targets"].shape[2] == 3 and namespace["ik"]["model_xml"]
        assert out["quality"]["reserve_share"] < 0.05
    if "PhysicsLoss(model" in code:
        assert namespace["q"].grad is not None
    if "LayoutPhysicsLoss(" in code:
        assert all(x.grad is not None for x in namespace["x"])


def test_jax_wrapper_gives_the_loss_gradients_under_grad_and_jit(model):
    jax = pytest.importorskip("jax")
    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    from musculo.jax import physics_loss

    f = physics_loss(model, contacts="model")
    q, qd, qdd = state(model, 2, 10)
    rng = np.random.default_rng(11)
    tau = model.inverse_dynamics(q, qd, qdd) + rng.normal(0, 0.5, q.shape)
    lam = rng.normal(0, 1.0, (2, 8, 3))
    args = [jnp.asarray(x) for x in (q, qd, qdd, tau, lam)]
    value, grads = jax.value_and_grad(f, argnums=(0, 1, 2, 3, 4))(*args)
    ref = musculo.EulerLagrangeLoss(model, contacts="model")(q, qd, qdd, tau, lam)
    assert float(value) == pytest.approx(ref["loss"], rel=1e-12)
    for g, name in zip(grads, ["grad_q", "grad_qd", "grad_qdd", "grad_tau", "grad_lambda"]):
        np.testing.assert_allclose(np.asarray(g), ref[name], rtol=1e-12, atol=0)
    # a directional derivative of the jitted gradient against a central difference of the loss
    direction = [rng.normal(0, 1, x.shape) for x in (q, qd, qdd, tau, lam)]
    jitted = jax.jit(jax.grad(f, argnums=(0, 1, 2, 3, 4)))(*args)
    slope = sum(float(np.sum(np.asarray(g) * d)) for g, d in zip(jitted, direction))
    h = 1e-6
    plus = f(*[a + h * d for a, d in zip(args, direction)])
    minus = f(*[a - h * d for a, d in zip(args, direction)])
    assert slope == pytest.approx(float(plus - minus) / (2 * h), rel=1e-6)


HUMANML3D = os.path.join(REFERENCE, "humanml3d", "new_joints_012314.npy")


@pytest.mark.skipif(not os.path.exists(HUMANML3D), reason="reference data not found")
def test_the_joint_layout_maps_back_to_the_coordinates():
    joints = np.load(HUMANML3D)
    out = musculo.augment_clip(joints, fps=20.0)
    scaled = musculo.Model.from_osim_string(out["model_xml"])
    c = scaled.coordinates_from_layout(*(out[k] for k in ("joint_pos", "joint_rot", "joint_vel",
                                                          "joint_acc", "joint_torque")), fps=20.0)
    assert c["q"].shape == out["q"].shape and c["rotation_error"].max() < 1e-5
    # through the shoulder's gimbal lock (the arms swung overhead, frames 10-35) other shoulder
    # angles give the same rotations, and the inverse's continuation may take them; every other
    # coordinate comes back to float32 rounding
    names = scaled.coordinate_names
    shoulder = [j for j, n in enumerate(names) if n.startswith("arm_") and not n.startswith("arm_elev")]
    others = [j for j in range(len(names)) if j not in shoulder]
    np.testing.assert_allclose(c["q"][:, others], out["q"][:, others], atol=1e-5)
    off = np.abs(c["q"][:, shoulder] - out["q"][:, shoulder]).max(axis=1) > 1e-5
    assert all(10 <= f <= 35 for f in np.flatnonzero(off)), np.flatnonzero(off)
    with pytest.raises(musculo.MusculoError, match="joint_rot"):
        scaled.coordinates_from_layout(out["joint_pos"], out["joint_rot"][:, :3], out["joint_vel"],
                                       out["joint_acc"], out["joint_torque"], fps=20.0)


LAYOUT = ("joint_pos", "joint_rot", "joint_vel", "joint_acc", "joint_torque")


def disturbed_layout(frames, seed):
    """The first `frames` frames of the HumanML3D sample augmented, its layout blocks then
    disturbed so that they disagree (as a generated motion's do); with the scaled model and
    the activations."""
    out = musculo.augment_clip(np.load(HUMANML3D)[:frames], fps=20.0)
    model = musculo.Model.from_osim_string(out["model_xml"])
    rng = np.random.default_rng(seed)
    noise = dict(zip(LAYOUT, (0.005, 0.02, 0.1, 0.5, 1.0)))
    blocks = [out[k].astype(np.float64) + noise[k] * rng.uniform(-1, 1, out[k].shape)
              for k in LAYOUT]
    return model, blocks, out["muscle_act"].astype(np.float64)


@pytest.mark.skipif(not os.path.exists(HUMANML3D), reason="reference data not found")
def test_muscle_loss_gradient_with_respect_to_the_joint_layout():
    model, blocks, a = disturbed_layout(10, 5)
    muscle = musculo.MuscleLoss(model, beta=1e-3)

    def loss(blocks):
        c = model.coordinates_from_layout(*blocks, fps=20.0)
        return muscle(c["q"], c["qdd"], a, gradients=True), c

    value, c = loss(blocks)
    assert c["rotation_error"].max() > 1e-3  # the fit leaves residuals
    g = model.coordinates_from_layout_vjp(*blocks, 20.0, value["grad_q"],
                                          np.zeros_like(c["qd"]), value["grad_qdd"],
                                          np.zeros_like(c["tau"]))
    rng = np.random.default_rng(6)
    for k, name in enumerate(LAYOUT):
        direction = rng.uniform(-1, 1, blocks[k].shape)
        slope = float(np.sum(g["grad_" + name] * direction))
        # the loss is large (~1e9) and the fit converges to 1e-12: steps that move it well
        # above that noise
        h = 1e-4

        def at(s):
            moved = [b + s * direction if i == k else b for i, b in enumerate(blocks)]
            return loss(moved)[0]["loss"]

        fd = (at(h) - at(-h)) / (2 * h)
        assert slope == pytest.approx(fd, rel=1e-5, abs=1e-9 * abs(value["loss"])), name
    with pytest.raises(musculo.MusculoError, match="grad_q"):
        model.coordinates_from_layout_vjp(*blocks, 20.0, value["grad_q"][:3],
                                          np.zeros_like(c["qd"]), value["grad_qdd"],
                                          np.zeros_like(c["tau"]))


@pytest.mark.skipif(not os.path.exists(HUMANML3D), reason="reference data not found")
def test_layout_physics_loss_and_its_gradient_with_respect_to_the_joint_layout():
    out = musculo.augment_clip(np.load(HUMANML3D)[:12], fps=20.0)
    model = musculo.Model.from_osim_string(out["model_xml"])
    loss = musculo.LayoutEulerLagrangeLoss(model)
    assert loss.couple_bodies and all(b.startswith(("calcn", "toes")) for b in loss.couple_bodies)
    # the augmented clip's own layout: its contact forces explain the motion as augment's did
    blocks = [out[k].astype(np.float64) for k in LAYOUT]
    force = out["contact_force"].astype(np.float64)
    c = model.coordinates_from_layout(*blocks, fps=20.0)
    with_forces = loss(c["q"], c["qd"], c["qdd"], c["tau"], force, gradients=False)
    without = loss(c["q"], c["qd"], c["qdd"], c["tau"], 0 * force, gradients=False)
    assert with_forces["loss"] < 0.1 * without["loss"]
    # what is left is the root's acceleration: the layout has no linear rates, so q̈ of the
    # translations comes from differences of its centre (here up to ~2 m/s² off augment's)
    names = model.coordinate_names
    trans = [names.index(k) for k in ("pelvis_tx", "pelvis_ty", "pelvis_tz")]
    moved = model.total_mass * (c["qdd"] - out["qdd"])[:, trans]
    left = with_forces["residual"][:, trans] - moved
    assert np.sqrt(np.mean(left**2)) < 0.05 * np.sqrt(np.mean(moved**2))
    # gradients through the fit and the loss, on a disturbed layout
    _, blocks, _ = disturbed_layout(12, 9)
    rng = np.random.default_rng(10)
    force = force + 20 * rng.uniform(-1, 1, force.shape)

    def value(blocks, force, gradients=False):
        c = model.coordinates_from_layout(*blocks, fps=20.0)
        return loss(c["q"], c["qd"], c["qdd"], c["tau"], force, gradients=gradients), c

    v, c = value(blocks, force, gradients=True)
    g = model.coordinates_from_layout_vjp(*blocks, 20.0, v["grad_q"], v["grad_qd"],
                                          v["grad_qdd"], v["grad_tau"])
    grads = [g["grad_" + k] for k in LAYOUT] + [v["grad_contact_force"]]
    for k, grad in enumerate(grads):
        direction = rng.uniform(-1, 1, grad.shape)
        h = 1e-4

        def at(s):
            moved = [b + s * direction if i == k else b for i, b in enumerate(blocks)]
            return value(moved, force + s * direction if k == 5 else force)[0]["loss"]

        fd = (at(h) - at(-h)) / (2 * h)
        assert float(np.sum(grad * direction)) == pytest.approx(fd, rel=1e-5), k


@pytest.mark.skipif(not os.path.exists(HUMANML3D), reason="reference data not found")
def test_torch_layout_coordinates_pass_gradcheck():
    torch = pytest.importorskip("torch")
    from musculo.torch import LayoutCoordinates, LayoutPhysicsLoss, MuscleLoss

    model, blocks, a = disturbed_layout(5, 7)
    layout = LayoutCoordinates(model, fps=20.0)
    args = tuple(torch.tensor(b, requires_grad=True) for b in blocks)
    assert torch.autograd.gradcheck(layout, args, eps=1e-6, atol=1e-5, rtol=1e-5)
    # a batch of two clips, into the muscle loss, as a trainer composes them
    batch = tuple(torch.stack([x.detach(), x.detach()]).requires_grad_() for x in args)
    q, qd, qdd, tau = layout(*batch)
    assert q.shape == (2, 5, model.nq)
    total = MuscleLoss(model)(q, qdd, torch.tensor(np.stack([a, a])))
    force = torch.zeros(2, 5, batch[0].shape[2], 3, dtype=torch.float64, requires_grad=True)
    total = total + LayoutPhysicsLoss(model)(q, qd, qdd, tau, force)
    total.backward()
    assert all(x.grad is not None and torch.isfinite(x.grad).all() for x in batch)
    assert torch.isfinite(force.grad).all() and force.grad.abs().max() > 0


@pytest.mark.skipif(not os.path.exists(HUMANML3D), reason="reference data not found")
def test_augment_clip_gives_tensors_that_satisfy_the_equations_of_motion():
    joints = np.load(HUMANML3D)
    out = musculo.augment_clip(joints, fps=20.0)
    t = joints.shape[0]
    assert out["quality"]["frames"] == t and out["q"].shape[0] == t
    assert out["q"].dtype == np.float32 and out["muscle_act"].shape == (t, 324)
    model = musculo.Model.from_osim_string(out["model_xml"], "scaled")
    # the body the arrays belong to: the built-in model scaled to the clip's bones
    identity = out["model_identity"]
    assert identity["base"]["name"] == "musculo_fullbody" and identity["scale"]["bodies"]
    loss = musculo.EulerLagrangeLoss(model, contacts="model")
    arrays = [out[k].astype(np.float64) for k in ("q", "qd", "qdd", "tau", "contact_point_force")]
    res = loss(*arrays, gradients=False)
    tau_id = model.inverse_dynamics(*arrays[:3])
    relative = np.linalg.norm(res["residual"], axis=-1) / np.linalg.norm(tau_id, axis=-1)
    assert relative.max() < 1e-6, relative.max()
    with pytest.raises(musculo.MusculoError):
        musculo.augment_clip(joints[:, :5])
    # the jump asks more than the model's muscles give (13.5 % of the joint moments on the
    # reserves); with every muscle twice as strong the reserves carry less than half (5.5 %)
    strong = musculo.augment_clip(joints, fps=20.0, muscle_strength=2.0)
    assert (
        strong["quality"]["reserve_share"] < 0.5 * out["quality"]["reserve_share"]
    ), (strong["quality"]["reserve_share"], out["quality"]["reserve_share"])
    with pytest.raises(musculo.MusculoError, match="muscle_strength"):
        musculo.augment_clip(joints, muscle_strength=0.0)


@pytest.mark.skipif(not os.path.exists(HUMANML3D), reason="reference data not found")
def test_inverse_kinematics_of_a_humanml3d_clip(model):
    joints = np.load(HUMANML3D)
    ik = model.inverse_kinematics(joints)
    t = joints.shape[0]
    assert ik["q"].shape == (t, model.nq) and ik["rmse"].shape == (t,)
    assert ik["marker_error"].shape[0] == t and np.all(np.isfinite(ik["q"]))
    # the unscaled default model fits this subject's joint centres to a few centimetres (55 mm
    # median), the model scaled to the clip's bones to about 12 mm, as augment's own IK reports
    assert np.median(ik["rmse"]) < 0.07, np.median(ik["rmse"])
    assert np.all(ik["max_error"] >= ik["rmse"] - 1e-12)
    out = musculo.augment_clip(joints)
    scaled = musculo.Model.from_osim_string(out["model_xml"]).inverse_kinematics(joints)
    assert np.median(scaled["rmse"]) < 0.02
    assert np.median(scaled["rmse"]) == pytest.approx(out["quality"]["ik_rmse_median"], rel=0.05)
    assert scaled["frames_at_limit"] == out["quality"]["ik_frames_at_bound"]
    with pytest.raises(musculo.MusculoError, match="kit"):
        model.inverse_kinematics(joints, format="bvh")


GAIT2392_DIR = os.path.join(REFERENCE, "opensim-models", "Pipelines", "Gait2392_Simbody")
WALK_TRC = os.path.join(GAIT2392_DIR, "subject01_walk1.trc")
WALK_MODEL = os.path.join(GAIT2392_DIR, "OutputReference", "subject01_simbody.osim")
BVH = os.path.join(REFERENCE, "bvh", "131_01.bvh")
C3D = os.path.join(REFERENCE, "c3d", "walking2.c3d")
C3D_CSV = os.path.join(REFERENCE, "c3d", "walking2_markers.csv")


@pytest.mark.skipif(not os.path.exists(WALK_TRC), reason="reference data not found")
def test_read_motion_of_a_trc_file_equals_its_text():
    m = musculo.read_motion(WALK_TRC)
    lines = open(WALK_TRC).read().splitlines()
    names = [n for n in lines[3].split("\t")[2:] if n]
    rows = np.array([[float(v) for v in line.split("\t")[2:2 + 3 * len(names)]]
                     for line in lines[5:] if line.strip()])
    assert m["names"] == names and m["rate_hz"] == 60.0
    assert m["targets"].shape == (rows.shape[0], len(names), 3)
    # the file is in millimetres; read_motion gives metres
    assert np.abs(m["targets"].reshape(rows.shape[0], -1) - rows / 1000.0).max() < 1e-12


@pytest.mark.skipif(not os.path.exists(C3D_CSV), reason="reference data not found")
def test_read_motion_of_a_c3d_file_matches_the_ezc3d_export():
    m = musculo.read_motion(C3D)
    header = open(C3D_CSV).readline().strip().split(",")
    csv = np.genfromtxt(C3D_CSV, delimiter=",", skip_header=1)[:, 2:] / 1000.0  # mm, lab axes
    markers = [h[:-2] for h in header[2::3]]
    t = m["targets"].shape[0]
    assert csv.shape[0] == t
    for a, b in [(0, 1), (2, 5), (7, 11)]:
        ia, ib = m["names"].index(markers[a]), m["names"].index(markers[b])
        # a rotation into OpenSim's axes keeps distances; gaps (NaN) fall on the same samples
        ours = np.linalg.norm(m["targets"][:, ia] - m["targets"][:, ib], axis=-1)
        ref = np.linalg.norm(csv[:, 3 * a:3 * a + 3] - csv[:, 3 * b:3 * b + 3], axis=-1)
        assert np.array_equal(np.isnan(ours), np.isnan(ref))
        ok = ~np.isnan(ref)
        assert ok.sum() > 100 and np.abs(ours[ok] - ref[ok]).max() < 1e-6


@pytest.mark.skipif(not os.path.exists(WALK_MODEL), reason="reference data not found")
def test_inverse_kinematics_of_marker_and_bvh_files():
    walk = musculo.Model.from_osim(WALK_MODEL)
    ik = walk.inverse_kinematics_file(WALK_TRC)
    t = ik["q"].shape[0]
    assert t == 151 and ik["time"].shape == (t,) and len(ik["marker_names"]) == ik["marker_error"].shape[1]
    # all 41 markers matched by name, every weight 1 (19 mm median; the IK setup file, which
    # `musculo ik --setup` reads, weights the markers and fits to about a centimetre)
    assert 0.005 < np.median(ik["rmse"]) < 0.025, np.median(ik["rmse"])
    model = musculo.Model.default()
    bvh = model.inverse_kinematics_file(BVH, length_unit="0.056444")
    assert bvh["q"].shape == (994, model.nq) and np.all(np.isfinite(bvh["q"]))
    assert bvh["model_xml"] is None
    # the 1.43 m subject on the unscaled 1.8 m model: about 8 cm; scaled to the clip's bones
    # as `musculo ik --scale auto` does (the book, "Motion inputs": 8.3 mm median for this clip)
    scaled = model.inverse_kinematics_file(BVH, length_unit="0.056444", scale=True)
    assert np.median(scaled["rmse"]) < 0.012 < 0.05 < np.median(bvh["rmse"])
    refit = musculo.Model.from_osim_string(scaled["model_xml"]).inverse_kinematics_file(
        BVH, length_unit="0.056444")
    assert np.abs(refit["q"] - scaled["q"]).max() < 1e-9
    with pytest.raises(musculo.MusculoError, match="body height"):
        model.inverse_kinematics_file(BVH, length_unit="m")
    with pytest.raises(musculo.MusculoError, match="same name"):
        model.inverse_kinematics_file(WALK_TRC)
    with pytest.raises(musculo.MusculoError, match="expected humanml3d"):
        model.inverse_kinematics_file(BVH, format="fbx")


@pytest.mark.skipif(not os.path.exists(BVH), reason="reference data not found")
def test_length_unit_is_a_unit_name_or_metres_per_unit_as_text_or_number():
    as_text = musculo.read_motion(BVH, length_unit="0.056444")
    as_number = musculo.read_motion(BVH, length_unit=0.056444)
    assert np.array_equal(as_text["targets"], as_number["targets"], equal_nan=True)
    # an integer is a number of metres too: 1, like "m", makes this CMU subject 25 m tall
    for metres in ("m", 1):
        with pytest.raises(musculo.MusculoError, match="body height"):
            musculo.read_motion(BVH, length_unit=metres)
    # both forms accept the same range (1e-6 to 1e3 m per unit)
    for bad in (0.0, -0.05, 1e4, float("nan"), "1e4", True, False):
        with pytest.raises(musculo.MusculoError, match="length_unit"):
            musculo.read_motion(BVH, length_unit=bad)
    with pytest.raises(TypeError):
        musculo.read_motion(BVH, length_unit=[0.05])


@pytest.mark.skipif(not os.path.exists(C3D), reason="reference data not found")
def test_augment_file_with_force_plates_satisfies_the_equations_of_motion():
    out = musculo.augment_file(C3D, map="c3d_lower_body", force_plates=True)
    t = out["q"].shape[0]
    assert t > 400 and out["muscle_act"].shape == (t, 324)
    assert 0.0 <= out["muscle_act"].min() and out["muscle_act"].max() <= 1.0
    model = musculo.Model.from_osim_string(out["model_xml"], "scaled")
    q, qd, qdd, tau, ext = (out[k].astype(np.float64) for k in ("q", "qd", "qdd", "tau", "external"))
    tau_id = model.inverse_dynamics(q, qd, qdd)
    relative = np.linalg.norm(tau_id - tau - ext, axis=-1) / np.linalg.norm(tau_id, axis=-1)
    assert relative.max() < 1e-6, relative.max()
    # the measured loads carry the body: the floating base's residual forces stay small
    assert out["quality"]["reserve_share"] < 0.05
    with pytest.raises(musculo.MusculoError, match="C3D"):
        musculo.augment_file(BVH, length_unit="0.056444", force_plates=True)


def test_jax_muscle_loss_gives_the_loss_gradients(model):
    jax = pytest.importorskip("jax")
    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    from musculo.jax import muscle_loss

    f = muscle_loss(model, beta=0.1)
    q, qdd, a = muscle_state(model, 2, 16)
    value, grads = jax.value_and_grad(f, argnums=(0, 1, 2))(*(jnp.asarray(x) for x in (q, qdd, a)))
    ref = musculo.MuscleLoss(model, beta=0.1)(q, qdd, a)
    assert float(value) == pytest.approx(ref["loss"], rel=1e-12)
    for g, name in zip(grads, ["grad_q", "grad_qdd", "grad_a"]):
        np.testing.assert_allclose(np.asarray(g), ref[name], rtol=1e-12, atol=0)


def test_evaluate_a_motion_file_and_augmented_tensors(tmp_path):
    """musculo.evaluate: a motion file (through the chain without muscles) and the tensors of
    the same clip written from augment_file's arrays give the same kinematic figures and a
    zero Euler–Lagrange residual."""
    if not os.path.exists(C3D):
        pytest.skip("reference data not found")
    direct = musculo.evaluate([C3D], map="c3d_lower_body")
    assert direct["failed"] == [] and len(direct["clips"]) == 1
    a = direct["clips"][0]
    out = augment_file_cached()
    keep = {k: v for k, v in out.items() if isinstance(v, np.ndarray)}
    np.savez(tmp_path / "walking2.npz", **keep)
    (tmp_path / "walking2.osim").write_text(out["model_xml"])
    b = musculo.evaluate([str(tmp_path)])["clips"][0]
    for key in ("frames", "skate", "skate_speed", "float", "penetrate"):
        assert abs(a[key] - b[key]) <= 1e-6 * (1 + abs(a[key])), (key, a[key], b[key])
    assert a["el_residual"] < 1e-6 and b["el_residual"] < 1e-6
    summary = musculo.evaluate([str(tmp_path)], floor="clip")["summary"]
    assert summary["clips"] == 1 and summary["float"] < a["float"]
    with pytest.raises(musculo.MusculoError, match="no such file"):
        musculo.evaluate([str(tmp_path / "missing.npz")])
    with pytest.raises(musculo.MusculoError, match="floor"):
        musculo.evaluate([str(tmp_path)], floor="ground")


def test_evaluate_a_treadmill_walk_against_its_belt():
    """The gait2392 walk was recorded on a treadmill: its feet skate at belt speed against a
    floor at rest and stand on the belt with the floor's velocity taken from the clip."""
    trc = os.path.join(GAIT2392_DIR, "subject01_walk1.trc")
    model = os.path.join(GAIT2392_DIR, "OutputReference", "subject01_simbody.osim")
    if not (os.path.exists(trc) and os.path.exists(model)):
        pytest.skip("reference data not found")
    rest = musculo.evaluate([trc], model=model, floor="clip")["clips"][0]
    belt = musculo.evaluate([trc], model=model, floor="clip", floor_velocity="clip")["clips"][0]
    assert rest["skate_speed"] > 0.8 and belt["skate_speed"] < 0.1, (rest, belt)
    with pytest.raises(musculo.MusculoError, match="floor_velocity"):
        musculo.evaluate([trc], model=model, floor_velocity=(1.0, 0.0))


_AUGMENTED = {}


def augment_file_cached():
    if "walking2" not in _AUGMENTED:
        _AUGMENTED["walking2"] = musculo.augment_file(C3D, map="c3d_lower_body")
    return _AUGMENTED["walking2"]


@pytest.mark.skipif(not os.path.exists(HUMANML3D), reason="reference data not found")
def test_jax_layout_physics_loss_gives_the_composed_gradients():
    jax = pytest.importorskip("jax")
    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    from musculo.jax import layout_physics_loss

    model, blocks, _ = disturbed_layout(8, 12)
    out = musculo.augment_clip(np.load(HUMANML3D)[:8], fps=20.0)
    force = out["contact_force"].astype(np.float64)
    f = layout_physics_loss(model, fps=20.0)
    args = [jnp.asarray(b) for b in blocks] + [jnp.asarray(force)]
    value, grads = jax.value_and_grad(f, argnums=tuple(range(6)))(*args)
    # the same composition by hand: fit, loss, VJP
    loss = musculo.LayoutEulerLagrangeLoss(model)
    c = model.coordinates_from_layout(*blocks, fps=20.0)
    ref = loss(c["q"], c["qd"], c["qdd"], c["tau"], force)
    g = model.coordinates_from_layout_vjp(*blocks, 20.0, ref["grad_q"], ref["grad_qd"],
                                          ref["grad_qdd"], ref["grad_tau"])
    assert float(value) == pytest.approx(ref["loss"], rel=1e-12)
    for k, name in enumerate(LAYOUT):
        np.testing.assert_allclose(np.asarray(grads[k]), g["grad_" + name], rtol=1e-12, atol=0)
    np.testing.assert_allclose(np.asarray(grads[5]), ref["grad_contact_force"], rtol=1e-12)
    jitted = jax.jit(jax.grad(f, argnums=(1,)))(*args)
    np.testing.assert_allclose(np.asarray(jitted[0]), g["grad_joint_rot"], rtol=1e-12, atol=0)
