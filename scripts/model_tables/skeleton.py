#!/usr/bin/env python3
"""Derives the skeleton rows of data/model/{joints,coordinates,joint_splines}.csv for the
pelvis, legs and arms from the public OpenSim models (gait2392: pelvis and legs, Delp et al.
1990; Rajagopal2016: arms, Holzbaur et al. 2005 via Hamner et al. 2010). Run once by hand;
the CSVs are the authored source the model builder reads. Prints CSV rows to stdout.

Changes against the sources (documented in data/model/README.md):
- talus lumped into calcn: the ankle joint's child frame is the talus origin expressed in the
  calcn frame at subtalar_angle = 0; subtalar_angle becomes a locked second rotation axis of
  the ankle joint (the subtalar axis direction); the builder completes the axis basis;
- mtp_angle locked; hand lumped into radius (no wrist joint);
- PinJoints (elbow, radioulnar) written as CustomJoints rotating about their frames' z axis.
"""
import os, sys
import xml.etree.ElementTree as ET
import numpy as np

REF = os.environ.get("MUSCULO_REFERENCE", os.path.join(os.path.dirname(__file__), "../../../shared/reference"))
G = ET.parse(os.path.join(REF, "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim")).getroot()
R = ET.parse(os.path.join(REF, "opensim-models/Models/Rajagopal/Rajagopal2016.osim")).getroot()
SG = "Delp et al. 1990 IEEE TBME 37:757-767 via OpenSim gait2392_thelen2003muscle.osim"
SR = "Rajagopal et al. 2016 IEEE TBME 63:2068-2079 (arms: Holzbaur et al. 2005) via OpenSim Rajagopal2016.osim"
HG, HR = 1.80, 1.70  # standing heights the two models' geometry represents

def joint(root, name):
    for j in root.iter():
        if j.get("name") == name and j.tag.endswith("Joint"):
            return j
    raise KeyError(name)

def frames(j):
    out = []
    for fr in j.iter("PhysicalOffsetFrame"):
        t = [float(v) for v in fr.findtext("translation").split()]
        o = [float(v) for v in fr.findtext("orientation").split()]
        out.append((t, o))
    return out  # parent, child

def coords(j):
    return {c.get("name"): (float(c.findtext("default_value")), [float(v) for v in c.findtext("range").split()]) for c in j.iter("Coordinate")}

def fmt(x):
    return repr(float(x)) if x != 0 else "0"

joints, axes, splines = [], [], []

def add_joint(name, parent, child, pf, cf, h, src):
    joints.append([name, "custom", parent, child, *pf[0], *pf[1], *cf[0], *cf[1], h, src])

def add_axis(jname, slot, coord, axis, function, c=None, locked=False, src=SG):
    d = rng = None
    if c is not None:
        d, rng = c
    axes.append([jname, slot, coord, *axis, function,
                 "" if d is None else d, "" if rng is None else rng[0], "" if rng is None else rng[1],
                 "" if c is None else str(locked).lower(), src])

# pelvis, hips, knees
j = joint(G, "ground_pelvis"); c = coords(j); p, ch = frames(j)
add_joint("ground_pelvis", "ground", "pelvis", p, ch, HG, SG)
for slot, name, ax in [("rotation1", "pelvis_tilt", (0, 0, 1)), ("rotation2", "pelvis_list", (1, 0, 0)), ("rotation3", "pelvis_rotation", (0, 1, 0)),
                       ("translation1", "pelvis_tx", (1, 0, 0)), ("translation2", "pelvis_ty", (0, 1, 0)), ("translation3", "pelvis_tz", (0, 0, 1))]:
    d, rng = c[name]
    if name == "pelvis_ty":
        d = d * 1.75 / HG  # the default standing height of the pelvis scales with the model
    add_axis("ground_pelvis", slot, name, ax, "identity", (d, rng))
for s in "rl":
    j = joint(G, f"hip_{s}"); c = coords(j); p, ch = frames(j)
    add_joint(f"hip_{s}", "pelvis", f"femur_{s}", p, ch, HG, SG)
    for ta in j.iter("TransformAxis"):
        if ta.findtext("coordinates"):
            n = ta.findtext("coordinates").strip()
            add_axis(f"hip_{s}", ta.get("name"), n, [float(v) for v in ta.findtext("axis").split()], "identity", c[n])
    j = joint(G, f"knee_{s}"); c = coords(j); p, ch = frames(j)
    add_joint(f"knee_{s}", f"femur_{s}", f"tibia_{s}", p, ch, HG, SG)
    n = f"knee_angle_{s}"
    for ta in j.iter("TransformAxis"):
        if not (ta.findtext("coordinates") or "").strip():
            continue
        axis = [float(v) for v in ta.findtext("axis").split()]
        sp = ta.find("SimmSpline")
        if sp is None:
            add_axis(f"knee_{s}", ta.get("name"), n, axis, "identity", c[n])
        else:
            spname = f"knee_{ta.get('name')}_{s}"
            xs = [float(v) for v in sp.findtext("x").split()]; ys = [float(v) for v in sp.findtext("y").split()]
            for x, y in zip(xs, ys):
                splines.append([spname, x, y, SG + f" knee_{s} {ta.get('name')} SimmSpline"])
            add_axis(f"knee_{s}", ta.get("name"), n, axis, f"spline:{spname}")
    # ankle (talus lumped into calcn), subtalar locked as the second axis
    ja, js, jm = joint(G, f"ankle_{s}"), joint(G, f"subtalar_{s}"), joint(G, f"mtp_{s}")
    pa, _ = frames(ja); ps, _ = frames(js)
    talus_in_calcn = [-v for v in ps[0]]
    add_joint(f"ankle_{s}", f"tibia_{s}", f"calcn_{s}", pa, (talus_in_calcn, [0, 0, 0]), HG, SG + "; talus lumped into calcn (child frame = talus origin in calcn at subtalar 0)")
    a1 = np.array([float(v) for v in next(ja.iter("TransformAxis")).findtext("axis").split()])
    a2 = np.array([float(v) for v in next(js.iter("TransformAxis")).findtext("axis").split()])
    add_axis(f"ankle_{s}", "rotation1", f"ankle_angle_{s}", a1, "identity", coords(ja)[f"ankle_angle_{s}"])
    add_axis(f"ankle_{s}", "rotation2", f"subtalar_angle_{s}", a2, "identity", (0.0, coords(js)[f"subtalar_angle_{s}"][1]), locked=True)
    pm, cm = frames(jm)
    add_joint(f"mtp_{s}", f"calcn_{s}", f"toes_{s}", pm, cm, HG, SG)
    am = [float(v) for v in next(jm.iter("TransformAxis")).findtext("axis").split()]
    add_axis(f"mtp_{s}", "rotation1", f"mtp_angle_{s}", am, "identity", (0.0, coords(jm)[f"mtp_angle_{s}"][1]), locked=True)

# arms (Rajagopal2016)
for s in "rl":
    j = joint(R, f"acromial_{s}"); c = coords(j); p, ch = frames(j)
    add_joint(f"acromial_{s}", "torso", f"humerus_{s}", p, ch, HR, SR)
    for ta in j.iter("TransformAxis"):
        if (ta.findtext("coordinates") or "").strip():
            n = ta.findtext("coordinates").strip()
            add_axis(f"acromial_{s}", ta.get("name"), n, [float(v) for v in ta.findtext("axis").split()], "identity", c[n], src=SR)
    for jn, parent, child, cn in [(f"elbow_{s}", f"humerus_{s}", f"ulna_{s}", f"elbow_flex_{s}"), (f"radioulnar_{s}", f"ulna_{s}", f"radius_{s}", f"pro_sup_{s}")]:
        j = joint(R, jn); c = coords(j); p, ch = frames(j)
        add_joint(jn, parent, child, p, ch, HR, SR + " (PinJoint: rotation about the joint frames' z)")
        add_axis(jn, "rotation1", cn, (0, 0, 1), "identity", c[cn], src=SR)

w = lambda rows, f: [print(",".join(fmt(v) if isinstance(v, (int, float, np.floating)) and not isinstance(v, bool) else str(v) for v in r), file=f) for r in rows]
out = os.path.join(os.path.dirname(__file__), "../../data/model")
with open(os.path.join(out, "joints.csv"), "w") as f:
    print("joint,kind,parent,child,parent_x,parent_y,parent_z,parent_rx,parent_ry,parent_rz,child_x,child_y,child_z,child_rx,child_ry,child_rz,source_height,source", file=f)
    w(joints, f)
with open(os.path.join(out, "coordinates.csv"), "w") as f:
    print("joint,slot,coordinate,axis_x,axis_y,axis_z,function,default_value,range_min,range_max,locked,source", file=f)
    w(axes, f)
with open(os.path.join(out, "joint_splines.csv"), "w") as f:
    print("spline,x,y,source", file=f)
    w(splines, f)
print(len(joints), "joints,", len(axes), "axes,", len(splines), "knots")
