#!/usr/bin/env python3
"""Extract musculo's lower-limb and arm muscle tables (data/model/*.csv) from public
OpenSim models.  Provenance script: the CSVs it writes are the authored source and
are committed; this script documents how their figures were obtained.

Inputs (read in place, never copied into the repository):
  --gait2392  gait2392_thelen2003muscle.osim   (opensim-models, Models/Gait2392_Simbody)
  --rajagopal Rajagopal2016.osim               (opensim-models, Models/Rajagopal)
  --mobl      MOBL_ARMS_41.osim                (MoBL-ARMS 4.1, Saul et al. 2015; mirror:
              github.com/CEINMS-RT/UpperLimbModel @ 459e2ebb, file MOBL_ARMS_41.osim,
              sha256 58bacbc1c61d1d42cff9a48b0a9dced9c648893f44adc7d9817cca56441a9fcf)
  --geom      folder holding the bone meshes humerus.vtp ulna.vtp radius.vtp (MoBL-ARMS)
              and humerus_rv.vtp ulna_rv.vtp radius_rv.vtp (Hamner 2010 / Rajagopal 2016;
              opensim-models Geometry/), used for the frame registration.
  --out       output folder (data/model)
"""
import argparse, csv, math, os, sys
import xml.etree.ElementTree as ET
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from register_arm_frames import read_vtp_points, icp, euler_xyz_body  # noqa: E402

G2392_SRC = 'gait2392 (Delp et al. 1990; OpenSim gait2392_thelen2003muscle.osim)'
MOBL_SRC = 'MoBL-ARMS 4.1 (Saul et al. 2015; Holzbaur et al. 2005)'

# ercspn/intobl/extobl: replaced by the lumbar fascicles (data/model/lumbar_*.csv);
# psoas: replaced by the 11 lumbar psoas major fascicles per side, which are extended to the
# femur along gait2392's psoas path (README_lumbar.md).  iliacus is kept.
DROP_LEG = {'ercspn', 'intobl', 'extobl', 'psoas'}
HIP = {'glut_med1', 'glut_med2', 'glut_med3', 'glut_min1', 'glut_min2', 'glut_min3',
       'add_long', 'add_brev', 'add_mag1', 'add_mag2', 'add_mag3', 'tfl', 'pect',
       'glut_max1', 'glut_max2', 'glut_max3', 'iliacus', 'quad_fem', 'gem', 'peri'}
KNEE = {'semimem', 'semiten', 'bifemlh', 'bifemsh', 'sar', 'grac', 'rect_fem',
        'vas_med', 'vas_int', 'vas_lat'}
ANKLE = {'med_gas', 'lat_gas', 'soleus', 'tib_post', 'tib_ant', 'per_brev', 'per_long',
         'per_tert'}
TOES = {'flex_dig', 'flex_hal', 'ext_dig', 'ext_hal'}

# 15 arm muscles (see README): the six arm26 muscles + deltoid (3), pectoralis major
# clavicular head, rotator cuff (supraspinatus, infraspinatus, subscapularis), teres major,
# brachioradialis (BRD: humerus -> radius, 3 fixed points, wrap Elbow_BIC_BRD shared with BIC).
ARM = [('DELT1', 'shoulder'), ('DELT2', 'shoulder'), ('DELT3', 'shoulder'),
       ('PECM1', 'shoulder'), ('SUPSP', 'shoulder'), ('INFSP', 'shoulder'),
       ('SUBSC', 'shoulder'), ('TMAJ', 'shoulder'),
       ('BIClong', 'elbow'), ('BICshort', 'elbow'), ('TRIlong', 'elbow'),
       ('TRIlat', 'elbow'), ('TRImed', 'elbow'), ('BRA', 'elbow'),
       ('BRD', 'elbow')]
# MoBL coordinate -> Rajagopal (right side) coordinate, for points that stay coordinate-dependent
MOBL_COORD = {'elbow_flexion': 'elbow_flex', 'pro_sup': 'pro_sup'}
# MoBL shoulder coordinates have no counterpart in the torso->humerus ball joint: points
# moving with them are frozen at the arm-at-side pose, points conditional on them dropped.
FROZEN_AT = {'shoulder_elv': 0.0, 'shoulder_rot': 0.0, 'elv_angle': 0.0}


def fnum(x):
    return float(repr(float(x)))


def fmt(x):
    if x is None or x == '':
        return ''
    x = float(x)
    if x == 0:
        return '0'
    return repr(round(x, 12)).rstrip('0').rstrip('.') if 'e' not in repr(x) else repr(x)


def vec(text):
    return np.array([float(v) for v in text.split()])


def model_of(path):
    return ET.parse(path).getroot().find('Model')


def last(path):
    return path.strip().split('/')[-1]


def rot_xyz(a, b, c):
    ca, sa, cb, sb, cc, sc = math.cos(a), math.sin(a), math.cos(b), math.sin(b), math.cos(c), math.sin(c)
    Rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    Ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    Rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    return Rx @ Ry @ Rz


# ---------------------------------------------------------------- functions
def read_function(el):
    """el: the <x_location> etc. element -> (type, xs, ys)"""
    f = list(el)[0]
    if f.tag == 'Constant':
        v = float(f.findtext('value'))
        return 'Constant', [0.0], [v]
    if f.tag == 'LinearFunction':
        a, b = vec(f.findtext('coefficients'))
        return 'LinearFunction', [0.0, 1.0], [b, a + b]
    return f.tag, list(vec(f.findtext('x'))), list(vec(f.findtext('y')))


def eval_function(kind, xs, ys, q):
    xs, ys = np.asarray(xs, float), np.asarray(ys, float)
    if kind == 'Constant' or len(xs) == 1:
        return ys[0]
    if kind in ('PiecewiseLinearFunction', 'LinearFunction') or len(xs) == 2:
        return float(np.interp(q, xs, ys)) if xs[0] <= q <= xs[-1] else float(
            ys[0] + (ys[1] - ys[0]) / (xs[1] - xs[0]) * (q - xs[0]) if q < xs[0] else
            ys[-2] + (ys[-1] - ys[-2]) / (xs[-1] - xs[-2]) * (q - xs[-2]))
    if kind == 'SimmSpline' and len(xs) == 3:
        # SIMM/FMM spline with 3 knots is the interpolating parabola
        return float(np.polyval(np.polyfit(xs, ys, 2), q))
    raise ValueError('cannot evaluate %s with %d knots' % (kind, len(xs)))


# ---------------------------------------------------------------- muscle reading
def read_muscle(mu):
    rec = {k: float(mu.findtext(k)) for k in ('max_isometric_force', 'optimal_fiber_length',
                                              'tendon_slack_length', 'pennation_angle_at_optimal',
                                              'max_contraction_velocity')}
    gp = mu.find('GeometryPath')
    pts = []
    for p in gp.find('PathPointSet/objects'):
        d = {'tag': p.tag, 'name': p.get('name'), 'body': last(p.findtext('socket_parent_frame'))}
        if p.tag in ('PathPoint', 'ConditionalPathPoint'):
            d['loc'] = vec(p.findtext('location'))
        if p.tag == 'ConditionalPathPoint':
            d['coord'] = last(p.findtext('socket_coordinate'))
            d['range'] = vec(p.findtext('range'))
        if p.tag == 'MovingPathPoint':
            d['funcs'] = {}
            for ax in 'xyz':
                d['funcs'][ax] = (last(p.findtext('socket_%s_coordinate' % ax)),) + read_function(p.find('%s_location' % ax))
        pts.append(d)
    wraps = []
    for w in gp.find('PathWrapSet/objects'):
        wo = w.findtext('socket_wrap_object') or w.findtext('wrap_object')
        wraps.append({'wrap': last(wo), 'method': w.findtext('method') or 'hybrid',
                      'range': [int(v) for v in w.findtext('range').split()]})
    rec['points'] = pts
    rec['wraps'] = wraps
    return rec


def read_wrap_objects(model):
    out = {}
    for b in model.find('BodySet/objects'):
        for w in b.findall('WrapObjectSet/objects/*'):
            d = {'name': w.get('name'), 'body': b.get('name'), 'tag': w.tag,
                 'rot': vec(w.findtext('xyz_body_rotation')), 't': vec(w.findtext('translation')),
                 'quadrant': (w.findtext('quadrant') or 'all').strip()}
            for k in ('radius', 'length', 'dimensions', 'inner_radius', 'outer_radius'):
                if w.findtext(k) is not None:
                    d[k] = w.findtext(k)
            out[w.get('name')] = d
    return out


# ---------------------------------------------------------------- frame maps for the arm
class FrameMap:
    """p_new = s R p_old + t, into body `body` of the target model"""
    def __init__(self, body, s=1.0, R=None, t=None, note=''):
        self.body, self.s = body, s
        self.R = np.eye(3) if R is None else R
        self.t = np.zeros(3) if t is None else t
        self.note = note

    def point(self, p):
        return self.s * self.R @ p + self.t

    def rotation(self, rot_xyz_angles):
        return euler_xyz_body(self.R @ rot_xyz(*rot_xyz_angles))


def arm_frame_maps(mobl, raj, geom):
    """Maps from MoBL-ARMS bodies (arm at side: shoulder_elv = 0, which makes every
    shoulder-girdle coordinate of MoBL 0 through its coupler constraints) into the
    Rajagopal2016 torso/humerus_r/ulna_r/radius_r frames."""
    joints = {j.get('name'): j for j in mobl.find('JointSet/objects')}

    def loc_in_parent(jn):
        j = joints[jn]
        pf = j.findtext('socket_parent_frame')
        for f in j.findall('frames/PhysicalOffsetFrame'):
            if f.get('name') == pf:
                assert np.allclose(vec(f.findtext('orientation')), 0)
                return vec(f.findtext('translation'))
    # shoulder girdle at shoulder_elv = 0: all girdle rotations are 0 -> pure translations
    clav = loc_in_parent('sternoclavicular')
    scap = clav + loc_in_parent('unrotscap')            # acromioclavicular sits at clavphant origin
    gh = scap + loc_in_parent('unrothum')               # glenohumeral centre in thorax
    rj = {j.get('name'): j for j in raj.find('JointSet/objects')}
    acr = None
    for f in rj['acromial_r'].findall('frames/PhysicalOffsetFrame'):
        if f.get('name') == rj['acromial_r'].findtext('socket_parent_frame'):
            acr = vec(f.findtext('translation'))
    thorax_to_torso = acr - gh
    maps = {
        'thorax': FrameMap('torso', t=thorax_to_torso),
        'clavicle': FrameMap('torso', t=thorax_to_torso + clav),
        'scapula': FrameMap('torso', t=thorax_to_torso + scap),
    }
    info = {'gh_in_thorax': gh, 'acromial_r': acr, 'thorax_to_torso': thorax_to_torso,
            'clavicle_in_thorax': clav, 'scapula_in_thorax': scap}
    for b in ('humerus', 'ulna', 'radius'):
        src = read_vtp_points(os.path.join(geom, b + '.vtp'))
        dst = read_vtp_points(os.path.join(geom, b + '_rv.vtp'))
        s0 = math.sqrt((dst ** 2).sum(1).mean() / (src ** 2).sum(1).mean())
        s, R, t, rms = icp(src, dst, s0, np.eye(3), np.zeros(3), fix_origin=True)
        maps[b] = FrameMap(b + '_r', s, R, np.zeros(3))
        info[b] = {'s': s, 'R': R, 'rms': rms, 'euler_deg': np.degrees(euler_xyz_body(R))}
    return maps, info


def pinjoint_axis(joint):
    pf = joint.findtext('socket_parent_frame')
    for f in joint.findall('frames/PhysicalOffsetFrame'):
        if f.get('name') == pf:
            return rot_xyz(*vec(f.findtext('orientation')))[:, 2], vec(f.findtext('translation'))


def landmark_report(mobl, raj, maps):
    mj = {j.get('name'): j for j in mobl.find('JointSet/objects')}
    rj = {j.get('name'): j for j in raj.find('JointSet/objects')}
    out = []

    def mloc(jn):
        j = mj[jn]
        pf = j.findtext('socket_parent_frame')
        for f in j.findall('frames/PhysicalOffsetFrame'):
            if f.get('name') == pf:
                return vec(f.findtext('translation'))

    def maxis(jn):
        return vec(mj[jn].find('SpatialTransform/TransformAxis').findtext('axis'))
    for mjn, rjn, body in (('elbow', 'elbow_r', 'humerus'), ('radioulnar', 'radioulnar_r', 'ulna'),
                           ('radiocarpal', 'radius_hand_r', 'radius')):
        ax_r, loc_r = pinjoint_axis(rj[rjn])
        m = maps[body]
        loc_m = m.point(mloc(mjn))
        line = '%s centre in %s_r: mapped MoBL %s vs Rajagopal %s (|d| = %.1f mm)' % (
            rjn, body, np.round(loc_m, 4), np.round(loc_r, 4), 1000 * np.linalg.norm(loc_m - loc_r))
        if rjn != 'radius_hand_r':
            ax_m = m.R @ maxis(mjn)
            ang = math.degrees(math.acos(abs(np.clip(ax_m @ ax_r / np.linalg.norm(ax_m), -1, 1))))
            line += '; axis angle %.1f deg' % ang
        out.append(line)
    return out


def prosup_offset(raj, maps):
    """q_R - q_M at which MoBL's radius (q_M = 0) and Rajagopal's radius agree best
    relative to the ulna: angle of R_u R_r^T about Rajagopal's pro_sup axis."""
    rj = {j.get('name'): j for j in raj.find('JointSet/objects')}
    k, _ = pinjoint_axis(rj['radioulnar_r'])
    M = maps['ulna'].R @ maps['radius'].R.T
    # rotation angle about k of the closest rotation: use the projection of M onto rotations about k
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    s = np.trace(M @ K.T) / 2.0
    c = (np.trace(M) - k @ M @ k) / 2.0
    return math.atan2(s, c)


# ---------------------------------------------------------------- writers
class Tables:
    def __init__(self):
        self.muscles, self.points, self.funcs, self.wraps, self.mwraps = [], [], [], [], []
        self.wrap_names = set()


def add_wrap(T, name, body, tag, rot, t, d, source):
    if name in T.wrap_names:
        return
    T.wrap_names.add(name)
    typ = {'WrapCylinder': 'cylinder', 'WrapSphere': 'sphere', 'WrapEllipsoid': 'ellipsoid',
           'WrapTorus': 'torus'}[tag]
    row = {'name': name, 'body': body, 'type': typ, 'rot_x': rot[0], 'rot_y': rot[1], 'rot_z': rot[2],
           'tx': t[0], 'ty': t[1], 'tz': t[2], 'radius': '', 'length': '', 'dim_x': '', 'dim_y': '',
           'dim_z': '', 'quadrant': d['quadrant'], 'source': source}
    sc = d.get('scale', 1.0)
    if typ in ('cylinder', 'sphere'):
        row['radius'] = float(d['radius']) * sc
    if typ == 'cylinder':
        row['length'] = float(d['length']) * sc
    if typ == 'ellipsoid':
        row['dim_x'], row['dim_y'], row['dim_z'] = (vec(d['dimensions']) * sc)
    if typ == 'torus':   # documented: radius = inner_radius, dim_x = outer_radius
        row['radius'] = float(d['inner_radius']) * sc
        row['dim_x'] = float(d['outer_radius']) * sc
    T.wraps.append(row)


def mirror_quadrant(q):
    return {'z': '-z', '-z': 'z', '+z': '-z'}.get(q, q)


def legs(T, g2392):
    wraps = read_wrap_objects(g2392)
    for mu in g2392.find('ForceSet/objects'):
        name = mu.get('name')
        base, side = name.rsplit('_', 1)
        if base in DROP_LEG:
            continue
        group = 'hip' if base in HIP else 'knee' if base in KNEE else 'ankle' if base in ANKLE else 'toes' if base in TOES else None
        assert group, name
        r = read_muscle(mu)
        T.muscles.append({'name': name, 'group': group, 'side': side,
                          'max_isometric_force': r['max_isometric_force'],
                          'optimal_fiber_length': r['optimal_fiber_length'],
                          'tendon_slack_length': r['tendon_slack_length'],
                          'pennation_angle': r['pennation_angle_at_optimal'],
                          'max_contraction_velocity': r['max_contraction_velocity'],
                          'source': G2392_SRC})
        for i, p in enumerate(r['points'], 1):
            assert not p['body'].startswith('talus')   # gait2392 has none: see README
            row = {'muscle': name, 'index': i, 'body': p['body'], 'x': '', 'y': '', 'z': '',
                   'coordinate': '', 'range_min': '', 'range_max': '', 'source': G2392_SRC}
            if p['tag'] == 'PathPoint':
                row['type'] = 'fixed'
            elif p['tag'] == 'ConditionalPathPoint':
                row.update(type='conditional', coordinate=p['coord'], range_min=p['range'][0], range_max=p['range'][1])
            else:
                row['type'] = 'moving'
                for ax in 'xyz':
                    coord, kind, xs, ys = p['funcs'][ax]
                    for x, y in zip(xs, ys):
                        T.funcs.append({'muscle': name, 'index': i, 'axis': ax, 'function': kind,
                                        'coordinate': coord, 'knot': x, 'value': y})
            if p['tag'] != 'MovingPathPoint':
                row['x'], row['y'], row['z'] = p['loc']
            T.points.append(row)
        for k, w in enumerate(r['wraps'], 1):   # none in gait2392
            T.mwraps.append({'muscle': name, 'order': k, 'wrap_object': w['wrap'], 'method': w['method'],
                             'range_start': w['range'][0], 'range_end': w['range'][1]})
            d = wraps[w['wrap']]
            add_wrap(T, d['name'], d['body'], d['tag'], d['rot'], d['t'], d, G2392_SRC)


def arms(T, mobl, maps, dq, notes):
    wraps = read_wrap_objects(mobl)
    forces = {m.get('name'): m for m in mobl.find('ForceSet/objects')}
    right = Tables()
    for name, group in ARM:
        r = read_muscle(forces[name])
        mname = name + '_r'
        right.muscles.append({'name': mname, 'group': group, 'side': 'r',
                              'max_isometric_force': r['max_isometric_force'],
                              'optimal_fiber_length': r['optimal_fiber_length'],
                              'tendon_slack_length': r['tendon_slack_length'],
                              'pennation_angle': r['pennation_angle_at_optimal'],
                              'max_contraction_velocity': r['max_contraction_velocity'],
                              'source': MOBL_SRC})
        newidx = {}
        i = 0
        for k, p in enumerate(r['points'], 1):
            # hand -> radius lumping (hand re-expressed in radius at wrist angles 0) is not
            # implemented: no muscle of this set has a point on MoBL's hand/carpal bodies.
            assert p['body'] in maps, (mname, k, p['body'])
            m = maps[p['body']]
            if p['tag'] == 'ConditionalPathPoint' and p['coord'] in FROZEN_AT:
                notes.append('%s: dropped conditional point %d (%s on %s, range %s)' % (
                    mname, k, p['body'], p['coord'], p['range']))
                continue
            i += 1
            newidx[k] = i
            row = {'muscle': mname, 'index': i, 'body': m.body, 'x': '', 'y': '', 'z': '',
                   'coordinate': '', 'range_min': '', 'range_max': '', 'source': MOBL_SRC}
            if p['tag'] == 'MovingPathPoint':
                coords = {p['funcs'][ax][0] for ax in 'xyz'}
                if coords <= set(FROZEN_AT):
                    loc = np.array([eval_function(*p['funcs'][ax][1:], FROZEN_AT[p['funcs'][ax][0]]) for ax in 'xyz'])
                    p = dict(p, tag='PathPoint', loc=loc)
                    notes.append('%s: moving point %d (%s, %s) frozen at arm-at-side pose -> %s' % (
                        mname, k, m.body, '/'.join(sorted(coords)), np.round(loc, 5)))
            if p['tag'] == 'PathPoint':
                row['type'] = 'fixed'
                row['x'], row['y'], row['z'] = m.point(p['loc'])
            elif p['tag'] == 'ConditionalPathPoint':
                row.update(type='conditional', coordinate=MOBL_COORD[p['coord']] + '_r',
                           range_min=p['range'][0], range_max=p['range'][1])
                row['x'], row['y'], row['z'] = m.point(p['loc'])
            else:
                # coordinate-dependent point: map the whole curve into the new frame.
                coords = {p['funcs'][ax][0] for ax in 'xyz'}
                assert coords == {'pro_sup'} and m.body == 'radius_r', (mname, coords)
                knots = sorted(set().union(*[set(p['funcs'][ax][2]) for ax in 'xyz']))
                # sample the source curve at the union of knots and re-express the samples;
                # the mapped curve is stored per axis as a natural cubic through the samples.
                samp = np.array([[eval_function(*p['funcs'][ax][1:], q) for ax in 'xyz'] for q in knots])
                mapped = np.array([m.point(v) for v in samp])
                row['type'] = 'moving'
                for a, ax in enumerate('xyz'):
                    for q, v in zip(knots, mapped[:, a]):
                        right.funcs.append({'muscle': mname, 'index': i, 'axis': ax,
                                            'function': 'NaturalCubicSpline', 'coordinate': 'pro_sup_r',
                                            'knot': q + dq, 'value': v})
                notes.append('%s: moving point %d on radius (pro_sup) resampled at knots %s, mapped, knots shifted by %+.4f rad' % (
                    mname, k, np.round(knots, 4), dq))
            right.points.append(row)
        for k, w in enumerate(r['wraps'], 1):
            a, b = w['range']
            if a > 0:
                # remap point indices (dropped conditional points)
                ks = [kk for kk in newidx if a <= kk <= b]
                a, b = (newidx[min(ks)], newidx[max(ks)]) if ks else (-1, -1)
            right.mwraps.append({'muscle': mname, 'order': k, 'wrap_object': w['wrap'] + '_r',
                                 'method': w['method'], 'range_start': a, 'range_end': b})
            d = dict(wraps[w['wrap']])
            m = maps[d['body']]
            d['scale'] = m.s
            add_wrap(right, d['name'] + '_r', m.body, d['tag'], m.rotation(d['rot']), m.point(d['t']), d, MOBL_SRC)
    # left = mirror of right (z -> -z)
    left = Tables()
    L = lambda s: s[:-2] + '_l' if s.endswith('_r') else s
    for row in right.muscles:
        left.muscles.append(dict(row, name=L(row['name']), side='l'))
    for row in right.points:
        left.points.append(dict(row, muscle=L(row['muscle']), body=L(row['body']),
                                z=(-row['z'] if row['z'] != '' else ''), coordinate=L(row['coordinate'])))
    for row in right.funcs:
        left.funcs.append(dict(row, muscle=L(row['muscle']), coordinate=L(row['coordinate']),
                               value=(-row['value'] if row['axis'] == 'z' else row['value'])))
    for row in right.mwraps:
        left.mwraps.append(dict(row, muscle=L(row['muscle']), wrap_object=L(row['wrap_object'])))
    for row in right.wraps:
        left.wraps.append(dict(row, name=L(row['name']), body=L(row['body']), rot_x=-row['rot_x'],
                               rot_y=-row['rot_y'], tz=-row['tz'], quadrant=mirror_quadrant(row['quadrant'])))
    for part in (right, left):
        T.muscles += part.muscles; T.points += part.points; T.funcs += part.funcs
        T.mwraps += part.mwraps; T.wraps += part.wraps


def write(path, cols, rows):
    with open(path, 'w', newline='') as f:
        w = csv.writer(f, lineterminator='\n')
        w.writerow(cols)
        for r in rows:
            w.writerow([fmt(r[c]) if isinstance(r[c], (float, np.floating)) else r[c] for c in cols])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--gait2392', required=True)
    ap.add_argument('--rajagopal', required=True)
    ap.add_argument('--mobl', required=True)
    ap.add_argument('--geom', required=True)
    ap.add_argument('--out', required=True)
    a = ap.parse_args()
    g, raj, mobl = model_of(a.gait2392), model_of(a.rajagopal), model_of(a.mobl)
    T = Tables()
    legs(T, g)
    maps, info = arm_frame_maps(mobl, raj, a.geom)
    dq = prosup_offset(raj, maps)
    notes = []
    arms(T, mobl, maps, dq, notes)
    os.makedirs(a.out, exist_ok=True)
    write(os.path.join(a.out, 'muscles.csv'), ['name', 'group', 'side', 'max_isometric_force',
          'optimal_fiber_length', 'tendon_slack_length', 'pennation_angle', 'max_contraction_velocity', 'source'], T.muscles)
    write(os.path.join(a.out, 'path_points.csv'), ['muscle', 'index', 'type', 'body', 'x', 'y', 'z',
          'coordinate', 'range_min', 'range_max', 'source'], T.points)
    write(os.path.join(a.out, 'moving_point_functions.csv'), ['muscle', 'index', 'axis', 'function',
          'coordinate', 'knot', 'value'], T.funcs)
    write(os.path.join(a.out, 'wrap_objects.csv'), ['name', 'body', 'type', 'rot_x', 'rot_y', 'rot_z',
          'tx', 'ty', 'tz', 'radius', 'length', 'dim_x', 'dim_y', 'dim_z', 'quadrant', 'source'], T.wraps)
    write(os.path.join(a.out, 'muscle_wraps.csv'), ['muscle', 'order', 'wrap_object', 'method',
          'range_start', 'range_end'], T.mwraps)
    np.set_printoptions(precision=6, suppress=True)
    print('frame maps (MoBL-ARMS -> Rajagopal2016):')
    for k in ('gh_in_thorax', 'acromial_r', 'thorax_to_torso', 'clavicle_in_thorax', 'scapula_in_thorax'):
        print('  %s: %s' % (k, info[k]))
    for b in ('humerus', 'ulna', 'radius'):
        d = info[b]
        print('  %s: s = %.4f, xyz body rotation (deg) = %s, mesh rms = %.1f mm\n    R = %s' % (
            b, d['s'], d['euler_deg'], 1000 * d['rms'], d['R'].tolist()))
    for line in landmark_report(mobl, raj, maps):
        print('  ' + line)
    print('  pro_sup zero offset (Rajagopal - MoBL): %.4f rad (%.1f deg)' % (dq, math.degrees(dq)))
    for n in notes:
        print('  note: ' + n)
    print('rows: muscles %d, points %d, function knots %d, wrap objects %d, muscle wraps %d' % (
        len(T.muscles), len(T.points), len(T.funcs), len(T.wraps), len(T.mwraps)))


if __name__ == '__main__':
    main()
