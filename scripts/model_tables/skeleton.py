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
import math, os, sys
import xml.etree.ElementTree as ET
import numpy as np

REF = os.environ.get("MUSCULO_REFERENCE", os.path.join(os.path.dirname(__file__), "../../../shared/reference"))
G = ET.parse(os.path.join(REF, "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim")).getroot()
R = ET.parse(os.path.join(REF, "opensim-models/Models/Rajagopal/Rajagopal2016.osim")).getroot()
SG = "Delp et al. 1990 IEEE TBME 37:757-767 via OpenSim gait2392_thelen2003muscle.osim"
SR = "Rajagopal et al. 2016 IEEE TBME 63:2068-2079 (arms: Holzbaur et al. 2005) via OpenSim Rajagopal2016.osim"
HG = HR = 1.80  # one geometry: Rajagopal2016 sits its upper body on gait2392's pelvis and torso frames

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

# Coordinate ranges narrowed from the source models' (which span up to +-120 deg) to where the
# muscle paths hold: `musculo check` finds moment-arm sign flips or jumps beyond them. Each is
# within or at the normal adult range of motion (AAOS 1965, data/check/range_of_motion.csv).
RANGE = {
    "hip_adduction": ((-45, 30), "AAOS 1965 abduction 45, adduction 30 (gluteus minimus, TFL and quadratus femoris paths break at -95, -118 and +78 deg)"),
    "hip_rotation": ((-45, 45), "AAOS 1965 internal and external rotation 45"),
    "ankle_angle": ((-50, 30), "AAOS 1965 plantarflexion 50; dorsiflexion 30 (Rajagopal2016's limit; the toe extensors' paths break at 48 deg)"),
    "arm_flex": ((-60, 70), "AAOS 1965 extension 60; flexion limited to 70 deg (no scapular motion in this model; the posterior deltoid's wraps break at 73 deg, the infraspinatus' at 83 deg)"),
    "arm_add": ((-120, 30), "abduction to 120 deg (glenohumeral with a fixed scapula), adduction 30 deg (the middle deltoid's wrap breaks at 58 deg)"),
    "arm_rot": ((-70, 70), "AAOS 1965 internal rotation 70 deg, both ways (the posterior deltoid's wrap breaks at 85 deg)"),
}
def add_axis(jname, slot, coord, axis, function, c=None, locked=False, src=SG):
    d = rng = None
    if c is not None:
        d, rng = c
        key = coord.rsplit("_", 1)[0]
        if key in RANGE:
            (lo, hi), why = RANGE[key]
            rng = [round(math.radians(lo), 8), round(math.radians(hi), 8)]
            src = src + "; range " + why
    axes.append([jname, slot, coord, *axis, function,
                 "" if d is None else d, "" if rng is None else rng[0], "" if rng is None else rng[1],
                 "" if c is None else str(locked).lower(), src])

# pelvis, hips, knees
j = joint(G, "ground_pelvis"); c = coords(j); p, ch = frames(j)
add_joint("ground_pelvis", "ground", "pelvis", p, ch, HG, SG)
for slot, name, ax in [("rotation1", "pelvis_tilt", (0, 0, 1)), ("rotation2", "pelvis_list", (1, 0, 0)), ("rotation3", "pelvis_rotation", (0, 1, 0)),
                       ("translation1", "pelvis_tx", (1, 0, 0)), ("translation2", "pelvis_ty", (0, 1, 0)), ("translation3", "pelvis_tz", (0, 0, 1))]:
    d, rng = c[name]
    src = SG
    if name == "pelvis_ty":
        d = d * 1.75 / HG  # the default standing height of the pelvis scales with the model
    if name == "pelvis_rotation":
        rng = [-6.2831853, 6.2831853]
        src = SG + "; range a full turn either way (gait2392: ±90 deg; musculo check allows at most 2π): the heading of the free-floating pelvis has no anatomical limit, and motion datasets turn round (IK follows the heading continuously from frame to frame)"
    add_axis("ground_pelvis", slot, name, ax, "identity", (d, rng), src=src)
for s in "rl":
    j = joint(G, f"hip_{s}"); c = coords(j); p, ch = frames(j)
    add_joint(f"hip_{s}", "pelvis", f"femur_{s}", p, ch, HG, SG)
    # gait2392's lower-limb paths keep their moment-arm signs up to 100 deg of hip flexion
    # (iliacus, psoas and gluteus maximus turn over beyond it) and the psoas' conditional point
    # switches at -90 deg: the hip's flexion range is limited to [-30, 100] deg (AAOS extension
    # 30 deg), the knee's to 115 deg of flexion (bifemlh turns over at 120 deg).
    c[f"hip_flexion_{s}"] = (0.0, [-0.52359878, 1.74532925])
    for ta in j.iter("TransformAxis"):
        if ta.findtext("coordinates"):
            n = ta.findtext("coordinates").strip()
            src = SG + ("; range limited to [-30, 100] deg where the gait2392 paths hold (musculo check)" if n.startswith("hip_flexion") else "")
            add_axis(f"hip_{s}", ta.get("name"), n, [float(v) for v in ta.findtext("axis").split()], "identity", c[n], src=src)
    j = joint(G, f"knee_{s}"); c = coords(j); p, ch = frames(j)
    c[f"knee_angle_{s}"] = (0.0, [-2.00712864, c[f"knee_angle_{s}"][1][1]])
    add_joint(f"knee_{s}", f"femur_{s}", f"tibia_{s}", p, ch, HG, SG)
    n = f"knee_angle_{s}"
    for ta in j.iter("TransformAxis"):
        if not (ta.findtext("coordinates") or "").strip():
            continue
        axis = [float(v) for v in ta.findtext("axis").split()]
        sp = ta.find("SimmSpline")
        if sp is None:
            add_axis(f"knee_{s}", ta.get("name"), n, axis, "identity", c[n], src=SG + "; flexion limited to 115 deg where bifemlh keeps its sign (musculo check)")
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

import csv as _csv
def w(rows, f):
    writer = _csv.writer(f, lineterminator="\n")
    for r in rows:
        writer.writerow([fmt(v) if isinstance(v, (int, float, np.floating)) and not isinstance(v, bool) else str(v) for v in r])
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

# ---------------------------------------------------------------------------------------
# Lumbar chain (data/model/lumbar_joints.csv, Christophy et al. 2012): L5/S1 carries the three
# independent coordinates (its axes turn by the L5/S1 share of each); the four joints above it
# have their own coordinates, coupled to the independent ones by their shares; T12/L1 is welded.
import csv
SC = "Christophy et al. 2012 Biomech Model Mechanobiol 11:19-34 (Lumbar_C_210 joints and couplers)"
lumbar = list(csv.DictReader(open(os.path.join(out, "lumbar_joints.csv"))))
HALF_PI = 1.5707963300000001
LUMBAR_RANGE = {"lumbar_extension": (-1.35, 0.7538), "lumbar_bending": (-0.4363, 0.4363), "lumbar_rotation": (-0.7854, 0.7854)}
names = {"extension": ("lumbar_extension", "FE"), "bending": ("lumbar_bending", "LB"), "rotation": ("lumbar_rotation", "AR")}
couplers = []
origin = {"pelvis": np.zeros(3)}
for row in lumbar:
    pl = [float(row[f"parent_{a}"]) for a in "xyz"]; cl = [float(row[f"child_{a}"]) for a in "xyz"]
    pr = [float(row[f"parent_rot_{a}"]) for a in "xyz"]; cr = [float(row[f"child_rot_{a}"]) for a in "xyz"]
    assert pr == [0, 0, 0] and cr == [0, 0, 0], "the lumbar frames are parallel at the default pose"
    origin[row["child"]] = origin[row["parent"]] + np.array(pl) - np.array(cl)
    name = row["name"]
    if row["ratio_extension"] in ("0.0", "0") and row["ratio_bending"] in ("0.0", "0"):
        joints.append([name, "weld", row["parent"], row["child"], *pl, *pr, *cl, *cr, HG, SC])
        continue
    joints.append([name, "custom", row["parent"], row["child"], *pl, *pr, *cl, *cr, HG, SC])
    level = name.split("_IVDjnt")[0]
    for slot, axis_text, (dof, suffix) in zip(["rotation1", "rotation2", "rotation3"], [row["axis1"], row["axis2"], row["axis3"]], [names["extension"], names["bending"], names["rotation"]]):
        axis = [float(v) for v in axis_text.split()]
        ratio = float(row["ratio_" + {"FE": "extension", "LB": "bending", "AR": "rotation"}[suffix]])
        src = SC + ("; axial-rotation shares normalised to 1 (Millard 2024), see README_lumbar.md" if suffix == "AR" else "")
        # ranges of the three lumbar coordinates: Christophy's model as MyoSuite ships it
        # (flexion 77 deg, extension 43 deg, bending 25 deg, rotation 45 deg)
        lo, hi = LUMBAR_RANGE[dof]
        if level == "L5_S1":
            add_axis(name, slot, dof, axis, f"linear:{ratio!r}", (0.0, [lo, hi]), src=src + "; range: MyoTorso (Christophy 2012) virtual joint ranges")
        else:
            coord = f"{level}_{suffix}"
            add_axis(name, slot, coord, axis, "identity", (0.0, [lo * ratio, hi * ratio]), src=src)
            couplers.append([f"{coord}_con", coord, dof, ratio, src])

# ---------------------------------------------------------------------------------------
# Segment landmarks (de Leva 1996 endpoints) in each body's frame, source geometry (1.80 m).
SL = 1.80 / 1.741  # de Leva's male sample: mean stature 1.741 m
SD = "de Leva 1996 J Biomech 29:1223-1230 Table 4 (males); landmarks: "
midh = np.array([-0.0707, -0.0661, 0.0])  # hip centres' midpoint in the pelvis frame (gait2392)
omph = midh + [0, 0.1457 * SL, 0]; xyph = omph + [0, 0.2155 * SL, 0]
cerv = xyph + [0, 0.1707 * SL, 0]; vert = cerv + [0, 0.2429 * SL, 0]
trunk_note = "trunk landmarks stacked vertically above the hip centres' midpoint (gait2392 pelvis frame) at de Leva's segment lengths scaled to 1.80 m"
bodies = []
def seg(body, segment, share, a, b, note, u0=0.0, u1=1.0):
    bodies.append([body, segment, share, *a, *b, u0, u1, HG, SD + note])
seg("pelvis", "lower_trunk", 1.0, omph, midh, "OMPH-MIDH; " + trunk_note)
for k, body in enumerate(["lumbar1", "lumbar2", "lumbar3", "lumbar4", "lumbar5"]):
    o = origin[body]
    seg(body, "middle_trunk", 0.2, xyph - o, omph - o, f"XYPH-OMPH, fifth {k + 1} from XYPH (uniform slices); " + trunk_note, 0.2 * k, 0.2 * (k + 1))
ot = origin["torso"]
seg("torso", "upper_trunk", 1.0, cerv - ot, xyph - ot, "CERV-XYPH; " + trunk_note)
seg("torso", "head", 1.0, vert - ot, cerv - ot, "VERT-CERV; " + trunk_note)
knee = np.array([-0.0041, -0.3959, 0.0])  # knee_r translations at knee angle 0 (gait2392 splines)
ankle = np.array([0.0, -0.43, 0.0])
talus_in_calcn = np.array([0.04877, 0.04195, -0.00792])
mtp = np.array([0.1788, -0.002, 0.00108]); toe_tip = np.array([0.06, 0.0, 0.0])
elbow = np.array([0.013144, -0.286273, -0.009595])
ulna_radius = np.array([-0.006727, -0.013007, 0.026083])  # radius origin in the ulna frame
wrist_in_radius = np.array([-0.008797, -0.235841, 0.01361])
met3_in_radius = wrist_in_radius + [0, -0.0862 * SL, 0]
for s, m in (("r", 1.0), ("l", -1.0)):
    z = np.array([1.0, 1.0, m])
    seg(f"femur_{s}", "thigh", 1.0, [0, 0, 0], knee * z, "HJC-KJC at the femur origin and the knee joint (gait2392)")
    seg(f"tibia_{s}", "shank", 1.0, [0, 0, 0], ankle * z, "KJC-LMAL at the tibia origin and the ankle joint (gait2392)")
    seg(f"calcn_{s}", "foot", 1.35 / 1.5666, [0, 0, 0], (mtp + toe_tip) * z, "HEEL-TTIP at the calcn origin and the toe tip; foot mass split calcn+talus : toes as in gait2392 (1.35 : 0.2166 kg)")
    seg(f"toes_{s}", "foot", 0.2166 / 1.5666, [0, 0, 0], toe_tip * z, "MTP-TTIP (the toes' share of the foot with the foot's radii of gyration on the toes' length)")
    seg(f"humerus_{s}", "upper_arm", 1.0, [0, 0, 0], elbow * z, "SJC-EJC at the shoulder and elbow joints (Rajagopal2016)")
    seg(f"ulna_{s}", "forearm", 0.5, [0, 0, 0], (ulna_radius + wrist_in_radius) * z, "EJC-WJC; forearm mass split ulna : radius 1 : 1 as in Rajagopal2016")
    seg(f"radius_{s}", "forearm", 0.5, -ulna_radius * z, wrist_in_radius * z, "EJC-WJC in the radius frame; forearm mass split 1 : 1")
    seg(f"radius_{s}", "hand", 1.0, wrist_in_radius * z, met3_in_radius * z, "WJC-MET3, the hand lumped into the radius, MET3 at de Leva's hand length below the wrist")
with open(os.path.join(out, "bodies.csv"), "w") as f:
    print("body,segment,share,proximal_x,proximal_y,proximal_z,distal_x,distal_y,distal_z,slice_start,slice_end,source_height,source", file=f)
    w(bodies, f)
with open(os.path.join(out, "couplers.csv"), "w") as f:
    print("name,dependent,independent,ratio,source", file=f)
    w(couplers, f)

# ---------------------------------------------------------------------------------------
# Markers at joint centres, named after the 22 SMPL joints of HumanML3D and the CMU BVH
# skeleton's joints; foot contact spheres tangent to the floor at the default pose.
SM = "joint centre of the model (gait2392 / Rajagopal2016 geometry); name from SMPL (HumanML3D)"
SB = "joint centre of the model (gait2392 / Rajagopal2016 geometry); name from the CMU mocap BVH skeleton"
markers = []
def mark(name, body, p, src):
    markers.append([name, body, *np.round(np.asarray(p, float), 6), HG, src])
head_centre = vert - [0, 0.12 * SL, 0]
chest = xyph + [0, 0.5 * (cerv[1] - xyph[1]), 0]
acromial = np.array([0.003155, 0.3715, 0.17])  # Rajagopal2016 shoulder in the torso frame
for smpl, cmu, body, p in [
    ("pelvis", "Hips", "pelvis", midh),
    ("spine1", "Spine", "lumbar4", origin["lumbar4"] * 0),
    ("spine2", "Spine1", "lumbar1", origin["lumbar1"] * 0),
    ("spine3", None, "torso", chest - ot),
    ("neck", "Neck", "torso", cerv - ot),
    ("head", "Head", "torso", head_centre - ot),
]:
    mark(smpl, body, p, SM)
    if cmu:
        mark(cmu, body, p, SB)
for s, side, Side, m in (("r", "right", "Right", 1.0), ("l", "left", "Left", -1.0)):
    z = np.array([1.0, 1.0, m])
    collar = 0.5 * (acromial + (cerv - ot)) * z
    for smpl, cmu, body, p in [
        ("hip", "UpLeg", f"femur_{s}", [0, 0, 0]),
        ("knee", "Leg", f"tibia_{s}", [0, 0, 0]),
        ("ankle", "Foot", f"calcn_{s}", talus_in_calcn * z),
        ("foot", "ToeBase", f"toes_{s}", [0, 0, 0]),
        ("collar", "Shoulder", "torso", collar),
        ("shoulder", "Arm", f"humerus_{s}", [0, 0, 0]),
        ("elbow", "ForeArm", f"ulna_{s}", [0, 0, 0]),
        ("wrist", "Hand", f"radius_{s}", wrist_in_radius * z),
    ]:
        mark(f"{side}_{smpl}", body, p, SM)
        mark(f"{Side}{cmu}", body, p, SB)
# Pelvis landmarks of gait marker sets (Plug-in Gait names, as in the C3D trials), so that
# marker data fixes the pelvis tilt: gait2392's ASIS (its pelvis frame is this model's), the
# PSIS placed from them by Rajagopal2016's ASIS -> PSIS vector (-0.16453, 0.016918; its
# pelvis frame differs, its marker set has both landmarks).
SASI = "anterior superior iliac spine: OpenSim gait2392_Scale_MarkerSet.xml R.ASIS / L.ASIS (gait2392 pelvis frame = this model's)"
SPSI = "posterior superior iliac spine: the ASIS moved by Rajagopal2016's RASI -> RPSI vector (-0.16453, 0.016918; z 0.045 as there)"
for side, m in (("R", 1.0), ("L", -1.0)):
    asis = np.array([0.02, 0.03, 0.128 * m])
    mark(f"{side}ASI", "pelvis", asis, SASI)
    mark(f"{side}PSI", "pelvis", asis + [-0.16453047, 0.0169184, 0.045 * m - asis[2]], SPSI)
with open(os.path.join(out, "markers.csv"), "w") as f:
    print("marker,body,x,y,z,source_height,source", file=f)
    w(markers, f)

# calcn origin height at the default pose: pelvis_ty + hip + knee + ankle + (calcn origin - talus)
calcn_height = 0.95 - 0.0661 + knee[1] + ankle[1] - talus_in_calcn[1]
toes_height = calcn_height + mtp[1]
SCn = "contact sphere on gait2392's foot geometry, tangent to the floor at the default pose"
contacts = []
for s, m in (("r", 1.0), ("l", -1.0)):
    for name, body, x, zc, r, base in [
        ("heel", f"calcn_{s}", 0.012, 0.0, 0.025, calcn_height),
        ("metatarsal1", f"calcn_{s}", 0.17, -0.025, 0.015, calcn_height),
        ("metatarsal5", f"calcn_{s}", 0.145, 0.04, 0.015, calcn_height),
        ("toe_tip", f"toes_{s}", 0.05, -0.005, 0.01, toes_height),
    ]:
        contacts.append([f"{name}_{s}", body, x, round(r - base, 6), zc * m, r, HG, SCn])
with open(os.path.join(out, "contacts.csv"), "w") as f:
    print("contact,body,x,y,z,radius,source_height,source", file=f)
    w(contacts, f)
print(len(bodies), "body rows,", len(couplers), "couplers,", len(markers), "markers,", len(contacts), "contacts")

# the joint tables again, now with the lumbar chain
with open(os.path.join(out, "joints.csv"), "w") as f:
    print("joint,kind,parent,child,parent_x,parent_y,parent_z,parent_rx,parent_ry,parent_rz,child_x,child_y,child_z,child_rx,child_ry,child_rz,source_height,source", file=f)
    w(joints, f)
with open(os.path.join(out, "coordinates.csv"), "w") as f:
    print("joint,slot,coordinate,axis_x,axis_y,axis_z,function,default_value,range_min,range_max,locked,source", file=f)
    w(axes, f)
print(len(joints), "joints,", len(axes), "axes")
