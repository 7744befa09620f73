"""musculo's per-call speed side by side with Pinocchio's on the MJCF that musculo exports.

For each model (gait2392, Rajagopal2016, models/musculo_fullbody.osim):
1. `musculo export-mjcf` writes target/pinocchio/<name>.xml (one hinge or slide per movable
   transform axis, so Pinocchio's coordinates are musculo's full coordinates θ);
2. examples/dynamics_timing.rs draws the random states (independent coordinates q, q̇, q̈),
   times musculo on them and writes them in full coordinates (θ, θ̇, θ̈) with musculo's full
   mass matrix and inverse dynamics at the first one;
3. Pinocchio reads the MJCF (pinocchio.buildModelFromMJCF), with gravity set to the file's
   <option gravity> (its reader keeps −9.81 z); its M, τ, ∂τ/∂θ and ∂τ/∂θ̇ (against central differences of its
   rnea: its computeRNEADerivatives is wrong on composite joints) at the first state and its total mass
   are checked against musculo's;
4. Pinocchio is timed on the same θ states: from C++ (validation/pinocchio/speed.cpp, built by
   run.sh against the `pin` wheel's headers and libraries), and from Python, where the binding
   overhead is measured by a trivial binding call (pin.isNormalized(model, q)) in the same loop
   and subtracted.

Every figure is a per-call median over K batches (default 41) of one call per state over B
states (default 100), each batch's time divided by B. The table goes to stdout (markdown); all
figures, min and max included, to target/pinocchio/speed.json.

Usage: speed.py [--count B] [--batches K] [--no-cpp]
(run by validation/pinocchio/run.sh, which builds target/release/musculo, the example and the
C++ program first)
Exit status 1 when a model's M, τ or total mass disagrees with musculo's.
"""

import argparse
import json
import os
import platform
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
REFERENCE = os.environ.get("MUSCULO_REFERENCE", os.path.join(ROOT, "..", "shared", "reference"))
OSIM = os.path.join(REFERENCE, "opensim-models", "Models")
MODELS = [
    ("gait2392", os.path.join(OSIM, "Gait2392_Simbody", "gait2392_thelen2003muscle.osim")),
    ("Rajagopal2016", os.path.join(OSIM, "Rajagopal", "Rajagopal2016.osim")),
    ("musculo_fullbody", os.path.join(ROOT, "models", "musculo_fullbody.osim")),
]
WORK = os.path.join(ROOT, "target", "pinocchio")
MUSCULO = os.path.join(ROOT, "target", "release", "musculo")
EXAMPLE = os.path.join(ROOT, "target", "release", "examples", "dynamics_timing")
CPP = os.path.join(WORK, "speed_cpp")

# Relative tolerance of the correctness check (both are exact O(n) / O(n²) recursions in double).
TOLERANCE = 1e-9

# (row label, musculo's key, Pinocchio's function, musculo uses independent coordinates)
ROWS = [
    ("M = crba", "M", "crba", True),
    ("M, full θ", "M_full", "crba", False),
    ("bias = nonLinearEffects", "bias", "nonLinearEffects", True),
    ("bias, full θ", "bias_full", "nonLinearEffects", False),
    ("ID = rnea", "ID", "rnea", True),
    ("ID, full θ", "ID_full", "rnea", False),
    ("ID derivatives", "ID_derivatives_full", "computeRNEADerivatives", False),
    ("ID derivatives, q", "ID_derivatives", "computeRNEADerivatives", True),
    ("ID VJP uᵀ∂τ (loss gradient)", "ID_vjp", "computeRNEADerivatives", True),
]


def run(cmd):
    """Runs `cmd`, returns its stdout; exits with its stderr when it fails."""
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"speed.py: {' '.join(cmd)} failed:\n{p.stderr}")
    return p.stdout


def mjcf_gravity_and_joints(path):
    """The file's <option gravity> and its <joint> names in document order (Pinocchio's order)."""
    root = ET.parse(path).getroot()
    opt = root.find("option")
    g = [0.0, 0.0, -9.81]
    if opt is not None and opt.get("gravity"):
        g = [float(x) for x in opt.get("gravity").split()]
    joints = root.find("worldbody").iter("joint")
    return np.array(g), [j.get("name") for j in joints]


def time_calls(fn, args, batches):
    """Per-call µs {median, min, max} of `batches` batches of fn(*a) for a in args."""
    for a in args:
        fn(*a)
    per_call = []
    for _ in range(batches):
        t0 = time.perf_counter()
        for a in args:
            fn(*a)
        per_call.append((time.perf_counter() - t0) * 1e6 / len(args))
    per_call.sort()
    return {"median": per_call[len(per_call) // 2], "min": per_call[0], "max": per_call[-1]}


def split_composites(model):
    """The same tree with each JointModelComposite (the several axes of one MJCF body) replaced
    by the chain of its simple joints joined by massless links, in the same coordinate order:
    Pinocchio's derivative recursions are exact on simple joints."""
    out = pin.Model()
    out.gravity = model.gravity
    new_id = {0: 0}
    for i in range(1, model.njoints):
        joint, parent = model.joints[i], new_id[model.parents[i]]
        if joint.shortname() == "JointModelComposite":
            c = joint.extract()
            placement = model.jointPlacements[i]
            for k in range(c.njoints):
                # the composite's transform is Π_k jointPlacements[k] · M_k(q_k)
                parent = out.addJoint(parent, c.joints[k], placement * c.jointPlacements[k],
                                      f"{model.names[i]}#{k}")
                placement = pin.SE3.Identity()
        else:
            parent = out.addJoint(parent, joint, model.jointPlacements[i], model.names[i])
        out.appendBodyToJoint(parent, model.inertias[i], pin.SE3.Identity())
        new_id[i] = parent
    return out


def symmetric(upper):
    """Pinocchio's crba fills the upper triangle only."""
    return np.triu(upper) + np.triu(upper, 1).T


def one_model(name, osim, count, batches, cpp):
    xml = os.path.join(WORK, name + ".xml")
    full = os.path.join(WORK, name + "_full.npz")
    run([MUSCULO, "export-mjcf", osim, "-o", xml])
    ours = json.loads(run([EXAMPLE, osim, "--count", str(count), "--batches", str(batches),
                           "--full", full]))
    states = np.load(full)

    model = pin.buildModelFromMJCF(xml)
    gravity, joints = mjcf_gravity_and_joints(xml)
    model.gravity.linear = gravity
    if model.nq != model.nv or model.nv != len(joints) or model.nv != ours["n_full"]:
        sys.exit(f"{name}: Pinocchio nq {model.nq}, nv {model.nv}; MJCF joints {len(joints)}; "
                 f"musculo full coordinates {ours['n_full']}")
    perm = [ours["full_names"].index(j) for j in joints]
    q = np.ascontiguousarray(states["theta"][:, perm])
    v = np.ascontiguousarray(states["theta_dot"][:, perm])
    a = np.ascontiguousarray(states["theta_ddot"][:, perm])

    # Correctness at the first state (not speed).
    data = model.createData()
    m_ref = states["M_full"][np.ix_(perm, perm)]
    tau_ref = states["tau_full"][perm]
    m_err = np.abs(symmetric(pin.crba(model, data, q[0])) - m_ref).max() / np.abs(m_ref).max()
    tau = pin.rnea(model, data, q[0], v[0], a[0])
    tau_err = np.abs(tau - tau_ref).max() / np.abs(tau_ref).max()
    # ∂τ/∂θ, ∂τ/∂θ̇: against Pinocchio's computeRNEADerivatives and against central differences
    # of Pinocchio's rnea (h = 1e-6). On this MJCF Pinocchio builds JointModelComposite joints
    # (several axes per body), and its derivatives there disagree with its own rnea; the
    # differences of its rnea are the reference.
    dq, dv, _ = pin.computeRNEADerivatives(model, data, q[0], v[0], a[0])
    dq, dv = np.array(dq), np.array(dv)
    h = 1e-6
    fq, fv = np.zeros_like(dq), np.zeros_like(dv)
    for j in range(model.nv):
        e = np.zeros(model.nv)
        e[j] = h
        fq[:, j] = (pin.rnea(model, data, q[0] + e, v[0], a[0])
                    - pin.rnea(model, data, q[0] - e, v[0], a[0])) / (2 * h)
        fv[:, j] = (pin.rnea(model, data, q[0], v[0] + e, a[0])
                    - pin.rnea(model, data, q[0], v[0] - e, a[0])) / (2 * h)
    d_err, pin_err = {}, {}
    for key, theirs, fd in (("dtau_dtheta", dq, fq), ("dtau_dtheta_dot", dv, fv)):
        ref = states[key][np.ix_(perm, perm)]
        scale = np.abs(ref).max()
        d_err[key] = float(np.abs(fd - ref).max() / scale)
        pin_err[key] = (float(np.abs(theirs - ref).max() / scale),
                        float(np.abs(theirs - fd).max() / np.abs(fd).max()))
    # the same on simple joints: Pinocchio's computeRNEADerivatives against musculo's
    split = split_composites(model)
    sdata = split.createData()
    split_tau_err = float(np.abs(pin.rnea(split, sdata, q[0], v[0], a[0]) - tau_ref).max()
                          / np.abs(tau_ref).max())
    sq, sv, _ = pin.computeRNEADerivatives(split, sdata, q[0], v[0], a[0])
    split_err = {}
    for key, theirs in (("dtau_dtheta", np.array(sq)), ("dtau_dtheta_dot", np.array(sv))):
        ref = states[key][np.ix_(perm, perm)]
        split_err[key] = float(np.abs(theirs - ref).max() / np.abs(ref).max())
    mass = sum(inertia.mass for inertia in model.inertias)
    check = {"M_rel_err": m_err, "tau_rel_err": tau_err, "mass_pinocchio": mass,
             "mass_musculo": ours["total_mass"], "dtau_dq_rel_err": d_err["dtau_dtheta"],
             "dtau_dv_rel_err": d_err["dtau_dtheta_dot"],
             "pinocchio_derivatives_vs_musculo_and_own_differences": pin_err,
             "split_tau_rel_err": split_tau_err, "split_joints": split.njoints - 1,
             "pinocchio_simple_joint_derivatives_vs_musculo": split_err}
    # finite differences hold to about 1e-8 of the largest entry
    check["ok"] = bool(m_err < TOLERANCE and tau_err < TOLERANCE
                       and max(d_err.values()) < 1e-6
                       and split_tau_err < TOLERANCE and max(split_err.values()) < TOLERANCE
                       and abs(mass - ours["total_mass"]) < TOLERANCE * mass)

    # Python, the same states; the loop and the call through the binding as a trivial call.
    qs = list(q)
    qv = list(zip(q, v))
    qva = list(zip(q, v, a))
    fns = {
        "crba": (lambda x: pin.crba(model, data, x), [(x,) for x in qs]),
        "nonLinearEffects": (lambda x, y: pin.nonLinearEffects(model, data, x, y), qv),
        "rnea": (lambda x, y, z: pin.rnea(model, data, x, y, z), qva),
        "computeRNEADerivatives":
            (lambda x, y, z: pin.computeRNEADerivatives(model, data, x, y, z), qva),
        "overhead": (lambda x: pin.isNormalized(model, x), [(x,) for x in qs]),
        "computeRNEADerivatives_split":
            (lambda x, y, z: pin.computeRNEADerivatives(split, sdata, x, y, z), qva),
    }
    python = {k: time_calls(f, args, batches) for k, (f, args) in fns.items()}

    if cpp:
        states_bin = os.path.join(WORK, name + "_states.bin")
        np.ascontiguousarray(np.stack([q, v, a], axis=1)).tofile(states_bin)
        cpp = json.loads(run([CPP, xml, states_bin, str(len(q)), str(batches),
                              *(repr(float(x)) for x in gravity)]))
    else:
        cpp = None
    return {"name": name, "osim": osim, "nq": ours["nq"], "nv": model.nv,
            "pinocchio_joints": model.njoints - 1, "check": check, "musculo": ours,
            "python": python, "cpp": cpp}


def fmt(x):
    return "—" if x is None else f"{x:.2f}"


def table(results):
    cpp = all(r["cpp"] for r in results)
    head = ["model", "nq (musculo / Pinocchio)", "quantity", "musculo µs",
            "Pinocchio µs" + (" (C++)" if cpp else " (Python − overhead)"),
            "ratio musculo/Pinocchio"]
    if cpp:
        head.append("Pinocchio C++ unrolled µs")
    head += ["Pinocchio Python raw µs", "Python − overhead µs"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in results:
        over = r["python"]["overhead"]["median"]
        for label, key, fn, independent in ROWS:
            ours = r["musculo"]["per_call_us"][key]["median"] if key else None
            raw = r["python"][fn]["median"]
            theirs = r["cpp"]["mjcf"][fn]["median"] if cpp else raw - over
            n = f"{r['nq'] if independent else r['nv']} / {r['nv']}"
            row = [r["name"], n, label, fmt(ours), fmt(theirs),
                   fmt(ours / theirs if ours is not None else None)]
            if cpp:
                row.append(fmt(r["cpp"]["unrolled"][fn]["median"]))
            row += [fmt(raw), fmt(raw - over)]
            lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--count", type=int, default=100, help="random states (default 100)")
    parser.add_argument("--batches", type=int, default=41, help="batches (default 41)")
    parser.add_argument("--no-cpp", action="store_true",
                        help="time Pinocchio from Python only (also when speed_cpp is missing)")
    args = parser.parse_args()
    cpp = not args.no_cpp and os.path.exists(CPP)
    for path in (MUSCULO, EXAMPLE):
        if not os.path.exists(path):
            sys.exit(f"speed.py: {path} is missing; run validation/pinocchio/run.sh")
    os.makedirs(WORK, exist_ok=True)
    results = [one_model(name, osim, args.count, args.batches, cpp) for name, osim in MODELS]

    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo")
                if line.startswith("model name")), platform.processor())
    print(f"musculo vs Pinocchio {pin.__version__} (`pin` wheel), per-call medians over "
          f"{args.batches} batches of {args.count} random states; {cpu}, {os.cpu_count()} cores")
    how = ("from C++ (speed_cpp, built against the wheel) and from Python" if cpp
           else "from Python only (no C++ program)")
    print(f"Pinocchio timed {how}; Python overhead (loop + pin.isNormalized(model, q)): "
          + ", ".join(f"{r['name']} {r['python']['overhead']['median']:.2f} µs" for r in results))
    print()
    print(table(results))
    print()
    status = 0
    for r in results:
        c = r["check"]
        print(f"check {r['name']}: M at state 0 max rel. diff {c['M_rel_err']:.1e}, τ (gravity "
              f"included) {c['tau_rel_err']:.1e}, ∂τ/∂θ {c['dtau_dq_rel_err']:.1e}, ∂τ/∂θ̇ "
              f"{c['dtau_dv_rel_err']:.1e} (vs differences of Pinocchio's rnea; Pinocchio's "
              "computeRNEADerivatives on its composite joints is off musculo by "
              + ", ".join(f"{x[0]:.1e}" for x in c["pinocchio_derivatives_vs_musculo_and_own_differences"].values())
              + " and off its own differences by "
              + ", ".join(f"{x[1]:.1e}" for x in c["pinocchio_derivatives_vs_musculo_and_own_differences"].values())
              + f"; with the composites split into {c['split_joints']} simple joints Pinocchio's "
              f"τ is {c['split_tau_rel_err']:.1e} and its computeRNEADerivatives "
              + ", ".join(f"{x:.1e}" for x in c["pinocchio_simple_joint_derivatives_vs_musculo"].values())
              + f" from musculo's, {r['python']['computeRNEADerivatives_split']['median'] - r['python']['overhead']['median']:.1f} µs per call from Python less overhead against "
              f"{r['python']['computeRNEADerivatives']['median'] - r['python']['overhead']['median']:.1f} µs on the composites); total mass musculo {c['mass_musculo']:.4f} kg, "
              f"Pinocchio {c['mass_pinocchio']:.4f} kg; Pinocchio joints {r['pinocchio_joints']} "
              f"(composite per body) — {'ok' if c['ok'] else 'DIFFERENT'}")
        status |= not c["ok"]
    with open(os.path.join(WORK, "speed.json"), "w") as f:
        json.dump(results, f, indent=1)
    sys.exit(status)


if __name__ == "__main__":
    main()
