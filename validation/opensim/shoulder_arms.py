"""Shoulder moment arms of the default model's right arm at a handful of poses, from OpenSim
4.6's own lengths (central differences, h = 1e-4 rad): r = -dl/dq about arm_flex_r, arm_add_r,
arm_rot_r (and elbow_flex_r). Used to compare the shoulder paths before and after a change of
their wrap surfaces (data/model/README.md, arm).

usage: python shoulder_arms.py MODEL.osim [--json OUT.json]
"""

import argparse
import json
import sys

import numpy as np

import osimval as ov

osim = ov.osim
ov.quiet_opensim()

MUSCLES = ["DELT1", "DELT2", "DELT3", "PECM1", "SUPSP", "INFSP", "SUBSC", "TMAJ",
           "BIClong", "BICshort", "TRIlong"]
COORDS = ["arm_flex_r", "arm_add_r", "arm_rot_r", "elbow_flex_r"]
# (label, {coordinate: degrees}); elbow at 90 deg flexion throughout unless given
POSES = [
    ("side", {}),
    ("flex45", {"arm_flex_r": 45}),
    ("flex90", {"arm_flex_r": 90}),
    ("abd45", {"arm_add_r": -45}),
    ("abd90", {"arm_add_r": -90}),
    ("rot+45", {"arm_rot_r": 45}),
    ("rot-45", {"arm_rot_r": -45}),
    ("abd90 rot+45", {"arm_add_r": -90, "arm_rot_r": 45}),
]
H = 1e-4


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("model")
    ap.add_argument("--json")
    args = ap.parse_args()
    model = osim.Model(args.model)
    state = model.initSystem()
    cs = model.getCoordinateSet()
    ms = model.getMuscles()

    def set_pose(pose):
        for i in range(cs.getSize()):
            c = cs.get(i)
            c.setValue(state, c.getDefaultValue(), False)
        cs.get("elbow_flex_r").setValue(state, np.radians(90), False)
        for k, v in pose.items():
            cs.get(k).setValue(state, np.radians(v), False)
        model.realizePosition(state)

    out = {}
    for label, pose in POSES:
        out[label] = {}
        for m in MUSCLES:
            mu = ms.get(m + "_r")
            arms = []
            for c in COORDS:
                ls = []
                for s in (1, -1):
                    p = dict(pose)
                    base = p.get(c, 90.0 if c == "elbow_flex_r" else 0.0)
                    p[c] = base + s * np.degrees(H)
                    set_pose(p)
                    ls.append(mu.getLength(state))
                arms.append(-(ls[0] - ls[1]) / (2 * H))
            out[label][m] = arms
    print("moment arms (mm) about " + ", ".join(COORDS) + "; elbow 90 deg")
    for label, _ in POSES:
        print(f"-- {label}")
        for m in MUSCLES:
            print(f"   {m:9s} " + " ".join(f"{1e3 * r:8.1f}" for r in out[label][m]))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
