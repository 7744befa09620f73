#!/usr/bin/env python3
"""Make the default model's paths continuous where a conditional path point switched off the
path: iliacus at the pelvic brim (gait2392), brachialis at the elbow (MoBL-ARMS 4.1).
The lumbar psoas fascicles take the same brim treatment in build_lumbar_tables.py, which
imports `brim_sphere` from here (data/model/README.md, item 7).

Why. A ConditionalPathPoint is on the path while its coordinate lies in a range and off it
outside; the length jumps by how far the point lies from the path without it at the pose
where it switches. `musculo check --random-lines` walks straight lines through the joint space
in 0.5 deg steps and found: iliacus_r/l 13 mm at hip_flexion 45 deg with the hip abducted
~43 deg (gait2392's brim point `iliacus-P3`, active for hip_flexion in [-90, 45] deg), the
22 psoas fascicles 8.6-8.8 mm there (gait2392's `psoas-P3`, same point and range), BRA_r/l
1.4 mm at elbow_flex 46.6 deg (MoBL's two points, active for elbow_flexion in [0, 46.6] deg).

Pelvic brim (iliacus; psoas in build_lumbar_tables.py). The hip has three coordinates, so no
placement of a conditional point lies on the path at every pose where it switches. Rajagopal
et al. (2016) replaced these very points by wrap surfaces on the pelvis (cylinders
`IL_at_brim_r/l`, R 0.0549 m, and `PS_at_brim_r/l`, R 0.05 m, quadrant -y, wrapping the
pelvis -> femur segment), which hold the path on the brim in extension and release it in
flexion. Their cylinders do not carry over as they are: Rajagopal2016's pelvis frame has
gait2392's back joint (-0.1007, 0.0815, 0) but its hip centre moved from gait2392's
(-0.0707, -0.0661, +-0.0835) to (-0.056276, -0.07849, +-0.07726), 2 cm, and their axes pass
1.5-2.5 cm from the hip centre with radii as large as the insertions' distance from it
(5.5 cm), so the femoral insertion, which moves on a sphere about the hip centre, enters the
cylinder at some hip poses and the wrap is then skipped (OpenSim's rule, also musculo's):
`musculo check --random-lines 1000` found the cylinders taken unchanged to jump the psoas
fascicles by 13-15 mm (and their moment arms by 19 mm) and, moved with the hip centre
(translation + (gait2392 hip - Rajagopal2016 hip)), iliacus by 12-13 mm at hip extension 29
deg with adduction 23 deg (its insertion 0.1 mm inside the cylinder there).

We keep Rajagopal's idea (a wrap surface on the pelvis over the pelvis -> femur segment in
place of the conditional point) with a surface for which no such pose exists: a sphere
centred at the hip centre (on the pelvis, quadrant `all`). The segment's endpoints are at
fixed distances d1 (pelvis point), d2 (femur point) from that centre whatever the pose, so
with D the angle between them seen from the centre its length is (as for the shoulder
spheres, shoulder_paths.py)

    straight:  l(D) = sqrt(d1^2 + d2^2 - 2 d1 d2 cos D)               while D <= b1 + b2
    wrapped:   l(D) = h1 + h2 + R (D - b1 - b2),  h_i = sqrt(d_i^2 - R^2), b_i = acos(R/d_i)

the two branches meeting with equal value and slope: continuous (and C1) over every hip
rotation. R = 0.04 m (gait2392 size; 0.0389 m built) is below every endpoint distance
(iliacus 0.0463 / 0.0546 m, psoas 0.0484 / 0.0509 m) and about the femoral head (~0.024 m)
plus the iliopsoas tendon; while wrapped the flexion moment arm is R dD/dq <= R, 38.7 mm in
pure flexion-extension, against gait2392's 30-42 mm between -30 and 40 deg of flexion (the
table in data/model/README.md). The conditional point is dropped; the sphere wraps the segment
from the last pelvis point to the first femur point (range `2 3`, Rajagopal's indices too).

Elbow (BRA). The elbow is one coordinate, so each conditional point can be put on the path
at the switching angle: at elbow_flex = theta_s (the range's upper end; its lower end is the
coordinate's lower limit, 0, so no other switch occurs) the path without the two points is
the segment P1 (humerus) -> P4 (ulna); each conditional point is moved to its orthogonal
projection on that segment (the humerus point in the humerus frame; the ulna point through
the elbow joint at theta_s, then back to the ulna frame). The length is then continuous at
theta_s (the moment arm still changes there, by the points' old bend), and below theta_s the
points still hold the path off the joint. Projection is idempotent, so running this again
changes nothing.

usage: brim_paths.py [data/model]   (run after extract_limb_muscles.py and shoulder_paths.py;
rewrites the iliacus and BRA rows of path_points.csv, adds IL_at_brim_r/l to
wrap_objects.csv and iliacus' links to muscle_wraps.csv)
"""

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from extract_limb_muscles import rot_xyz  # noqa: E402  (OpenSim body-fixed x-y-z: Rx Ry Rz)
from shoulder_paths import read, write  # noqa: E402

# Sphere radii (table units, gait2392 size), below every endpoint's distance from the hip
# centre (iliacus 0.0463 pelvis / 0.0546 femur, psoas 0.0484 / 0.0509).
BRIM_RADIUS = {"IL": 0.04, "PS": 0.04}
BRIM_SOURCE = ("this model (scripts/model_tables/brim_paths.py): sphere centred at the hip centre "
               "(gait2392), radius %s m, replacing gait2392's conditional pelvic-brim point as "
               "Rajagopal et al. 2016 replaced it by a wrap surface (IL_at_brim, PS_at_brim)")
BRA_NOTE = ("; moved onto the segment P1-P4 at elbow_flex = %s rad, where it switches "
            "(scripts/model_tables/brim_paths.py)")


def brim_sphere(prefix, side, hip_ours_r, header, radius=None):
    """wrap_objects.csv row of `{prefix}_at_brim_{side}` (prefix IL or PS): a sphere on the
    pelvis centred at our hip centre, unconstrained (quadrant `all`)."""
    radius = BRIM_RADIUS[prefix] if radius is None else radius
    t = np.asarray(hip_ours_r, float) * ([1, 1, 1] if side == "r" else [1, 1, -1])
    row = {k: "" for k in header}
    row.update(name=f"{prefix}_at_brim_{side}", body="pelvis", type="sphere", rot_x="0",
               rot_y="0", rot_z="0", tx=fmt(t[0]), ty=fmt(t[1]), tz=fmt(t[2]),
               radius=fmt(radius), quadrant="all", source=BRIM_SOURCE % fmt(radius))
    return row


def assert_outside(muscle, pelvis_point, femur_point, hip, radius):
    """The construction holds only if both endpoints of the wrapped segment lie outside the
    sphere: the pelvis point (pelvis frame) and the femur point (femur frame, origin at the
    hip centre) at their fixed distances from the centre."""
    d1 = float(np.linalg.norm(np.asarray(pelvis_point) - np.asarray(hip)))
    d2 = float(np.linalg.norm(np.asarray(femur_point)))
    assert min(d1, d2) > radius, (muscle, d1, d2, radius)


def fmt(x):
    return f"{float(x):.12g}"


def hip_centre(joints, side="r"):
    for j in joints:
        if j["joint"] == f"hip_{side}":
            return np.array([float(j[k]) for k in ("parent_x", "parent_y", "parent_z")])
    sys.exit(f"joints.csv: no hip_{side}")


def elbow_transform(joints, side, theta):
    """(R, t) with p_humerus = R p_ulna + t at elbow_flex = theta: the joint rotates about the
    z axis of its parent (humerus) frame, child frame = parent frame at 0 (joints.csv)."""
    j = next(j for j in joints if j["joint"] == f"elbow_{side}")
    f = lambda pre: (np.array([float(j[pre + k]) for k in ("_x", "_y", "_z")]),
                     rot_xyz(*[float(j[pre + k]) for k in ("_rx", "_ry", "_rz")]))
    tp, rp = f("parent")
    tc, rc = f("child")
    rz = rot_xyz(0.0, 0.0, theta)
    r = rp @ rz @ rc.T
    return r, tp - r @ tc


def xyz(row):
    return np.array([float(row[k]) for k in "xyz"])


def iliacus(prows, side):
    """Drop iliacus' conditional brim point, renumbering the points after it."""
    m = f"iliacus_{side}"
    dropped = [int(r["index"]) for r in prows if r["muscle"] == m and r["type"] == "conditional"]
    out = []
    for r in prows:
        if r["muscle"] == m and int(r["index"]) in dropped:
            continue
        if r["muscle"] == m:
            r = dict(r, index=str(int(r["index"]) - sum(1 for d in dropped if d < int(r["index"]))))
        out.append(r)
    return out


def bra(prows, joints, coords, side):
    """Project BRA's conditional points onto its path without them at the switching angle;
    returns the rows and a report line."""
    m = f"BRA_{side}"
    rows = [r for r in prows if r["muscle"] == m]
    cond = [r for r in rows if r["type"] == "conditional"]
    fixed = [r for r in rows if r["type"] == "fixed"]
    assert len(cond) == 2 and len(fixed) == 2, m
    coord = cond[0]["coordinate"]
    lo, hi = float(cond[0]["range_min"]), float(cond[0]["range_max"])
    assert all(r["coordinate"] == coord and float(r["range_min"]) == lo
               and float(r["range_max"]) == hi for r in cond), m
    c = next(c for c in coords if c["coordinate"] == coord)
    assert float(c["range_min"]) >= lo and float(c["range_max"]) > hi, (m, "one switch only")
    r_hu, t_hu = elbow_transform(joints, side, hi)

    def in_humerus(row):
        p = xyz(row)
        return p if row["body"].startswith("humerus") else r_hu @ p + t_hu

    a, b = in_humerus(fixed[0]), in_humerus(fixed[-1])
    d = b - a
    report, params = [], []
    for r in cond:
        p = in_humerus(r)
        s = float(np.dot(p - a, d) / np.dot(d, d))
        assert 0.0 < s < 1.0, (m, r["index"], s)
        q = a + s * d
        params.append(s)
        new = q if r["body"].startswith("humerus") else r_hu.T @ (q - t_hu)
        report.append(f"{m} point {r['index']} ({r['body']}) moved {1e3 * np.linalg.norm(q - p):.2f} mm")
        if np.linalg.norm(q - p) > 1e-9:     # on the segment already: an earlier run's
            r.update(x=fmt(new[0]), y=fmt(new[1]), z=fmt(new[2]))
        if "moved onto the segment" not in r["source"]:
            r["source"] += BRA_NOTE % r["range_max"]
    assert params == sorted(params), (m, "points keep their order along the path")
    return report


def main():
    folder = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(__file__), "..", "..", "data", "model")
    ppath = os.path.join(folder, "path_points.csv")
    wpath = os.path.join(folder, "wrap_objects.csv")
    mpath = os.path.join(folder, "muscle_wraps.csv")
    ph, prows = read(ppath)
    wh, wrows = read(wpath)
    mh, mrows = read(mpath)
    _, joints = read(os.path.join(folder, "joints.csv"))
    _, coords = read(os.path.join(folder, "coordinates.csv"))
    hip_r = hip_centre(joints, "r")
    assert np.allclose(hip_centre(joints, "l"), hip_r * [1, 1, -1]), "mirrored hips"

    report = []
    for side in "rl":
        prows = iliacus(prows, side)
        report += bra(prows, joints, coords, side)
        il = {int(r["index"]): xyz(r) for r in prows if r["muscle"] == f"iliacus_{side}"}
        assert_outside(f"iliacus_{side}", il[2], il[3], hip_centre(joints, side), BRIM_RADIUS["IL"])

    names = {f"IL_at_brim_{s}" for s in "rl"}
    wout = [brim_sphere("IL", s, hip_r, wh) for s in "rl"] + \
        [r for r in wrows if r["name"] not in names]
    mout = [r for r in mrows if not r["muscle"].startswith("iliacus_")]
    for s in "rl":
        mout.append(dict(muscle=f"iliacus_{s}", order="1", wrap_object=f"IL_at_brim_{s}",
                         method="hybrid", range_start="2", range_end="3"))
    write(ppath, ph, prows)
    write(wpath, wh, wout)
    write(mpath, mh, mout)
    for line in report:
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
