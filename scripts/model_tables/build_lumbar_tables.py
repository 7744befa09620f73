#!/usr/bin/env python3
"""Provenance script: derives data/model/lumbar_*.csv from
  * MyoSuite MyoTorso (myo_sim/torso, Apache-2.0; MuJoCo conversion of
    Christophy et al. 2012's Lumbar_C_210) -- read in place;
  * the joint figures of Lumbar_C_210 (Christophy et al. 2012, as
    redistributed with updated axial-rotation couplers by M. Millard,
    github.com/mjhmilla/kinematicPassengerModel,
    models/Christophy2012_axialRotationUpd_skeletonOnly.osim);
  * gait2392 (opensim-models, Gait2392_Simbody) for the psoas' femoral part;
  * Rajagopal et al. 2016 (opensim-models, Rajagopal2016.osim) for the psoas'
    pelvic-brim wrap idea (here a sphere at the hip centre, brim_paths.py).
The CSVs are the authored source; this script documents how their figures
were obtained (see data/model/README_lumbar.md).  Run from the repo root:
    python3 scripts/model_tables/build_lumbar_tables.py
"""
import csv
import math
import os
import statistics
import sys
import xml.etree.ElementTree as ET

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from myotorso_parse import parse_chain, parse_assets, site_body_map  # noqa: E402
from geometry import body_origins, path_length  # noqa: E402
from brim_paths import BRIM_RADIUS, assert_outside, brim_sphere, rot_xyz  # noqa: E402

OUT = "data/model"
GAIT2392 = os.environ.get(
    "GAIT2392", "/work/shared/reference/opensim-models/Models/Gait2392_Simbody/"
                "gait2392_thelen2003muscle.osim")

SRC_MYO = "MyoTorso2024"          # MyoSuite myo_sim/torso (Walia et al. 2025)
SRC_CHR = "Christophy2012"        # Lumbar_C_210 figures
SRC_MIL = "Christophy2012+Millard2024AR"
SRC_G23 = "Delp1990/gait2392"

# --- Lumbar_C_210 joints (figures from the .osim; orientations all zero) ---
# name, parent, child, location_in_parent, location_in_child,
# ratio FE, ratio LB, ratio AR (Millard's normalised update), AR as published
JOINTS = [
    ("L5_S1_IVDjnt", "pelvis", "lumbar5", (-0.098, 0.071, 0.0), (0.0, 0.0, 0.0),
     0.125, 0.1356, 0.207792207792208, 0.0355556),
    ("L4_L5_IVDjnt", "lumbar5", "lumbar4", (0.010, 0.0296, 0.0), (0.001, -0.0025, 0.0),
     0.185, 0.181086173, 0.220779220779221, 0.03778),
    ("L3_L4_IVDjnt", "lumbar4", "lumbar3", (0.0, 0.032, 0.0), (-0.0006, -0.0012, 0.0),
     0.204, 0.245331965, 0.220779220779221, 0.03778),
    ("L2_L3_IVDjnt", "lumbar3", "lumbar2", (-0.008, 0.0312, 0.0), (-0.0013, -0.0039, 0.0),
     0.231, 0.250128491, 0.181818181818182, 0.03111),
    ("L1_L2_IVDjnt", "lumbar2", "lumbar1", (-0.010, 0.025, 0.0), (0.0014, -0.0038, 0.0),
     0.255, 0.188, 0.168831168831169, 0.02889),
    # Lumbar_C_210 welds the torso to lumbar1 with the torso origin at
    # (0.0025, -0.089, 0) in lumbar1.  We keep that relative placement but put
    # the joint at the T12 inferior endplate: the T12 mesh origin in the torso
    # frame (-0.019, 0.121, 0) (MyoTorso torso_geom_1 = thoracic12), i.e.
    # (-0.0165, 0.032, 0) in lumbar1.
    ("L1_T12_IVDjnt", "lumbar1", "torso", (0.0025 - 0.019, -0.089 + 0.121, 0.0), (-0.019, 0.121, 0.0),
     0.0, 0.0, 0.0, 0.0),
]

BODY_MAP = {"sacrum": "pelvis", "lumbar5": "lumbar5", "lumbar4": "lumbar4",
            "lumbar3": "lumbar3", "lumbar2": "lumbar2", "lumbar1": "lumbar1",
            "torso": "torso", "Abdomen": "lumbar5"}
# MyoTorso's massless 'Abdomen' plate is a child of lumbar5 at (0.098, 0.0711, 0)
# (slides locked, rotation 0.6429*flex_extension); at the neutral pose its
# points are rigidly re-expressed in lumbar5.
ABDOMEN_IN_L5 = np.array([0.098, 0.0711, 0.0])

GROUPS = [("Ps_", "psoas_major"), ("rect_abd", "rectus_abdominis"), ("EO", "external_oblique"),
          ("IO", "internal_oblique"), ("IL_", "iliocostalis"), ("LTp", "longissimus"),
          ("MF_", "multifidus"), ("QL_", "quadratus_lumborum")]

MIRROR = np.array([1.0, 1.0, -1.0])

# MyoSuite's torso wraps still enter the neutral lengths (rule R) as when the tables were
# made, but are left out of the written tables: fitted to MyoSuite's adjusted vertebrae, they wrap around the far side of their
# surfaces in our geometry (README_lumbar.md, "Wrap surfaces removed from the build").
WRITE_MYOSUITE_WRAPS = False


def group_of(name):
    for pre, g in GROUPS:
        if name.startswith(pre):
            return g
    raise ValueError(name)


def to_our_frame(body, p):
    p = np.asarray(p, float)
    if body == "Abdomen":
        p = p + ABDOMEN_IN_L5
    return BODY_MAP[body], p


def quadrant_of(direction, gtype):
    """MuJoCo sidesite direction (wrap-geom frame) -> OpenSim quadrant."""
    d = np.array(direction, float)
    if gtype == "cylinder":
        d[2] = 0.0
    ax = int(np.argmax(np.abs(d)))
    return ("+" if d[ax] > 0 else "-") + "xyz"[ax]


def gait2392_psoas(side):
    root = ET.parse(GAIT2392).getroot()
    for el in root.iter():
        if el.get("name") == f"psoas_{side}" and el.tag.endswith("Muscle"):
            pts = []
            for pp in el.iter():
                if pp.tag in ("PathPoint", "ConditionalPathPoint"):
                    frame = pp.find("socket_parent_frame").text.split("/")[-1]
                    loc = [float(x) for x in pp.find("location").text.split()]
                    d = dict(name=pp.get("name"), body=frame, xyz=loc, type="fixed",
                             coordinate="", range_min="", range_max="")
                    if pp.tag == "ConditionalPathPoint":
                        d["type"] = "conditional"
                        d["coordinate"] = pp.find("socket_coordinate").text.split("/")[-1]
                        r = [float(x) for x in pp.find("range").text.split()]
                        d["range_min"], d["range_max"] = r
                    pts.append(d)
            return pts
    raise KeyError(side)


def hip_centre(side):
    root = ET.parse(GAIT2392).getroot()
    for j in root.iter("CustomJoint"):
        if j.get("name") == f"hip_{side}":
            for f in j.iter("PhysicalOffsetFrame"):
                if f.get("name") == "pelvis_offset":
                    return np.array([float(x) for x in f.find("translation").text.split()])
    raise KeyError(side)


def main():
    bodies = parse_chain()
    tendons, muscles, _eq = parse_assets()
    smap = site_body_map(bodies)
    mus = {m["name"]: m for m in muscles}

    joints = [dict(parent=j[1], child=j[2], parent_loc=j[3], child_loc=j[4]) for j in JOINTS]
    origins = body_origins(joints)
    for s in "rl":
        origins[f"femur_{s}"] = hip_centre(s)

    # ---------------- wrap objects (from the right-side muscles) -------------
    gbody = {}
    for b in bodies.values():
        for g, d in b.geoms.items():
            gbody[g] = (b.name, d)
    wrapobjs = {}

    def wrap_object_for(geom, sidesite, mirror):
        bname, d = gbody[geom]
        sb, sp = smap[sidesite]
        assert sb == bname, (geom, sidesite)
        direction = d["R"].T @ (sp - d["pos"])
        gtype = d["type"]
        pos = d["pos"].copy()
        if mirror:
            geom = geom.replace("_r_", "_l_") if "_r_" in geom else geom
            bname2, d2 = gbody[geom]
            pos2 = d2["pos"]
            assert np.allclose(pos2, pos * MIRROR, atol=1e-9), geom
            direction = direction * MIRROR
            pos = pos2
        q = quadrant_of(direction, gtype)
        name = f"{geom}_{'p' if q[0] == '+' else 'n'}{q[1]}"
        body, t = to_our_frame(bname, pos)
        if name not in wrapobjs:
            wrapobjs[name] = dict(name=name, body=body, type=gtype, t=t, R=np.eye(3),
                                  radius=d["size"][0],
                                  length=(2 * d["size"][1] if gtype == "cylinder" else ""),
                                  quadrant=q)
        return name

    wo_header = ["name", "body", "type", "rot_x", "rot_y", "rot_z", "tx", "ty", "tz",
                 "radius", "length", "dim_x", "dim_y", "dim_z", "quadrant", "source"]
    brim_rows = [brim_sphere("PS", s, hip_centre("r"), wo_header) for s in "rl"]
    for r in brim_rows:
        rot = [float(r[k]) for k in ("rot_x", "rot_y", "rot_z")]
        wrapobjs[r["name"]] = dict(name=r["name"], body=r["body"], type=r["type"],
                                   t=np.array([float(r[k]) for k in ("tx", "ty", "tz")]),
                                   R=rot_xyz(*rot), radius=float(r["radius"]),
                                   length="", quadrant=r["quadrant"])

    # ---------------- paths --------------------------------------------------
    rights = sorted(n for n in mus if n.endswith("_r"))
    rows_m, rows_p, rows_w = [], [], []
    asym = []
    lengths = {}
    g23 = {s: gait2392_psoas(s) for s in "rl"}

    def build_path(rname, mirror):
        pts, wraps = [], []
        for kind, nm, ss in tendons[mus[rname]["tendon"]]:
            if kind == "site":
                b, p = smap[nm]
                body, xyz = to_our_frame(b, p)
                if mirror:
                    xyz = xyz * MIRROR
                pts.append(dict(index=len(pts) + 1, body=body, xyz=xyz, type="fixed",
                                coordinate="", range_min="", range_max=""))
            else:
                wname = wrap_object_for(nm, ss, mirror)
                # wraps the segment between the previous and the next site
                wraps.append(dict(wrap_object=wname, range_start=len(pts), range_end=len(pts) + 1))
        return pts, wraps

    # MyoTorso's own neutral lengths (its body placement) for the fit analysis
    def myo_length(name):
        W = {}
        def get(n):
            if n not in W:
                b = bodies[n]
                if b.parent is None:
                    W[n] = (np.zeros(3), np.eye(3))
                else:
                    o, R = get(b.parent)
                    W[n] = (o + R @ b.pos, R @ b.R)
            return W[n]
        P = []
        for kind, nm, ss in tendons[mus[name]["tendon"]]:
            if kind == "site":
                b, p = smap[nm]
                o, R = get(b)
                P.append(o + R @ p)
        return sum(np.linalg.norm(P[i + 1] - P[i]) for i in range(len(P) - 1))

    fit = {}
    for n, m in mus.items():
        gp, lr = m["gainprm"], m["lengthrange"]
        L0 = (lr[1] - lr[0]) / (gp[1] - gp[0])
        Lts = lr[0] - gp[0] * L0
        lm = myo_length(n)
        nn = (lm - Lts) / L0
        phi = 1.0 - Lts / lm
        ok = Lts >= 0.0 and 0.2 <= phi <= 1.0 and L0 <= 1.5 * lm
        fit[n] = dict(F=gp[2], L0=L0, Lts=Lts, lmyo=lm, n=nn, phi=phi, ok=ok, vmax=gp[6])

    group_phi = {}
    for n, f in fit.items():
        if f["ok"]:
            group_phi.setdefault(group_of(n), []).append(f["phi"])
    all_phi = [f["phi"] for f in fit.values() if f["ok"]]

    for rname in rights:
        lname = rname[:-2] + "_l"
        base = rname[:-2]
        grp = group_of(rname)
        # parameters (r/l averaged; see README_lumbar.md, rule R)
        fr, fl = fit[rname], fit[lname]
        F = 0.5 * (fr["F"] + fl["F"])
        oks = [f["phi"] for f in (fr, fl) if f["ok"]]
        if oks:
            phi, how = sum(oks) / len(oks), "fit"
        elif grp in group_phi:
            phi, how = statistics.median(group_phi[grp]), "group-median"
        else:
            phi, how = statistics.median(all_phi), "all-median"
        nfl = min(max(0.5 * (fr["n"] + fl["n"]), 0.8), 1.2)
        vmax = fr["vmax"]
        for side, name, mirror in (("r", rname, False), ("l", lname, True)):
            pts, wraps = build_path(rname, mirror)
            # record source asymmetry (left as given vs mirrored right)
            if mirror:
                ptsL, _ = build_path(lname, False)
                dmax = max((np.abs(np.asarray(a["xyz"]) - np.asarray(b["xyz"])).max()
                            if a["body"] == b["body"] else 9.0) for a, b in zip(pts, ptsL)) \
                    if len(pts) == len(ptsL) else 9.0
                if dmax > 1e-3:
                    asym.append((lname, dmax))
            l_lumbar = path_length(pts, wraps, origins, wrapobjs)
            extra = 0.0
            if grp == "psoas_major":
                # extend to the femur along gait2392's psoas (P4-P5 on the femur); P2 of
                # the fascicle is the pelvic-brim point shared with gait2392's psoas-P2.
                # gait2392's P3 (a brim point conditional on hip flexion, whose switch
                # made the length jump) is replaced by Rajagopal2016's PS_at_brim
                # replaced in turn by a sphere at the hip centre (brim_paths.py).
                g = g23[side]
                assert np.allclose(g[1]["xyz"], pts[-1]["xyz"], atol=1e-6), (name, g[1], pts[-1])
                assert g[2]["type"] == "conditional" and g[2]["body"] == "pelvis", g[2]
                brim = len(pts)
                for gp_ in g[3:]:
                    pts.append(dict(index=len(pts) + 1, body=gp_["body"], xyz=np.array(gp_["xyz"]),
                                    type=gp_["type"], coordinate=gp_["coordinate"],
                                    range_min=gp_["range_min"], range_max=gp_["range_max"]))
                assert_outside(name, pts[brim - 1]["xyz"], pts[brim]["xyz"],
                               origins[f"femur_{side}"], BRIM_RADIUS["PS"])
                wraps.append(dict(wrap_object=f"PS_at_brim_{side}", range_start=brim,
                                  range_end=brim + 1))
                extra = path_length(pts, wraps, origins, wrapobjs) - l_lumbar
            Lopt = phi * l_lumbar / nfl
            Lts = (1.0 - phi) * l_lumbar + extra
            lengths[name] = (l_lumbar + extra, Lopt, Lts)
            src = f"{SRC_CHR} via {SRC_MYO}: F=gainprm[2] mean r/l; Lopt,Lts rule R ({how}, phi={phi:.3f}, n={nfl:.3f})"
            if grp == "psoas_major":
                src += (f"; +{extra:.4f} m tendon to femur ({SRC_G23} psoas path without its "
                        f"conditional brim point, over the PS_at_brim sphere of brim_paths.py)")
            rows_m.append(dict(name=name, group=grp, side=side, max_isometric_force=f"{F:.4f}",
                               optimal_fiber_length=f"{Lopt:.5f}", tendon_slack_length=f"{Lts:.5f}",
                               pennation_angle="0", max_contraction_velocity=f"{vmax:g}", source=src))
            for p in pts:
                psrc = SRC_G23 if p["body"].startswith("femur") or p["type"] == "conditional" else \
                    (f"{SRC_MYO} ({SRC_CHR})" + ("; mirrored from _r" if mirror else ""))
                rows_p.append(dict(muscle=name, index=p["index"], type=p["type"], body=p["body"],
                                   x=f"{p['xyz'][0]:.6f}", y=f"{p['xyz'][1]:.6f}", z=f"{p['xyz'][2]:.6f}",
                                   coordinate=p["coordinate"],
                                   range_min=("" if p["range_min"] == "" else f"{p['range_min']:g}"),
                                   range_max=("" if p["range_max"] == "" else f"{p['range_max']:g}"),
                                   source=psrc))
            if not WRITE_MYOSUITE_WRAPS:
                wraps = [w for w in wraps if "_at_brim_" in w["wrap_object"]]
            for k, w in enumerate(wraps, 1):
                rows_w.append(dict(muscle=name, order=k, wrap_object=w["wrap_object"], method="hybrid",
                                   range_start=w["range_start"], range_end=w["range_end"]))

    os.makedirs(OUT, exist_ok=True)

    def write(fn, header, rows):
        with open(os.path.join(OUT, fn), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=header, lineterminator="\n")
            w.writeheader()
            for r in rows:
                w.writerow(r)

    write("lumbar_muscles.csv", ["name", "group", "side", "max_isometric_force", "optimal_fiber_length",
                                 "tendon_slack_length", "pennation_angle", "max_contraction_velocity",
                                 "source"], rows_m)
    write("lumbar_path_points.csv", ["muscle", "index", "type", "body", "x", "y", "z", "coordinate",
                                     "range_min", "range_max", "source"], rows_p)
    write("lumbar_muscle_wraps.csv", ["muscle", "order", "wrap_object", "method", "range_start",
                                      "range_end"], rows_w)
    wo_rows = list(brim_rows)
    for w in sorted(wrapobjs.values(), key=lambda w: w["name"]):
        if "_at_brim_" in w["name"] or not WRITE_MYOSUITE_WRAPS:
            continue
        wo_rows.append(dict(name=w["name"], body=w["body"], type=w["type"], rot_x=0, rot_y=0, rot_z=0,
                            tx=f"{w['t'][0]:.6f}", ty=f"{w['t'][1]:.6f}", tz=f"{w['t'][2]:.6f}",
                            radius=f"{w['radius']:g}",
                            length=("" if w["length"] == "" else f"{w['length']:g}"),
                            dim_x="", dim_y="", dim_z="", quadrant=w["quadrant"],
                            source=f"{SRC_MYO} geom (quadrant from MuJoCo sidesite)"))
    write("lumbar_wrap_objects.csv", wo_header, wo_rows)

    jrows = []
    for (name, par, ch, lp, lc, rfe, rlb, rar, rar0) in JOINTS:
        jrows.append(dict(name=name, parent=par, child=ch,
                          parent_x=lp[0], parent_y=lp[1], parent_z=lp[2],
                          child_x=lc[0], child_y=lc[1], child_z=lc[2],
                          parent_rot_x=0, parent_rot_y=0, parent_rot_z=0,
                          child_rot_x=0, child_rot_y=0, child_rot_z=0,
                          axis1="0 0 1", axis2="1 0 0", axis3="0 1 0",
                          ratio_extension=rfe, ratio_bending=rlb, ratio_rotation=rar,
                          ratio_rotation_published=rar0,
                          source=(f"{SRC_CHR} (Lumbar_C_210 joint/couplers); AR ratios {SRC_MIL}"
                                  if name != "L1_T12_IVDjnt" else
                                  f"{SRC_CHR} torsojnt weld offset; joint placed at T12 mesh origin of {SRC_MYO}")))
    write("lumbar_joints.csv", ["name", "parent", "child", "parent_x", "parent_y", "parent_z",
                                "child_x", "child_y", "child_z", "parent_rot_x", "parent_rot_y",
                                "parent_rot_z", "child_rot_x", "child_rot_y", "child_rot_z",
                                "axis1", "axis2", "axis3", "ratio_extension", "ratio_bending",
                                "ratio_rotation", "ratio_rotation_published", "source"], jrows)

    # vertebral bodies (Lumbar_C_210 figures; inertia about the COM, body axes)
    brows = []
    for b in ["lumbar5", "lumbar4", "lumbar3", "lumbar2", "lumbar1", "torso"]:
        inn = bodies[b].inertial
        brows.append(dict(body=b, mass=inn["mass"], com_x=inn["pos"][0], com_y=inn["pos"][1],
                          com_z=inn["pos"][2]))
    # OpenSim inertia (xx, yy, zz) of Lumbar_C_210; MyoTorso lists the same
    # values as diaginertia in a quat-rotated (x<->y swapped) principal frame.
    I = {"lumbar5": (0.01219, 0.01765, 0.00546), "lumbar4": (0.01123, 0.01643, 0.0052),
         "lumbar3": (0.01066, 0.01608, 0.00551), "lumbar2": (0.01091, 0.01682, 0.00591),
         "lumbar1": (0.01113, 0.01753, 0.0064), "torso": (0.165, 0.15, 0.125)}
    for r in brows:
        r["ixx"], r["iyy"], r["izz"] = I[r["body"]]
        r["ixy"] = r["ixz"] = r["iyz"] = 0
        r["source"] = SRC_CHR + " (torso = thorax+head+arms lumped, 18.619 kg)" if r["body"] == "torso" else SRC_CHR
    write("lumbar_bodies.csv", ["body", "mass", "com_x", "com_y", "com_z", "ixx", "iyy", "izz", "ixy", "ixz",
                                "iyz", "source"], brows)

    # ---------------- report -------------------------------------------------
    nfit = sum(1 for n in rights if fit[n]["ok"] or fit[n[:-2] + "_l"]["ok"])
    print(f"muscles: {len(rows_m)}  points: {len(rows_p)}  wraps: {len(rows_w)}  wrap objects: {len(wrapobjs)}")
    print(f"pairs with a usable MyoTorso fit (rule R 'fit'): {nfit} of {len(rights)}")
    print("group phi medians:", {g: round(statistics.median(v), 3) for g, v in group_phi.items()},
          "all:", round(statistics.median(all_phi), 3))
    print("source left/right asymmetries (>1 mm) replaced by the mirrored right side:")
    for n, d in asym:
        print(f"  {n}: {d*1000:.1f} mm")


if __name__ == "__main__":
    main()
