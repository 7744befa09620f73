"""The default model's arm muscles: musculo's musculotendon lengths against OpenSim 4.6's at
random states over the full coordinate ranges (the shoulder paths of
scripts/model_tables/shoulder_paths.py; data/model/README.md, arm).

States: N (default 100, seed 0) from osimval's Sampler: every independent unlocked
coordinate of models/musculo_fullbody.osim uniform over its whole range (the shoulders over
their thoracohumeral ranges). Muscles: the 15 arm muscles per side (the 11 shoulder-crossing
ones and TRIlat, TRImed, BRA, BRD).

A (state, muscle) pair is *unambiguous* where OpenSim's `getLength` equals its own path
re-summed: the straight distances between the ground locations of its current path points
(`getCurrentPath`), with the stored arc length (`PathWrapPoint::getWrapLength`) between two
tangent points of one wrap object, within 1e-9 m, both with the cached ground locations
OpenSim measured and with fresh ones (paths_compare.py, "stale"). The count reported is the
unambiguous pairs where |musculo - OpenSim| > 1 mm; the others are counted apart.

usage: python arm_paths_compare.py [--states N] [--model PATH] [--self-test | --opensim-only]
(exit 1 when that count > 0; --self-test takes OpenSim's lengths as musculo's, which must give
0 everywhere; --opensim-only has nothing to do)
"""

import argparse
import os
import sys

import numpy as np

import osimval as ov
from paths_compare import current_path, same_object, musculo_lengths

osim = ov.osim
ov.quiet_opensim()

TOL = 1e-3
SAME = 1e-9
ARM = ["DELT1", "DELT2", "DELT3", "PECM1", "SUPSP", "INFSP", "SUBSC", "TMAJ", "BIClong",
       "BICshort", "TRIlong", "TRIlat", "TRImed", "BRA", "BRD"]


def resummed(pts, state, which):
    """OpenSim's current path re-summed over its cached (which = 1) or fresh (2) ground
    locations, with its stored arcs between tangent points of one object."""
    total = 0.0
    for a, b in zip(pts, pts[1:]):
        if same_object(a[0], b[0]):
            total += osim.PathWrapPoint.safeDownCast(b[0]).getWrapLength(state)
        else:
            total += np.linalg.norm(a[which] - b[which])
    return total


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--states", type=int, default=100)
    ap.add_argument("--model", default=os.path.join(ov.REPO, "models", "musculo_fullbody.osim"))
    ap.add_argument("--self-test", action="store_true")
    ap.add_argument("--opensim-only", action="store_true")
    args = ap.parse_args()
    if args.opensim_only:
        print("arm_paths: nothing to do with --opensim-only (the check compares lengths)")
        return 0
    model = osim.Model(args.model)
    sampler = ov.Sampler(model)
    muscles = model.getMuscles()
    names = [m + s for s in ("_r", "_l") for m in ARM]
    q = sampler.sample(args.states, 0)
    folder = ov.fresh_dir(os.path.join(ov.WORK, "arm_paths"))
    mot = os.path.join(folder, "states.mot")
    sampler.write_mot(mot, q)
    if args.self_test:
        L_mu = np.zeros((args.states, len(names)))
        for k in range(args.states):
            sampler.set(q[k])
            L_mu[k] = [muscles.get(n).getLength(sampler.state) for n in names]
    else:
        L_mu, err = musculo_lengths(args.model, mot, os.path.join(folder, "musculo"), names)
        if L_mu is None:
            sys.exit(f"musculo refused the model: {err}")
    unambiguous, ambiguous, beyond, worst, worst_amb = 0, 0, [], (0.0, None), (0.0, None)
    for k in range(args.states):
        sampler.set(q[k])
        for m, name in enumerate(names):
            mu = muscles.get(name)
            length = mu.getLength(sampler.state)
            pts = current_path(mu.getGeometryPath(), sampler.state)
            d = abs(L_mu[k, m] - length)
            ok = all(abs(resummed(pts, sampler.state, w) - length) <= SAME for w in (1, 2))
            if not ok:
                ambiguous += 1
                if d > worst_amb[0]:
                    worst_amb = (d, f"{name} at state {k}")
                continue
            unambiguous += 1
            if d > worst[0]:
                worst = (d, f"{name} at state {k}")
            if d > TOL:
                beyond.append((name, k, d, L_mu[k, m], length))
    print(f"arm muscles ({len(names)}), {args.states} random states over the full ranges (seed 0), "
          f"musculo vs OpenSim 4.6 getLength")
    print(f"  unambiguous (state, muscle) pairs: {unambiguous}; beyond {TOL * 1e3:g} mm: {len(beyond)}; "
          f"max |dl| {worst[0] * 1e3:.4f} mm ({worst[1]})")
    print(f"  pairs where OpenSim's length is not its re-summed path: {ambiguous}"
          + (f"; max |dl| there {worst_amb[0] * 1e3:.3f} mm ({worst_amb[1]})" if ambiguous else ""))
    for name, k, d, a, b in beyond[:40]:
        print(f"  FAIL {name} at state {k}: |dl| {d * 1e3:.3f} mm (musculo {a:.6f}, OpenSim {b:.6f})")
    return 1 if beyond else 0


if __name__ == "__main__":
    sys.exit(main())
