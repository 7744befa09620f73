#!/usr/bin/env python3
"""Estimate the similarity transform (scale s, rotation R, translation t) that maps
points expressed in a Holzbaur et al. (2005) / MoBL-ARMS body frame onto the
corresponding Hamner (2010) / Rajagopal et al. (2016) body frame, p' = s R p + t.

Method: iterative closest point (ICP) with a similarity (Umeyama) fit between the
bone surface meshes the two models display in those frames, started from the joint
landmarks both models share (elbow centre + flexion axis for the humerus; the
frame origin for the forearm bones).  Mesh vertices are read from the .vtp files
(ASCII VTK PolyData) given on the command line; nothing is copied into the repo.

usage: register_arm_frames.py SRC.vtp DST.vtp [--fix-origin]
(--fix-origin: t = 0, i.e. the two frame origins, which are joint centres in both
models, are held coincident)
prints s, R (row-major), t, RMS residual (m) and xyz-body-fixed Euler angles.
"""
import sys, re
import numpy as np

def read_vtp_points(path):
    txt = open(path).read()
    m = re.search(r'<Points>\s*<DataArray[^>]*>(.*?)</DataArray>', txt, re.S)
    return np.array(m.group(1).split(), float).reshape(-1, 3)

def umeyama(a, b, fix_origin=False):
    """best s,R,t with b ~ s R a + t (t = 0 when fix_origin)"""
    ma, mb = a.mean(0), b.mean(0)
    if fix_origin:
        ma, mb = np.zeros(3), np.zeros(3)
    A, B = a - ma, b - mb
    U, S, Vt = np.linalg.svd(B.T @ A / len(a))
    D = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        D[2, 2] = -1
    R = U @ D @ Vt
    s = np.trace(np.diag(S) @ D) / (A ** 2).sum(1).mean()
    return s, R, mb - s * R @ ma

def icp(src, dst, s, R, t, iters=200, fix_origin=False):
    for _ in range(iters):
        y = (s * (R @ src.T)).T + t
        d2 = ((y[:, None, :] - dst[None, :, :]) ** 2).sum(-1)
        j = d2.argmin(1)
        # symmetric correspondences: also dst -> nearest moved src
        i = d2.argmin(0)
        a = np.vstack([src, src[i]])
        b = np.vstack([dst[j], dst])
        s, R, t = umeyama(a, b, fix_origin)
    y = (s * (R @ src.T)).T + t
    d2 = ((y[:, None, :] - dst[None, :, :]) ** 2).sum(-1)
    rms = np.sqrt(np.concatenate([d2.min(1), d2.min(0)]).mean())
    return s, R, t, rms

def euler_xyz_body(R):
    # R = Rx(a) Ry(b) Rz(c)
    b = np.arcsin(np.clip(R[0, 2], -1, 1))
    a = np.arctan2(-R[1, 2], R[2, 2])
    c = np.arctan2(-R[0, 1], R[0, 0])
    return a, b, c

def rot_between(u, v):
    u, v = u / np.linalg.norm(u), v / np.linalg.norm(v)
    k = np.cross(u, v); sn = np.linalg.norm(k); cs = u @ v
    if sn < 1e-12:
        return np.eye(3)
    k /= sn
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + sn * K + (1 - cs) * K @ K

if __name__ == '__main__':
    src, dst = read_vtp_points(sys.argv[1]), read_vtp_points(sys.argv[2])
    R0 = np.eye(3)
    fix = '--fix-origin' in sys.argv
    s0 = np.sqrt(((dst - dst.mean(0)) ** 2).sum(1).mean() / ((src - src.mean(0)) ** 2).sum(1).mean())
    t0 = np.zeros(3) if fix else dst.mean(0) - s0 * R0 @ src.mean(0)
    s, R, t, rms = icp(src, dst, s0, R0, t0, fix_origin=fix)
    np.set_printoptions(precision=6, suppress=True)
    print('n_src', len(src), 'n_dst', len(dst))
    print('s', s); print('R', R.tolist()); print('t', t.tolist()); print('rms', rms)
    print('euler_xyz_deg', np.degrees(euler_xyz_body(R)))
