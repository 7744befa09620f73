#!/usr/bin/env python3
"""Rewrite the wrapping of the default model's 11 shoulder-crossing muscles (both arms).

Muscles: DELT1, DELT2, DELT3, PECM1, SUPSP, INFSP, SUBSC, TMAJ, BIClong, BICshort, TRIlong
(MoBL-ARMS 4.1, Saul et al. 2015; Holzbaur et al. 2005; data/model/README.md, arm).

Why. MoBL-ARMS wraps these muscles over about 20 surfaces per arm (tori, ellipsoids,
cylinders and spheres, some on the thorax/scapula, some on the humerus, several per muscle,
many with a quadrant). They were placed for MoBL's own shoulder (a scapula and clavicle that
move with humeral elevation, three shoulder coordinates of its own) and for its range. On our
torso->humerus ball joint with the girdle frozen at the arm-at-side pose they break: a path
switches side of a surface (or slides off a finite cylinder, or leaves a quadrant) and its
length jumps, and moment arms reach metres per radian (DELT3 8.8 m/rad, TRIlong 0.89 m/rad
at abduction beyond ~87 deg), which is why the shoulder ranges had been narrowed. The
thoracohumeral ranges (elevation to 180 deg) make that worse.

Construction (smooth by construction). Every shoulder muscle crosses the joint in one
segment of its path: from its last point on the torso (scapula/clavicle) to its first point on
the humerus (or the reverse). Only that segment wraps at the shoulder, over a sphere on the
humerus centred at the humeral head, i.e. at the glenohumeral centre (the humerus_r origin,
the acromial joint's child frame). For such a segment, with endpoints at fixed distances d1,
d2 > R from the centre (one fixed in the torso, one in the humerus: the ball joint does not
move the centre), the length is a function of the angle D between the two endpoints seen from
the centre only:

    straight:  l(D) = sqrt(d1^2 + d2^2 - 2 d1 d2 cos D)          (segment misses the sphere)
    wrapped:   l(D) = h1 + h2 + R (D - b1 - b2),  h_i = sqrt(d_i^2 - R^2), b_i = acos(R / d_i)

and the two branches meet with equal value and slope where the segment is tangent to the
sphere. D is a continuous function of the pose, so every length is continuous over all
rotations of the humerus, whatever the coordinate ranges; the sphere is symmetric, so when
the segment passes through the centre (D = pi) both sides of the sphere give the same length
(the moment arm changes sign there, but the length does not jump). The moment arm about any
axis through the centre is R dD/dq when wrapped (|r| <= R) and the distance of the straight
segment from the centre when not (|r| <= min(d1, d2)), so every shoulder moment arm is
bounded by construction (all radii and distances below are under 0.07 m, the check's bound).
Every other segment of these paths is fixed in one body and has a constant length. The elbow
wraps of BIClong, BICshort (Elbow_BIC_BRD) and TRIlong (TRI) are humerus-borne and untouched.

Scapulohumeral rhythm (planned): the scapula/clavicle-borne origins and the glenohumeral
centre will move together by 1-3 cm with elevation. The spheres ride on the humerus and are
centred on the humeral head, so they follow the centre; every origin lies at least 1 cm
outside its sphere (distances below), so a few cm of motion of the origins relative to the
thorax keep the construction valid (a point inside a sphere would make OpenSim skip the wrap).

Radii. Two spheres per arm, both centred at the humeral head:
- humhead (R = 0.030 m): DELT1, DELT2, DELT3, PECM1, TMAJ, BICshort, TRIlong: the deltoid
  and the muscles that pass over/around the head from far origins; 0.03 m is about the
  humeral head (~0.023 m) plus the cuff and deltoid thickness. Crossing-segment endpoint
  distances (table units): DELT2 0.040/0.066, PECM1 0.052/0.043, BICshort 0.043/0.077,
  TRIlong 0.043/0.116, DELT1 0.053/0.110, TMAJ 0.134/0.055, DELT3 0.063/0.076.
- cuff (R = 0.020 m, MoBL's own SUPSP sphere radius): SUPSP, INFSP, SUBSC and BIClong, whose
  insertions (greater/lesser tubercle) and origin (supraglenoid tubercle) sit on the head, at
  0.021 (SUBSC) to 0.029 m from its centre.
At ordinary poses a path that MoBL leaves straight stays straight here (same moment arm);
where MoBL wraps it over the head a sphere gives the head's lever arm. validation/opensim/
shoulder_arms.py prints the moment arms at eight poses for the comparison
(data/model/README.md, arm).

Left arm: generated as the mirror of the right (README item 2: z -> -z; a sphere at the
origin mirrors to itself). The MoBL wrap objects no muscle uses any more are removed.

usage: shoulder_paths.py [data/model]   (rewrites wrap_objects.csv and muscle_wraps.csv in
place; running it again changes nothing)
"""

import csv
import os
import sys

SHOULDER = ["DELT1", "DELT2", "DELT3", "PECM1", "SUPSP", "INFSP", "SUBSC", "TMAJ",
            "BIClong", "BICshort", "TRIlong"]
# Humerus-borne elbow wraps kept as MoBL-ARMS has them.
ELBOW_WRAPS = {"Elbow_BIC_BRD", "TRI"}
# The crossing segment of each muscle: (first, last) path-point index (muscle_wraps range).
SEGMENT = {
    "DELT1": (2, 3), "DELT2": (2, 3), "DELT3": (2, 3), "PECM1": (2, 3),
    "SUPSP": (1, 2), "INFSP": (2, 3), "SUBSC": (1, 2), "TMAJ": (1, 2),
    "BIClong": (2, 3), "BICshort": (2, 3), "TRIlong": (1, 2),
}
# Via points on the humerus inserted after a path point: muscle -> (after index, x, y, z) in
# the right humerus frame (table units); the crossing segment (SEGMENT) counts them.
VIA = {
    # INFSP: its insertion (greater tubercle, lateral) and its origin (infraspinous fossa,
    # posterior-medial) are 123 deg apart about the humeral axis, so internal rotation by 57
    # deg put them on opposite sides of the head and the path flipped to the front of the
    # head (moment arm about arm_rot jumping by 2R). The muscle wraps the back of the head
    # (MoBL's infsp cylinder, quadrant -x): a via point there, 0.025 m from the centre, puts
    # the flip beyond 100 deg of internal rotation, outside the range.
    "INFSP": (1, -0.0204, 0.0054, 0.0127),
}
VIA_SOURCE = ("this model (scripts/model_tables/shoulder_paths.py): via point on the back of "
              "the humeral head, 0.025 m from the glenohumeral centre")
SOURCE = ("this model (scripts/model_tables/shoulder_paths.py): sphere on the humerus centred "
          "at the humeral head (glenohumeral centre) replacing MoBL-ARMS 4.1's shoulder wraps; "
          "radius %s m")
SPHERES = {"humhead": 0.030, "cuff": 0.020}
GROUP = {"DELT1": "humhead", "DELT2": "humhead", "DELT3": "humhead", "PECM1": "humhead",
         "TMAJ": "humhead", "BICshort": "humhead", "TRIlong": "humhead",
         "SUPSP": "cuff", "INFSP": "cuff", "SUBSC": "cuff", "BIClong": "cuff"}


def read(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    with open(path, newline="") as f:
        header = next(csv.reader(f))
    return header, rows


def write(path, header, rows):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=header, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


def base(name):
    """(name without side suffix, side) of 'X_r' / 'X_l'."""
    return name[:-2], name[-1]


def fmt(x):
    return repr(float(x))


def main():
    folder = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(__file__), "..", "..", "data", "model")
    ppath = os.path.join(folder, "path_points.csv")
    ph, prows = read(ppath)
    # via points: insert (once) after the given index, renumbering the muscle's later points
    pout, removed = [], {}
    for row in prows:
        b, side = base(row["muscle"])
        if b in VIA and row["source"].startswith(VIA_SOURCE.split(":")[0]):
            removed[row["muscle"]] = int(row["index"])    # an earlier run's, re-made below
            continue
        i = int(row["index"])
        if row["muscle"] in removed and i > removed[row["muscle"]]:
            row = dict(row, index=str(i - 1))
        pout.append(row)
    prows, pout = pout, []
    for row in prows:
        b, side = base(row["muscle"])
        pout.append(row)
        if b in VIA and side in "rl":
            after, x, y, z = VIA[b]
            i = int(row["index"])
            if i > after:
                pout[-1] = dict(row, index=str(i + 1))
            if i == after:
                via = {k: "" for k in ph}
                via.update(muscle=row["muscle"], index=str(after + 1), type="fixed",
                           body="humerus_" + side, x=fmt(x), y=fmt(y),
                           z=fmt(z if side == "r" else -z), source=VIA_SOURCE)
                pout.append(via)
    write(ppath, ph, pout)
    wpath = os.path.join(folder, "wrap_objects.csv")
    mpath = os.path.join(folder, "muscle_wraps.csv")
    wh, wrows = read(wpath)
    mh, mrows = read(mpath)
    shoulder = {m + "_" + s for m in SHOULDER for s in "rl"}

    # muscle_wraps: each shoulder muscle keeps its elbow wraps, then takes its sphere.
    out, done = [], set()
    for row in mrows:
        m = row["muscle"]
        if m not in shoulder:
            out.append(row)
            continue
        if m in done:
            continue
        done.add(m)
        b, side = base(m)
        kept = [r for r in mrows if r["muscle"] == m and base(r["wrap_object"])[0] in ELBOW_WRAPS]
        for k, r in enumerate(kept, 1):
            out.append(dict(r, order=str(k)))
        lo, hi = SEGMENT[b]
        out.append({"muscle": m, "order": str(len(kept) + 1),
                    "wrap_object": GROUP[b] + "_" + side, "method": "hybrid",
                    "range_start": str(lo), "range_end": str(hi)})

    # wrap_objects: drop the ones no muscle uses any more, add the spheres after the last
    # arm object of each side.
    used = {r["wrap_object"] for r in out}
    wout = [r for r in wrows if r["name"] in used]
    for side in "rl":
        names = [r["name"] for r in wout]
        arm = [i for i, r in enumerate(wout) if r["body"].endswith("_" + side)
               and r["body"].split("_")[0] in ("humerus", "ulna", "radius")]
        at = (max(arm) + 1) if arm else len(wout)
        for g, radius in SPHERES.items():
            name = g + "_" + side
            row = {k: "" for k in wh}
            row.update(name=name, body="humerus_" + side, type="sphere", rot_x="0", rot_y="0",
                       rot_z="0", tx="0", ty="0", tz="0", radius=fmt(radius), quadrant="all",
                       source=SOURCE % fmt(radius))
            if name in names:
                wout[names.index(name)] = row
            else:
                wout.insert(at, row)
                at += 1
                names = [r["name"] for r in wout]
    missing = used - {r["name"] for r in wout}
    if missing:
        sys.exit("muscle_wraps.csv names unknown wrap objects: %s" % " ".join(sorted(missing)))
    write(wpath, wh, wout)
    write(mpath, mh, out)
    print("%d wrap objects (%d before), %d muscle-wrap links (%d before)"
          % (len(wout), len(wrows), len(out), len(mrows)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
