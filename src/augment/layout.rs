//! The per-joint layout of METHOD.md §1: for every joint of the model (in `Model::joints`
//! order, welds included) the frame quantities a motion model is trained on, and the
//! flattened per-frame vector `x` with its index ranges.
//!
//! For joint j with parent frame F (fixed in the parent body) and child frame M (fixed in the
//! child body), with R_F, R_M their orientations in ground and ω_p, ω_c, α_p, α_c the angular
//! velocities and accelerations of the parent and child bodies (ground axes):
//! - `joint_pos`  p_j = origin of M in ground (the joint centre), m;
//! - `joint_rot`  r_j = log(R_Fᵀ R_M), the rotation vector of M relative to F (F axes), rad;
//! - `joint_vel`  w_j = R_Fᵀ (ω_c − ω_p), the relative angular velocity in F axes, rad/s;
//! - `joint_acc`  ẇ_j = R_Fᵀ (α_c − α_p) − R_Fᵀ (ω_p × (ω_c − ω_p)), its time derivative
//!   (d R_Fᵀ/dt = −R_Fᵀ \[ω_p\]×), rad/s²;
//! - `joint_torque` m_j (F axes, N·m): the net joint moments. With A_j (3 × n, ground axes)
//!   the Jacobian of the relative angular velocity ω_c − ω_p with respect to q̇, the
//!   generalized forces of the angular coordinates K (rotational or coupled coordinates that
//!   turn at least one joint) satisfy τ_K = Σ_j A_j,Kᵀ m_j when every joint j transmits the
//!   moment m_j. The moments of least norm that do so are
//!   m = A_K (A_Kᵀ A_K)⁻¹ τ_K (A_K: the 3J × |K| stack of the A_j,K),
//!   which for a joint whose coordinates turn only that joint is the moment whose power on
//!   the joint's rotation equals Σ τ_c q̇_c — for a pin joint, τ along its axis and zero
//!   about the others ("zero where the joint has no such axis"). A coordinate that turns
//!   several joints (the default model's lumbar coordinates turn five vertebral joints)
//!   shares its moment among them in proportion to the rotation each gets. The moments of the
//!   ground→pelvis joint are the unexplained (residual) moments. Forces along translational
//!   coordinates are not part of this layout; they are in `tau`.
//! - `contact_force` λ_j (ground axes, N): the sum of the contact forces on the joint's
//!   child body.
//!
//! `muscle_act` (one per muscle, [0, 1]) sits between `joint_acc` and `joint_torque`, as in
//! FlexMotion's eq. 1.

use crate::dynamics::{self, Data, Stage};
use crate::linalg::{cholesky_in_place, cholesky_solve_in_place};
use crate::model::{CoordinateRole, DofKind, Model, MotionType};
use crate::spatial::{Mat3, Vec3};
use nalgebra::{DMatrix, Rotation3, UnitQuaternion};

/// The blocks of the per-frame vector `x`, in order: (name, values per frame).
pub const BLOCKS: [&str; 7] = [
    "joint_pos",
    "joint_rot",
    "joint_vel",
    "joint_acc",
    "muscle_act",
    "joint_torque",
    "contact_force",
];

/// The joints of a model and the coordinates whose generalized forces become joint moments.
#[derive(Clone, Debug)]
pub struct JointLayout {
    /// Joint names, `Model::joints` order.
    pub names: Vec<String>,
    /// Number of muscles in `muscle_act`.
    pub n_muscles: usize,
    /// Independent coordinates (indices into q) whose forces are turned into moments.
    angular: Vec<usize>,
}

/// Index range of one block of `x`.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct BlockRange {
    pub name: String,
    pub start: usize,
    pub end: usize,
    /// Shape of the block per frame, e.g. `[21, 3]` or `[324]`.
    pub shape: Vec<usize>,
}

/// The quantities of one frame, one entry per joint.
#[derive(Clone, Debug)]
pub struct JointFrame {
    pub pos: Vec<Vec3>,
    pub rot: Vec<Vec3>,
    pub vel: Vec<Vec3>,
    pub acc: Vec<Vec3>,
    pub torque: Vec<Vec3>,
    pub contact: Vec<Vec3>,
}

/// Scratch arrays of [`JointLayout::frame`], allocated once per thread.
#[derive(Clone, Debug)]
pub struct LayoutWorkspace {
    /// Body Jacobian of one body (6 × n).
    jac: DMatrix<f64>,
    /// Angular Jacobian rows of every body, restricted to the angular coordinates
    /// (bodies × 3 × |K|, flat).
    body_ang: Vec<f64>,
    /// A_Kᵀ A_K, column-major |K| × |K|.
    normal: Vec<f64>,
    rhs: Vec<f64>,
    /// Parent-frame orientation per joint.
    frame_rot: Vec<Mat3>,
    /// The nonzero columns of each A_j as (a, column), joint j's at
    /// `columns[column_start[j]..column_start[j + 1]]`: a joint's relative rotation moves
    /// with its own coordinates (and those coupled to them) only.
    columns: Vec<(usize, Vec3)>,
    column_start: Vec<usize>,
}

impl JointFrame {
    pub fn new(layout: &JointLayout) -> JointFrame {
        let j = layout.names.len();
        JointFrame {
            pos: vec![Vec3::zeros(); j],
            rot: vec![Vec3::zeros(); j],
            vel: vec![Vec3::zeros(); j],
            acc: vec![Vec3::zeros(); j],
            torque: vec![Vec3::zeros(); j],
            contact: vec![Vec3::zeros(); j],
        }
    }
}

impl JointLayout {
    /// The layout of `model` with `n_muscles` muscle activations.
    pub fn new(model: &Model, n_muscles: usize) -> JointLayout {
        // K: independent coordinates that are angles and move a hinge of some joint.
        let mut angular = Vec::new();
        for (j, &c) in model.reduction.independent.iter().enumerate() {
            let coordinate = &model.coordinates[c];
            if coordinate.motion_type == MotionType::Translational {
                continue;
            }
            let turns = model
                .dofs
                .iter()
                .any(|d| d.kind == DofKind::Hinge && depends_on(model, &d.args, c));
            if turns {
                angular.push(j);
            }
        }
        JointLayout {
            names: model.joints.iter().map(|j| j.name.clone()).collect(),
            n_muscles,
            angular,
        }
    }

    /// The independent coordinates (indices into q) whose generalized forces the joint
    /// moments carry: the angles that turn at least one hinge.
    pub fn angular_coordinates(&self) -> impl Iterator<Item = usize> + '_ {
        self.angular.iter().copied()
    }

    pub fn n_joints(&self) -> usize {
        self.names.len()
    }

    /// Values per frame of `x`.
    pub fn width(&self) -> usize {
        18 * self.n_joints() + self.n_muscles
    }

    /// The blocks of `x` with their index ranges.
    pub fn ranges(&self) -> Vec<BlockRange> {
        let j = self.n_joints();
        let mut start = 0;
        BLOCKS
            .iter()
            .map(|&name| {
                let shape = if name == "muscle_act" {
                    vec![self.n_muscles]
                } else {
                    vec![j, 3]
                };
                let len: usize = shape.iter().product();
                let r = BlockRange {
                    name: name.to_string(),
                    start,
                    end: start + len,
                    shape,
                };
                start += len;
                r
            })
            .collect()
    }

    pub fn workspace(&self, model: &Model) -> LayoutWorkspace {
        let k = self.angular.len();
        LayoutWorkspace {
            jac: DMatrix::zeros(6, model.nq()),
            body_ang: vec![0.0; model.bodies.len() * 3 * k],
            normal: vec![0.0; k * k],
            rhs: vec![0.0; k],
            frame_rot: vec![Mat3::identity(); model.joints.len()],
            columns: Vec::with_capacity(model.joints.len() * k),
            column_start: Vec::with_capacity(model.joints.len() + 1),
        }
    }

    /// Fills `out` for the state in `data` (acceleration stage: after
    /// [`dynamics::rnea`]), the generalized forces `tau` the joints carry (n; inverse
    /// dynamics minus the contact forces' share) and the contact force on each body
    /// (`body_contact`, `Model::bodies` order, ground axes).
    pub fn frame(
        &self,
        model: &Model,
        data: &Data,
        tau: &[f64],
        body_contact: &[Vec3],
        ws: &mut LayoutWorkspace,
        out: &mut JointFrame,
    ) -> crate::Result<()> {
        data.require(model, Stage::Acceleration, "joint layout")?;
        if tau.len() != model.nq() || body_contact.len() != model.bodies.len() {
            return Err(crate::Error::invalid(
                "joint layout",
                format!(
                    "tau has {} values (expected {}), body_contact {} (expected {})",
                    tau.len(),
                    model.nq(),
                    body_contact.len(),
                    model.bodies.len()
                ),
            ));
        }
        let k = self.angular.len();
        // Angular Jacobian rows of every body on the coordinates K.
        for b in 1..model.bodies.len() {
            dynamics::body_jacobian(model, data, b, &mut ws.jac)?;
            let rows = &mut ws.body_ang[b * 3 * k..(b + 1) * 3 * k];
            for (i, &c) in self.angular.iter().enumerate() {
                for r in 0..3 {
                    rows[3 * i + r] = ws.jac[(r, c)];
                }
            }
        }
        ws.normal.fill(0.0);
        ws.columns.clear();
        ws.column_start.clear();
        let zero = Vec3::zeros();
        for (j, joint) in model.joints.iter().enumerate() {
            let (rp, _) = if joint.parent_body == 0 {
                (Mat3::identity(), Vec3::zeros())
            } else {
                data.body_pose(joint.parent_body)
            };
            let (rc, pc) = data.body_pose(joint.child_body);
            let r_f = rp * joint.parent_offset.rot;
            let r_m = rc * joint.child_offset.rot;
            ws.frame_rot[j] = r_f;
            out.pos[j] = pc + rc * joint.child_offset.pos;
            out.rot[j] = rotation_vector(&(r_f.transpose() * r_m));
            let (wp, ap) = if joint.parent_body == 0 {
                (zero, zero)
            } else {
                (
                    data.body_velocity(joint.parent_body).0,
                    data.point_acceleration(joint.parent_body, &zero).0,
                )
            };
            let wc = data.body_velocity(joint.child_body).0;
            let ac = data.point_acceleration(joint.child_body, &zero).0;
            let rel = wc - wp;
            out.vel[j] = r_f.transpose() * rel;
            out.acc[j] = r_f.transpose() * (ac - ap - wp.cross(&rel));
            out.contact[j] = body_contact[joint.child_body];
            // A_Kᵀ A_K += A_j,Kᵀ A_j,K (lower triangle), A_j = child rows − parent rows,
            // over the columns of A_j that are not zero
            let start = ws.columns.len();
            ws.column_start.push(start);
            for a in 0..k {
                let c = joint_column(ws, joint.child_body, joint.parent_body, k, a);
                if c != zero {
                    ws.columns.push((a, c));
                }
            }
            for (i, &(a, ca)) in ws.columns[start..].iter().enumerate() {
                for &(b, cb) in &ws.columns[start + i..] {
                    ws.normal[a * k + b] += ca.dot(&cb);
                }
            }
        }
        ws.column_start.push(ws.columns.len());
        // m = A_K (A_Kᵀ A_K)⁻¹ τ_K
        for (i, &c) in self.angular.iter().enumerate() {
            ws.rhs[i] = tau[c];
        }
        if k > 0 {
            let trace: f64 = (0..k).map(|i| ws.normal[i * k + i]).sum();
            for i in 0..k {
                // a relative floor keeps a coordinate that turns nothing at this pose
                // (zero column) from making the system singular
                ws.normal[i * k + i] += 1e-14 * trace.max(1e-300);
            }
            if !cholesky_in_place(&mut ws.normal, k) {
                return Err(crate::Error::invalid(
                    "joint layout",
                    "the angular Jacobian of the joints is not of full rank at this pose",
                ));
            }
            cholesky_solve_in_place(&ws.normal, k, &mut ws.rhs);
        }
        for j in 0..model.joints.len() {
            let mut m = Vec3::zeros();
            for &(a, c) in &ws.columns[ws.column_start[j]..ws.column_start[j + 1]] {
                m += c * ws.rhs[a];
            }
            out.torque[j] = ws.frame_rot[j].transpose() * m;
        }
        Ok(())
    }

    /// Appends frame `out` and the activations to `x` in the order of [`BLOCKS`].
    pub fn flatten(&self, frame: &JointFrame, activations: &[f64], x: &mut Vec<f32>) {
        for block in [&frame.pos, &frame.rot, &frame.vel, &frame.acc] {
            push_vectors(block, x);
        }
        x.extend(activations.iter().map(|&a| a as f32));
        push_vectors(&frame.torque, x);
        push_vectors(&frame.contact, x);
    }
}

fn push_vectors(v: &[Vec3], x: &mut Vec<f32>) {
    for p in v {
        x.extend([p.x as f32, p.y as f32, p.z as f32]);
    }
}

/// Column a of A_j (ground axes): the child body's angular Jacobian column minus the
/// parent's (ground has none).
fn joint_column(ws: &LayoutWorkspace, child: usize, parent: usize, k: usize, a: usize) -> Vec3 {
    let at = |b: usize| {
        if b == 0 {
            Vec3::zeros()
        } else {
            let s = &ws.body_ang[b * 3 * k + 3 * a..b * 3 * k + 3 * a + 3];
            Vec3::new(s[0], s[1], s[2])
        }
    };
    at(child) - at(parent)
}

/// True when one of `args` is coordinate `c` or a dependent coordinate driven by it.
fn depends_on(model: &Model, args: &[usize], c: usize) -> bool {
    args.iter().any(|&a| {
        a == c
            || match model.coordinates[a].role {
                CoordinateRole::Dependent(k) => model.couplers[k].independents.contains(&c),
                _ => false,
            }
    })
}

/// The rotation vector θ u of a rotation matrix: through its unit quaternion (w, v) (Shepperd's
/// method, stable at every angle), θ u = 2 atan2(|v|, w) v / |v| with w ≥ 0, so θ ∈ [0, π].
pub fn rotation_vector(r: &Mat3) -> Vec3 {
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*r));
    let (w, v) = (q.w, q.imag());
    let (w, v) = if w < 0.0 { (-w, -v) } else { (w, v) };
    let s = v.norm();
    if s < 1e-300 {
        return Vec3::zeros();
    }
    v * (2.0 * s.atan2(w) / s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random sequence in [−1, 1).
    fn noise(k: usize) -> f64 {
        let x = ((k as f64 + 1.0) * 12.9898).sin() * 43_758.545_3;
        2.0 * (x - x.floor()) - 1.0
    }

    fn state(model: &Model) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let n = model.nq();
        let q: Vec<f64> = (0..n)
            .map(|j| {
                let c = &model.coordinates[model.reduction.independent[j]];
                let mid = 0.5 * (c.range[0] + c.range[1]);
                let half = 0.25 * (c.range[1] - c.range[0]).min(2.0);
                mid + half * noise(j)
            })
            .collect();
        let qd = (0..n).map(|j| 0.8 * noise(100 + j)).collect();
        let qdd = (0..n).map(|j| 3.0 * noise(200 + j)).collect();
        (q, qd, qdd)
    }

    fn frame_at(
        model: &Model,
        layout: &JointLayout,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau: &[f64],
    ) -> JointFrame {
        let mut data = Data::new(model);
        dynamics::forward_kinematics_acceleration(model, &mut data, q, qd, qdd).unwrap();
        let mut ws = layout.workspace(model);
        let mut out = JointFrame::new(layout);
        let contact = vec![Vec3::zeros(); model.bodies.len()];
        layout
            .frame(model, &data, tau, &contact, &mut ws, &mut out)
            .unwrap();
        out
    }

    /// R_Fᵀ R_M of every joint at q.
    fn relative_rotations(model: &Model, q: &[f64]) -> Vec<Mat3> {
        let mut data = Data::new(model);
        dynamics::forward_kinematics(model, &mut data, q).unwrap();
        model
            .joints
            .iter()
            .map(|j| {
                let rp = if j.parent_body == 0 {
                    Mat3::identity()
                } else {
                    data.body_pose(j.parent_body).0
                };
                let rc = data.body_pose(j.child_body).0;
                (rp * j.parent_offset.rot).transpose() * rc * j.child_offset.rot
            })
            .collect()
    }

    #[test]
    fn joint_velocities_and_accelerations_match_differences_of_the_joint_rotations() {
        let model = Model::default_fullbody();
        let layout = JointLayout::new(&model, 0);
        let (q, qd, qdd) = state(&model);
        let tau = vec![0.0; model.nq()];
        let at = |t: f64| -> Vec<f64> {
            (0..q.len())
                .map(|j| q[j] + qd[j] * t + 0.5 * qdd[j] * t * t)
                .collect()
        };
        let h = 1e-5;
        let out = frame_at(&model, &layout, &q, &qd, &qdd, &tau);
        let (rm, r0, rp) = (
            relative_rotations(&model, &at(-h)),
            relative_rotations(&model, &q),
            relative_rotations(&model, &at(h)),
        );
        // w (F axes): [w]× = Ṙ Rᵀ, Ṙ by central differences
        let w_of = |a: &Mat3, b: &Mat3, r: &Mat3, dt: f64| {
            let s = (b - a) / dt * r.transpose();
            Vec3::new(
                s[(2, 1)] - s[(1, 2)],
                s[(0, 2)] - s[(2, 0)],
                s[(1, 0)] - s[(0, 1)],
            ) * 0.5
        };
        for j in 0..model.joints.len() {
            let w = w_of(&rm[j], &rp[j], &r0[j], 2.0 * h);
            assert!(
                (w - out.vel[j]).norm() < 1e-6 * (1.0 + w.norm()),
                "joint {j}: {w} vs {}",
                out.vel[j]
            );
            // rotation vector: exp(r) = R_FM
            let r = Rotation3::from_scaled_axis(out.rot[j]);
            assert!((r.matrix() - r0[j]).norm() < 1e-12);
        }
        // ẇ by central differences of w at t ± h (velocity q̇ + q̈ t)
        let vel_at = |t: f64| -> Vec<Vec3> {
            let qd_t: Vec<f64> = (0..q.len()).map(|j| qd[j] + qdd[j] * t).collect();
            frame_at(&model, &layout, &at(t), &qd_t, &qdd, &tau).vel
        };
        let (wm, wp) = (vel_at(-h), vel_at(h));
        for j in 0..model.joints.len() {
            let dw = (wp[j] - wm[j]) / (2.0 * h);
            assert!(
                (dw - out.acc[j]).norm() < 1e-5 * (1.0 + dw.norm()),
                "joint {j}: {dw} vs {}",
                out.acc[j]
            );
        }
    }

    #[test]
    fn joint_moments_deliver_the_power_of_the_generalized_forces() {
        let model = Model::default_fullbody();
        let layout = JointLayout::new(&model, 0);
        let (q, qd, qdd) = state(&model);
        let tau: Vec<f64> = (0..model.nq()).map(|j| 50.0 * noise(300 + j)).collect();
        let out = frame_at(&model, &layout, &q, &qd, &qdd, &tau);
        // Σ_j m_j · w_j = Σ_{c ∈ K} τ_c q̇_c (both in F axes: the power of the joint moments)
        let power_moments: f64 = (0..model.joints.len())
            .map(|j| out.torque[j].dot(&out.vel[j]))
            .sum();
        let power_forces: f64 = layout.angular.iter().map(|&c| tau[c] * qd[c]).sum();
        assert!(
            (power_moments - power_forces).abs() < 1e-9 * power_forces.abs().max(1.0),
            "{power_moments} vs {power_forces}"
        );
        // a pin joint: the moment lies along its axis and equals the coordinate's force
        let knee = model
            .joints
            .iter()
            .position(|j| j.name == "knee_r")
            .unwrap();
        let k = model
            .q_names()
            .iter()
            .position(|n| *n == "knee_angle_r")
            .unwrap();
        let w = out.vel[knee];
        let axis = w / w.norm();
        assert!((out.torque[knee].cross(&axis)).norm() < 1e-9 * tau[k].abs());
        assert!(
            (out.torque[knee].dot(&axis) * w.norm() - tau[k] * qd[k]).abs() < 1e-9 * tau[k].abs()
        );
        // translations carry no joint moment: the pelvis moments come from its rotations only
        let mut only_translation = vec![0.0; model.nq()];
        for name in ["pelvis_tx", "pelvis_ty", "pelvis_tz"] {
            let j = model.q_names().iter().position(|n| *n == name).unwrap();
            only_translation[j] = 100.0;
        }
        let out = frame_at(&model, &layout, &q, &qd, &qdd, &only_translation);
        assert!(out.torque.iter().all(|m| m.norm() < 1e-9));
    }
}
