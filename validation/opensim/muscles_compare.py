"""Musculotendon lengthening speeds and muscle forces at equilibrium, musculo against OpenSim 4.6.

Models: every .osim under opensim-models that both programs load and that has muscles, the
default model and a scaled copy (osimval.all_models), and De Groote–Fregly 2016 copies of four of
them made by OpenSim itself (`DeGrooteFregly2016Muscle.replaceMuscles`: arm26, gait2392, Rajagopal
2016 and the default model), so that each muscle class OpenSim 4.6 ships and musculo models —
Thelen2003Muscle, Millard2012EquilibriumMuscle (elastic and rigid tendons, fiber damping) and
DeGrooteFregly2016Muscle — is compared on real parameter sets.

States (seed 2): coordinates uniform over their full ranges, independent speeds normal with σ
1 rad/s (0.3 m/s for translations; locked coordinates at rest), coupled coordinates' speeds
θ̇ = f′(q) q̇; each muscle's activation uniform on [0.02, 1].

OpenSim: coordinates and speeds set, `Muscle::setActivation`, then per muscle
`computeEquilibrium` (what `Model::equilibrateMuscles` calls: each class's
`computeInitialFiberEquilibrium`), then at the dynamics stage `getLength`,
`getLengtheningSpeed`, `getActivation`, `getFiberLength` and `getTendonForce`. musculo
(`examples/opensim_muscles.rs`): ℓ̇ = −rᵀq̇ from its own paths at the same q, q̇, and the muscle
state at OpenSim's own (a, ℓ, ℓ̇), so the force check does not inherit a path difference; each
class's initialisation rule for the fiber velocity (Thelen: stiffness split; Millard: fiber at
rest; De Groote–Fregly: tendon at constant length), rigid tendons in closed form.

Tolerances (exit 1 when one is missed):
- ℓ̇ of paths without wrap objects: 1e-9 m/s + 1e-9 relative (both are exact kinematics);
- ℓ̇ of wrapped paths: 1e-9 m/s + 1e-4 m · Σ_j |q̇_j| — the moment-arm tolerance of
  paths_compare.py carried through ℓ̇ = −rᵀq̇; states where OpenSim's path is stale (its
  tangent-point cache, see README) are counted and not judged;
- tendon force: 1e-6 · F_max. OpenSim solves the force balance to 1e-8 · F_max (Thelen,
  Millard; De Groote–Fregly's bisection to 1e-10 in normalised tendon force), musculo to
  1e-12 · F_max; Thelen's initialisation lags the velocity split one Newton step behind the
  fiber length, which moves its answer by more than its own tolerance in fast states;
- fiber length: 1e-6 · optimal fiber length, judged where the tendon is taut (a slack tendon
  leaves the fiber length undetermined in OpenSim's Millard, which then returns its guess);
- a muscle OpenSim cannot equilibrate (MuscleCannotEquilibrate) must not have a solved state in
  musculo either, and vice versa (counted per model).

Usage: muscles_compare.py [--states N] [--model PATH]... [--self-test | --opensim-only]
"""

import argparse
import json
import os
import subprocess
import sys

import numpy as np

import osimval as ov
from osimval import Sampler
from paths_compare import steepest

osim = ov.osim
ov.quiet_opensim()

EXAMPLE = os.path.join(ov.REPO, "target", "release", "examples", "opensim_muscles")
SPEED_TOL = 1e-9
ARM_TOL = 1e-4
FORCE_TOL = 1e-6
FIBER_TOL = 1e-6
FD_H = 1e-6
SMOOTH = 1e-5
RULE_TOL = 1e-6
GAVE_UP_RULE_TOL = 1e-2
NEAR_SINGULAR = 0.2  # m/rad: twice the largest human moment arm (data/check bounds)
AT_FIBER_TOL = 1e-9
AT_FIBER_VELOCITY_TOL = 1e-8
SPEED_SCALE = float(os.environ.get("MUSCULO_SPEED_SCALE", "1"))
DEGROOTE = ["Models/Arm26/arm26.osim", "Models/Gait2392_Simbody/gait2392_simbody.osim",
            "Models/Rajagopal/Rajagopal2016.osim"]


def degroote_copies(work):
    """(label, path) of De Groote–Fregly copies written by OpenSim's own replaceMuscles."""
    out = []
    sources = [os.path.join(ov.MODELS, p) for p in DEGROOTE]
    sources.append(os.path.join(ov.REPO, "models", "musculo_fullbody.osim"))
    for src in sources:
        if not os.path.exists(src):
            continue
        model = osim.Model(src)
        model.initSystem()
        osim.DeGrooteFregly2016Muscle.replaceMuscles(model)
        stem = os.path.splitext(os.path.basename(src))[0]
        os.makedirs(os.path.join(work, "degroote"), exist_ok=True)
        dst = os.path.join(work, "degroote", f"{stem}_degroote.osim")
        model.printToXML(dst)
        out.append((f"{stem}, De Groote–Fregly copy", dst))
    return out


def stale(path_points, state):
    """Whether OpenSim's cached ground location of a wrap tangent point is stale."""
    for j in range(path_points.getSize()):
        p = path_points.get(j)
        if p.getWrapObject() is None:
            continue
        fresh = p.getParentFrame().findStationLocationInGround(state, p.getLocation(state))
        cached = p.getLocationInGround(state)
        if max(abs(fresh[i] - cached[i]) for i in range(3)) > 1e-9:
            return True
    return False


def opensim_side(sampler, cols, locked, n, rng, n_muscles):
    """States and OpenSim's muscle quantities: (states B × 2n, inputs B × m × 3, results dict)."""
    model, state = sampler.model, sampler.state
    muscles = model.getMuscles()
    q_all = sampler.sample(n, 2)
    rot = np.array([ov.is_rotational(sampler.coords.get(c)) for c in cols])
    sigma = np.where(rot, 1.0, 0.3) * SPEED_SCALE
    states, inputs, replay = [], [], []
    res = {key: np.full((n, n_muscles), np.nan) for key in
           ("fiber_length", "tendon_force", "fiber_velocity", "active_fiber_force", "stale",
            "failed", "speed_fd", "rough", "fiber_along_tendon")}
    wrapped = [m for m in range(n_muscles)
               if muscles.get(m).getGeometryPath().getWrapSet().getSize() > 0]
    for k in range(n):
        qd = np.where(locked, 0.0, rng.normal(0, 1, len(cols)) * sigma)
        full_qd = np.zeros(len(sampler.names))
        full_qd[cols] = qd
        full_qd = ov.full_speeds(sampler, q_all[k], full_qd)
        # OpenSim's own ℓ̇ by central differences of its length along q̇ (wrapped paths).
        # The same with 4h: where the two differ by more than SMOOTH · Σ|q̇| the path is not
        # smooth along q̇ there (a wrap engaging, a singular state) and ℓ̇ is not judged.
        lengths, stale_near = {}, np.zeros(n_muscles, dtype=bool)
        for step in (FD_H, -FD_H, 4 * FD_H, -4 * FD_H):
            full_q = q_all[k].copy()
            full_q[cols] += step * qd
            sampler.set(sampler.complete(full_q))
            lengths[step] = {m: muscles.get(m).getLength(state) for m in wrapped}
            for m in wrapped:
                stale_near[m] |= stale(muscles.get(m).getGeometryPath().getCurrentPath(state), state)
        for m in wrapped:
            fd = (lengths[FD_H][m] - lengths[-FD_H][m]) / (2 * FD_H)
            fd4 = (lengths[4 * FD_H][m] - lengths[-4 * FD_H][m]) / (8 * FD_H)
            res["speed_fd"][k, m] = fd
            res["rough"][k, m] = abs(fd - fd4) > SMOOTH * np.abs(qd).sum()
        sampler.set(q_all[k])
        for i in range(len(sampler.names)):
            sampler.coords.get(i).setSpeedValue(state, full_qd[i])
        act = rng.uniform(0.02, 1.0, n_muscles)
        replay.append((q_all[k], full_qd, act))
        for m in range(n_muscles):
            muscles.get(m).setActivation(state, act[m])
        model.realizeVelocity(state)
        failed = np.zeros(n_muscles, dtype=bool)
        for m in range(n_muscles):
            try:
                muscles.get(m).computeEquilibrium(state)
            except Exception:  # noqa: BLE001 — OpenSim raises MuscleCannotEquilibrate
                failed[m] = True
        model.realizeDynamics(state)
        row = np.zeros((n_muscles, 4))
        for m in range(n_muscles):
            mu = muscles.get(m)
            row[m] = (mu.getActivation(state), mu.getLength(state), mu.getLengtheningSpeed(state),
                      mu.getFiberLength(state))
            res["fiber_length"][k, m] = mu.getFiberLength(state)
            res["tendon_force"][k, m] = mu.getTendonForce(state)
            res["fiber_velocity"][k, m] = mu.getFiberVelocity(state)
            res["active_fiber_force"][k, m] = mu.getActiveFiberForce(state)
            res["fiber_along_tendon"][k, m] = mu.getLength(state) - mu.getTendonLength(state)
            res["stale"][k, m] = stale_near[m] or stale(mu.getGeometryPath().getCurrentPath(state),
                                                        state)
        res["failed"][k] = failed
        states.append(np.concatenate([q_all[k][cols], qd]))
        inputs.append(row)
    res["replay"] = replay
    return np.array(states), np.array(inputs), res


def split_residual(muscle, state):
    """(|ℓ̇_T − share · ℓ̇_MT| / v_max, share) at OpenSim's current state of a Thelen muscle, with
    OpenSim's own initialisation rule (Thelen2003Muscle::initMuscleState): share =
    K_M' / (K_M' + K_T), K_M' = ∂F_AT/∂l · cos α, and all of ℓ̇_MT to a slack tendon."""
    v_mt = muscle.getLengtheningSpeed(state)
    share = 1.0
    if muscle.getTendonLength(state) <= muscle.getTendonSlackLength():
        rule = v_mt
    else:
        k_m = muscle.getFiberStiffnessAlongTendon(state)  # ∂F_AT/∂l_AT
        k_t = muscle.getTendonStiffness(state)
        l, c = muscle.getFiberLength(state), muscle.getCosPennationAngle(state)
        h = muscle.getOptimalFiberLength() * np.sin(muscle.getPennationAngleAtOptimalFiberLength())
        dcos = h * h / (l ** 3 * c) if c < 1 else 0.0
        k_m = k_m * (c + l * dcos) * c  # ∂F_AT/∂l · cos α
        share = k_m / (k_m + k_t)
        rule = share * v_mt
    v_max = muscle.getMaxContractionVelocity() * muscle.getOptimalFiberLength()
    return abs(muscle.getTendonVelocity(state) - rule) / v_max, share


def thelen_class(sampler, replay, m, musculo_fiber_length, os_solved, stats):
    """Why a Thelen muscle's equilibrium differs, judged by OpenSim at both answers: 'lagged'
    (OpenSim's state breaks its own split rule, musculo's keeps it), 'other_root' (both keep
    it: the rule has two fixed points), 'gave_up' (OpenSim found none; musculo's state keeps
    the rule, or the rule's share there lies outside [−1, 1], where musculo clamps it), or
    None (musculo's state breaks the rule)."""
    model, state = sampler.model, sampler.state
    full_q, full_qd, act = replay
    sampler.set(full_q)
    for i in range(len(sampler.names)):
        sampler.coords.get(i).setSpeedValue(state, full_qd[i])
    muscles = model.getMuscles()
    for j in range(muscles.getSize()):
        muscles.get(j).setActivation(state, act[j])
    muscle = osim.ActivationFiberLengthMuscle.safeDownCast(muscles.get(m))
    model.realizeVelocity(state)
    r_os = None
    if os_solved:
        muscle.computeEquilibrium(state)
        model.realizeDynamics(state)
        r_os, _ = split_residual(muscle, state)
    muscle.setFiberLength(state, float(musculo_fiber_length))
    model.realizeDynamics(state)
    r_mu, share = split_residual(muscle, state)
    stats["last_rule"] = (f"{r_mu:.1e} v_max (tendon {muscle.getTendonLength(state):.9f} m, "
                          f"slack {muscle.getTendonSlackLength():.9f} m, share {share:.3g}, "
                          f"force {muscle.getTendonForce(state):.3g} N)")
    stats["worst_rule"] = max(stats["worst_rule"], r_mu)
    if r_os is None and r_mu > RULE_TOL and not -1.0 <= share <= 1.0:
        # No fixed point with the tendon's share of ℓ̇_MT in [−1, 1]: OpenSim's iteration
        # gives up, musculo returns the fixed point with the share clamped to [−1, 1].
        stats["gave_up"] += 1
        return "gave_up"
    if r_os is None and r_mu <= GAVE_UP_RULE_TOL:
        # OpenSim threw after its 20 iterations; no reference value. musculo's state balances
        # the forces (fiber velocity from the balance) and keeps the rule to this tolerance.
        stats["gave_up"] += 1
        return "gave_up"
    if r_mu > RULE_TOL:
        return None
    kind = "gave_up" if r_os is None else ("lagged" if r_os > RULE_TOL else "other_root")
    stats[kind] += 1
    return kind


def compare_model(label, path, n, work, self_test):
    model = osim.Model(path)
    if model.getMuscles().getSize() == 0:
        return None, "no muscles"
    sampler = Sampler(model)
    folder = ov.fresh_dir(os.path.join(work, label))
    names, err = ov.example_names(EXAMPLE, path, folder, "coordinates", "muscles")
    if names is None:
        return None, "musculo refused it: " + err
    q_names, muscle_names = names
    muscles = model.getMuscles()
    os_names = [muscles.get(m).getName() for m in range(muscles.getSize())]
    if os_names != muscle_names:
        return None, "musculo's muscles are not OpenSim's (names or order)"
    cols = [sampler.names.index(c) for c in q_names]
    locked = np.array([sampler.coords.get(c).getLocked(sampler.state) for c in cols])
    rng = np.random.default_rng(2)
    states, inputs, res = opensim_side(sampler, cols, locked, n, rng, len(os_names))
    if self_test:
        ours = {"length": inputs[:, :, 1], "speed": inputs[:, :, 2],
                "fiber_length": res["fiber_length"], "tendon_force": res["tendon_force"],
                "status": np.where(res["failed"] > 0, 2.0, 0.0),
                "at_fiber_tendon_force": res["tendon_force"],
                "at_fiber_fiber_velocity": res["fiber_velocity"],
                "at_fiber_active_fiber_force": res["active_fiber_force"]}
    else:
        sp, ip, op = (os.path.join(folder, f) for f in ("states.npy", "inputs.npy", "musculo.npz"))
        np.save(sp, states)
        np.save(ip, inputs)
        proc = subprocess.run([EXAMPLE, path, sp, ip, op], capture_output=True, text=True)
        if proc.returncode != 0:
            return None, "musculo refused it: " + proc.stderr.strip().splitlines()[-1]
        ours = dict(np.load(op))
    nq = len(cols)
    qd_l1 = np.abs(states[:, nq:]).sum(axis=1)
    wrapped = np.array([muscles.get(m).getGeometryPath().getWrapSet().getSize() > 0
                        for m in range(len(os_names))])
    kinds = sorted({muscles.get(m).getConcreteClassName() for m in range(len(os_names))})
    f_max = np.array([muscles.get(m).getMaxIsometricForce() for m in range(len(os_names))])
    l_opt = np.array([muscles.get(m).getOptimalFiberLength() for m in range(len(os_names))])
    rigid = np.array([muscles.get(m).get_ignore_tendon_compliance()
                      for m in range(len(os_names))])
    thelen = np.array([muscles.get(m).getConcreteClassName() == "Thelen2003Muscle"
                       for m in range(len(os_names))])
    damped_degroote = np.array([
        muscles.get(m).getConcreteClassName() == "DeGrooteFregly2016Muscle"
        and not rigid[m]
        and osim.DeGrooteFregly2016Muscle.safeDownCast(muscles.get(m)).get_fiber_damping() > 0
        for m in range(len(os_names))])
    stats = dict(muscles=len(os_names), wrapped=int(wrapped.sum()), kinds=kinds,
                 rigid=int(rigid.sum()), stale=0, rough=0, fails=[], both_failed=0,
                 lagged=0, other_root=0, gave_up=0, worst_rule=0.0,
                 undamped_velocity=0, near_singular=0, negative_projection=0)
    worst = {k: (0.0, None) for k in ("speed_plain", "speed_wrapped", "os_speed", "force",
                                      "fiber", "at_force", "at_velocity", "at_active")}

    def note(key, value, where):
        if value > worst[key][0]:
            worst[key] = (value, where)

    for k in range(n):
        for m in range(len(os_names)):
            where = f"{os_names[m]} at state {k}"
            v_os, v_mu = inputs[k, m, 2], ours["speed"][k, m]
            dv = abs(v_mu - v_os)
            if wrapped[m]:
                if res["stale"][k, m] > 0 and not self_test:
                    stats["stale"] += 1
                elif res["rough"][k, m] > 0 and not self_test:
                    stats["rough"] += 1
                else:
                    v_fd = res["speed_fd"][k, m] if not self_test else v_mu
                    dv = abs(v_mu - v_fd)
                    tol = SPEED_TOL + ARM_TOL * qd_l1[k]
                    if dv > tol:
                        slope, _ = steepest(sampler, muscles.get(m), res["replay"][k][0])
                        if slope > NEAR_SINGULAR:
                            stats["near_singular"] += 1
                            continue
                    note("speed_wrapped", dv / max(qd_l1[k], 1e-300), where)
                    note("os_speed", abs(v_os - v_fd) / max(qd_l1[k], 1e-300), where)
                    if dv > tol:
                        stats["fails"].append(f"ℓ̇ {where}: {v_mu:.9f} vs {v_fd:.9f} m/s, "
                                              f"OpenSim's difference quotient (tolerance {tol:.1e})")
            else:
                note("speed_plain", dv, where)
                if dv > SPEED_TOL * (1 + abs(v_os)):
                    stats["fails"].append(f"ℓ̇ {where}: {v_mu:.12f} vs {v_os:.12f} m/s")
            os_failed = res["failed"][k, m] > 0
            mu_failed = ours["status"][k, m] >= 2
            if os_failed or mu_failed:
                if os_failed and mu_failed:
                    stats["both_failed"] += 1
                elif os_failed and thelen[m] and not self_test:
                    kind = thelen_class(sampler, res["replay"][k], m, ours["fiber_length"][k, m],
                                        False, stats)
                    if kind != "gave_up":
                        stats["fails"].append(f"equilibrium {where}: OpenSim found none and "
                                              f"musculo's state breaks OpenSim's split rule "
                                              f"by {stats['last_rule']}")
                elif mu_failed and res["fiber_along_tendon"][k, m] < 0 and not self_test:
                    # ℓ_MT shorter than any tendon length with force ≥ 0: no fiber length is
                    # admissible. OpenSim's De Groote–Fregly bisection in tendon force still
                    # returns one, with the fiber's projection on the tendon negative (its
                    # fiber length √(proj² + width²) hides the sign).
                    stats["negative_projection"] += 1
                else:
                    who = "OpenSim" if os_failed else "musculo"
                    stats["fails"].append(f"equilibrium {where}: only {who} found none")
                continue
            v_max = muscles.get(m).getMaxContractionVelocity() * l_opt[m]
            checks = (
                    ("at_force", "tendon_force", f_max[m], AT_FIBER_TOL),
                    ("at_active", "active_fiber_force", f_max[m], AT_FIBER_TOL),
                    ("at_velocity", "fiber_velocity", v_max, AT_FIBER_VELOCITY_TOL))
            if damped_degroote[m]:
                # OpenSim 4.6's explicit De Groote–Fregly mode inverts f_V without the damping
                # term (calcFiberVelocityInfoHelper), so its fiber velocity is not the one
                # that balances the forces it applies; only the tendon force is compared.
                stats["undamped_velocity"] += 1
                checks = checks[:1]
            for key, name, scale, tol in checks:
                d = abs(ours["at_fiber_" + name][k, m] - res[name][k, m]) / scale
                note(key, d, where)
                if d > tol:
                    stats["fails"].append(
                        f"{name} at OpenSim's fiber length, {where}: "
                        f"{ours['at_fiber_' + name][k, m]:.9g} vs {res[name][k, m]:.9g}")
            df = abs(ours["tendon_force"][k, m] - res["tendon_force"][k, m]) / f_max[m]
            if df > FORCE_TOL and thelen[m] and not rigid[m] and not self_test:
                kind = thelen_class(sampler, res["replay"][k], m, ours["fiber_length"][k, m],
                                    True, stats)
                if kind in ("lagged", "other_root"):
                    continue
            note("force", df, where)
            if df > FORCE_TOL:
                stats["fails"].append(
                    f"tendon force {where}: {ours['tendon_force'][k, m]:.6f} vs "
                    f"{res['tendon_force'][k, m]:.6f} N ({df:.1e} F_max)")
            taut = res["tendon_force"][k, m] > 1e-6 * f_max[m] or rigid[m]
            if taut:
                dl = abs(ours["fiber_length"][k, m] - res["fiber_length"][k, m]) / l_opt[m]
                note("fiber", dl, where)
                if dl > FIBER_TOL:
                    stats["fails"].append(
                        f"fiber length {where}: {ours['fiber_length'][k, m]:.9f} vs "
                        f"{res['fiber_length'][k, m]:.9f} m ({dl:.1e} l_opt)")
    stats["worst"] = worst
    return stats, None


def isolated(tag, path, args, work):
    """compare_model in a fresh Python process. A model file's `<defaults>` element replaces
    OpenSim's process-wide default objects: a model loaded later in the same process takes
    those values for every property its own file omits (seen here: the default model's Thelen
    muscles, loaded after Estimating_Joint_Reaction_Loads/subject01_simbody_adjusted_StaticOp
    .osim, got that file's tendon and force-length defaults)."""
    out = os.path.join(work, tag + ".json")
    cmd = [sys.executable, os.path.abspath(__file__), "--states", str(args.states),
           "--one", tag, path, out] + (["--self-test"] if args.self_test else [])
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0 or not os.path.exists(out):
        return None, "the comparison crashed: " + (proc.stderr.strip().splitlines() or ["?"])[-1]
    with open(out) as f:
        result = json.load(f)
    return result["stats"], result["why"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--states", type=int, default=40)
    ap.add_argument("--model", action="append", default=[])
    ap.add_argument("--self-test", action="store_true")
    ap.add_argument("--opensim-only", action="store_true")
    ap.add_argument("--one", nargs=3, metavar=("LABEL", "PATH", "OUT_JSON"),
                    help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        label, path, out = args.one
        try:
            stats, why = compare_model(label, path, args.states, os.path.dirname(out),
                                       args.self_test)
        except RuntimeError as e:
            stats, why = None, f"OpenSim 4.6 refused it: {str(e).splitlines()[0][:120]}"
        with open(out, "w") as f:
            json.dump({"stats": stats, "why": why}, f,
                      default=lambda o: o.item() if hasattr(o, "item") else str(o))
        return 0
    if args.opensim_only:
        print("muscles: nothing to do with --opensim-only")
        return 0
    work = os.path.join(ov.WORK, "muscles")
    os.makedirs(work, exist_ok=True)
    if args.model:
        todo = [(os.path.basename(p), p) for p in args.model]
    else:
        todo = ov.all_models(work) + degroote_copies(work)
    rows, fails, skipped = [], [], []
    for label, path in todo:
        tag = label.replace("/", "_").replace(" ", "_").replace(",", "")
        stats, why = isolated(tag, path, args, work)
        if stats is None and why.startswith("the comparison crashed"):
            fails.append((label, why))
        if stats is None:
            skipped.append((label, why))
            continue
        w = stats["worst"]
        cell = (lambda key, unit: f"{w[key][0]:.1e}{unit} ({w[key][1]})" if w[key][1] else "-")
        rows.append([label, ", ".join(k.replace("Muscle", "") for k in stats["kinds"]),
                     f"{stats['muscles']} ({stats['wrapped']}, {stats['rigid']})",
                     cell("speed_plain", " m/s"), cell("speed_wrapped", " m"),
                     cell("os_speed", " m"), f"{stats['stale']} / {stats['rough']} / {stats['near_singular']}",
                     cell("at_force", ""),
                     cell("at_velocity", "") if not stats["undamped_velocity"]
                     else f"not compared ({stats['undamped_velocity']}, damped De Groote)",
                     cell("at_active", ""),
                     cell("force", ""), cell("fiber", ""),
                     f"{stats['lagged']} / {stats['other_root']} / {stats['gave_up']}",
                     f"{stats['both_failed']} / {stats['negative_projection']}",
                     len(stats["fails"])])
        fails += [(label, f) for f in stats["fails"]]
    print(f"\nLengthening speeds and muscle forces at equilibrium, musculo vs OpenSim 4.6: "
          f"{args.states} random states per model (seed 2). ℓ̇ plain: |Δℓ̇| (tolerance "
          f"{SPEED_TOL:g} m/s + {SPEED_TOL:g} relative); ℓ̇ wrapped: |Δℓ̇| / Σ|q̇| (tolerance "
          f"{ARM_TOL:g} m, OpenSim's stale paths not judged); tendon force in F_max (tolerance "
          f"{FORCE_TOL:g}); fiber length in optimal fiber lengths, taut tendons (tolerance "
          f"{FIBER_TOL:g})")
    ov.print_table(["model", "classes", "muscles (wrapped, rigid tendon)", "ℓ̇ plain (worst at)",
                    "ℓ̇ wrapped vs OpenSim's difference (worst at)",
                    "OpenSim's own ℓ̇ vs its difference", "stale / not smooth / near singular",
                    "at OpenSim's fiber length: "
                    "tendon force", "fiber velocity", "active fiber force",
                    "equilibrium: tendon force (worst at)",
                    "fiber length (worst at)",
                    "Thelen: OpenSim lagged / other root / gave up", "no equilibrium: both / OpenSim's fiber projection < 0",
                    "failures"], rows)
    for label, why in skipped:
        print(f"skipped {label}: {why}")
    for label, f in fails[:int(os.environ.get("MUSCULO_SHOW_FAILS", "40"))]:
        print(f"FAIL {label}: {f}")
    if fails:
        print(f"muscles: {len(fails)} values outside tolerance")
        return 1
    print("muscles: pass")
    return 0


if __name__ == "__main__":
    sys.exit(main())
