#!/usr/bin/env python3
"""Re-read data/model's limb muscle tables and check them.

  every muscle has >= 2 path points, indices 1..n; bodies are musculo's body names;
  numbers finite; moving points have x, y and z functions; wraps name existing objects;
  left/right counts symmetric and left = right mirrored (z -> -z) for every row;
  gait2392-derived rows reproduce gait2392_thelen2003muscle.osim exactly (when its path
  is given; max_isometric_force excepted where the row names Rajagopal et al. 2016, see
  strength_rajagopal.py --check), including gait2392's own left leg (which checks the mirroring convention);
  muscle counts per group and side are exactly EXPECT (57 per side, 114 in all), gait2392's
  psoas is absent (the lumbar psoas fascicles replace it), the gait2392 muscles not taken are
  exactly NOT_TAKEN, and, when lumbar_muscles.csv is present, limb + lumbar = 324 muscles
  with no shared name;
  when shoulder_rhythm*.csv are present (scripts/model_tables/shoulder_rhythm.py): every curve has
  one coordinate, increasing knots and a knot at 0 (theta or u = 1 - cos theta) where the GH
  displacement is 0, every muscle point's value at 0 equals its path_points.csv row (it names
  an existing muscle point on the same body), every wrap's pose at 0 equals its wrap_objects.csv
  row, and the left rows mirror the right ones (z -> -z; wraps also rot_x, rot_y, drot_x,
  drot_y negated).

usage: check_limb_tables.py [data/model] [--gait2392 PATH]
"""
import csv, math, os, sys
from collections import Counter, defaultdict

BODIES = {'pelvis', 'torso', 'lumbar1', 'lumbar2', 'lumbar3', 'lumbar4', 'lumbar5'} | {
    b + s for b in ('femur', 'tibia', 'calcn', 'toes', 'humerus', 'ulna', 'radius') for s in ('_r', '_l')}
ERR = []
EXPECT = {'hip': 20, 'knee': 10, 'ankle': 8, 'toes': 4, 'shoulder': 8, 'elbow': 7}   # per side
EXPECT_TOTAL = 114
EXPECT_WITH_LUMBAR = 324   # 210 lumbar fascicles + 114 limb muscles
NOT_TAKEN = {b + s for b in ('ercspn', 'intobl', 'extobl', 'psoas') for s in ('_r', '_l')}
REQUIRED = {'iliacus_r', 'iliacus_l', 'BRD_r', 'BRD_l'}
# gait2392 muscles whose conditional pelvic-brim point brim_paths.py replaced by a wrap sphere
BRIM_WRAPPED = {'iliacus_r', 'iliacus_l'}


def err(msg):
    ERR.append(msg)


def rd(d, f):
    with open(os.path.join(d, f)) as fh:
        return list(csv.DictReader(fh))


def num(v, what, allow_empty=False):
    if v == '' and allow_empty:
        return None
    try:
        x = float(v)
    except ValueError:
        err('%s: not a number: %r' % (what, v)); return None
    if not math.isfinite(x):
        err('%s: not finite' % what)
    return x


def mirror_name(n):
    return n[:-2] + '_l' if n.endswith('_r') else n


def close(a, b, tol=1e-9):
    if a is None or b is None:
        return a is None and b is None
    return abs(a - b) <= tol * max(1.0, abs(a), abs(b))


def main():
    args = [a for a in sys.argv[1:]]
    g2392 = None
    if '--gait2392' in args:
        i = args.index('--gait2392'); g2392 = args[i + 1]; del args[i:i + 2]
    d = args[0] if args else os.path.join(os.path.dirname(__file__), '..', '..', 'data', 'model')
    M, P, F, W, MW = (rd(d, f) for f in ('muscles.csv', 'path_points.csv', 'moving_point_functions.csv',
                                          'wrap_objects.csv', 'muscle_wraps.csv'))
    names = {m['name'] for m in M}
    if len(names) != len(M):
        err('duplicate muscle names')
    for m in M:
        for k in ('max_isometric_force', 'optimal_fiber_length', 'tendon_slack_length',
                  'pennation_angle', 'max_contraction_velocity'):
            x = num(m[k], m['name'] + '.' + k)
            if x is not None and (x < 0 or (k != 'pennation_angle' and x == 0)):
                err('%s.%s out of range: %s' % (m['name'], k, x))
        if m['side'] not in ('r', 'l') or not m['name'].endswith('_' + m['side']):
            err('%s: bad side' % m['name'])
        if not m['source']:
            err('%s: no source' % m['name'])
    pts = defaultdict(list)
    for p in P:
        if p['muscle'] not in names:
            err('path point of unknown muscle %s' % p['muscle'])
        pts[p['muscle']].append(p)
        if p['body'] not in BODIES:
            err('%s[%s]: body %s not allowed' % (p['muscle'], p['index'], p['body']))
        if p['type'] not in ('fixed', 'conditional', 'moving'):
            err('%s[%s]: bad type' % (p['muscle'], p['index']))
        for k in 'xyz':
            num(p[k], '%s[%s].%s' % (p['muscle'], p['index'], k), allow_empty=(p['type'] == 'moving'))
        if p['type'] == 'conditional':
            lo, hi = num(p['range_min'], 'range'), num(p['range_max'], 'range')
            if not p['coordinate'] or lo is None or hi is None or lo > hi:
                err('%s[%s]: bad conditional' % (p['muscle'], p['index']))
    fun = defaultdict(list)
    for f in F:
        fun[(f['muscle'], f['index'], f['axis'])].append((num(f['knot'], 'knot'), num(f['value'], 'value')))
    for m in names:
        ps = pts[m]
        if len(ps) < 2:
            err('%s: %d path points' % (m, len(ps)))
        if [int(p['index']) for p in ps] != list(range(1, len(ps) + 1)):
            err('%s: indices not 1..n' % m)
        for p in ps:
            if p['type'] == 'moving':
                for ax in 'xyz':
                    ks = [k for k, _ in fun.get((m, p['index'], ax), [])]
                    if not ks or ks != sorted(ks):
                        err('%s[%s]: %s function missing or knots unsorted' % (m, p['index'], ax))
    wnames = Counter(w['name'] for w in W)
    for w in W:
        if w['body'] not in BODIES:
            err('wrap %s: body %s' % (w['name'], w['body']))
        for k in ('rot_x', 'rot_y', 'rot_z', 'tx', 'ty', 'tz'):
            num(w[k], 'wrap %s.%s' % (w['name'], k))
    if any(c > 1 for c in wnames.values()):
        err('duplicate wrap objects')
    for mw in MW:
        if mw['wrap_object'] not in wnames:
            err('%s: unknown wrap %s' % (mw['muscle'], mw['wrap_object']))
        if mw['muscle'] not in names:
            err('wrap of unknown muscle %s' % mw['muscle'])
    # left/right symmetry
    right = [m for m in M if m['side'] == 'r']
    for m in right:
        l = mirror_name(m['name'])
        ml = next((x for x in M if x['name'] == l), None)
        if ml is None:
            err('%s has no left twin' % m['name']); continue
        for k in ('max_isometric_force', 'optimal_fiber_length', 'tendon_slack_length', 'pennation_angle',
                  'max_contraction_velocity', 'group'):
            if ml[k] != m[k]:
                err('%s vs %s: %s differs' % (m['name'], l, k))
        pr, pl = pts[m['name']], pts[l]
        if len(pr) != len(pl):
            err('%s: %d vs %d points' % (m['name'], len(pr), len(pl))); continue
        for a, b in zip(pr, pl):
            ok = (mirror_name(a['body']) == b['body'] and a['type'] == b['type']
                  and mirror_name(a['coordinate']) == b['coordinate']
                  and close(num(a['x'], '', True), num(b['x'], '', True))
                  and close(num(a['y'], '', True), num(b['y'], '', True))
                  and (a['z'] == '' and b['z'] == '' or close(-float(a['z']), float(b['z'])))
                  and a['range_min'] == b['range_min'] and a['range_max'] == b['range_max'])
            if not ok:
                err('%s[%s] is not the mirror of its right twin' % (l, b['index']))
            if a['type'] == 'moving':
                for ax in 'xyz':
                    fa, fb = fun[(m['name'], a['index'], ax)], fun[(l, b['index'], ax)]
                    sg = -1 if ax == 'z' else 1
                    if len(fa) != len(fb) or any(not close(x1, x2) or not close(sg * y1, y2) for (x1, y1), (x2, y2) in zip(fa, fb)):
                        err('%s[%s].%s function is not mirrored' % (l, b['index'], ax))
    cnt = Counter((m['group'], m['side']) for m in M)
    if any(cnt[(g, 'r')] != cnt[(g, 'l')] for g, _ in cnt):
        err('left/right group counts differ')
    got = {(g, s): cnt[(g, s)] for g in set(EXPECT) | {g for g, _ in cnt} for s in ('r', 'l')}
    for (g, s), c in sorted(got.items()):
        if c != EXPECT.get(g, 0):
            err('group %s side %s: %d muscles, expected %d' % (g, s, c, EXPECT.get(g, 0)))
    if len(M) != EXPECT_TOTAL:
        err('%d limb muscles, expected %d' % (len(M), EXPECT_TOTAL))
    if names & NOT_TAKEN:
        err('muscles that must not be in the limb tables: %s' % ' '.join(sorted(names & NOT_TAKEN)))
    if REQUIRED - names:
        err('missing muscles: %s' % ' '.join(sorted(REQUIRED - names)))
    lum = os.path.join(d, 'lumbar_muscles.csv')
    if os.path.exists(lum):
        LN = {m['name'] for m in rd(d, 'lumbar_muscles.csv')}
        if names & LN:
            err('names in both limb and lumbar tables: %s' % ' '.join(sorted(names & LN)))
        if len(names | LN) != EXPECT_WITH_LUMBAR:
            err('limb + lumbar = %d muscles, expected %d' % (len(names | LN), EXPECT_WITH_LUMBAR))
        print('limb %d + lumbar %d = %d muscles' % (len(names), len(LN), len(names | LN)))
    if os.path.exists(os.path.join(d, 'shoulder_rhythm.csv')):
        check_rhythm(d, P, W)
    # gait2392 reproduction
    if g2392:
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        import xml.etree.ElementTree as ET
        from extract_limb_muscles import read_muscle
        model = ET.parse(g2392).getroot().find('Model')
        src = {mu.get('name'): read_muscle(mu) for mu in model.find('ForceSet/objects')}
        n = 0
        for m in M:
            if not m['source'].startswith('gait2392'):
                continue
            s = src[m['name']]
            n += 1
            for k, sk in (('max_isometric_force', 'max_isometric_force'), ('optimal_fiber_length', 'optimal_fiber_length'),
                          ('tendon_slack_length', 'tendon_slack_length'), ('pennation_angle', 'pennation_angle_at_optimal'),
                          ('max_contraction_velocity', 'max_contraction_velocity')):
                if k == 'max_isometric_force' and 'max_isometric_force: Rajagopal' in m['source']:
                    continue   # strength_rajagopal.py's rows: checked by its --check
                if not close(float(m[k]), s[sk]):
                    err('%s.%s: %s vs gait2392 %s' % (m['name'], k, m[k], s[sk]))
            ps = pts[m['name']]
            spts = s['points']
            if m['name'] in BRIM_WRAPPED:   # brim_paths.py: conditional brim point -> sphere
                spts = [q for q in spts if q['tag'] != 'ConditionalPathPoint']
            if len(ps) != len(spts):
                err('%s: %d points vs gait2392 %d' % (m['name'], len(ps), len(spts))); continue
            for p, q in zip(ps, spts):
                if p['body'] != q['body']:   # talus would be re-expressed in calcn; gait2392 has none
                    err('%s[%s]: body %s vs %s' % (m['name'], p['index'], p['body'], q['body']))
                if q['tag'] != 'MovingPathPoint':
                    if any(not close(float(p[a]), q['loc'][i]) for i, a in enumerate('xyz')):
                        err('%s[%s]: location differs from gait2392' % (m['name'], p['index']))
                if q['tag'] == 'ConditionalPathPoint' and (p['coordinate'] != q['coord'] or not close(float(p['range_min']), q['range'][0]) or not close(float(p['range_max']), q['range'][1])):
                    err('%s[%s]: condition differs' % (m['name'], p['index']))
                if q['tag'] == 'MovingPathPoint':
                    for ax in 'xyz':
                        coord, kind, xs, ys = q['funcs'][ax]
                        got = fun[(m['name'], p['index'], ax)]
                        if len(got) != len(xs) or any(not close(a, b) or not close(c, e) for (a, c), b, e in zip(got, xs, ys)):
                            err('%s[%s].%s: function differs from gait2392' % (m['name'], p['index'], ax))
        dropped = sorted(set(src) - names)
        if set(dropped) != NOT_TAKEN:
            err('gait2392 muscles not taken: %s, expected %s' % (' '.join(dropped), ' '.join(sorted(NOT_TAKEN))))
        print('gait2392 rows re-composed: %d muscles; not taken: %s' % (n, ' '.join(dropped)))
    print('muscles by group and side:')
    for g in sorted({g for g, _ in cnt}):
        print('  %-9s r %3d  l %3d' % (g, cnt[(g, 'r')], cnt[(g, 'l')]))
    print('  total     %d muscles, %d path points (%s), %d function knots, %d wrap objects, %d muscle-wrap links' % (
        len(M), len(P), ', '.join('%s %d' % kv for kv in sorted(Counter(p['type'] for p in P).items())),
        len(F), len(W), len(MW)))
    if ERR:
        print('%d problems:' % len(ERR))
        for e in ERR[:50]:
            print('  ' + e)
        sys.exit(1)
    print('OK')


def check_rhythm(d, P, W):
    """shoulder_rhythm.csv, shoulder_rhythm_points.csv, shoulder_rhythm_wraps.csv"""
    GH, RP, RW = (rd(d, f) for f in ('shoulder_rhythm.csv', 'shoulder_rhythm_points.csv',
                                     'shoulder_rhythm_wraps.csv'))
    prow = {(p['muscle'], p['index']): p for p in P}
    wrow = {w['name']: w for w in W}
    curves = defaultdict(list)
    for r in GH:
        curves[('gh', r['joint'], '', r['axis'])].append(r)
    for r in RP:
        curves[('pt', r['muscle'], r['index'], r['axis'])].append(r)
    coords = set()
    for key, rows in curves.items():
        if not all(r['source'] for r in rows):
            err('%s: row without source' % (key,))
        cs = {r['coordinate'] for r in rows}
        coords |= cs
        side = key[1][-1]
        if len(cs) != 1 or not next(iter(cs)).endswith('_' + side):
            err('%s: coordinates %s' % (key, cs))
        ks = [num(r['knot'], '%s knot' % (key,)) for r in rows]
        vs = {k: num(r['value'], '%s value' % (key,)) for k, r in zip(ks, rows)}
        if None in ks or ks != sorted(ks) or len(set(ks)) != len(ks) or 0.0 not in vs:
            err('%s: knots not increasing or no knot at 0' % (key,)); continue
        if key[0] == 'gh' and abs(vs[0.0]) > 1e-12:
            err('%s: GH displacement at 0 is %g' % (key, vs[0.0]))
        if key[0] == 'pt':
            p = prow.get((key[1], key[2]))
            if p is None or p['body'] != rows[0]['body'] or p['type'] != 'fixed':
                err('%s: no fixed point on %s in path_points.csv' % (key, rows[0]['body']))
            elif abs(float(p[key[3]]) - vs[0.0]) > 1e-6:
                err('%s: value at 0 %g differs from path_points.csv %s' % (key, vs[0.0], p[key[3]]))
        if side == 'r':
            twin = curves.get((key[0], mirror_name(key[1]), key[2], key[3]))
            sg = -1 if key[3] == 'z' else 1
            if twin is None or len(twin) != len(rows) or any(
                    not close(float(a['knot']), float(b['knot'])) or not close(sg * float(a['value']), float(b['value']))
                    for a, b in zip(rows, twin)):
                err('%s: left rows are not the mirror' % (key,))
    wraps = defaultdict(list)
    for r in RW:
        wraps[r['name']].append(r)
    for name, rows in wraps.items():
        w = wrow.get(name)
        r0 = next((r for r in rows if float(r['knot']) == 0.0), None)
        if w is None or r0 is None or w['body'] != r0['body'] or w['type'] != r0['type']:
            err('rhythm wrap %s: no wrap_objects.csv row of that body and type, or no knot at 0' % name); continue
        for k in ('tx', 'ty', 'tz', 'rot_x', 'rot_y', 'rot_z'):
            if abs(float(w[k]) - float(r0[k])) > 1e-6:
                err('rhythm wrap %s: %s at 0 is %s, wrap_objects.csv %s' % (name, k, r0[k], w[k]))
        if name.endswith('_r'):
            twin = wraps.get(mirror_name(name), [])
            neg = ('tz', 'rot_x', 'rot_y', 'drot_x', 'drot_y')
            for a, b in zip(rows, twin):
                for k in ('knot', 'tx', 'ty', 'tz', 'rot_x', 'rot_y', 'rot_z', 'drot_x', 'drot_y', 'drot_z'):
                    if not close((-1 if k in neg else 1) * float(a[k]), float(b[k])):
                        err('rhythm wrap %s: %s not mirrored' % (mirror_name(name), k)); break
            if len(twin) != len(rows):
                err('rhythm wrap %s: %d left rows for %d right' % (name, len(twin), len(rows)))
    print('shoulder rhythm: %d GH curves, %d muscle-point curves, %d wraps; coordinates %s' % (
        sum(k[0] == 'gh' for k in curves), sum(k[0] == 'pt' for k in curves), len(wraps), ' '.join(sorted(coords))))


if __name__ == '__main__':
    main()
