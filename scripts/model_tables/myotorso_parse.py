"""Read MyoSuite's MyoTorso MJCF (read in place, never copied) into plain Python
structures: body tree, sites, wrapping geoms, tendon paths, muscle actuators.

Source: /work/shared/reference/myo_sim/torso (MyoSuite myo_sim, Apache-2.0),
a MuJoCo conversion of Christophy et al. 2012's "Constrained lumbar spine
model" (Lumbar_C_210).
"""
import math
import os
import xml.etree.ElementTree as ET

import numpy as np

SRC = os.environ.get("MYOTORSO_DIR", "/work/shared/reference/myo_sim/torso")
CHAIN = os.path.join(SRC, "assets", "myotorso_chain.xml")
ASSETS = os.path.join(SRC, "assets", "myotorso_assets.xml")


def vec(s, n=3):
    v = [float(x) for x in s.split()]
    assert len(v) == n, s
    return np.array(v)


def quat_to_mat(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def rot_axis(axis, a):
    c, s = math.cos(a), math.sin(a)
    if axis == 0:
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == 1:
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def euler_xyz_intrinsic(e):
    """MuJoCo default eulerseq 'xyz' (intrinsic, body-fixed) == OpenSim
    body-fixed X-Y-Z: R = Rx(a) Ry(b) Rz(c)."""
    return rot_axis(0, e[0]) @ rot_axis(1, e[1]) @ rot_axis(2, e[2])


def frame_of(el):
    pos = vec(el.get("pos", "0 0 0"))
    if el.get("quat") is not None:
        R = quat_to_mat(vec(el.get("quat"), 4))
    elif el.get("euler") is not None:
        R = euler_xyz_intrinsic(vec(el.get("euler")))
    else:
        R = np.eye(3)
    return pos, R


class Body:
    def __init__(self, name, parent, pos, R):
        self.name, self.parent, self.pos, self.R = name, parent, pos, R
        self.sites = {}
        self.geoms = {}
        self.joints = []
        self.inertial = None


def parse_chain():
    root = ET.parse(CHAIN).getroot()
    bodies = {}

    def walk(el, parent):
        pos, R = frame_of(el)
        b = Body(el.get("name"), parent, pos, R)
        bodies[b.name] = b
        for ch in el:
            if ch.tag == "body":
                walk(ch, b.name)
            elif ch.tag == "site":
                p, Rs = frame_of(ch)
                b.sites[ch.get("name")] = p
            elif ch.tag == "geom" and ch.get("name"):
                p, Rg = frame_of(ch)
                cls = ch.get("class", "")
                typ = ch.get("type") or ("cylinder" if cls == "myoBack_wrap" else "sphere")
                size = [float(x) for x in ch.get("size", "0").split()]
                b.geoms[ch.get("name")] = dict(type=typ, pos=p, R=Rg, size=size, cls=cls,
                                               mesh=ch.get("mesh"))
            elif ch.tag == "joint":
                b.joints.append(dict(name=ch.get("name"), type=ch.get("type", "hinge"),
                                     axis=vec(ch.get("axis", "0 0 1")),
                                     pos=vec(ch.get("pos", "0 0 0")),
                                     range=ch.get("range")))
            elif ch.tag == "inertial":
                b.inertial = dict(pos=vec(ch.get("pos")), mass=float(ch.get("mass")),
                                  quat=ch.get("quat"), diag=ch.get("diaginertia"))

    for el in root:
        if el.tag == "body":
            walk(el, None)
    return bodies


def parse_assets():
    root = ET.parse(ASSETS).getroot()
    tendons = {}
    for sp in root.iter("spatial"):
        path = []
        for ch in sp:
            if ch.tag == "site":
                path.append(("site", ch.get("site"), None))
            elif ch.tag == "geom":
                path.append(("geom", ch.get("geom"), ch.get("sidesite")))
        tendons[sp.get("name")] = path
    muscles = []
    for g in root.iter("general"):
        if g.get("class") != "myoBack_muscle" or g.get("tendon") is None:
            continue
        gp = [float(x) for x in g.get("gainprm").split()]
        lr = [float(x) for x in g.get("lengthrange").split()]
        muscles.append(dict(name=g.get("name"), tendon=g.get("tendon"), gainprm=gp,
                            lengthrange=lr, dynprm=g.get("dynprm")))
    equality = []
    for j in root.iter("joint"):
        if j.get("joint1") is not None:
            equality.append(dict(name=j.get("name"), joint1=j.get("joint1"),
                                 joint2=j.get("joint2"),
                                 polycoef=[float(x) for x in j.get("polycoef").split()]))
    return tendons, muscles, equality


def site_body_map(bodies):
    m = {}
    for b in bodies.values():
        for s, p in b.sites.items():
            assert s not in m, s
            m[s] = (b.name, p)
    return m


def geom_body_map(bodies):
    m = {}
    for b in bodies.values():
        for g, d in b.geoms.items():
            m[g] = (b.name, d)
    return m


if __name__ == "__main__":
    bodies = parse_chain()
    for b in bodies.values():
        print(b.name, b.parent, b.pos, [j["name"] for j in b.joints], len(b.sites), list(b.geoms))
    tendons, muscles, eq = parse_assets()
    print(len(tendons), len(muscles), len(eq))
