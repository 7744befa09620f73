//! Wrapping of one straight path segment P → S over a wrap surface (sphere, cylinder,
//! ellipsoid, torus), as OpenSim 4.x defines it (`WrapSphere`, `WrapCylinder`,
//! `WrapEllipsoid`, `WrapTorus`, `WrapObject`).
//!
//! Everything is expressed in the wrap object's own frame: origin at its centre, the
//! cylinder's and the torus' axis along z. A wrapped segment is P → T1 → (curve on the
//! surface) → T2 → S. Each function returns OpenSim's outcome (`WrapOutcome`): no wrap (no
//! contact, or a degenerate configuration, each documented at its function), a path point
//! inside the object (which OpenSim's path algorithm treats specially), or the wrap, with
//! OpenSim's "mandatory" flag; `WrapOutcome::wrapped` gives it as an `Option`.
//!
//! - sphere: wraps when the segment crosses the sphere; great circle through P, S and the
//!   centre; a shortest path (the quadrant-forced far-side wrap is a stationary one).
//! - cylinder: wraps when the projected segment crosses the circle, or when quadrant rules
//!   force it; helix; a shortest path (geodesic).
//! - ellipsoid: wraps when the segment crosses the ellipsoid; the plane section through P, S
//!   and a heuristic surface point c1; not a shortest path.
//! - torus: a cylinder tangent to the ring at the point nearest the line, wrapped by the
//!   cylinder's rules; helix on that cylinder; not a shortest path.
//!
//! `Wrapped::dlength_dp` / `dlength_ds` are the exact derivatives of `Wrapped::length` with
//! the wrap frame fixed. For the sphere and the cylinder the envelope theorem gives them in
//! closed form (unit vectors T1→P and T2→S); the ellipsoid and torus constructions are not
//! stationary in their hidden choices (wrap plane, cylinder placement), so they are
//! differentiated exactly by forward-mode dual numbers (`real::D6`), with the iterative parts
//! lifted by the implicit-function theorem. `Wrapped::dt1` / `dt2`, the Jacobians of the
//! contact points with respect to (P, S), are exact derivatives of what each algorithm
//! computes: by dual numbers through the ellipsoid and torus constructions (the same passes
//! that give their length gradients), and in closed form for the sphere and the cylinder,
//! whose contact points are closed forms of P and S. [`WrapSurface::second_order`] gives
//! the next order along a direction (Hessian of the length times δ, rates of the contact
//! Jacobians) by the same constructions on `D6<D1>`, for the exact q-gradients of
//! moment arms. No function here allocates, and every iteration has a fixed bound.
//!
//! Checked against OpenSim 4.6 itself (`tests/opensim_reference.txt`, random segments over
//! every surface, method and quadrant): the sphere agrees to round-off, the cylinder to
//! ~1e-6 m (OpenSim's helix iteration), the torus to ~1e-7 m, the ellipsoid to ~2e-5 m
//! (OpenSim's solver tolerance and polyline arc). Each function's documentation lists the
//! OpenSim defects deliberately not reproduced.

// Comparisons are written `!(x > 0.0)` where a NaN must be rejected along with the
// non-positive values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod closest;
mod cylinder;
mod ellipsoid;
mod elliptic;
mod fan_sum;
mod real;
mod sphere;
mod torus;

#[cfg(test)]
mod tests;

pub use cylinder::wrap_cylinder;
pub use ellipsoid::wrap_ellipsoid;
pub use sphere::wrap_sphere;
pub use torus::wrap_torus;

use nalgebra::Matrix3x6;

use crate::spatial::Vec3;

/// OpenSim's `quadrant` property: restricts the wrap to the side of a coordinate plane of the
/// wrap frame where the given axis has the given sign. Axis 0, 1, 2 = x, y, z.
///
/// A point is on the *active* side when `sign(x[axis]) == sign`, with OpenSim's convention
/// that 0 counts as positive. An axis above 2 (only constructible by hand) makes every wrap
/// function return `WrapOutcome::NoWrap`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quadrant {
    All,
    Positive(usize),
    Negative(usize),
}

impl Quadrant {
    /// Parses OpenSim's strings: `all`/`All`/`ALL` (and `Unassigned`, OpenSim's default,
    /// which means all), and `x`, `+x`, `-x` with either case, likewise y and z.
    /// Surrounding whitespace is ignored.
    pub fn parse(s: &str) -> Result<Quadrant, String> {
        let t = s.trim();
        match t {
            "all" | "All" | "ALL" | "Unassigned" => return Ok(Quadrant::All),
            _ => {}
        }
        let (negative, axis_name) = match t.strip_prefix('-') {
            Some(rest) => (true, rest),
            None => (false, t.strip_prefix('+').unwrap_or(t)),
        };
        let axis = match axis_name {
            "x" | "X" => 0,
            "y" | "Y" => 1,
            "z" | "Z" => 2,
            _ => {
                return Err(format!(
                    "invalid wrap quadrant {s:?}: expected all, x, +x, -x, y, +y, -y, z, +z or -z"
                ));
            }
        };
        Ok(if negative {
            Quadrant::Negative(axis)
        } else {
            Quadrant::Positive(axis)
        })
    }

    /// `(axis, sign)` of a constrained quadrant, `None` for `All`.
    pub(crate) fn constraint(self) -> Option<(usize, f64)> {
        match self {
            Quadrant::All => None,
            Quadrant::Positive(a) => Some((a, 1.0)),
            Quadrant::Negative(a) => Some((a, -1.0)),
        }
    }

    pub(crate) fn is_valid(self) -> bool {
        match self {
            Quadrant::All => true,
            Quadrant::Positive(a) | Quadrant::Negative(a) => a < 3,
        }
    }
}

/// OpenSim's sign convention (`DSIGN`): 0 counts as positive.
#[inline]
pub(crate) fn dsign(v: f64) -> f64 {
    if v >= 0.0 { 1.0 } else { -1.0 }
}

/// OpenSim's `method` for ellipsoid wrapping: how the point c1 that fixes the wrap plane is
/// found (see `wrap_ellipsoid`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EllipsoidMethod {
    Hybrid,
    Midpoint,
    Axial,
}

impl EllipsoidMethod {
    /// Parses OpenSim's strings: `hybrid`/`Hybrid`/`HYBRID`, likewise midpoint and axial;
    /// `Unassigned` (OpenSim's default) means hybrid. Surrounding whitespace is ignored.
    pub fn parse(s: &str) -> Result<Self, String> {
        match s.trim() {
            "hybrid" | "Hybrid" | "HYBRID" | "Unassigned" => Ok(EllipsoidMethod::Hybrid),
            "midpoint" | "Midpoint" | "MIDPOINT" => Ok(EllipsoidMethod::Midpoint),
            "axial" | "Axial" | "AXIAL" => Ok(EllipsoidMethod::Axial),
            _ => Err(format!(
                "invalid ellipsoid wrap method {s:?}: expected hybrid, midpoint or axial"
            )),
        }
    }
}

/// The curve on the surface from T1 to T2, in the wrap frame:
/// `x(f) = center + cos(f·span)·w1 + sin(f·span)·w2 + f·w3`, f ∈ [0, 1], with x(0) = T1 and
/// x(1) = T2. Great circle (sphere), helix (cylinder, torus) and plane section (ellipsoid)
/// all take this form. The parameter is uniform in angle, not in arc length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceArc {
    pub center: Vec3,
    pub w1: Vec3,
    pub w2: Vec3,
    pub w3: Vec3,
    pub span: f64,
}

impl SurfaceArc {
    /// The point at fraction `f` ∈ [0, 1] of the arc parameter.
    pub fn point(&self, f: f64) -> Vec3 {
        let (s, c) = (f * self.span).sin_cos();
        self.center + self.w1 * c + self.w2 * s + self.w3 * f
    }
}

/// A wrapped segment P → T1 → (surface) → T2 → S, in the wrap frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wrapped {
    /// First contact point (the end of the straight part from P).
    pub t1: Vec3,
    /// Last contact point (the start of the straight part to S).
    pub t2: Vec3,
    /// Length along the surface from t1 to t2.
    pub surface_length: f64,
    /// |P − T1| + surface_length + |T2 − S|.
    pub length: f64,
    /// Exact ∂length/∂P, wrap frame fixed.
    pub dlength_dp: Vec3,
    /// Exact ∂length/∂S, wrap frame fixed.
    pub dlength_ds: Vec3,
    /// Exact ∂t1/∂(P, S), wrap frame fixed: 3 × 6, rows x, y, z of t1, columns P.x, P.y,
    /// P.z, S.x, S.y, S.z. Unbounded as P or S approaches the surface (a contact point
    /// moves as the square root of the point's distance to it); not finite when P or S lies
    /// exactly on it.
    pub dt1: Matrix3x6<f64>,
    /// Exact ∂t2/∂(P, S), laid out as `dt1`.
    pub dt2: Matrix3x6<f64>,
    /// OpenSim's `mandatoryWrap`: its path algorithm must take this segment's wrap (rather
    /// than the segment of the path whose wrap lengthens it least). See each function for
    /// when OpenSim sets it.
    pub mandatory: bool,
    /// The surface curve, for drawing and export.
    pub arc: SurfaceArc,
}

impl Wrapped {
    /// Fills `out` with points evenly spaced in the arc parameter from t1 to t2 inclusive
    /// (one point gives t1). Points for drawing/export; allocation is the caller's.
    pub fn surface_path(&self, out: &mut [Vec3]) {
        let n = out.len();
        for (i, p) in out.iter_mut().enumerate() {
            let f = if n > 1 {
                i as f64 / (n - 1) as f64
            } else {
                0.0
            };
            *p = self.arc.point(f);
        }
        if n > 1 {
            out[0] = self.t1;
            out[n - 1] = self.t2;
        }
    }
}

/// What OpenSim's `WrapObject::wrapLine` reports for one segment.
#[derive(Clone, Copy, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)] // returned by value: boxing would allocate per call
pub enum WrapOutcome {
    /// The segment stays straight (`noWrap`).
    NoWrap,
    /// P or S lies inside the object (`insideRadius`): no wrap, but OpenSim's path algorithm
    /// may then swap the order of two wrap objects.
    InsideRadius,
    /// The segment wraps (`wrapped`, or `mandatoryWrap` when `Wrapped::mandatory`).
    Wrapped(Wrapped),
}

impl WrapOutcome {
    /// The wrap, if any.
    pub fn wrapped(self) -> Option<Wrapped> {
        match self {
            WrapOutcome::Wrapped(w) => Some(w),
            _ => None,
        }
    }

    /// Whether the segment wraps.
    pub fn is_wrapped(&self) -> bool {
        matches!(self, WrapOutcome::Wrapped(_))
    }
}

/// A wrap surface with its dimensions, for callers that store one per wrap object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WrapSurface {
    Sphere {
        radius: f64,
    },
    Cylinder {
        radius: f64,
        length: f64,
    },
    Ellipsoid {
        radii: Vec3,
        method: EllipsoidMethod,
    },
    Torus {
        inner_radius: f64,
        outer_radius: f64,
    },
}

impl WrapSurface {
    /// Wraps the segment P → S (wrap frame) over this surface; see the per-surface functions.
    pub fn wrap(&self, quadrant: Quadrant, p: &Vec3, s: &Vec3) -> WrapOutcome {
        match *self {
            WrapSurface::Sphere { radius } => wrap_sphere(radius, quadrant, p, s),
            WrapSurface::Cylinder { radius, length } => {
                wrap_cylinder(radius, length, quadrant, p, s)
            }
            WrapSurface::Ellipsoid { radii, method } => {
                wrap_ellipsoid(&radii, quadrant, method, p, s)
            }
            WrapSurface::Torus {
                inner_radius,
                outer_radius,
            } => wrap_torus(inner_radius, outer_radius, quadrant, p, s),
        }
    }
}

/// Second derivatives of a wrapped segment along a direction δ = (δP, δS) of its end points
/// (wrap frame fixed): the rates, as P and S move by ε·δ, of the length gradient and of the
/// contact-point Jacobians. Computed by running each construction on `D6<D1>` (dual numbers
/// whose slots carry their own rate along δ), with the implicit solves lifted by two Newton
/// steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WrapSecondOrder {
    /// H·δ with H the Hessian of `Wrapped::length` in (P, S): the rate of
    /// (`dlength_dp`, `dlength_ds`).
    pub hessian_dir: [f64; 6],
    /// The rates of `Wrapped::dt1` and `Wrapped::dt2`.
    pub dt1_dir: Matrix3x6<f64>,
    pub dt2_dir: Matrix3x6<f64>,
}

impl WrapSurface {
    /// The second-order rates of the wrap of P → S along `dir` = (δP, δS), or `None` where
    /// [`WrapSurface::wrap`] does not wrap (or the rates are not finite: a contact point's
    /// derivatives are unbounded as P or S approaches the surface).
    pub fn second_order(
        &self,
        quadrant: Quadrant,
        p: &Vec3,
        s: &Vec3,
        dir: &[f64; 6],
    ) -> Option<WrapSecondOrder> {
        let w = self.wrap(quadrant, p, s).wrapped()?;
        self.second_order_of(quadrant, p, s, &w, dir)
    }

    /// [`Self::second_order`] for a wrap `w` that [`Self::wrap`] returned for the same P and S
    /// (saves computing it again).
    pub fn second_order_of(
        &self,
        quadrant: Quadrant,
        p: &Vec3,
        s: &Vec3,
        w: &Wrapped,
        dir: &[f64; 6],
    ) -> Option<WrapSecondOrder> {
        let out = match *self {
            WrapSurface::Sphere { radius } => sphere::second_order(radius, quadrant, p, s, w, dir),
            WrapSurface::Cylinder { radius, length } => {
                cylinder::second_order(radius, length, quadrant, p, s, dir)
            }
            WrapSurface::Ellipsoid { radii, method } => {
                ellipsoid::second_order(&radii, quadrant, method, p, s, dir)
            }
            WrapSurface::Torus {
                inner_radius,
                outer_radius,
            } => torus::second_order(inner_radius, outer_radius, quadrant, p, s, dir),
        }?;
        let finite = out.hessian_dir.iter().all(|v| v.is_finite())
            && out
                .dt1_dir
                .iter()
                .chain(out.dt2_dir.iter())
                .all(|v| v.is_finite());
        finite.then_some(out)
    }
}

#[inline]
pub(crate) fn all_finite(p: &Vec3, s: &Vec3) -> bool {
    p.iter().chain(s.iter()).all(|v| v.is_finite())
}
