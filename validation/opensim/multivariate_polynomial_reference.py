"""Regenerates tests/data/multivariate_polynomial_opensim.txt: values computed by OpenSim 4.6
itself (the `opensim` Python package) for musculo's MultivariatePolynomialFunction tests
(tests/multivariate_polynomial.rs), so that the tests need no Python.

1. `function` / `point` lines: random MultivariatePolynomialFunctions (dimension 2 and 3,
   order 1 to 4, coefficients uniform in [-1, 1]) and, at random points, OpenSim's
   calcValue and its first derivatives calcDerivative([a]) (OpenSim 4.6 computes first
   derivatives only: getMaxDerivativeOrder() is 1).
2. `state` lines: the model tests/data/multivariate_coupler.osim at random states of its
   independent coordinates, the dependent coordinate `elev` set from the coupler's own
   function (OpenSim's constraint error at that state is printed as a comment), and the
   ground poses of both bodies and the wrist marker.

    eval "$(scripts/setup-opensim.sh)"
    $MUSCULO_OPENSIM_PYTHON validation/opensim/multivariate_polynomial_reference.py \
        > tests/data/multivariate_polynomial_opensim.txt

(OpenSim's log is set to errors only, so that nothing else reaches the table.)
"""
import math
import os
import random
import sys

import opensim as osim

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
MODEL = os.path.join(ROOT, "tests", "data", "multivariate_coupler.osim")
POLYNOMIALS = [(2, 1), (2, 3), (2, 4), (3, 2), (3, 3), (3, 4)]
POINTS = 5
STATES = 8


def vector(values):
    v = osim.Vector(len(values), 0.0)
    for i, x in enumerate(values):
        v.set(i, x)
    return v


def numbers(values):
    return " ".join(repr(float(x)) for x in values)


def derivative(f, component, x):
    comps = osim.StdVectorInt()
    comps.append(component)
    return f.calcDerivative(comps, vector(x))


def functions(rng):
    print("# function dimension order coefficients... (OpenSim's order)")
    print("# point x_0 .. x_{n-1} calcValue calcDerivative([0]) .. calcDerivative([n-1])")
    for dimension, order in POLYNOMIALS:
        count = math.comb(dimension + order, order)
        c = [rng.uniform(-1.0, 1.0) for _ in range(count)]
        f = osim.MultivariatePolynomialFunction(vector(c), dimension, order)
        print(f"function {dimension} {order} {numbers(c)}")
        for _ in range(POINTS):
            x = [rng.uniform(-1.5, 1.5) for _ in range(dimension)]
            d = [derivative(f, a, x) for a in range(dimension)]
            print(f"point {numbers(x)} {numbers([f.calcValue(vector(x))])} {numbers(d)}")


def pose(frame, state):
    t = frame.getTransformInGround(state)
    p = t.p()
    r = t.R()
    return [p.get(i) for i in range(3)] + [r.get(i, j) for i in range(3) for j in range(3)]


def states(rng):
    model = osim.Model(MODEL)
    state = model.initSystem()
    coords = model.getCoordinateSet()
    coupler = osim.CoordinateCouplerConstraint.safeDownCast(
        model.getConstraintSet().get("shoulder_rhythm"))
    function = coupler.getFunction()
    scale = osim.PropertyHelper.getValueDouble(coupler.getPropertyByName("scale_factor"))
    humerus = model.getBodySet().get("humerus")
    forearm = model.getBodySet().get("forearm")
    wrist = model.getMarkerSet().get("wrist")
    print("# state arm_flex arm_add elbow_flex elev, then the humerus's and the forearm's")
    print("#   ground origin (3) and rotation (9, row-major), then the wrist marker (3)")
    worst = 0.0
    for _ in range(STATES):
        q = {}
        for name in ("arm_flex", "arm_add", "elbow_flex"):
            lo, hi = coords.get(name).getRangeMin(), coords.get(name).getRangeMax()
            q[name] = rng.uniform(lo, hi)
            coords.get(name).setValue(state, q[name], False)
        q["elev"] = scale * function.calcValue(vector([q["arm_flex"], q["arm_add"]]))
        coords.get("elev").setValue(state, q["elev"], False)
        model.realizePosition(state)
        qerr = state.getQErr()
        worst = max([worst] + [abs(qerr.get(i)) for i in range(qerr.size())])
        row = [q["arm_flex"], q["arm_add"], q["elbow_flex"], q["elev"]]
        row += pose(humerus, state) + pose(forearm, state)
        loc = wrist.getLocationInGround(state)
        row += [loc.get(i) for i in range(3)]
        print(f"state {numbers(row)}")
    print(f"# largest constraint error |q_err| of OpenSim at these states: {worst:.3e}")


def main():
    osim.Logger.setLevelString("error")
    rng = random.Random(20261203)
    print(f"# OpenSim {osim.GetVersion()}: {os.path.basename(__file__)} (do not edit)")
    functions(rng)
    states(rng)


if __name__ == "__main__":
    sys.exit(main())
