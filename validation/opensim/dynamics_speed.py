"""Per-call speed of the mass matrix and inverse dynamics: OpenSim 4.6 (Simbody, through its
Python bindings) beside musculo, same machine, same run, same states
(validation/opensim/README.md, "Dynamics per call").

For gait2392, Rajagopal2016 and the default model, B random states (seed 1; the independent
coordinates uniform over their ranges, q̇ and q̈ normal as in dynamics_compare.py, couplers
followed):
- musculo: examples/dynamics_timing.rs on the same states (`dynamics::crba(q)`, M = Φᵀ M_θ Φ,
  and `dynamics::rnea(q, q̇, q̈)`, each from q: kinematics included);
- OpenSim, every force element disabled as for its ID tool (gravity only, like musculo):
  * `SimbodyMatterSubsystem::calcM(state, M)` and `InverseDynamicsSolver::solve(state, u̇)` at a
    state already realized to velocity: Simbody's cheapest call, its kinematics cached;
  * the same "from q": `state.setQ`, `state.setU`, `realizeVelocity`, then the call — what musculo's
    figure includes;
  * the Python binding overhead: a trivial bound call (`state.getNU()`) timed the same way, and
    subtracted from the realized-state figures (the "C++" column estimates the call without
    Python). OpenSim's C++ API is not reachable without Python from the PyPI wheel (it ships no
    headers).

Every figure is a per-call median over K batches of R calls at each of the B states (the state
set before each state's R calls, untimed except in "from q", which sets it on every call).
Prints a markdown table; writes all figures to target/opensim/dynamics_speed.json.

Usage: dynamics_speed.py [--count B] [--batches K] [--repeat R]
(run by validation/opensim/run.sh; with its --self-test or --opensim-only it does nothing)
"""

import argparse
import json
import os
import platform
import subprocess
import sys
import time

import numpy as np

import osimval as ov
from osimval import Sampler

osim = ov.osim
ov.quiet_opensim()

EXAMPLE = os.path.join(ov.REPO, "target", "release", "examples", "dynamics_timing")
OSIM = os.path.join(ov.REFERENCE, "opensim-models", "Models")
MODELS = [
    ("gait2392", os.path.join(OSIM, "Gait2392_Simbody", "gait2392_thelen2003muscle.osim")),
    ("Rajagopal2016", os.path.join(OSIM, "Rajagopal", "Rajagopal2016.osim")),
    ("musculo_fullbody", os.path.join(ov.REPO, "models", "musculo_fullbody.osim")),
]
WORK = os.path.join(ov.REPO, "target", "opensim")


def simbody_states(sampler, umap, q_names, states):
    """Per state: Simbody's (Q, U, U̇) as osim.Vector, from musculo's (q, q̇, q̈) rows."""
    model, state = sampler.model, sampler.state
    n = len(q_names)
    cols = [sampler.names.index(c) for c in q_names]
    q_default = np.array([sampler.coords.get(i).getDefaultValue()
                          for i in range(sampler.coords.getSize())])
    out = []
    for row in states:
        full_q = q_default.copy()
        full_q[cols] = row[:n]
        full_q = sampler.complete(full_q)
        full_qd = np.zeros(len(full_q))
        full_qdd = np.zeros(len(full_q))
        full_qd[cols] = row[n:2 * n]
        full_qdd[cols] = row[2 * n:]
        for dep, first, second in ov.coupler_derivatives(sampler, full_q):
            full_qd[dep] = sum(d * full_qd[i] for i, d in first)
            full_qdd[dep] = (sum(d * full_qdd[i] for i, d in first)
                             + sum(v * full_qd[i] * full_qd[j] for (i, j), v in second.items()))
        sampler.set(full_q)
        for i in range(sampler.coords.getSize()):
            sampler.coords.get(i).setSpeedValue(state, full_qd[i])
        model.realizeVelocity(state)
        udot = np.zeros(state.getNU())
        for i in range(len(full_q)):
            udot[umap[i]] = full_qdd[i]
        out.append((osim.Vector(state.getQ()), osim.Vector(state.getU()),
                    osim.Vector.createFromMat(udot)))
    return out


def per_call(batches, states, repeat, setup, call):
    """Median, min, max per-call µs over `batches` batches of `repeat` calls per state."""
    for s in states:
        setup(s)
        call(s)
    times = []
    for _ in range(batches):
        total = 0.0
        for s in states:
            setup(s)
            t = time.perf_counter()
            for _ in range(repeat):
                call(s)
            total += time.perf_counter() - t
        times.append(total * 1e6 / (len(states) * repeat))
    times.sort()
    return {"median": times[len(times) // 2], "min": times[0], "max": times[-1]}


def time_model(label, path, count, batches, repeat):
    model = osim.Model(path)
    forces = model.updForceSet()
    for i in range(forces.getSize()):
        forces.get(i).set_appliesForce(False)
    sampler = Sampler(model)
    # the mobility (index in U) of each coordinate's speed
    state = sampler.state
    umap = []
    for i in range(sampler.coords.getSize()):
        state.updU().setToZero()
        sampler.coords.get(i).setSpeedValue(state, 1.0)
        umap.append(int(np.flatnonzero(state.getU().to_numpy())[0]))
    state.updU().setToZero()
    folder = ov.fresh_dir(os.path.join(WORK, "dynamics_speed", label))
    names, err = ov.example_names(os.path.join(ov.REPO, "target", "release", "examples",
                                               "opensim_dynamics"), path, folder, "coordinates")
    if names is None:
        raise RuntimeError(f"{label}: musculo refused it: {err}")
    (q_names,) = names
    cols = [sampler.names.index(c) for c in q_names]
    rot = np.array([ov.is_rotational(sampler.coords.get(c)) for c in cols])
    locked = np.array([sampler.coords.get(c).getLocked(state) for c in cols])
    rng = np.random.default_rng(1)
    q_all = sampler.sample(count, 1)
    rows = []
    for k in range(count):
        qd = np.where(locked, 0.0, rng.normal(0, 1, len(cols)) * np.where(rot, 2.0, 0.5))
        qdd = np.where(locked, 0.0, rng.normal(0, 1, len(cols)) * np.where(rot, 10.0, 2.0))
        rows.append(np.concatenate([q_all[k][cols], qd, qdd]))
    probe = os.path.join(folder, "states.npy")
    np.save(probe, np.array(rows))

    proc = subprocess.run([EXAMPLE, path, "--states", probe, "--batches", str(batches)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"{label}: dynamics_timing failed: {proc.stderr.strip()}")
    ours = json.loads(proc.stdout)["per_call_us"]

    sim = simbody_states(sampler, umap, q_names, rows)
    matter = model.getMatterSubsystem()
    solver = osim.InverseDynamicsSolver(model)
    mu = osim.Matrix()

    def set_state(s):
        state.setQ(s[0])
        state.setU(s[1])
        model.realizeVelocity(state)

    def nothing(_):
        pass

    theirs = {
        "overhead": per_call(batches, sim, repeat, set_state, lambda s: state.getNU()),
        "M": per_call(batches, sim, repeat, set_state, lambda s: matter.calcM(state, mu)),
        "ID": per_call(batches, sim, repeat, set_state, lambda s: solver.solve(state, s[2])),
        "M_from_q": per_call(batches, sim, repeat, nothing,
                             lambda s: (set_state(s), matter.calcM(state, mu))),
        "ID_from_q": per_call(batches, sim, repeat, nothing,
                              lambda s: (set_state(s), solver.solve(state, s[2]))),
    }
    return {"nq": len(q_names), "nu": state.getNU(), "musculo": ours, "opensim": theirs}


def main():
    if any(a in ("--self-test", "--opensim-only") for a in sys.argv[1:]):
        print("dynamics_speed: timing needs both programs; skipped in this mode")
        return 0
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--count", type=int, default=50)
    ap.add_argument("--batches", type=int, default=11)
    ap.add_argument("--repeat", type=int, default=10)
    a = ap.parse_args()
    for what, p in [("the example", EXAMPLE)] + [(lbl, p) for lbl, p in MODELS]:
        ov.require(p, what)
    results = {}
    for label, path in MODELS:
        results[label] = time_model(label, path, a.count, a.batches, a.repeat)
    headers = ["model", "n (Simbody u)", "quantity", "musculo (from q)", "OpenSim from q",
               "OpenSim, realized state", "its Python overhead", "OpenSim C++ (est.)",
               "OpenSim from q / musculo", "OpenSim C++ / musculo"]
    table = []
    for label, r in results.items():
        o, m = r["opensim"], r["musculo"]
        over = o["overhead"]["median"]
        for key, name in [("M", "M (calcM / crba)"), ("ID", "ID (InverseDynamicsSolver / rnea)")]:
            ours = m[key]["median"]
            cpp = max(o[key]["median"] - over, 0.0)
            table.append([label, f"{r['nq']} ({r['nu']})", name, f"{ours:.2f} µs",
                          f"{o[key + '_from_q']['median']:.1f} µs", f"{o[key]['median']:.1f} µs",
                          f"{over:.2f} µs", f"{cpp:.1f} µs",
                          f"{o[key + '_from_q']['median'] / ours:.1f}×", f"{cpp / ours:.1f}×"])
    ov.print_table(headers, table)
    print(f"\n{platform.processor() or platform.machine()}, {os.cpu_count()} cores; per-call "
          f"medians over {a.batches} batches × {a.count} states × {a.repeat} calls")
    os.makedirs(WORK, exist_ok=True)
    with open(os.path.join(WORK, "dynamics_speed.json"), "w") as f:
        json.dump({"settings": vars(a), "models": results}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
