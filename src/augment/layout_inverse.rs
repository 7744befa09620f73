//! From the per-joint layout back to the model's coordinates: the inverse of
//! [`super::layout::JointLayout::frame`], for motions that come in FlexMotion's layout only
//! (a generated motion) and for losses or checks that need q, q̇, q̈ and τ.
//!
//! With the quantities of [`super::layout`] (joint j: parent frame F, child frame M,
//! R_j(q) = R_Fᵀ R_M, A_j(q) = R_Fᵀ (J_ω,child − J_ω,parent) the Jacobian of the relative
//! angular velocity in F axes, p_j(q) the joint centre), per frame t:
//!
//! - **q** (joint rotations → coordinates): Gauss–Newton on
//!   Σ_j ‖log(exp(r_j) R_j(q)ᵀ)‖² + w_p² Σ_{root joints} ‖p_j − p_j(q)‖², each step solving
//!   (Jᵀ J) δ = Jᵀ e with the rows A_j (rotations: a change δ turns R_j by A_j δ in F axes, so
//!   the error log(exp(r_j) R_jᵀ) moves by −A_j δ to first order) and w_p J_p (positions),
//!   started from the previous frame's motion extrapolated by its rates (q + Δt q̇ + Δt²q̈/2;
//!   the model's default pose for the first frame), with steps of at most 0.3 rad. A joint of
//!   several rotations has other angle sets giving the same rotation (a turn of 2π of an
//!   axial rotation, another Euler branch); the extrapolated start keeps the fit on the
//!   motion's, and of the turns of 2π of a coordinate that leave the fit's error unchanged the
//!   one nearest the start brought into the coordinate's range is taken (the middle of the
//!   range for the first frame). The
//!   root joints (those whose parent is ground) add their centres, which fix the translational
//!   coordinates; every rotational coordinate is fixed by the rotations alone. A coordinate
//!   that turns several joints (the default model's lumbar coordinates, shared by five
//!   vertebral joints) is the least-squares fit of all of them. w_p = 10 rad/m (1 cm weighs as
//!   0.1 rad; for a consistent layout the weights do not matter).
//! - **q̇**: the least-squares solution of A_j q̇ = w_j (all joints) and J_p q̇ = ṗ_j (root
//!   joints), with ṗ_j the central difference of the root centres over frames (second-order
//!   one-sided at the ends): the layout holds no linear velocity.
//! - **q̈**: likewise from A_j q̈ = ẇ_j − b_j, b_j the layout's joint acceleration at q̈ = 0,
//!   and J_p q̈ = p̈_j − J̇_p q̇ with p̈_j the second difference of the root centres.
//! - **τ**: τ_K = Σ_j A_jᵀ m_j for the angular coordinates K (the layout's moments are the
//!   least-norm ones with exactly these generalized forces, so this is exact); the other
//!   coordinates' forces are not in the layout and come back as 0.
//!
//! For a layout written by `musculo augment` this returns its q to the float32 rounding of the
//! stored rotations, q̇ and q̈ of the rotational coordinates likewise, the root translation rates
//! to the accuracy of the finite differences, and τ_K — except where a joint of three rotations
//! passes near gimbal lock, where other angles give the same rotations: augment keeps the
//! angles nearest IK's own, the continuation here may take others (HumanML3D 012314: 12 of 170
//! frames, at the shoulders while the arms swing overhead; `tests/augment.rs`). Both give the
//! same rotations, and so the same joint torques. The per-frame rotation error left by
//! the fit (the largest |log(exp(r_j) R_j(q)ᵀ)| over the joints) is reported: zero up to
//! rounding for a consistent layout, the inconsistency of a generated one otherwise.
//!
//! Gradients of a loss on these coordinates with respect to the layout itself:
//! [`super::layout_inverse_vjp`]; the layout's contact forces in L_euler: [`crate::loss::layout`].

use super::layout::{JointLayout, rotation_vector};
use crate::dynamics::{self, Data};
use crate::linalg::{cholesky_in_place, cholesky_solve_in_place};
use crate::model::Model;
use crate::spatial::{Mat3, Vec3};
use nalgebra::{DMatrix, Rotation3};

/// Gauss–Newton iterations per frame, and the step (max |δ|) that ends them.
const MAX_ITERATIONS: usize = 50;
const STEP_TOLERANCE: f64 = 1e-12;
/// The largest Gauss–Newton step (max |δ|, rad or m); longer steps are shortened to it.
const MAX_STEP: f64 = 0.3;
/// Weight of the root joint centres against the rotations (rad per m).
pub(super) const POSITION_WEIGHT: f64 = 10.0;

/// A clip in the per-joint layout: every array T × J × 3, row-major, joints in
/// `Model::joints` order, in the units and frames of [`super::layout`].
#[derive(Clone, Copy, Debug)]
pub struct LayoutClip<'a> {
    pub frames: usize,
    /// Frame rate (Hz), for the root centres' differences.
    pub rate_hz: f64,
    pub joint_pos: &'a [f64],
    pub joint_rot: &'a [f64],
    pub joint_vel: &'a [f64],
    pub joint_acc: &'a [f64],
    pub joint_torque: &'a [f64],
}

/// The coordinates of a layout clip (T × n each, row-major).
#[derive(Clone, Debug, Default)]
pub struct LayoutCoordinates {
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    pub qdd: Vec<f64>,
    pub tau: Vec<f64>,
    /// Per frame, the largest rotation error left by the fit (rad).
    pub rotation_error: Vec<f64>,
}

/// The coordinates of `clip` (see the module documentation).
pub fn coordinates_from_layout(
    model: &Model,
    layout: &JointLayout,
    clip: &LayoutClip,
) -> crate::Result<LayoutCoordinates> {
    check_layout_clip(model, layout, clip)?;
    let (n, t) = (model.nq(), clip.frames);
    let fit = LayoutFit::new(model, layout, clip);
    let mut ws = Solver::new(model, fit.rows);
    let mut out = LayoutCoordinates {
        q: vec![0.0; t * n],
        qd: vec![0.0; t * n],
        qdd: vec![0.0; t * n],
        tau: vec![0.0; t * n],
        rotation_error: vec![0.0; t],
    };
    let mut q = model.default_q();
    for f in 0..t {
        fit.positions(f, &mut ws, &mut q, &mut out)?;
        let qd = fit.velocities(f, &mut ws, &mut out)?;
        fit.accelerations(f, &mut ws, &q, &qd, &mut out)?;
        fit.torques(f, &ws, &mut out);
    }
    Ok(out)
}

/// The clip's arrays checked against the model and layout: the joint count, every array's
/// size (T × joints × 3) and finiteness, and a positive frame rate.
fn check_layout_clip(model: &Model, layout: &JointLayout, clip: &LayoutClip) -> crate::Result<()> {
    let (nj, t) = (layout.n_joints(), clip.frames);
    if nj != model.joints.len() {
        return Err(crate::Error::invalid(
            "layout",
            format!(
                "the layout has {nj} joints, the model \"{}\" {}",
                model.name,
                model.joints.len()
            ),
        ));
    }
    for (name, a) in [
        ("joint_pos", clip.joint_pos),
        ("joint_rot", clip.joint_rot),
        ("joint_vel", clip.joint_vel),
        ("joint_acc", clip.joint_acc),
        ("joint_torque", clip.joint_torque),
    ] {
        if a.len() != t * nj * 3 {
            return Err(crate::Error::invalid(
                name,
                format!(
                    "expected {t} frames × {nj} joints × 3 = {}, got {}",
                    t * nj * 3,
                    a.len()
                ),
            ));
        }
        if let Some(i) = a.iter().position(|v| !v.is_finite()) {
            return Err(crate::Error::invalid(
                name,
                format!("frame {}, joint {}: not finite", i / (3 * nj), i / 3 % nj),
            ));
        }
    }
    if !(clip.rate_hz > 0.0 && clip.rate_hz.is_finite()) {
        return Err(crate::Error::invalid(
            "rate_hz",
            format!("{} (must be positive)", clip.rate_hz),
        ));
    }
    Ok(())
}

/// What every frame of the fit reads: the model, layout and clip, the root joints, and the
/// sizes of the fitted rows.
struct LayoutFit<'a> {
    model: &'a Model,
    layout: &'a JointLayout,
    clip: &'a LayoutClip<'a>,
    /// The joints attached to ground, whose centres are fitted too.
    roots: Vec<usize>,
    n: usize,
    nj: usize,
    /// Rows of the fit: 3 per joint rotation, 3 per root centre.
    rows: usize,
    /// Sample interval (s).
    dt: f64,
}

impl<'a> LayoutFit<'a> {
    fn new(model: &'a Model, layout: &'a JointLayout, clip: &'a LayoutClip<'a>) -> LayoutFit<'a> {
        let nj = layout.n_joints();
        let roots: Vec<usize> = (0..nj)
            .filter(|&j| model.joints[j].parent_body == 0)
            .collect();
        LayoutFit {
            model,
            layout,
            clip,
            n: model.nq(),
            nj,
            rows: 3 * nj + 3 * roots.len(),
            roots,
            dt: 1.0 / clip.rate_hz,
        }
    }

    /// Joint `j`'s vector at frame `f` of a T × joints × 3 array.
    fn vec3(&self, a: &[f64], f: usize, j: usize) -> Vec3 {
        let i = (f * self.nj + j) * 3;
        Vec3::new(a[i], a[i + 1], a[i + 2])
    }

    /// Root `r`'s centre's first and second differences over frames at frame `f` (see
    /// `root_stencil`).
    fn root_rates(&self, f: usize, r: usize) -> (Vec3, Vec3) {
        let [first, second] = root_stencil(f, self.clip.frames, self.dt);
        let p = |(g, c): (usize, f64)| self.vec3(self.clip.joint_pos, g, self.roots[r]) * c;
        (
            first.into_iter().map(p).sum(),
            second.into_iter().map(p).sum(),
        )
    }

    /// q at frame `f`: Gauss–Newton on the joint rotations and root centres from the
    /// previous frame's motion extrapolated by its rates, each coordinate's turn of 2π
    /// chosen, then the kinematics and Jacobians left at the fitted q for the rates.
    fn positions(
        &self,
        f: usize,
        ws: &mut Solver,
        q: &mut [f64],
        out: &mut LayoutCoordinates,
    ) -> crate::Result<()> {
        let (model, n, dt) = (self.model, self.n, self.dt);
        // start from the previous frame's motion extrapolated by its rates
        if f > 0 {
            for j in 0..n {
                let p = (f - 1) * n + j;
                q[j] = out.q[p] + dt * out.qd[p] + 0.5 * dt * dt * out.qdd[p];
            }
        }
        let prev = q.to_vec();
        let error = self.gauss_newton(f, ws, q)?;
        let error = self.nearest_turns(f, ws, q, &prev, error)?;
        dynamics::forward_kinematics(model, &mut ws.data, q)?;
        ws.jacobians(model, self.layout, &self.roots)?;
        out.rotation_error[f] = error;
        out.q[f * n..(f + 1) * n].copy_from_slice(q);
        Ok(())
    }

    /// Gauss–Newton steps on the fit's errors at frame `f` from `q`; returns the largest
    /// rotation error of the last linearization.
    fn gauss_newton(&self, f: usize, ws: &mut Solver, q: &mut [f64]) -> crate::Result<f64> {
        let model = self.model;
        let mut error = 0.0;
        for _ in 0..MAX_ITERATIONS {
            dynamics::forward_kinematics(model, &mut ws.data, q)?;
            ws.jacobians(model, self.layout, &self.roots)?;
            error = ws.errors(model, self.clip, f, &self.roots);
            let step = ws.solve(self.n, self.rows)?;
            // steps of at most MAX_STEP, so that the fit follows the motion from the
            // previous frame's q rather than jumping to another set of angles with the same
            // rotations
            let scale = if step > MAX_STEP {
                MAX_STEP / step
            } else {
                1.0
            };
            for (qj, d) in q.iter_mut().zip(&ws.rhs) {
                *qj += d * scale;
            }
            if step <= STEP_TOLERANCE {
                break;
            }
        }
        Ok(error)
    }

    /// A turn of 2π of a coordinate gives the same rotations when it only turns hinges by
    /// itself (a shoulder's axial rotation): take the turn nearest to the extrapolated
    /// start `prev` brought into the range (the middle of the range for the first frame),
    /// kept only where the fit's error does not grow. Returns the error.
    fn nearest_turns(
        &self,
        f: usize,
        ws: &mut Solver,
        q: &mut [f64],
        prev: &[f64],
        mut error: f64,
    ) -> crate::Result<f64> {
        let model = self.model;
        for (j, &c) in model.reduction.independent.iter().enumerate() {
            let coordinate = &model.coordinates[c];
            if coordinate.motion_type == crate::model::MotionType::Translational {
                continue;
            }
            let [lo, hi] = coordinate.range;
            let target = if f == 0 {
                0.5 * (lo + hi)
            } else {
                prev[j].clamp(lo.min(hi), hi.max(lo))
            };
            let turns = ((target - q[j]) / std::f64::consts::TAU).round();
            if turns == 0.0 {
                continue;
            }
            let before = q[j];
            q[j] += turns * std::f64::consts::TAU;
            dynamics::forward_kinematics(model, &mut ws.data, q)?;
            let e = ws.errors(model, self.clip, f, &self.roots);
            if e <= error + 1e-9 {
                error = error.max(e);
            } else {
                q[j] = before;
            }
        }
        Ok(error)
    }

    /// q̇ at frame `f`: A q̇ = w, J_p q̇ = ṗ (with `ws` linearized at the frame's q).
    fn velocities(
        &self,
        f: usize,
        ws: &mut Solver,
        out: &mut LayoutCoordinates,
    ) -> crate::Result<Vec<f64>> {
        let (n, nj) = (self.n, self.nj);
        for j in 0..nj {
            ws.e[3 * j..3 * j + 3].copy_from_slice(self.vec3(self.clip.joint_vel, f, j).as_slice());
        }
        for r in 0..self.roots.len() {
            let v = self.root_rates(f, r).0 * POSITION_WEIGHT;
            ws.e[3 * nj + 3 * r..3 * nj + 3 * r + 3].copy_from_slice(v.as_slice());
        }
        ws.solve(n, self.rows)?;
        let qd = ws.rhs.clone();
        out.qd[f * n..(f + 1) * n].copy_from_slice(&qd);
        Ok(qd)
    }

    /// q̈ at frame `f`: A q̈ = ẇ − b, J_p q̈ = p̈ − J̇_p q̇.
    fn accelerations(
        &self,
        f: usize,
        ws: &mut Solver,
        q: &[f64],
        qd: &[f64],
        out: &mut LayoutCoordinates,
    ) -> crate::Result<()> {
        let (model, n, nj) = (self.model, self.n, self.nj);
        dynamics::forward_kinematics_velocity(model, &mut ws.data, q, qd)?;
        for (j, joint) in model.joints.iter().enumerate() {
            let b = bias_joint_acceleration(model, &mut ws.data, joint, &ws.frame_rot[j])?;
            let e = self.vec3(self.clip.joint_acc, f, j) - b;
            ws.e[3 * j..3 * j + 3].copy_from_slice(e.as_slice());
        }
        for (r, &j) in self.roots.iter().enumerate() {
            let joint = &model.joints[j];
            let bias = dynamics::point_jacobian_dot_qd(
                model,
                &mut ws.data,
                joint.child_body,
                &joint.child_offset.pos,
            )?;
            let e = (self.root_rates(f, r).1 - bias) * POSITION_WEIGHT;
            ws.e[3 * nj + 3 * r..3 * nj + 3 * r + 3].copy_from_slice(e.as_slice());
        }
        ws.solve(n, self.rows)?;
        out.qdd[f * n..(f + 1) * n].copy_from_slice(&ws.rhs);
        Ok(())
    }

    /// τ_K = Σ_j A_jᵀ m_j at frame `f`, on the layout's angular coordinates.
    fn torques(&self, f: usize, ws: &Solver, out: &mut LayoutCoordinates) {
        let n = self.n;
        for c in self.layout.angular_coordinates() {
            let mut s = 0.0;
            for j in 0..self.nj {
                let m = self.vec3(self.clip.joint_torque, f, j);
                for k in 0..3 {
                    s += ws.a[(3 * j + k) * n + c] * m[k];
                }
            }
            out.tau[f * n + c] = s;
        }
    }
}

/// The root centres' first and second differences at frame `f` of `t` (step `dt`), as
/// (frame, coefficient) terms: central inside, second-order one-sided at the ends
/// (f′ ≈ (−3p₀ + 4p₁ − p₂)/2h, f″ ≈ (2p₀ − 5p₁ + 4p₂ − p₃)/h²); a clip of two or three
/// frames has one mean velocity (and with three frames one second difference), a single
/// frame none. Unused terms have coefficient 0.
pub(super) fn root_stencil(f: usize, t: usize, dt: f64) -> [[(usize, f64); 4]; 2] {
    let none = [(0, 0.0); 4];
    if t < 2 {
        return [none, none];
    }
    if t < 4 {
        let h = 1.0 / ((t - 1) as f64 * dt);
        let first = [(t - 1, h), (0, -h), (0, 0.0), (0, 0.0)];
        let second = if t == 3 {
            let h2 = 1.0 / (dt * dt);
            [(2, h2), (1, -2.0 * h2), (0, h2), (0, 0.0)]
        } else {
            none
        };
        return [first, second];
    }
    let (h1, h2) = (1.0 / (2.0 * dt), 1.0 / (dt * dt));
    // the one-sided stencils, read forwards from the first frame (s = 1) or backwards from
    // the last (s = −1)
    let end = |s: f64, i: [usize; 4]| {
        [
            [
                (i[0], -3.0 * s * h1),
                (i[1], 4.0 * s * h1),
                (i[2], -s * h1),
                (i[3], 0.0),
            ],
            [
                (i[0], 2.0 * h2),
                (i[1], -5.0 * h2),
                (i[2], 4.0 * h2),
                (i[3], -h2),
            ],
        ]
    };
    if f == 0 {
        end(1.0, [0, 1, 2, 3])
    } else if f + 1 == t {
        end(-1.0, [t - 1, t - 2, t - 3, t - 4])
    } else {
        [
            [(f + 1, h1), (f - 1, -h1), (0, 0.0), (0, 0.0)],
            [(f + 1, h2), (f, -2.0 * h2), (f - 1, h2), (0, 0.0)],
        ]
    }
}

/// exp of a rotation vector.
fn exp(r: &Vec3) -> Mat3 {
    Rotation3::new(*r).into_inner()
}

/// R_j = R_Fᵀ R_M of a joint at the state of `data`.
fn relative_rotation(data: &Data, joint: &crate::model::Joint) -> Mat3 {
    let rp = if joint.parent_body == 0 {
        Mat3::identity()
    } else {
        data.body_pose(joint.parent_body).0
    };
    let rc = data.body_pose(joint.child_body).0;
    (rp * joint.parent_offset.rot).transpose() * rc * joint.child_offset.rot
}

/// The layout's joint acceleration of `joint` at q̈ = 0 (velocity stage):
/// R_Fᵀ(α_c − α_p) − R_Fᵀ(ω_p × (ω_c − ω_p)) with the bias angular accelerations.
fn bias_joint_acceleration(
    model: &Model,
    data: &mut Data,
    joint: &crate::model::Joint,
    r_f: &Mat3,
) -> crate::Result<Vec3> {
    let zero = Vec3::zeros();
    let (wp, ap) = if joint.parent_body == 0 {
        (zero, zero)
    } else {
        (
            data.body_velocity(joint.parent_body).0,
            dynamics::body_jacobian_dot_qd(model, data, joint.parent_body)?.0,
        )
    };
    let wc = data.body_velocity(joint.child_body).0;
    let ac = dynamics::body_jacobian_dot_qd(model, data, joint.child_body)?.0;
    Ok(r_f.transpose() * (ac - ap - wp.cross(&(wc - wp))))
}

/// The stacked Jacobian rows (A_j, then w_p J_p of the root centres), the error vector and
/// the normal equations of one frame.
pub(super) struct Solver {
    pub(super) data: Data,
    jac: DMatrix<f64>,
    point: DMatrix<f64>,
    /// rows × n, row-major.
    pub(super) a: Vec<f64>,
    pub(super) e: Vec<f64>,
    normal: Vec<f64>,
    pub(super) rhs: Vec<f64>,
    frame_rot: Vec<Mat3>,
}

impl Solver {
    pub(super) fn new(model: &Model, rows: usize) -> Solver {
        let n = model.nq();
        Solver {
            data: Data::new(model),
            jac: DMatrix::zeros(6, n),
            point: DMatrix::zeros(3, n),
            a: vec![0.0; rows * n],
            e: vec![0.0; rows],
            normal: vec![0.0; n * n],
            rhs: vec![0.0; n],
            frame_rot: vec![Mat3::identity(); model.joints.len()],
        }
    }

    /// A_j = R_Fᵀ (J_ω,child − J_ω,parent) for every joint and w_p J_p for the root centres.
    pub(super) fn jacobians(
        &mut self,
        model: &Model,
        layout: &JointLayout,
        roots: &[usize],
    ) -> crate::Result<()> {
        let n = model.nq();
        let nj = layout.n_joints();
        for (j, joint) in model.joints.iter().enumerate() {
            let rp = if joint.parent_body == 0 {
                Mat3::identity()
            } else {
                self.data.body_pose(joint.parent_body).0
            };
            let r_f = rp * joint.parent_offset.rot;
            self.frame_rot[j] = r_f;
            dynamics::body_jacobian(model, &self.data, joint.child_body, &mut self.jac)?;
            for c in 0..n {
                let w = Vec3::new(self.jac[(0, c)], self.jac[(1, c)], self.jac[(2, c)]);
                for k in 0..3 {
                    self.a[(3 * j + k) * n + c] = w[k];
                }
            }
            if joint.parent_body != 0 {
                dynamics::body_jacobian(model, &self.data, joint.parent_body, &mut self.jac)?;
                for c in 0..n {
                    for k in 0..3 {
                        self.a[(3 * j + k) * n + c] -= self.jac[(k, c)];
                    }
                }
            }
            for c in 0..n {
                let w = Vec3::new(
                    self.a[(3 * j) * n + c],
                    self.a[(3 * j + 1) * n + c],
                    self.a[(3 * j + 2) * n + c],
                );
                let wf = r_f.transpose() * w;
                for k in 0..3 {
                    self.a[(3 * j + k) * n + c] = wf[k];
                }
            }
        }
        for (r, &j) in roots.iter().enumerate() {
            let joint = &model.joints[j];
            dynamics::point_jacobian(
                model,
                &self.data,
                joint.child_body,
                &joint.child_offset.pos,
                &mut self.point,
            )?;
            for k in 0..3 {
                for c in 0..n {
                    self.a[(3 * nj + 3 * r + k) * n + c] = POSITION_WEIGHT * self.point[(k, c)];
                }
            }
        }
        Ok(())
    }

    /// The error vector e of the fit at the state of `data` (rotations log(exp(r_j) R_jᵀ),
    /// then the weighted root centre errors); returns the largest rotation error.
    pub(super) fn errors(
        &mut self,
        model: &Model,
        clip: &LayoutClip,
        f: usize,
        roots: &[usize],
    ) -> f64 {
        let nj = model.joints.len();
        let vec3 = |a: &[f64], j: usize| {
            let i = (f * nj + j) * 3;
            Vec3::new(a[i], a[i + 1], a[i + 2])
        };
        let mut error = 0.0f64;
        for (j, joint) in model.joints.iter().enumerate() {
            let target = exp(&vec3(clip.joint_rot, j));
            let rel = relative_rotation(&self.data, joint);
            let e = rotation_vector(&(target * rel.transpose()));
            error = error.max(e.norm());
            self.e[3 * j..3 * j + 3].copy_from_slice(e.as_slice());
        }
        for (r, &j) in roots.iter().enumerate() {
            let joint = &model.joints[j];
            let (rc, pc) = self.data.body_pose(joint.child_body);
            let e =
                (vec3(clip.joint_pos, j) - (pc + rc * joint.child_offset.pos)) * POSITION_WEIGHT;
            self.e[3 * nj + 3 * r..3 * nj + 3 * r + 3].copy_from_slice(e.as_slice());
        }
        error
    }

    /// The least-squares solution of A x = e into `rhs` (normal equations, see
    /// [`Solver::factor`]); returns max |x|.
    fn solve(&mut self, n: usize, rows: usize) -> crate::Result<f64> {
        self.factor(n, rows)?;
        self.rhs.fill(0.0);
        for r in 0..rows {
            let row = &self.a[r * n..(r + 1) * n];
            for (x, &a) in self.rhs.iter_mut().zip(row) {
                *x += a * self.e[r];
            }
        }
        cholesky_solve_in_place(&self.normal, n, &mut self.rhs);
        Ok(self.rhs.iter().fold(0.0, |m, v| m.max(v.abs())))
    }

    /// The Cholesky factor of N = AᵀA (with a relative floor of 1e-14 of its trace on the
    /// diagonal against coordinates that move nothing at this pose), kept for
    /// [`Solver::solve_normal`].
    pub(super) fn factor(&mut self, n: usize, rows: usize) -> crate::Result<()> {
        self.normal.fill(0.0);
        for r in 0..rows {
            let row = &self.a[r * n..(r + 1) * n];
            for a in 0..n {
                if row[a] == 0.0 {
                    continue;
                }
                for b in a..n {
                    self.normal[a * n + b] += row[a] * row[b];
                }
            }
        }
        let trace: f64 = (0..n).map(|i| self.normal[i * n + i]).sum();
        for i in 0..n {
            self.normal[i * n + i] += 1e-14 * trace.max(1e-300);
        }
        if !cholesky_in_place(&mut self.normal, n) {
            return Err(crate::Error::invalid(
                "layout",
                "the joint rotations do not determine the coordinates at this pose",
            ));
        }
        Ok(())
    }

    /// x ← N⁻¹ x with the factor of the last [`Solver::factor`].
    pub(super) fn solve_normal(&self, x: &mut [f64]) {
        cholesky_solve_in_place(&self.normal, x.len(), x);
    }
}
