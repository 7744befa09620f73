#!/usr/bin/env python3
"""The shoulder rhythm's coupled coordinate: u = 1 - cos(theta) as a polynomial of the shoulder
coordinates, written as OpenSim 4.6 MultivariatePolynomialFunction coefficients.

theta is the thoracohumeral elevation, the angle between the humerus' long axis and the
torso's vertical. The default model's shoulder turns the humerus by arm_flex f about the torso
z axis, then arm_add a about x, then arm_rot about y; the humerus' long axis (-y) then points
along (sin f cos a, -cos f cos a, -sin a), so

    cos(theta) = cos(f) cos(a),        u = 1 - cos(f) cos(a)                (both sides).

The rhythm tables (shoulder_rhythm*.csv, knots in u) are splines of u; u is used instead of
theta because theta = arccos(...) is a cone at the arm-at-side pose (not differentiable there),
while u is smooth, with u = (f^2 + a^2)/2 + O(4) near rest. OpenSim's CoordinateCouplerConstraint
needs a function of the two coordinates, and the one OpenSim 4.6 offers for several arguments
is MultivariatePolynomialFunction; so u is fitted by a polynomial p(f, a) of total order N by
least squares on a grid over the box below (wider than the coordinate ranges), with no constant
and no linear terms, so that p and its gradient vanish exactly at rest, as u's do.

The term order is OpenSim's own: the script builds the function with OpenSim's Python API and
reads the monomial of each coefficient from getTermValues, then checks p against u with
OpenSim's calcValue. Run with OpenSim 4.6's Python (scripts/setup-opensim.sh):

usage: shoulder_elevation.py [--order N] [--out data/model/polynomial_couplers.csv]
"""
import argparse
import csv
import math
import os
import sys

import numpy as np
import opensim as osim

# fitting box (rad): arm_flex, arm_add; wider than any range the coordinates take
BOX_FLEX = (-math.pi / 2, math.pi)
BOX_ADD = (-math.pi, math.pi / 4)
SOURCE = ('u = 1 - cos(arm_flex) cos(arm_add) (thoracohumeral elevation theta, u = 1 - cos theta); '
          'least-squares polynomial fit, scripts/model_tables/shoulder_elevation.py')


# width of the blend that turns the flexion part of u off in extension (rad)
SIGMA = math.radians(40.0)


def girdle_u(f, a):
    """u_g(f, a) = (1 - cos a) + cos a (1 - cos f) w(f), w(f) = (1 + tanh(f / SIGMA)) / 2."""
    return (1.0 - np.cos(a)) + np.cos(a) * (1.0 - np.cos(f)) * 0.5 * (1.0 + np.tanh(f / SIGMA))


def opensim_terms(order):
    """Exponents (i, j) of f^i a^j of each coefficient, in OpenSim's order."""
    n = (order + 1) * (order + 2) // 2
    f = osim.MultivariatePolynomialFunction()
    f.setDimension(2)
    f.setOrder(order)
    f.setCoefficients(osim.Vector(n, 0.0))
    # two primes: term value 2^i 3^j identifies (i, j)
    x = osim.Vector(2, 0.0)
    x.set(0, 2.0)
    x.set(1, 3.0)
    t = f.getTermValues(x)
    terms = []
    for k in range(t.size()):
        v = int(round(t.get(k)))
        i = j = 0
        while v % 2 == 0:
            v //= 2
            i += 1
        while v % 3 == 0:
            v //= 3
            j += 1
        assert v == 1, 'unexpected term value'
        terms.append((i, j))
    assert len(set(terms)) == n and all(i + j <= order for i, j in terms)
    return terms


def fit(order):
    terms = opensim_terms(order)
    F, A = np.meshgrid(np.linspace(*BOX_FLEX, 271), np.linspace(*BOX_ADD, 226))
    f, a = F.ravel(), A.ravel()
    u = girdle_u(f, a)
    free = [k for k, (i, j) in enumerate(terms) if i + j >= 2]
    X = np.stack([f ** terms[k][0] * a ** terms[k][1] for k in free], 1)
    c_free, *_ = np.linalg.lstsq(X, u, rcond=None)
    c = np.zeros(len(terms))
    c[free] = c_free
    return terms, c


def opensim_value(order, c, f, a):
    fn = osim.MultivariatePolynomialFunction()
    fn.setDimension(2)
    fn.setOrder(order)
    v = osim.Vector(len(c), 0.0)
    for k, ck in enumerate(c):
        v.set(k, float(ck))
    fn.setCoefficients(v)
    x = osim.Vector(2, 0.0)
    out = []
    for fi, ai in zip(f, a):
        x.set(0, float(fi))
        x.set(1, float(ai))
        out.append(fn.calcValue(x))
    return np.array(out)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--order', type=int, default=12)
    ap.add_argument('--out', default=os.path.join(here, '..', '..', 'data', 'model', 'polynomial_couplers.csv'))
    args = ap.parse_args()
    terms, c = fit(args.order)
    rng = np.random.default_rng(7)
    f = rng.uniform(*BOX_FLEX, 2000)
    a = rng.uniform(*BOX_ADD, 2000)
    u = girdle_u(f, a)
    p = opensim_value(args.order, c, f, a)
    err = np.abs(p - u).max()
    # the same error in degrees of elevation where it matters (theta in [5, 175] deg)
    theta = np.arccos(np.clip(1 - u, -1, 1))
    mid = (theta > math.radians(5)) & (theta < math.radians(175))
    dtheta = np.degrees(np.abs(p - u)[mid] / np.sin(theta[mid])).max()
    print('order %d, %d coefficients: max |p - u| %.2e on 2000 random points (OpenSim calcValue); '
          'max elevation error %.3f deg for theta in [5, 175] deg' % (args.order, len(c), err, dtheta))
    if err > 1e-2:
        sys.exit('fit too coarse: raise --order')
    rows = []
    for side in ('r', 'l'):
        rows.append({
            'name': 'arm_elev_u_%s_con' % side,
            'dependent': 'arm_elev_u_%s' % side,
            'independent': 'arm_flex_%s arm_add_%s' % (side, side),
            'order': args.order,
            'coefficients': ' '.join(repr(float(x)) for x in c),
            'range_min': 0,
            'range_max': 2,
            'source': SOURCE,
        })
    with open(args.out, 'w', newline='') as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]), lineterminator='\n')
        w.writeheader()
        w.writerows(rows)
    print('wrote', os.path.normpath(args.out))


if __name__ == '__main__':
    main()
