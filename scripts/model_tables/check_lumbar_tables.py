#!/usr/bin/env python3
"""Re-reads data/model/lumbar_*.csv and checks them: 210 muscles, >= 2 points
each, known bodies, finite numbers, left/right mirror symmetry, wrap
references, coupler sums; then the neutral-pose musculotendon length (path
through the points, cylinder/sphere wrapping, joint offsets from
lumbar_joints.csv, femora at gait2392's hip centres) against
L_opt*cos(alpha) + L_ts.  Exit status 1 on a failed check.
    python3 scripts/model_tables/check_lumbar_tables.py
"""
import csv
import math
import os
import sys
from collections import Counter, defaultdict

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from geometry import body_origins, path_length  # noqa: E402

D = "data/model"
BODIES = {"pelvis", "lumbar5", "lumbar4", "lumbar3", "lumbar2", "lumbar1", "torso", "femur_r", "femur_l"}
HIP = {"r": (-0.0707, -0.0661, 0.0835), "l": (-0.0707, -0.0661, -0.0835)}  # gait2392 hip centres
fails = []


def check(cond, msg):
    if not cond:
        fails.append(msg)


def rd(fn):
    with open(os.path.join(D, fn), newline="") as f:
        return list(csv.DictReader(f))


def num(s, what):
    try:
        v = float(s)
    except ValueError:
        fails.append(f"{what}: not a number {s!r}")
        return float("nan")
    check(math.isfinite(v), f"{what}: not finite")
    return v


mus = rd("lumbar_muscles.csv")
pts = rd("lumbar_path_points.csv")
wo = rd("lumbar_wrap_objects.csv")
mw = rd("lumbar_muscle_wraps.csv")
jt = rd("lumbar_joints.csv")

names = [m["name"] for m in mus]
check(len(mus) == 210, f"{len(mus)} muscles, expected 210")
check(len(set(names)) == len(names), "duplicate muscle names")
for m in mus:
    for k in ("max_isometric_force", "optimal_fiber_length", "tendon_slack_length", "pennation_angle",
              "max_contraction_velocity"):
        v = num(m[k], f"{m['name']}.{k}")
        check(v >= 0 and (k == "pennation_angle" or v > 0), f"{m['name']}.{k} = {v} not positive")
    check(m["side"] in ("r", "l") and m["name"].endswith("_" + m["side"]), f"{m['name']} side")
    check(m["source"].strip() != "", f"{m['name']} no source")

P = defaultdict(list)
for p in pts:
    check(p["muscle"] in names, f"point of unknown muscle {p['muscle']}")
    check(p["body"] in BODIES, f"{p['muscle']} point on unknown body {p['body']}")
    check(p["type"] in ("fixed", "conditional"), f"{p['muscle']} point type {p['type']}")
    d = dict(index=int(p["index"]), body=p["body"], type=p["type"], coordinate=p["coordinate"],
             xyz=[num(p[c], f"{p['muscle']}.{c}") for c in "xyz"],
             range_min=num(p["range_min"], "range_min") if p["type"] == "conditional" else "",
             range_max=num(p["range_max"], "range_max") if p["type"] == "conditional" else "")
    P[p["muscle"]].append(d)
for n in names:
    ps = sorted(P[n], key=lambda d: d["index"])
    P[n] = ps
    check(len(ps) >= 2, f"{n}: {len(ps)} points")
    check([d["index"] for d in ps] == list(range(1, len(ps) + 1)), f"{n}: point indices not 1..n")

WO = {}
for w in wo:
    check(w["body"] in BODIES, f"wrap {w['name']} body {w['body']}")
    check(w["type"] in ("cylinder", "sphere"), f"wrap {w['name']} type")
    check(w["quadrant"] in ("+x", "-x", "+y", "-y", "+z", "-z", "all"), f"wrap {w['name']} quadrant")
    rot = [num(w[f"rot_{c}"], "rot") for c in "xyz"]
    check(all(abs(r) < 1e-12 for r in rot), f"wrap {w['name']}: rotations not supported by this check")
    WO[w["name"]] = dict(body=w["body"], type=w["type"], quadrant=w["quadrant"], R=np.eye(3),
                         t=[num(w[f"t{c}"], "t") for c in "xyz"], radius=num(w["radius"], "radius"))
W = defaultdict(list)
for w in mw:
    check(w["muscle"] in names, f"wrap of unknown muscle {w['muscle']}")
    check(w["wrap_object"] in WO, f"{w['muscle']}: unknown wrap object {w['wrap_object']}")
    rs, re_ = int(w["range_start"]), int(w["range_end"])
    check(1 <= rs < re_ <= len(P[w["muscle"]]), f"{w['muscle']}: wrap range {rs}..{re_}")
    W[w["muscle"]].append(dict(wrap_object=w["wrap_object"], range_start=rs, range_end=re_))

# left/right symmetry: parameters equal, points mirrored in z, wraps mirrored
def mirror_body(b):
    return b[:-1] + "l" if b.endswith("_r") else b
for n in names:
    if not n.endswith("_r"):
        continue
    l = n[:-2] + "_l"
    check(l in names, f"{n}: no left partner")
    if l not in names:
        continue
    mr, ml = mus[names.index(n)], mus[names.index(l)]
    for k in ("max_isometric_force", "optimal_fiber_length", "tendon_slack_length", "pennation_angle"):
        check(abs(float(mr[k]) - float(ml[k])) < 1e-9, f"{n}/{l}: {k} differs")
    check(len(P[n]) == len(P[l]), f"{n}/{l}: point counts")
    for a, b in zip(P[n], P[l]):
        check(mirror_body(a["body"]) == b["body"] and
              np.allclose(np.array(a["xyz"]) * [1, 1, -1], b["xyz"], atol=1e-6) and
              a["coordinate"].replace("_r", "_l") == b["coordinate"], f"{n}/{l}: point {a['index']} not mirrored")
    check(len(W[n]) == len(W[l]), f"{n}/{l}: wrap counts")
    for a, b in zip(W[n], W[l]):
        wa, wb = WO[a["wrap_object"]], WO[b["wrap_object"]]
        check(np.allclose(np.array(wa["t"]) * [1, 1, -1], wb["t"]) and wa["radius"] == wb["radius"]
              and (a["range_start"], a["range_end"]) == (b["range_start"], b["range_end"]),
              f"{n}/{l}: wraps not mirrored")

# joints and couplers
joints = []
for j in jt:
    joints.append(dict(parent=j["parent"], child=j["child"],
                       parent_loc=[num(j[f"parent_{c}"], "loc") for c in "xyz"],
                       child_loc=[num(j[f"child_{c}"], "loc") for c in "xyz"]))
for k in ("ratio_extension", "ratio_bending", "ratio_rotation"):
    s = sum(float(j[k]) for j in jt)
    check(abs(s - 1.0) < 1e-3, f"{k} sums to {s}")
    print(f"{k}: sum over joints = {s:.6f}")
print(f"ratio_rotation_published: sum = {sum(float(j['ratio_rotation_published']) for j in jt):.5f}")
origins = body_origins(joints)
for s in "rl":
    origins[f"femur_{s}"] = np.array(HIP[s])
check(set(origins) >= BODIES, "joint chain does not reach every body")

# neutral-pose length vs L_opt cos(alpha) + L_ts
ratios = {}
for m in mus:
    n = m["name"]
    L = path_length(P[n], W[n], origins, WO)
    ref = float(m["optimal_fiber_length"]) * math.cos(float(m["pennation_angle"])) + float(m["tendon_slack_length"])
    ratios[n] = L / ref
r = np.array(list(ratios.values()))
print(f"muscles {len(mus)}; points {len(pts)}; wrap objects {len(wo)}; wraps {len(mw)}")
print("groups:", dict(Counter((m['group'], m['side']) for m in mus)))
print("neutral MT length / (L_opt cos a + L_ts): min %.3f p5 %.3f median %.3f p95 %.3f max %.3f" %
      (r.min(), *np.percentile(r, [5, 50, 95]), r.max()))
hist = np.histogram(r, bins=[0, 0.8, 0.9, 0.95, 1.0, 1.05, 1.1, 1.2, 10])
for lo, hi, c in zip(hist[1][:-1], hist[1][1:], hist[0]):
    print(f"  [{lo:.2f}, {hi:.2f}): {c}")
for n, v in sorted(ratios.items(), key=lambda kv: abs(kv[1] - 1), reverse=True)[:6]:
    print(f"  farthest from 1: {n} {v:.3f}")
check(0.75 < r.min() and r.max() < 1.3, "neutral length ratio outside (0.75, 1.3)")

if fails:
    print(f"FAILED ({len(fails)}):")
    for f in fails[:50]:
        print("  " + f)
    sys.exit(1)
print("OK")
