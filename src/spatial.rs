//! Spatial algebra on nalgebra: rigid transforms, rotations, and spatial motion, force and
//! inertia in the *ground-aligned* convention used by the dynamics algorithms.
//!
//! Convention (as in MuJoCo's com-based quantities and Featherstone's spatial algebra
//! expressed in one frame): every spatial vector is expressed in ground axes and taken about
//! one reference point `O` that is fixed in ground for the instant considered
//! (`Data::reference_point`).
//! - a motion vector `(ang, lin)` is an angular velocity and the velocity of the body-fixed
//!   point that coincides with `O`;
//! - a force vector `(ang, lin)` is a moment about `O` and a force;
//! - a spatial inertia is `(mass, h = m·(c − O), I_O)`, with `I_O` the rotational inertia
//!   about `O`.
//!
//! Because every quantity lives in the same frame, propagating velocities and summing
//! composite inertias needs no coordinate transforms at all.

use nalgebra::{Matrix3, Vector3};

/// 3-vector of f64.
pub type Vec3 = Vector3<f64>;
/// 3×3 matrix of f64.
pub type Mat3 = Matrix3<f64>;

/// A rigid transform `x_parent = rot · x_child + pos`: the pose of a child frame in a parent
/// frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    pub rot: Mat3,
    pub pos: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Self::identity()
    }
}

impl Transform {
    pub fn identity() -> Self {
        Transform {
            rot: Mat3::identity(),
            pos: Vec3::zeros(),
        }
    }

    pub fn new(rot: Mat3, pos: Vec3) -> Self {
        Transform { rot, pos }
    }

    /// The transform of an OpenSim offset: `translation` and a body-fixed X-Y-Z rotation
    /// sequence `orientation` (OpenSim's `orientation` / `xyz_body_rotation`).
    pub fn from_translation_xyz_body(translation: Vec3, orientation: Vec3) -> Self {
        Transform {
            rot: rotation_body_fixed_xyz(orientation),
            pos: translation,
        }
    }

    /// `self ∘ other`: if `self` is X_AB and `other` is X_BC, the result is X_AC.
    #[inline]
    pub fn compose(&self, other: &Transform) -> Transform {
        Transform {
            rot: self.rot * other.rot,
            pos: self.rot * other.pos + self.pos,
        }
    }

    /// X_BA from X_AB.
    pub fn inverse(&self) -> Transform {
        let rt = self.rot.transpose();
        Transform {
            rot: rt,
            pos: -(rt * self.pos),
        }
    }

    /// Maps a point given in the child frame into the parent frame.
    #[inline]
    pub fn apply_point(&self, p: &Vec3) -> Vec3 {
        self.rot * p + self.pos
    }

    pub fn is_identity(&self) -> bool {
        self.rot == Mat3::identity() && self.pos == Vec3::zeros()
    }
}

/// Rotation matrix for a body-fixed X-Y-Z sequence: R = Rx(a)·Ry(b)·Rz(c).
pub fn rotation_body_fixed_xyz(angles: Vec3) -> Mat3 {
    let (sa, ca) = angles.x.sin_cos();
    let (sb, cb) = angles.y.sin_cos();
    let (sc, cc) = angles.z.sin_cos();
    Mat3::new(
        cb * cc,
        -cb * sc,
        sb,
        ca * sc + sa * sb * cc,
        ca * cc - sa * sb * sc,
        -sa * cb,
        sa * sc - ca * sb * cc,
        sa * cc + ca * sb * sc,
        ca * cb,
    )
}

/// Rotation by `angle` about the unit vector `axis` (Rodrigues' formula):
/// R = I + sinθ \[a\]× + (1 − cosθ) \[a\]×².
#[inline]
pub fn rotation_about_axis(axis: &Vec3, angle: f64) -> Mat3 {
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    let (x, y, z) = (axis.x, axis.y, axis.z);
    Mat3::new(
        t * x * x + c,
        t * x * y - s * z,
        t * x * z + s * y,
        t * x * y + s * z,
        t * y * y + c,
        t * y * z - s * x,
        t * x * z - s * y,
        t * y * z + s * x,
        t * z * z + c,
    )
}

/// R ← R · R(axis, angle): post-multiplication by a rotation about a unit axis of the frame R
/// describes (a body-fixed rotation). For an elementary axis σ e_k only the two columns
/// a = k+1, b = k+2 (cyclic) change: col_a ← c col_a + s col_b, col_b ← −s col_a + c col_b
/// with (s, c) = sincos(σ θ).
#[inline]
pub fn post_rotate(r: &mut Mat3, axis: &Vec3, elementary: Option<(usize, f64)>, angle: f64) {
    match elementary {
        Some((k, sign)) => {
            let (s, c) = (sign * angle).sin_cos();
            let (a, b) = ((k + 1) % 3, (k + 2) % 3);
            for i in 0..3 {
                let (ra, rb) = (r[(i, a)], r[(i, b)]);
                r[(i, a)] = c * ra + s * rb;
                r[(i, b)] = c * rb - s * ra;
            }
        }
        None => *r *= rotation_about_axis(axis, angle),
    }
}

/// Rotation vector (axis·angle) of a rotation matrix; the inverse of `rotation_about_axis`.
///
/// With v = vee((R − Rᵀ)/2) = sin θ · axis and cos θ = (tr R − 1)/2, θ = atan2(|v|, cos θ),
/// which stays accurate for small angles (where an arccos of the trace would not); near
/// θ = π the axis comes from the symmetric part, (R + 1)/2 = a aᵀ + cos-terms.
pub fn rotation_vector(r: &Mat3) -> Vec3 {
    let v = Vec3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    ) * 0.5;
    let s = v.norm();
    let c = ((r[(0, 0)] + r[(1, 1)] + r[(2, 2)]) - 1.0) * 0.5;
    let theta = s.atan2(c);
    if s < 1e-300 && c > 0.0 {
        return Vec3::zeros();
    }
    if c > -0.9 {
        return v * (theta / s);
    }
    // Near π: a aᵀ = (R + Rᵀ)/2 − cos θ · 1) / (1 − cos θ); take the largest column.
    let sym = (r + r.transpose()) * 0.5 - Mat3::identity() * c;
    let k = (0..3)
        .max_by(|&i, &j| sym[(i, i)].total_cmp(&sym[(j, j)]))
        .unwrap_or(0);
    let mut axis: Vec3 = sym.column(k).into();
    axis /= axis.norm();
    if axis.dot(&v) < 0.0 {
        axis = -axis;
    }
    axis * theta
}

/// A symmetric inertia matrix as the six numbers OpenSim and MJCF write,
/// `Ixx Iyy Izz Ixy Ixz Iyz`.
pub fn inertia_six(i: &Mat3) -> [f64; 6] {
    [
        i[(0, 0)],
        i[(1, 1)],
        i[(2, 2)],
        i[(0, 1)],
        i[(0, 2)],
        i[(1, 2)],
    ]
}

/// [`inertia_six`] as text, the numbers separated by spaces.
pub fn inertia_text(i: &Mat3) -> String {
    inertia_six(i).map(|v| v.to_string()).join(" ")
}

/// The cross-product matrix \[v\]× with \[v\]× w = v × w.
pub fn skew(v: &Vec3) -> Mat3 {
    Mat3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// A spatial motion vector (velocity, acceleration or joint axis) in ground axes about the
/// reference point O.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Motion {
    /// Angular part.
    pub ang: Vec3,
    /// Linear part: the velocity (or acceleration) of the body point at O.
    pub lin: Vec3,
}

impl Motion {
    pub const ZERO: Motion = Motion {
        ang: Vec3::new(0.0, 0.0, 0.0),
        lin: Vec3::new(0.0, 0.0, 0.0),
    };

    #[inline]
    pub fn new(ang: Vec3, lin: Vec3) -> Self {
        Motion { ang, lin }
    }

    #[inline]
    pub fn scale(&self, s: f64) -> Motion {
        Motion {
            ang: self.ang * s,
            lin: self.lin * s,
        }
    }

    #[inline]
    pub fn add(&self, o: &Motion) -> Motion {
        Motion {
            ang: self.ang + o.ang,
            lin: self.lin + o.lin,
        }
    }

    #[inline]
    pub fn add_scaled(&mut self, o: &Motion, s: f64) {
        self.ang += o.ang * s;
        self.lin += o.lin * s;
    }

    /// Spatial motion cross product v ×ₘ m = (ω × m_ang, ω × m_lin + v × m_ang).
    #[inline]
    pub fn cross_motion(&self, m: &Motion) -> Motion {
        Motion {
            ang: self.ang.cross(&m.ang),
            lin: self.ang.cross(&m.lin) + self.lin.cross(&m.ang),
        }
    }

    /// Spatial force cross product v ×* f = (ω × n + v × f, ω × f).
    #[inline]
    pub fn cross_force(&self, f: &Force) -> Force {
        Force {
            ang: self.ang.cross(&f.ang) + self.lin.cross(&f.lin),
            lin: self.ang.cross(&f.lin),
        }
    }

    /// Power pairing mᵀ f = ω·n + v·f.
    #[inline]
    pub fn dot(&self, f: &Force) -> f64 {
        // written out: nalgebra's generic dot goes through iterators here
        let (a, b) = (&self.ang, &self.lin);
        a.x * f.ang.x
            + a.y * f.ang.y
            + a.z * f.ang.z
            + b.x * f.lin.x
            + b.y * f.lin.y
            + b.z * f.lin.z
    }

    /// The velocity of the body point at `r` (r − O given as `offset`): v + ω × offset.
    #[inline]
    pub fn linear_at(&self, offset: &Vec3) -> Vec3 {
        self.lin + self.ang.cross(offset)
    }
}

/// A spatial force (wrench) in ground axes: moment about the reference point O and force.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Force {
    /// Moment about O.
    pub ang: Vec3,
    /// Force.
    pub lin: Vec3,
}

impl Force {
    pub const ZERO: Force = Force {
        ang: Vec3::new(0.0, 0.0, 0.0),
        lin: Vec3::new(0.0, 0.0, 0.0),
    };

    #[inline]
    pub fn add(&self, o: &Force) -> Force {
        Force {
            ang: self.ang + o.ang,
            lin: self.lin + o.lin,
        }
    }

    #[inline]
    pub fn add_assign(&mut self, o: &Force) {
        self.ang += o.ang;
        self.lin += o.lin;
    }
}

/// Rigid-body spatial inertia about the reference point O, in ground axes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpatialInertia {
    pub mass: f64,
    /// First mass moment h = m·(c − O).
    pub h: Vec3,
    /// Rotational inertia about O (symmetric).
    pub inertia: Mat3,
}

impl SpatialInertia {
    pub const ZERO: SpatialInertia = SpatialInertia {
        mass: 0.0,
        h: Vec3::new(0.0, 0.0, 0.0),
        inertia: Mat3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    };

    /// Inertia of a body of mass `m` whose centre of mass is at `c` (relative to O) and whose
    /// rotational inertia about its centre of mass is `i_com` (ground axes):
    /// I_O = I_c + m (cᵀc·1 − c cᵀ)  (parallel-axis theorem).
    #[inline]
    pub fn from_mass_com_inertia(m: f64, c: &Vec3, i_com: &Mat3) -> Self {
        let cc = c.dot(c);
        let mut i = *i_com;
        i[(0, 0)] += m * (cc - c.x * c.x);
        i[(1, 1)] += m * (cc - c.y * c.y);
        i[(2, 2)] += m * (cc - c.z * c.z);
        let xy = -m * c.x * c.y;
        let xz = -m * c.x * c.z;
        let yz = -m * c.y * c.z;
        i[(0, 1)] += xy;
        i[(1, 0)] += xy;
        i[(0, 2)] += xz;
        i[(2, 0)] += xz;
        i[(1, 2)] += yz;
        i[(2, 1)] += yz;
        SpatialInertia {
            mass: m,
            h: c * m,
            inertia: i,
        }
    }

    /// Momentum of a body moving with spatial velocity v: I·v = (I_O ω + h × v, m v − h × ω).
    #[inline]
    pub fn mul_motion(&self, v: &Motion) -> Force {
        let i = self.inertia.as_slice(); // column-major, symmetric
        let w = &v.ang;
        let iw = Vec3::new(
            i[0] * w.x + i[3] * w.y + i[6] * w.z,
            i[1] * w.x + i[4] * w.y + i[7] * w.z,
            i[2] * w.x + i[5] * w.y + i[8] * w.z,
        );
        Force {
            ang: iw + self.h.cross(&v.lin),
            lin: v.lin * self.mass - self.h.cross(&v.ang),
        }
    }

    #[inline]
    pub fn add_assign(&mut self, o: &SpatialInertia) {
        self.mass += o.mass;
        self.h += o.h;
        self.inertia += o.inertia;
    }

    /// Centre of mass relative to O (zero for a massless inertia).
    pub fn com(&self) -> Vec3 {
        if self.mass > 0.0 {
            self.h / self.mass
        } else {
            Vec3::zeros()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn body_fixed_xyz_equals_product_of_elementary_rotations() {
        let a = Vec3::new(0.3, -1.1, 2.0);
        let r = rotation_about_axis(&Vec3::x(), a.x)
            * rotation_about_axis(&Vec3::y(), a.y)
            * rotation_about_axis(&Vec3::z(), a.z);
        assert!((rotation_body_fixed_xyz(a) - r).norm() < 1e-15);
    }

    #[test]
    fn rotation_vector_inverts_axis_angle() {
        let axis = Vec3::new(1.0, -2.0, 0.5).normalize();
        for angle in [1e-9, 2e-6, 0.7, 2.5, 3.1, std::f64::consts::PI - 1e-5] {
            let r = rotation_about_axis(&axis, angle);
            let e = (rotation_vector(&r) - axis * angle).norm();
            assert!(
                e < 1e-14 * angle.max(1e-3) * 1e3,
                "angle {angle}: error {e}"
            );
        }
    }

    #[test]
    fn post_rotate_about_elementary_axes_matches_rodrigues() {
        let r0 = rotation_body_fixed_xyz(Vec3::new(0.3, -0.4, 1.2));
        for k in 0..3 {
            for sign in [1.0, -1.0] {
                let mut axis = Vec3::zeros();
                axis[k] = sign;
                let mut r = r0;
                post_rotate(&mut r, &axis, Some((k, sign)), 0.77);
                assert!((r - r0 * rotation_about_axis(&axis, 0.77)).norm() < 1e-15);
            }
        }
    }

    #[test]
    fn transform_inverse_composes_to_identity() {
        let t = Transform::from_translation_xyz_body(
            Vec3::new(0.1, 0.2, -0.3),
            Vec3::new(0.4, 0.5, -0.6),
        );
        let i = t.compose(&t.inverse());
        assert!((i.rot - Mat3::identity()).norm() < 1e-15);
        assert!(i.pos.norm() < 1e-15);
    }

    #[test]
    fn kinetic_energy_of_spatial_inertia_matches_point_mass_sum() {
        // A body made of two point masses; its spatial inertia about O must give the
        // same kinetic energy as the sum over the points.
        let pts = [
            (2.0, Vec3::new(0.3, -0.2, 0.1)),
            (1.5, Vec3::new(-0.1, 0.4, 0.2)),
        ];
        let mut total = SpatialInertia::ZERO;
        for (m, p) in pts {
            total.add_assign(&SpatialInertia::from_mass_com_inertia(
                m,
                &p,
                &Mat3::zeros(),
            ));
        }
        let v = Motion::new(Vec3::new(0.2, -0.7, 1.1), Vec3::new(0.5, 0.1, -0.3));
        let ke_spatial = 0.5 * v.dot(&total.mul_motion(&v));
        let ke_points: f64 = pts
            .iter()
            .map(|(m, p)| 0.5 * m * v.linear_at(p).norm_squared())
            .sum();
        assert!((ke_spatial - ke_points).abs() < 1e-14);
    }
}
