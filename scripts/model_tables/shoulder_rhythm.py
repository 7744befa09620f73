#!/usr/bin/env python3
"""Tabulate MoBL-ARMS 4.1's scapulohumeral rhythm for musculo's torso->humerus ball joint.

Provenance script (run with OpenSim 4.6's Python: `eval "$(scripts/setup-opensim.sh)"`, then
`$MUSCULO_OPENSIM_PYTHON scripts/model_tables/shoulder_rhythm.py MOBL_ARMS_41.osim`).
Input, read in place and never copied into the repository: MOBL_ARMS_41.osim (MoBL-ARMS 4.1,
Saul et al. 2015; mirror github.com/CEINMS-RT/UpperLimbModel @ 459e2ebb, sha256
58bacbc1c61d1d42cff9a48b0a9dced9c648893f44adc7d9817cca56441a9fcf).

What MoBL-ARMS does (read from the file, checked below): the shoulder girdle has five
coordinates (sternoclavicular_r2/r3, acromioclavicular_r1/r2/r3) and five "phantom" ones
(unrotscap_r3/r2, unrothum_r1/r3/r2) that undo the clavicle's and the scapula's rotations in
reverse order, so the humerus' parent frame (`scapphant`, origin = glenohumeral centre) is
parallel to the thorax at every elevation and only translates.  Each of the ten is tied by a
CoordinateCouplerConstraint to `shoulder_elv` alone (Holzbaur et al. 2005's implementation of
de Groot & Brand 2001's regression); the functions are two-knot SimmSplines, i.e. straight
lines through 0 at shoulder_elv = 0, with their second knot at 150 deg (2.61799 rad) for eight
couplers and at 180 deg (pi) for sternoclavicular_r3 / unrotscap_r3.  shoulder_elv's range is
[0, pi]; above 150 deg OpenSim's SimmSpline extrapolates linearly, so MoBL itself continues the
lines to 180 deg, and so does this script (flagged as an extrapolation in the tables' source).
`elv_angle` and `shoulder_rot` enter no girdle coupler; the script asserts that the recorded
positions do not depend on them.

MoBL's humerus chain, scapphant -> shoulder0 (elv_angle about ~y) -> shoulder1 (shoulder_elv
about ~-x, then -elv_angle about ~y) -> shoulder2 (shoulder_rot about ~y), makes shoulder_elv
the thoracohumeral elevation: the angle between the humerus' y axis and the thorax' y axis
(the script measures the difference, from the joint axes' small obliquity: <= 0.1 deg at 90 deg,
<= 0.4 deg up to 150 deg, 4.9 deg at 180 deg in the planes elv_angle = +-90 deg).  So
shoulder_elv is identified with musculo's theta, cos(theta) = cos(arm_flex) cos(arm_add).

Recorded for shoulder_elv = theta in [0, 180 deg], in MoBL's thorax frame, then moved into
musculo's torso frame by the thorax -> torso translation the limb tables use, (0.02071,
0.3785, 0) (data/model/README.md, Transformations item 3; parallel axes, no scaling):
  * the glenohumeral (GH) centre, origin of `scapphant` (child of joint `unrothum`, parent of
    `shoulder0`), written as its displacement from theta = 0;
  * every path point of musculo's 15 MoBL arm muscles that lies on a shoulder-girdle body
    (clavicle, clavphant, scapula, scapphant), index as in path_points.csv (TMAJ's two dropped
    conditional points are skipped in the numbering, as in extract_limb_muscles.py);
  * PECM1's two MovingPathPoints on shoulder_elv (thorax point 3 and humerus point 2, frozen
    at shoulder_elv = 0 in path_points.csv): they are functions of theta too;
  * the pose of the wrap objects on the girdle bodies that those muscles use.
At theta = 0 every torso value is asserted equal (1e-6 m) to the frozen row of path_points.csv
/ wrap_objects.csv.  Left side: mirror z -> -z (wraps: rot_x, rot_y negated), as the limb
tables do.

Parameterisation (--param), see DOCS-NOTES / data/model/README.md:
  theta  knots theta_k (rad) = 0, 10, ..., 180 deg, values MoBL's at theta_k (default;
         faithful, but MoBL's curves have a nonzero slope at theta = 0, and theta is a cone
         in (arm_flex, arm_add) there, so the rhythm is not differentiable at the rest pose);
  even   the same knots mirrored, -180 ... 180 deg, with f(-theta) = f(theta): the SimmSpline
         through symmetric data (its end conditions are symmetric too) is even, so its slope at
         0 is 0 and on [-10, 10] deg it is a + c theta^2, a smooth function of (arm_flex,
         arm_add); the corner of MoBL's curve is rounded inside the first 10 deg;
  u      knots u_k = 1 - cos(theta_k) (theta_k as above), values MoBL's at theta_k: a spline of
         u = 1 - cos(arm_flex) cos(arm_add), which is itself smooth in the joint coordinates
         (no arccos, no 0/0 in its derivative at the rest pose).
--setting-phase DEG (default 0 = off) replaces MoBL's rhythm on [0, DEG] by a time-warp
f(theta0 psi(theta/theta0)), psi(t) = 3t^2 - 3t^3 + t^4 (psi(0) = psi'(0) = 0, psi(1) = 1,
psi'(1) = 1, psi''(1) = 0): the girdle starts at rest and joins MoBL's curve C2 at DEG
(Inman et al. 1944's "setting phase"; Klopcar & Lenarcic's shoulder-girdle elevation is 0 below
30 deg of humeral elevation).
Recommended: --param u (the dependent coordinate u = 1 - cos(arm_flex) cos(arm_add) has a smooth
derivative everywhere; theta's is 0/0 at the rest pose), no setting phase: <= 0.7 mm off MoBL on
the GH centre, <= 1.4 mm on the points up to 150 deg (DOCS-NOTES-rhythm.md / data/model/README.md).
The script prints, for every curve, MoBL's slope at 0 and the largest deviation (mm) of the
chosen table (evaluated as the SimmSpline musculo's builder uses for NaturalCubicSpline) from
MoBL's curve sampled every 0.25 deg, and the same for all parameterisations in a summary.

usage: shoulder_rhythm.py MOBL_ARMS_41.osim [--tables data/model] [--out data/model]
                          [--param theta|even|u] [--setting-phase DEG] [--no-write]
"""
import argparse, csv, math, os, sys
import numpy as np
import opensim as osim

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from register_arm_frames import euler_xyz_body  # noqa: E402

THORAX_TO_TORSO = np.array([0.02071, 0.3785, 0.0])   # README Transformations item 3
GIRDLE_BODIES = ('clavicle', 'clavphant', 'scapula', 'scapphant')
GIRDLE_COORDS = ('sternoclavicular_r2', 'sternoclavicular_r3', 'unrotscap_r3', 'unrotscap_r2',
                 'acromioclavicular_r2', 'acromioclavicular_r3', 'acromioclavicular_r1',
                 'unrothum_r1', 'unrothum_r3', 'unrothum_r2')
ARM = ['DELT1', 'DELT2', 'DELT3', 'PECM1', 'SUPSP', 'INFSP', 'SUBSC', 'TMAJ', 'BIClong',
       'BICshort', 'TRIlong', 'TRIlat', 'TRImed', 'BRA', 'BRD']
FROZEN = ('shoulder_elv', 'shoulder_rot', 'elv_angle')   # conditional points on these: dropped
KNOTS_DEG = np.arange(0, 181, 10)
DENSE_DEG = np.arange(0, 180.0001, 0.25)
ELV_ANGLES_DEG = (-90, 0, 45, 90, 130)    # planes of elevation checked (range -95 .. 130 deg)
MOBL_SRC = ('MoBL-ARMS 4.1 (Saul et al. 2015); rhythm of Holzbaur et al. 2005 after de Groot & '
            'Brand 2001: couplers linear in shoulder_elv, continued linearly above 150 deg as '
            'OpenSim does')
COORD = {'theta': 'arm_elev', 'even': 'arm_elev', 'u': 'arm_elev_u'}


def v3(x):
    return np.array([x.get(0), x.get(1), x.get(2)])


def fmt(x):
    x = float(x)
    if abs(x) < 5e-13:
        return '0'
    return ('%.12g' % x)


class Mobl:
    def __init__(self, path):
        self.model = osim.Model(path)
        self.state = self.model.initSystem()
        m = self.model
        self.cs = m.getCoordinateSet()
        self.thorax = m.getBodySet().get('thorax')
        # couplers: dependent coordinate -> (independent names, function)
        self.couplers = {}
        cset = m.getConstraintSet()
        for i in range(cset.getSize()):
            c = osim.CoordinateCouplerConstraint.safeDownCast(cset.get(i))
            if c is None:
                continue
            ind = c.getIndependentCoordinateNames()
            f = c.getFunction()
            knots = None
            sp = osim.SimmSpline.safeDownCast(f)
            if sp is not None:
                knots = [(sp.getX(k), sp.getY(k)) for k in range(sp.getSize())]
            self.couplers[c.getDependentCoordinateName()] = (
                [ind.get(j) for j in range(ind.getSize())], f, f.getConcreteClassName(), knots)
        for q in GIRDLE_COORDS:
            assert self.couplers[q][0] == ['shoulder_elv'], (q, self.couplers[q][0])

    def pose(self, elv, elv_angle=0.0, rot=0.0):
        """set shoulder_elv, elv_angle, shoulder_rot and every coupled coordinate; realize."""
        s = self.state
        self.cs.get('shoulder_elv').setValue(s, elv, False)
        self.cs.get('elv_angle').setValue(s, elv_angle, False)
        self.cs.get('shoulder_rot').setValue(s, rot, False)
        indep = {'shoulder_elv': elv, 'elv_angle': elv_angle}
        for dep, (ind, f, _, _) in self.couplers.items():
            if ind[0] in indep:
                self.cs.get(dep).setValue(s, f.calcValue(osim.Vector(1, indep[ind[0]])), False)
        self.model.realizePosition(s)
        qerr = np.abs(np.array([s.getQErr().get(i) for i in range(s.getQErr().size())]))
        assert qerr.size == 0 or qerr.max() < 1e-9, qerr.max()

    def in_thorax(self, body, p):
        b = self.model.getBodySet().get(body)
        return v3(b.findStationLocationInAnotherFrame(self.state, osim.Vec3(*p), self.thorax))

    def gh(self):
        return self.in_thorax('scapphant', (0, 0, 0))

    def humerus_elevation(self):
        R = self.model.getBodySet().get('humerus').getTransformInGround(self.state).R()
        T = self.thorax.getTransformInGround(self.state).R()
        yh = np.array([R.get(i, 1) for i in range(3)])
        yt = np.array([T.get(i, 1) for i in range(3)])
        return math.acos(max(-1.0, min(1.0, float(yh @ yt))))

    def body_rotation_in_thorax(self, body):
        """R such that v_thorax = R v_body"""
        def rot(frame):
            R = frame.getTransformInGround(self.state).R()
            return np.array([[R.get(i, j) for j in range(3)] for i in range(3)])
        return rot(self.thorax).T @ rot(self.model.getBodySet().get(body))


def rot_xyz(a, b, c):
    ca, sa, cb, sb, cc, sc = math.cos(a), math.sin(a), math.cos(b), math.sin(b), math.cos(c), math.sin(c)
    Rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    Ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    Rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    return Rx @ Ry @ Rz


def muscle_points(mobl):
    """[(muscle, table index, mobl body, kind, data)] for the girdle points and PECM1's
    shoulder_elv MovingPathPoints; kind 'fixed' (data = location) or 'moving' (data = the
    MovingPathPoint)."""
    fs = mobl.model.getForceSet()
    out = []
    for name in ARM:
        path = osim.Muscle.safeDownCast(fs.get(name)).getGeometryPath()
        pps = path.getPathPointSet()
        i = 0
        for k in range(pps.getSize()):
            ap = pps.get(k)
            body = ap.getParentFrame().getName()
            cp = osim.ConditionalPathPoint.safeDownCast(ap)
            mp = osim.MovingPathPoint.safeDownCast(ap)
            if cp is not None and cp.getCoordinate().getName() in FROZEN:
                continue
            i += 1
            if mp is not None:
                coords = {mp.getXCoordinate().getName(), mp.getYCoordinate().getName(),
                          mp.getZCoordinate().getName()}
                if coords == {'shoulder_elv'}:
                    out.append((name, i, body, 'moving', mp))
                continue
            if body in GIRDLE_BODIES:
                assert cp is None, (name, k)
                pp = osim.PathPoint.safeDownCast(ap)
                out.append((name, i, body, 'fixed', v3(pp.get_location())))
    return out


def moving_location(mobl, mp):
    """a MovingPathPoint's location in its parent frame at the current state"""
    return v3(mp.getLocation(mobl.state))


def girdle_wraps(mobl, used):
    out = []
    for b in GIRDLE_BODIES:
        ws = mobl.model.getBodySet().get(b).getWrapObjectSet()
        for i in range(ws.getSize()):
            w = ws.get(i)
            if w.getName() in used:
                out.append((w.getName(), b, w.getConcreteClassName(), v3(w.get_translation()),
                            v3(w.get_xyz_body_rotation())))
    return out


def used_wraps(mobl):
    fs = mobl.model.getForceSet()
    used = {}
    for name in ARM:
        pw = osim.Muscle.safeDownCast(fs.get(name)).getGeometryPath().getWrapSet()
        for i in range(pw.getSize()):
            used.setdefault(pw.get(i).getWrapObject().getName(), []).append(name)
    return used


def read_table(d, f):
    with open(os.path.join(d, f)) as fh:
        return list(csv.DictReader(fh))


def unwrap_euler(prev, e):
    """choose the xyz-body Euler triple equivalent to e closest to prev (continuity)"""
    cands = []
    a, b, c = e
    for (x, y, z) in ((a, b, c), (a + math.pi, math.pi - b, c + math.pi)):
        for kx in (-2, -1, 0, 1, 2):
            for ky in (-2, -1, 0, 1, 2):
                for kz in (-2, -1, 0, 1, 2):
                    cands.append(np.array([x + 2 * math.pi * kx, y + 2 * math.pi * ky, z + 2 * math.pi * kz]))
    return min(cands, key=lambda v: np.abs(v - prev).sum())


def simm_spline(xk, yk):
    sp = osim.SimmSpline()
    for x, y in zip(xk, yk):
        sp.addPoint(float(x), float(y))
    return sp


def spline_eval(xk, yk, xs):
    """musculo's builder evaluates NaturalCubicSpline as OpenSim's SimmSpline"""
    sp = simm_spline(xk, yk)
    return np.array([sp.calcValue(osim.Vector(1, float(x))) for x in xs])


def spline_slope0(xk, yk, x0=0.0):
    iv = osim.StdVectorInt()
    iv.append(0)
    return simm_spline(xk, yk).calcDerivative(iv, osim.Vector(1, x0))


def rotation_vector(R):
    """axis * angle of a rotation matrix (angle < pi)"""
    c = max(-1.0, min(1.0, (np.trace(R) - 1) / 2))
    ang = math.acos(c)
    if ang < 1e-12:
        return np.zeros(3)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return w * ang / (2 * math.sin(ang))


def psi(t):
    return 3 * t ** 2 - 3 * t ** 3 + t ** 4


def warp(theta, theta0):
    """setting-phase time-warp of the argument (identity above theta0)"""
    if theta0 <= 0 or theta >= theta0:
        return theta
    return theta0 * psi(theta / theta0)


def knots_of(param, f_at):
    """(knot abscissae, values) for one scalar curve f_at(theta)"""
    th = np.radians(KNOTS_DEG)
    if param == 'theta':
        return th, np.array([f_at(t) for t in th])
    if param == 'even':
        neg = -th[1:][::-1]
        return np.concatenate([neg, th]), np.array([f_at(abs(t)) for t in np.concatenate([neg, th])])
    if param == 'u':
        return 1 - np.cos(th), np.array([f_at(t) for t in th])
    raise ValueError(param)


def table_curve(param, xk, yk, theta):
    x = 1 - np.cos(theta) if param == 'u' else theta
    return spline_eval(xk, yk, x)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('mobl')
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument('--tables', default=os.path.normpath(os.path.join(here, '..', '..', 'data', 'model')))
    ap.add_argument('--out', default=None, help='output folder (default: --tables)')
    ap.add_argument('--param', choices=('theta', 'even', 'u'), default='theta')
    ap.add_argument('--setting-phase', type=float, default=0.0, metavar='DEG')
    ap.add_argument('--no-write', action='store_true')
    a = ap.parse_args()
    out_dir = a.out or a.tables
    theta0 = math.radians(a.setting_phase)
    np.set_printoptions(precision=6, suppress=True)

    mobl = Mobl(a.mobl)
    print('couplers (dependent <- independent: function, knots (x, y)):')
    for dep, (ind, f, kind, knots) in mobl.couplers.items():
        if dep in GIRDLE_COORDS:
            print('  %-22s <- %s: %s %s' % (dep, ','.join(ind), kind, knots))
    r = mobl.cs.get('shoulder_elv')
    print('shoulder_elv range: [%g, %g] rad' % (r.getRangeMin(), r.getRangeMax()))

    used = used_wraps(mobl)
    points = muscle_points(mobl)
    wraps = girdle_wraps(mobl, used)

    # ---- sample MoBL at every dense theta (elv_angle = 0), check elv_angle independence
    def sample(theta, elv_angle=0.0, rot=0.0):
        mobl.pose(theta, elv_angle, rot)
        s = {'gh': mobl.gh()}
        # shoulder0/1/2 have no translation: the humerus origin is the GH centre
        assert np.abs(mobl.in_thorax('humerus', (0, 0, 0)) - s['gh']).max() < 1e-12
        for (mu, i, body, kind, data) in points:
            if kind == 'fixed':
                s[(mu, i)] = mobl.in_thorax(body, data)
            else:
                s[(mu, i)] = moving_location(mobl, data)   # in its own body frame
        for (wn, body, cls, t, rot_) in wraps:
            Rb = mobl.body_rotation_in_thorax(body)
            s[('wrap', wn)] = (mobl.in_thorax(body, t), Rb @ rot_xyz(*rot_))
        s['elev'] = mobl.humerus_elevation()
        return s

    dense = np.radians(DENSE_DEG)
    S = [sample(t) for t in dense]
    worst_dep = 0.0
    elev_diff, elev_by_theta = {}, {}
    for t in np.radians(np.arange(0, 181, 15)):
        ref = sample(t)
        for ea in ELV_ANGLES_DEG:
            for rot in (0.0, 0.8):
                s = sample(t, math.radians(ea), rot)
                for k, v in ref.items():
                    if k == 'elev':
                        continue
                    if isinstance(v, tuple):     # wrap: (translation, rotation matrix)
                        worst_dep = max(worst_dep, np.abs(s[k][0] - v[0]).max(), np.abs(s[k][1] - v[1]).max())
                    else:
                        worst_dep = max(worst_dep, np.abs(s[k] - v).max())
                if rot == 0.0:
                    d = abs(s['elev'] - t)
                    elev_by_theta[round(math.degrees(t))] = max(elev_by_theta.get(round(math.degrees(t)), 0.0), d)
                    elev_diff[ea] = max(elev_diff.get(ea, 0.0), d)
    assert worst_dep < 1e-12, worst_dep
    print('girdle points, GH centre and wraps independent of elv_angle %s deg and shoulder_rot: '
          'max difference %.1e' % (list(ELV_ANGLES_DEG), worst_dep))
    print('|thoracohumeral elevation (angle between humerus y and thorax y) - shoulder_elv|, '
          'largest over shoulder_elv, per elv_angle: %s' % ', '.join(
              '%d deg: %.2f deg' % (ea, math.degrees(d)) for ea, d in sorted(elev_diff.items())))
    print('  largest over those planes, per shoulder_elv: %s' % ', '.join(
        '%d: %.2f' % (t, math.degrees(d)) for t, d in sorted(elev_by_theta.items())))

    # ---- thorax -> torso, checks against the frozen rows at theta = 0
    P = read_table(a.tables, 'path_points.csv')
    row = {(p['muscle'], int(p['index'])): p for p in P}
    W = {w['name']: w for w in read_table(a.tables, 'wrap_objects.csv')}
    s0 = S[0]
    gh0 = s0['gh']
    assert np.allclose(gh0, [-0.017555, -0.007, 0.17], atol=1e-9), gh0
    acr = gh0 + THORAX_TO_TORSO
    print('GH centre at theta = 0: thorax %s, torso %s (acromial_r in joints.csv: 0.003155 0.3715 0.17)' % (gh0, acr))
    assert np.allclose(acr, [0.003155, 0.3715, 0.17], atol=1e-9)

    # humerus_r map from the table itself: A = s R with table = A p_mobl (fixed humerus points)
    humerus_pairs = []
    fs = mobl.model.getForceSet()
    for name in ARM:
        pps = osim.Muscle.safeDownCast(fs.get(name)).getGeometryPath().getPathPointSet()
        i = 0
        for k in range(pps.getSize()):
            ap_ = pps.get(k)
            cp = osim.ConditionalPathPoint.safeDownCast(ap_)
            if cp is not None and cp.getCoordinate().getName() in FROZEN:
                continue
            i += 1
            pp = osim.PathPoint.safeDownCast(ap_)
            if pp is not None and cp is None and ap_.getParentFrame().getName() == 'humerus':
                t = row[(name + '_r', i)]
                humerus_pairs.append((v3(pp.get_location()), np.array([float(t[c]) for c in 'xyz'])))
    Pm = np.array([p for p, _ in humerus_pairs])
    Pt = np.array([q for _, q in humerus_pairs])
    A = np.linalg.lstsq(Pm, Pt, rcond=None)[0].T
    res = np.abs(Pm @ A.T - Pt).max()
    assert res < 1e-9, res
    print('humerus -> humerus_r map recovered from %d table points (residual %.1e m): s = %.4f' % (
        len(Pm), res, np.cbrt(np.linalg.det(A))))

    def to_table(body, val):
        """MoBL value (thorax frame, or own frame for moving points) -> musculo frame"""
        if body == 'humerus':
            return 'humerus_r', A @ val
        return 'torso', val + THORAX_TO_TORSO

    curves = {}     # (kind, name, index, axis) -> (body, values over dense theta)
    for k in range(3):
        curves[('gh', 'acromial_r', 0, 'xyz'[k])] = ('torso', np.array([s['gh'][k] - gh0[k] for s in S]))
    for (mu, i, body, kind, data) in points:
        tb, _ = to_table(body, S[0][(mu, i)])
        vals = np.array([to_table(body, s[(mu, i)])[1] for s in S])
        r0 = row[(mu + '_r', i)]
        frozen = np.array([float(r0[c]) for c in 'xyz'])
        assert r0['body'] == tb, (mu, i, r0['body'], tb)
        assert np.abs(vals[0] - frozen).max() < 1e-6, (mu, i, vals[0], frozen)
        for k in range(3):
            curves[('point', mu + '_r', i, 'xyz'[k])] = (tb, vals[:, k])
    print('muscle points at theta = 0 equal path_points.csv rows to 1e-6 m: %d points' % len(points))
    wrap_curves = {}
    for (wn, body, cls, t, rot_) in wraps:
        tr = np.array([s[('wrap', wn)][0] + THORAX_TO_TORSO for s in S])
        eu, prev = [], None
        for s in S:
            e = np.array(euler_xyz_body(s[('wrap', wn)][1]))
            prev = e if prev is None else unwrap_euler(prev, e)
            assert np.allclose(rot_xyz(*prev), s[('wrap', wn)][1], atol=1e-9), wn
            eu.append(prev)
        eu = np.array(eu)
        w0 = W[wn + '_r']
        frozen_t = np.array([float(w0[c]) for c in ('tx', 'ty', 'tz')])
        frozen_r = np.array([float(w0[c]) for c in ('rot_x', 'rot_y', 'rot_z')])
        assert w0['body'] == 'torso'
        assert np.abs(tr[0] - frozen_t).max() < 1e-6, (wn, tr[0], frozen_t)
        assert np.allclose(rot_xyz(*eu[0]), rot_xyz(*frozen_r), atol=1e-6), (wn, eu[0], frozen_r)
        wrap_curves[wn] = (cls, tr, eu)
    print('girdle wrap poses at theta = 0 equal wrap_objects.csv rows (1e-6): %s' % sorted(wrap_curves))
    for (wn, body, cls, t, rot_) in wraps:
        _, tr, eu = wrap_curves[wn]
        parts = []
        for deg in (90, 150):
            j = int(round(deg / 0.25))
            dR = rot_xyz(*eu[j]) @ rot_xyz(*eu[0]).T
            ang = math.degrees(math.acos(max(-1, min(1, (np.trace(dR) - 1) / 2))))
            parts.append('theta %d: centre moved %.1f mm, rotated %.1f deg' % (deg, 1000 * np.linalg.norm(tr[j] - tr[0]), ang))
        print('  wrap %-12s on MoBL %s (%s), used by %s: %s' % (wn, body, cls, ', '.join(used[wn]), '; '.join(parts)))

    # ---- report: GH excursion, slopes at 0, scapula rotation
    ghd = np.array([s['gh'] - gh0 for s in S])
    for deg in (30, 60, 90, 120, 150, 180):
        j = int(round(deg / 0.25))
        d = ghd[j] * 1000
        mobl.pose(math.radians(deg))
        Rs = mobl.body_rotation_in_thorax('scapula')
        Rc = mobl.body_rotation_in_thorax('clavicle')
        ang = lambda R_: math.degrees(math.acos(max(-1, min(1, (np.trace(R_) - 1) / 2))))
        print('theta %3d deg: GH displacement (torso x ant, y up, z lat) = (%6.1f, %6.1f, %6.1f) mm, '
              '|d| = %5.1f mm; clavicle rotated %5.1f deg, scapula %5.1f deg' % (
                  deg, d[0], d[1], d[2], np.linalg.norm(d), ang(Rc), ang(Rs)))
    h = math.radians(0.25)
    print('slopes at theta = 0 (one-sided, MoBL; m/rad):')
    for key, (body, vals) in curves.items():
        sl = (-3 * vals[0] + 4 * vals[1] - vals[2]) / (2 * h)
        if abs(sl) > 0:
            print('  %-5s %-10s %2s %s (%s): %+.5f m/rad = %+.3f mm/deg' % (key[0], key[1], key[2] or '', key[3], body, sl, sl * math.pi / 180 * 1000))

    # ---- parameterisations: fitting error (mm) of each table against MoBL's dense curve
    def fit_error(param, th0, key_vals):
        f = lambda t: np.interp(warp(t, th0), dense, key_vals)
        xk, yk = knots_of(param, f)
        approx = table_curve(param, xk, yk, dense)
        return np.abs(approx - key_vals), spline_slope0(xk, yk), xk, yk

    print('largest deviation of the table (SimmSpline through its knots) from MoBL, mm: over [0, 180] deg | '
          '[0, 10] deg | [10, 180] deg; and the table\'s slope at 0 (m per knot unit):')
    summary = {}
    for param in ('theta', 'even', 'u'):
        for th0 in (0.0, math.radians(30)):
            worst = [0.0, 0.0, 0.0, None]
            worst_150 = 0.0
            for key, (body, vals) in curves.items():
                err, sl, _, _ = fit_error(param, th0, vals)
                e_all, e_lo, e_hi = err.max(), err[dense <= math.radians(10)].max(), err[dense >= math.radians(10)].max()
                e_150 = err[dense <= math.radians(150)].max()
                if e_all > worst[0]:
                    worst = [e_all, e_lo, e_hi, key, DENSE_DEG[int(np.argmax(err))]]
                worst_150 = max(worst_150, e_150)
                if key[0] == 'gh':
                    summary[(param, th0, key[3])] = (e_all * 1000, e_lo * 1000, e_hi * 1000, sl, DENSE_DEG[int(np.argmax(err))], e_150 * 1000)
            print('  %-5s setting phase %2d deg: worst curve %s %s: %.3f | %.3f | %.3f mm (at %.2f deg)' % (
                param, round(math.degrees(th0)), worst[3][1], worst[3][2:], worst[0] * 1000, worst[1] * 1000, worst[2] * 1000, worst[4]))
            print('        all curves over [0, 150] deg (MoBL\'s data range): %.3f mm' % (worst_150 * 1000))
            for ax in 'xyz':
                e = summary[(param, th0, ax)]
                print('        GH %s: %.3f | %.3f | %.3f mm (at %.2f deg; %.3f mm over [0, 150]), table slope at 0 = %+.6f' % (
                    ax, e[0], e[1], e[2], e[4], e[5], e[3]))

    if a.no_write:
        return
    # ---- write the chosen parameterisation, both sides
    param = a.param
    coord = COORD[param]
    src = MOBL_SRC + ('; knots: %s' % {'theta': 'theta (rad)', 'even': 'theta (rad), mirrored below 0',
                                       'u': 'u = 1 - cos(theta)'}[param])
    if theta0 > 0:
        src += '; setting phase: MoBL time-warped on [0, %g deg] (Inman et al. 1944)' % a.setting_phase
    rows_gh, rows_pt, rows_w = [], [], []
    for side in ('r', 'l'):
        zsign = 1 if side == 'r' else -1
        for key, (body, vals) in curves.items():
            f = lambda t, v=vals: np.interp(warp(t, theta0), dense, v)
            xk, yk = knots_of(param, f)
            if key[3] == 'z':
                yk = zsign * yk
            for x, y in zip(xk, yk):
                if key[0] == 'gh':
                    rows_gh.append(['acromial_' + side, key[3], 'NaturalCubicSpline', coord + '_' + side, fmt(x), fmt(y), src])
                else:
                    b = body if body == 'torso' else body[:-2] + '_' + side
                    rows_pt.append([key[1][:-2] + '_' + side, key[2], b, key[3], 'NaturalCubicSpline', coord + '_' + side, fmt(x), fmt(y), src])
        for wn, (cls, tr, eu) in wrap_curves.items():
            for j, deg in enumerate(KNOTS_DEG):
                t = math.radians(deg)
                jj = int(np.argmin(np.abs(dense - warp(t, theta0))))
                x = 1 - math.cos(t) if param == 'u' else t
                tx, ty, tz = tr[jj]
                rx, ry, rz = eu[jj]
                wx, wy, wz = rotation_vector(rot_xyz(*eu[jj]) @ rot_xyz(*eu[0]).T)
                if side == 'l':
                    tz, rx, ry, wx, wy = -tz, -rx, -ry, -wx, -wy
                rows_w.append([wn + '_' + side, 'torso', cls.replace('Wrap', '').lower(), coord + '_' + side, fmt(x),
                               fmt(tx), fmt(ty), fmt(tz), fmt(rx), fmt(ry), fmt(rz), fmt(wx), fmt(wy), fmt(wz), src])
    def write(fn, header, rows):
        with open(os.path.join(out_dir, fn), 'w', newline='') as fh:
            w = csv.writer(fh, lineterminator='\n')
            w.writerow(header)
            w.writerows(rows)
    write('shoulder_rhythm.csv', ['joint', 'axis', 'function', 'coordinate', 'knot', 'value', 'source'], rows_gh)
    write('shoulder_rhythm_points.csv', ['muscle', 'index', 'body', 'axis', 'function', 'coordinate', 'knot', 'value', 'source'], rows_pt)
    write('shoulder_rhythm_wraps.csv', ['name', 'body', 'type', 'coordinate', 'knot', 'tx', 'ty', 'tz', 'rot_x', 'rot_y', 'rot_z',
                                         'drot_x', 'drot_y', 'drot_z', 'source'], rows_w)
    print('wrote %d + %d + %d rows (%s knots) to %s' % (len(rows_gh), len(rows_pt), len(rows_w), param, out_dir))


if __name__ == '__main__':
    main()
