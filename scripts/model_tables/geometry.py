"""Neutral-pose geometry of the lumbar tables: body placement of musculo's
default model (pelvis = gait2392 pelvis frame = Christophy sacrum frame;
lumbar5..lumbar1, torso placed by Christophy et al. 2012's Lumbar_C_210 joint
offsets; femur_r/l at gait2392's hip centres) and musculotendon path length
with cylinder/sphere wrapping (MuJoCo-style: wrap only if the straight segment
crosses the surface, on the side given by the quadrant)."""
import math
import numpy as np

# Lumbar_C_210 (Christophy et al. 2012) joint offsets: body origin of the child
# in the parent frame = location_in_parent - location_in_child (all joint
# orientations are zero in that model).  Read from the figures in
# lumbar_joints.csv by callers; these defaults are only for the build script.
def body_origins(joints):
    """joints: list of dicts with parent, child, parent_loc, child_loc.
    Returns dict body -> world origin at the neutral pose (pelvis at 0)."""
    W = {"pelvis": np.zeros(3)}
    for j in joints:
        W[j["child"]] = W[j["parent"]] + np.asarray(j["parent_loc"]) - np.asarray(j["child_loc"])
    return W


def _wrap2d(p, q, r, side):
    """Shortest path from p to q (2-D, outside the circle |x|=r) around the
    circle on the half-plane given by unit vector `side`; None if the straight
    segment does not cross the circle."""
    d = q - p
    t = -np.dot(p, d) / max(np.dot(d, d), 1e-300)
    t = min(max(t, 0.0), 1.0)
    closest = p + t * d
    if np.linalg.norm(closest) >= r or np.linalg.norm(p) <= r or np.linalg.norm(q) <= r:
        return None
    def tangents(x):
        n = np.linalg.norm(x)
        a = math.acos(r / n)
        base = math.atan2(x[1], x[0])
        return [base + a, base - a]
    best = None
    for ap in tangents(p):
        for aq in tangents(q):
            tp = r * np.array([math.cos(ap), math.sin(ap)])
            tq = r * np.array([math.cos(aq), math.sin(aq)])
            dang = (aq - ap + math.pi) % (2 * math.pi) - math.pi
            mid = ap + dang / 2
            m = np.array([math.cos(mid), math.sin(mid)])
            if np.dot(m, side) <= 0:
                continue
            L = np.linalg.norm(tp - p) + r * abs(dang) + np.linalg.norm(q - tq)
            if best is None or L < best:
                best = L
    return best


QUAD = {"+x": (0, 1), "-x": (0, -1), "+y": (1, 1), "-y": (1, -1), "+z": (2, 1), "-z": (2, -1)}


def segment_length(P, Q, wrap):
    """Length of the segment P->Q (world, neutral pose) with an optional wrap
    object dict: type, centre (world), R (3x3 world rotation of the wrap
    frame), radius, quadrant."""
    if wrap is None:
        return float(np.linalg.norm(Q - P))
    c, R, r = wrap["centre"], wrap["R"], wrap["radius"]
    p = R.T @ (P - c)
    q = R.T @ (Q - c)
    if wrap["quadrant"] == "all" and wrap["type"] == "sphere":
        # unconstrained sphere: with d1, d2 the endpoints' distances from the centre and D the
        # angle between them, straight while D <= b1 + b2 (b_i = acos(r/d_i)), else the
        # tangents h_i = sqrt(d_i^2 - r^2) plus the arc r (D - b1 - b2)
        d1, d2 = np.linalg.norm(p), np.linalg.norm(q)
        D = math.acos(min(max(np.dot(p, q) / (d1 * d2), -1.0), 1.0))
        b1, b2 = math.acos(r / d1), math.acos(r / d2)
        if D <= b1 + b2:
            return float(np.linalg.norm(Q - P))
        return float(math.sqrt(d1 * d1 - r * r) + math.sqrt(d2 * d2 - r * r) + r * (D - b1 - b2))
    ax, sg = QUAD[wrap["quadrant"]]
    s3 = np.zeros(3); s3[ax] = sg
    if wrap["type"] == "cylinder":
        side = s3[:2]
        if np.linalg.norm(side) == 0:
            return float(np.linalg.norm(Q - P))
        L2 = _wrap2d(p[:2], q[:2], r, side / np.linalg.norm(side))
        if L2 is None:
            return float(np.linalg.norm(Q - P))
        return float(math.hypot(L2, q[2] - p[2]))
    # sphere: 2-D problem in the plane through the centre, p and q
    e1 = p / np.linalg.norm(p)
    n = np.cross(p, q)
    if np.linalg.norm(n) < 1e-12:
        return float(np.linalg.norm(Q - P))
    e2 = np.cross(n / np.linalg.norm(n), e1)
    side = np.array([np.dot(s3, e1), np.dot(s3, e2)])
    if np.linalg.norm(side) < 1e-9:
        return float(np.linalg.norm(Q - P))
    L2 = _wrap2d(np.array([np.linalg.norm(p), 0.0]), np.array([np.dot(q, e1), np.dot(q, e2)]),
                 r, side / np.linalg.norm(side))
    return float(np.linalg.norm(Q - P)) if L2 is None else float(L2)


def path_length(points, wraps, origins, wrapobjs, coord_values=None):
    """points: list of dicts (index, body, xyz, type, coordinate, range_min,
    range_max); wraps: list of dicts (wrap_object, range_start, range_end),
    1-based point indices.  All bodies are unrotated at the neutral pose."""
    coord_values = coord_values or {}
    act = []
    for p in points:
        if p["type"] == "conditional":
            v = coord_values.get(p["coordinate"], 0.0)
            if not (p["range_min"] <= v <= p["range_max"]):
                continue
        act.append(p)
    L = 0.0
    for a, b in zip(act[:-1], act[1:]):
        P = origins[a["body"]] + np.asarray(a["xyz"])
        Q = origins[b["body"]] + np.asarray(b["xyz"])
        w = None
        for wr in wraps:
            if wr["range_start"] <= a["index"] and b["index"] <= wr["range_end"]:
                wo = wrapobjs[wr["wrap_object"]]
                w = dict(type=wo["type"], radius=wo["radius"], quadrant=wo["quadrant"],
                         centre=origins[wo["body"]] + np.asarray(wo["t"]), R=wo["R"])
        L += segment_length(P, Q, w)
    return L
