"""Regenerates opensim_reference.txt: path lengths computed by OpenSim itself (the `opensim`
Python package, 4.6) for random segments over each wrap surface, method and quadrant.

Each case is a PathSpring whose GeometryPath has two ground path points P and S and the wrap
object on ground; a second, far-away sphere is added to the path so that OpenSim runs its
cylinder tangency iteration (it skips it when a path has a single wrap object). The total
path length is recorded (equal to |P - S| when OpenSim does not wrap).

    python opensim_reference.py | grep -v '^\[' > opensim_reference.txt

(OpenSim logs a warning line, starting with '[', for each model: it is filtered out.)
"""
import math
import random

import opensim as osim

SURFACES = [
    ("sphere", [0.05], [""]),
    ("cylinder", [0.05, 0.3], [""]),
    ("ellipsoid", [0.06, 0.025, 0.04], ["hybrid", "midpoint", "axial"]),
    ("torus", [0.02, 0.06], [""]),
    # A short cylinder with segments passing near its ends, where OpenSim's finite-length
    # test (on its trial contact heights) decides whether the path wraps.
    ("short_cylinder", [0.005, 0.03], [""]),
]
QUADRANTS = ["all", "+x", "-y", "z", "-x", "y"]
PER_CASE = 10
PER_SHORT_CASE = 40


def opensim_length(kind, dims, quadrant, method, p, s):
    model = osim.Model()
    ground = model.getGround()
    if kind == "sphere":
        wrap = osim.WrapSphere()
        wrap.set_radius(dims[0])
    elif kind in ("cylinder", "short_cylinder"):
        wrap = osim.WrapCylinder()
        wrap.set_radius(dims[0])
        wrap.set_length(dims[1])
    elif kind == "ellipsoid":
        wrap = osim.WrapEllipsoid()
        wrap.set_dimensions(osim.Vec3(*dims))
    else:
        wrap = osim.WrapTorus()
        wrap.set_inner_radius(dims[0])
        wrap.set_outer_radius(dims[1])
    wrap.setName("wrap")
    wrap.set_quadrant(quadrant)
    ground.addWrapObject(wrap)
    far = osim.WrapSphere()
    far.setName("far")
    far.set_radius(0.001)
    far.set_translation(osim.Vec3(10, 10, 10))
    ground.addWrapObject(far)
    spring = osim.PathSpring("spring", 1.0, 1.0, 0.1)
    path = spring.updGeometryPath()
    path.appendNewPathPoint("p", ground, osim.Vec3(*p))
    path.appendNewPathPoint("s", ground, osim.Vec3(*s))
    path.addPathWrap(wrap)
    path.addPathWrap(far)
    if method:
        path.getWrapSet().get(0).set_method(method)
    model.addForce(spring)
    state = model.initSystem()
    model.realizePosition(state)
    return spring.getGeometryPath().getLength(state)


def main():
    random.seed(2024)
    print("# kind method quadrant px py pz sx sy sz opensim_length (dims: see the test)")
    for kind, dims, methods in SURFACES:
        for method in methods:
            for quadrant in QUADRANTS:
                for _ in range(PER_SHORT_CASE if kind == "short_cylinder" else PER_CASE):
                    if kind == "short_cylinder":
                        end = random.choice([-0.015, 0.015])
                        c = [random.uniform(-0.004, 0.004), random.uniform(-0.004, 0.004),
                             end + random.uniform(-0.006, 0.006)]
                        u = [random.gauss(0, 1), random.gauss(0, 1), random.gauss(0, 0.5)]
                        n = math.sqrt(sum(x * x for x in u))
                        a, b = random.uniform(0.02, 0.1), random.uniform(0.02, 0.1)
                        p = [c[k] - a * u[k] / n for k in range(3)]
                        s = [c[k] + b * u[k] / n for k in range(3)]
                    elif kind == "torus":
                        p = [random.uniform(-0.08, 0.08), random.uniform(-0.08, 0.08), random.uniform(0.02, 0.12)]
                        s = [random.uniform(-0.08, 0.08), random.uniform(-0.08, 0.08), -random.uniform(0.02, 0.12)]
                    else:
                        c = [random.uniform(-0.05, 0.05) for _ in range(3)]
                        u = [random.gauss(0, 1) for _ in range(3)]
                        n = math.sqrt(sum(x * x for x in u))
                        a, b = random.uniform(0.08, 0.2), random.uniform(0.08, 0.2)
                        p = [c[k] - a * u[k] / n for k in range(3)]
                        s = [c[k] + b * u[k] / n for k in range(3)]
                    length = opensim_length(kind, dims, quadrant, method, p, s)
                    if length != length:
                        continue  # OpenSim returned NaN
                    values = " ".join(repr(v) for v in p + s + [length])
                    print(f"{kind} {method or '-'} {quadrant} {values}")


if __name__ == "__main__":
    main()
