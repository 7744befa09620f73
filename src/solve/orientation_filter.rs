//! Joint orientations filtered and differentiated as rotations, for the joints whose rotation
//! is three coordinate angles about successive body-fixed axes (an Euler or Cardan sequence:
//! a CustomJoint with three rotation axes, OpenSim's Ball and Gimbal joints).
//!
//! Such coordinates are singular where the middle rotation lines the first axis up with the
//! third (gimbal lock). A motion passing near that orientation turns smoothly, yet its first
//! and third coordinates swing by up to 180° while the orientation turns a few degrees.
//! Filtered and differentiated coordinate by coordinate, such a swing sampled at 20 frames/s
//! becomes accelerations of hundreds of rad/s² that the body never had, and torques no
//! muscle can explain. The default model's shoulder (flexion about z, adduction about x,
//! rotation about y) locks with the arm abducted to the horizontal, where a clip raising its
//! arms sideways passes.
//!
//! Method, per joint:
//! 1. the joint's rotation R(θ(q_f)) at every frame as a unit quaternion p_f, its sign chosen
//!    so that p_f · p_{f−1} ≥ 0 (the quaternions of a continuous motion);
//! 2. each of the four components low-passed as the coordinates are (OpenSim's padding and
//!    zero-lag Butterworth, [`crate::solve::filter::lowpass_padded`]) and interpolated by the
//!    same quintic spline;
//! 3. at time t, the spline's p, ṗ, p̈ normalised to r = p/n, n = |p|, with
//!    ṙ = (ṗ − ṅ r)/n, r̈ = (p̈ − 2ṅ ṙ − n̈ r)/n, ṅ = r·ṗ and n̈ = (ṗ·ṗ + p·p̈ − ṅ²)/n;
//!    then the angular velocity and acceleration in the joint's child frame, ω = 2 Im(r̄ ⊗ ṙ)
//!    and α = 2 Im(r̄ ⊗ r̈) (ṙ = ½ r ⊗ ω; the real part of r̄ ⊗ r̈ is −|ṙ|², which Im drops);
//! 4. the coordinates of R(r) by damped Gauss–Newton from the frame's own coordinates: the
//!    nearest solution, and at the lock the one that moves them least;
//! 5. q̇ and q̈ from ω = E(q) q̇ and α = E(q) q̈ + b(q, q̇) ([`EulerJoint::angular_terms`]).
//!
//! The coordinates then describe the filtered orientations, and their derivatives are the
//! body's own angular motion however near the lock it passes. Away from the lock the results
//! differ from coordinate-wise filtering only in what the filter smooths (the orientation
//! rather than its angles), a difference of second order in the angles' rates.

use super::filter::lowpass_padded;
use crate::model::natural_spline::NaturalSpline;
use crate::model::{CoordinateRole, DofKind, Function, JointStep, Model};
use crate::spatial::{Mat3, Vec3, rotation_about_axis, rotation_vector};
use nalgebra::{Quaternion, Rotation3, UnitQuaternion};

/// Damping of the least-squares solves with E, relative to tr(EᵀE): it only acts within about
/// 1e-6 rad of the lock, where E has no inverse.
const RELATIVE_DAMPING: f64 = 1e-12;

/// Gauss–Newton stops when the orientation is matched to this angle (rad).
const ORIENTATION_TOLERANCE: f64 = 1e-13;

/// A joint whose rotation is three body-fixed rotations θ_k = s_k q_k + c_k about axes a_k,
/// each driven by its own independent coordinate: R = R(a₁, θ₁) R(a₂, θ₂) R(a₃, θ₃).
#[derive(Clone, Debug, PartialEq)]
pub struct EulerJoint {
    /// The joint's index in `Model::joints`.
    pub joint: usize,
    /// The independent coordinate (q index) of each rotation, in the order applied.
    pub q: [usize; 3],
    axis: [Vec3; 3],
    slope: [f64; 3],
    offset: [f64; 3],
}

impl EulerJoint {
    /// The model's joints whose rotations are such a sequence: exactly three hinges, each a
    /// linear function of a distinct independent coordinate, with no fixed rotation between
    /// them (translations, before or after, do not change the orientation).
    pub fn of_model(model: &Model) -> Vec<EulerJoint> {
        (0..model.joints.len())
            .filter_map(|j| Self::of_joint(model, j))
            .collect()
    }

    fn of_joint(model: &Model, joint: usize) -> Option<EulerJoint> {
        let mut hinges = Vec::new();
        for step in &model.joints[joint].steps {
            match step {
                JointStep::Dof(d) if model.dofs[*d].kind == DofKind::Hinge => hinges.push(*d),
                JointStep::Dof(_) => {}
                JointStep::Fixed(t) => {
                    if !hinges.is_empty() && t.rot != Mat3::identity() {
                        return None;
                    }
                }
            }
        }
        let [h1, h2, h3] = hinges[..] else {
            return None;
        };
        let mut out = EulerJoint {
            joint,
            q: [0; 3],
            axis: [Vec3::zeros(); 3],
            slope: [0.0; 3],
            offset: [0.0; 3],
        };
        for (k, d) in [h1, h2, h3].into_iter().enumerate() {
            let dof = &model.dofs[d];
            let (Function::Linear(c), [arg]) = (&dof.function, &dof.args[..]) else {
                return None;
            };
            let CoordinateRole::Independent(qi) = model.coordinates[*arg].role else {
                return None;
            };
            if c.len() != 2 || c[0] == 0.0 || out.q[..k].contains(&qi) {
                return None;
            }
            (out.q[k], out.axis[k], out.slope[k], out.offset[k]) = (qi, dof.axis, c[0], c[1]);
        }
        Some(out)
    }

    /// The rotation angles θ_k of coordinates `q` (the whole q vector).
    fn angles(&self, q: &[f64]) -> [f64; 3] {
        std::array::from_fn(|k| self.slope[k] * q[self.q[k]] + self.offset[k])
    }

    /// R = R(a₁, θ₁) R(a₂, θ₂) R(a₃, θ₃): the child frame's orientation in the parent frame.
    pub fn rotation(&self, q: &[f64]) -> Mat3 {
        let theta = self.angles(q);
        (0..3).fold(Mat3::identity(), |r, k| {
            r * rotation_about_axis(&self.axis[k], theta[k])
        })
    }

    /// E and b of the joint's angular velocity and acceleration in its child frame,
    /// ω = E q̇ and α = E q̈ + b, at coordinates `q` (the whole vector) and the joint's own
    /// three speeds `qd` (E's columns and `qd` in the order of [`EulerJoint::q`]). Frame by frame, with R_k = R(a_k, θ_k)
    /// and ω_k the angular velocity in frame k after k rotations:
    ///   ω_k = R_kᵀ ω_{k−1} + a_k θ̇_k,
    ///   α_k = R_kᵀ α_{k−1} − (a_k θ̇_k) × (R_kᵀ ω_{k−1}) + a_k θ̈_k,
    /// since d(R_kᵀ)/dt = −[a_k θ̇_k]× R_kᵀ; b is α₃ with θ̈ = 0.
    pub fn angular_terms(&self, q: &[f64], qd: [f64; 3]) -> (Mat3, Vec3) {
        let theta = self.angles(q);
        let mut e = Mat3::zeros();
        let (mut omega, mut bias) = (Vec3::zeros(), Vec3::zeros());
        for k in 0..3 {
            let rt = rotation_about_axis(&self.axis[k], theta[k]).transpose();
            let turn = self.axis[k] * (self.slope[k] * qd[k]);
            // E's earlier columns carried into frame k; column k is a_k s_k
            e = rt * e;
            e.set_column(k, &(self.axis[k] * self.slope[k]));
            let carried = rt * omega;
            bias = rt * bias - turn.cross(&carried);
            omega = carried + turn;
        }
        (e, bias)
    }

    /// Sets the joint's coordinates in `q` (the whole vector, holding the starting guess) to
    /// those of rotation `target`, by Gauss–Newton on R(q) Exp(e) = target with the
    /// child-frame error e: E δq = e, damped so that at the lock the step is the smallest.
    /// Returns the remaining angle (rad).
    pub fn coordinates_of(&self, target: &Mat3, q: &mut [f64]) -> f64 {
        let mut error = f64::INFINITY;
        for _ in 0..50 {
            let e = rotation_vector(&(self.rotation(q).transpose() * target));
            error = e.norm();
            if error <= ORIENTATION_TOLERANCE {
                break;
            }
            let (jac, _) = self.angular_terms(q, [0.0; 3]);
            let step = damped_solve(&jac, &e);
            for k in 0..3 {
                q[self.q[k]] += step[k];
            }
        }
        error
    }
}

/// x = (EᵀE + μ I)⁻¹ Eᵀ v with μ = [`RELATIVE_DAMPING`] · tr(EᵀE): E⁻¹ v wherever E is
/// invertible to working precision, the least-norm solution at the lock.
fn damped_solve(e: &Mat3, v: &Vec3) -> Vec3 {
    let ete = e.transpose() * e;
    let mu = RELATIVE_DAMPING * ete.trace();
    let a = ete + Mat3::identity() * mu;
    a.cholesky()
        .map(|c| c.solve(&(e.transpose() * v)))
        .unwrap_or_else(Vec3::zeros)
}

/// The filtered orientations of a model's [`EulerJoint`]s over a clip, as quaternion splines.
#[derive(Clone, Debug)]
pub struct OrientationTrajectory {
    joints: Vec<EulerJoint>,
    /// Four splines (w, x, y, z) per joint.
    splines: Vec<NaturalSpline>,
}

impl OrientationTrajectory {
    /// Fits the orientations of `joints` over the frames `q` (frames × nq, row-major) at
    /// `time`, low-passed at `lowpass_hz` when given (the times must then be uniform, as
    /// [`crate::solve::kinematics::CoordinateTrajectory::from_table`] checks). Errors (as a
    /// message) when the spline or the filter cannot be built.
    pub fn fit(
        joints: Vec<EulerJoint>,
        time: &[f64],
        q: &[f64],
        nq: usize,
        lowpass_hz: Option<f64>,
    ) -> Result<OrientationTrajectory, String> {
        let frames = time.len();
        let mut columns = Vec::with_capacity(4 * joints.len());
        for joint in &joints {
            let mut previous: Option<Quaternion<f64>> = None;
            let mut components: [Vec<f64>; 4] = std::array::from_fn(|_| Vec::with_capacity(frames));
            for f in 0..frames {
                let rotation =
                    Rotation3::from_matrix_unchecked(joint.rotation(&q[f * nq..(f + 1) * nq]));
                let mut p = *UnitQuaternion::from_rotation_matrix(&rotation).quaternion();
                if previous.is_some_and(|prev| prev.dot(&p) < 0.0) {
                    p = -p;
                }
                previous = Some(p);
                for (c, v) in components.iter_mut().zip([p.w, p.i, p.j, p.k]) {
                    c.push(v);
                }
            }
            columns.extend(components);
        }
        let mut knots = time.to_vec();
        if let (Some(fc), true) = (lowpass_hz, frames > 1) {
            let dt = (time[frames - 1] - time[0]) / (frames - 1) as f64;
            knots = lowpass_padded(time, &mut columns, dt, fc).map_err(|(_, m)| m)?;
        }
        let splines = if columns.is_empty() {
            Vec::new()
        } else {
            NaturalSpline::interpolating_many(3, knots, columns).map_err(|(_, m)| m)?
        };
        Ok(OrientationTrajectory { joints, splines })
    }

    /// The joints whose orientations this trajectory holds.
    pub fn joints(&self) -> &[EulerJoint] {
        &self.joints
    }

    /// At time `t`, overwrites the joints' coordinates, speeds and accelerations in `q`, `qd`
    /// and `qdd` (whole vectors) with those of the filtered orientation; `q` holds the
    /// starting guess of the coordinates (the frame's unfiltered ones). Returns the largest
    /// angle by which a joint's coordinates miss its filtered orientation (rad).
    pub fn eval(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) -> f64 {
        let mut worst = 0.0f64;
        for (joint, s) in self.joints.iter().zip(self.splines.chunks_exact(4)) {
            let [(w, wd, wdd), (x, xd, xdd), (y, yd, ydd), (z, zd, zdd)] =
                std::array::from_fn(|c| s[c].eval(t));
            let (p, pd, pdd) = (
                Quaternion::new(w, x, y, z),
                Quaternion::new(wd, xd, yd, zd),
                Quaternion::new(wdd, xdd, ydd, zdd),
            );
            // r = p/n and its derivatives (module documentation, step 3)
            let n = p.norm();
            let r = p / n;
            let nd = r.dot(&pd);
            let rd = (pd - r * nd) / n;
            let ndd = (pd.dot(&pd) + p.dot(&pdd) - nd * nd) / n;
            let rdd = (pdd - rd * (2.0 * nd) - r * ndd) / n;
            let omega = (r.conjugate() * rd).imag() * 2.0;
            let alpha = (r.conjugate() * rdd).imag() * 2.0;
            let target = UnitQuaternion::new_unchecked(r).to_rotation_matrix();
            worst = worst.max(joint.coordinates_of(target.matrix(), q));
            // ω = E q̇, then α − b(q, q̇) = E q̈
            let (e, _) = joint.angular_terms(q, [0.0; 3]);
            let speeds = damped_solve(&e, &omega);
            let (_, bias) = joint.angular_terms(q, speeds.into());
            let accelerations = damped_solve(&e, &(alpha - bias));
            for k in 0..3 {
                qd[joint.q[k]] = speeds[k];
                qdd[joint.q[k]] = accelerations[k];
            }
        }
        worst
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default model's shoulder sequence: flexion about z, adduction about x, rotation
    /// about y; locked at adduction ±90°.
    fn shoulder() -> EulerJoint {
        EulerJoint {
            joint: 0,
            q: [0, 1, 2],
            axis: [Vec3::z(), Vec3::x(), Vec3::y()],
            slope: [1.0, 1.0, 1.0],
            offset: [0.0; 3],
        }
    }

    /// Rᵀ Ṙ = [ω]×: the child-frame angular velocity of R(t) by central differences.
    fn omega_by_differences(r: impl Fn(f64) -> Mat3, t: f64, h: f64) -> Vec3 {
        let w = r(t).transpose() * (r(t + h) - r(t - h)) / (2.0 * h);
        Vec3::new(
            w[(2, 1)] - w[(1, 2)],
            w[(0, 2)] - w[(2, 0)],
            w[(1, 0)] - w[(0, 1)],
        ) * 0.5
    }

    #[test]
    fn angular_terms_match_finite_differences_of_the_rotation() {
        let mut joint = shoulder();
        // a general sequence too: non-elementary axes, slopes and offsets
        let general = EulerJoint {
            joint: 0,
            q: [2, 0, 1],
            axis: [
                Vec3::new(0.3, 0.9, 0.1).normalize(),
                Vec3::new(1.0, -0.2, 0.4).normalize(),
                Vec3::new(-0.1, 0.2, 1.0).normalize(),
            ],
            slope: [0.7, -1.3, 2.0],
            offset: [0.1, -0.4, 0.25],
        };
        for j in [&mut joint, &mut general.clone()] {
            let (q0, qd, qdd) = ([0.4, -1.2, 0.9], [1.3, -0.7, 2.1], [-3.0, 5.0, 1.5]);
            let path = |t: f64| -> [f64; 3] {
                std::array::from_fn(|i| q0[i] + qd[i] * t + 0.5 * qdd[i] * t * t)
            };
            // speeds are indexed by the joint's own order
            let own = |v: [f64; 3]| -> [f64; 3] { std::array::from_fn(|k| v[j.q[k]]) };
            let rotation = |t: f64| j.rotation(&path(t));
            let (e, b) = j.angular_terms(&q0, own(qd));
            let omega = e * Vec3::from(own(qd));
            let alpha = e * Vec3::from(own(qdd)) + b;
            let h = 1e-5;
            let omega_fd = omega_by_differences(rotation, 0.0, h);
            let alpha_fd = (omega_by_differences(rotation, h, h)
                - omega_by_differences(rotation, -h, h))
                / (2.0 * h);
            assert!((omega - omega_fd).norm() < 1e-8, "{omega} vs {omega_fd}");
            assert!((alpha - alpha_fd).norm() < 1e-4, "{alpha} vs {alpha_fd}");
        }
    }

    #[test]
    fn coordinates_of_recovers_the_angles_and_moves_least_at_the_lock() {
        let joint = shoulder();
        let truth = [0.7, -0.4, 1.1];
        let mut q = [0.5, -0.2, 1.3];
        let miss = joint.coordinates_of(&joint.rotation(&truth), &mut q);
        assert!(miss < 1e-12);
        for k in 0..3 {
            assert!((q[k] - truth[k]).abs() < 1e-10, "{q:?}");
        }
        // at the lock (adduction −90°) only flexion − rotation... is fixed: from a start
        // off the true split, the solution keeps the start's split and fits the orientation
        let locked = [0.3, -std::f64::consts::FRAC_PI_2, 0.2];
        let target = joint.rotation(&locked);
        let mut q = [0.6, -std::f64::consts::FRAC_PI_2, 0.5];
        let miss = joint.coordinates_of(&target, &mut q);
        assert!(miss < 1e-9, "{miss}");
        assert!((joint.rotation(&q) - target).norm() < 1e-9);
        assert!(
            (q[0] - 0.6).abs() < 1e-6 && (q[2] - 0.5).abs() < 1e-6,
            "{q:?}"
        );
    }

    /// A rotation at a constant child-frame angular velocity whose arm passes 3° from the
    /// lock, sampled at 20 frames/s: the coordinates swing, the orientation does not. The
    /// derivatives from the orientation are the motion's (ω constant, α zero); those of a
    /// spline through each coordinate are not.
    #[test]
    fn a_rotation_passing_near_the_lock_keeps_its_angular_velocity() {
        let joint = shoulder();
        // start at flexion 0, adduction −87°: turning about the child-frame x axis (the arm
        // raised sideways in the frontal plane, 3° in front of it) crosses adduction −90°'s
        // neighbourhood, where flexion and rotation swing by tens of degrees between frames
        let start = joint.rotation(&[0.0, -80f64.to_radians(), 0.0])
            * rotation_about_axis(&Vec3::z(), 3f64.to_radians());
        let omega = Vec3::new(-2.0, 0.0, 0.0);
        let rotation = |t: f64| start * rotation_about_axis(&omega.normalize(), omega.norm() * t);
        let frames = 21;
        let time: Vec<f64> = (0..frames).map(|f| (f as f64 - 10.0) / 20.0).collect();
        let mut q = vec![0.0; 3 * frames];
        let mut guess = [0.0, -80f64.to_radians(), 0.0];
        // the coordinates followed continuously (1 ms steps), kept at the frames
        for f in 0..frames {
            for step in 1..=50 {
                let t = time[f] - 0.05 + 0.001 * step as f64;
                assert!(joint.coordinates_of(&rotation(t), &mut guess) < 1e-12);
            }
            q[3 * f..3 * f + 3].copy_from_slice(&guess);
        }
        let flexion: Vec<f64> = (0..frames).map(|f| q[3 * f]).collect();
        let swing = flexion
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f64::max);
        assert!(
            swing.to_degrees() > 20.0,
            "flexion swings {}°",
            swing.to_degrees()
        );

        let trajectory =
            OrientationTrajectory::fit(vec![joint.clone()], &time, &q, 3, None).unwrap();
        let coordinatewise = NaturalSpline::interpolating_many(
            3,
            time.clone(),
            (0..3)
                .map(|k| (0..frames).map(|f| q[3 * f + k]).collect())
                .collect(),
        )
        .unwrap();
        let (mut worst, mut worst_coordinatewise) = (0.0f64, 0.0f64);
        for f in 2..frames - 2 {
            let (mut qf, mut qd, mut qdd) = ([0.0; 3], [0.0; 3], [0.0; 3]);
            qf.copy_from_slice(&q[3 * f..3 * f + 3]);
            let miss = trajectory.eval(time[f], &mut qf, &mut qd, &mut qdd);
            assert!(miss < 1e-12);
            let (e, b) = joint.angular_terms(&qf, qd);
            let alpha = e * Vec3::from(qdd) + b;
            worst = worst
                .max((e * Vec3::from(qd) - omega).norm())
                .max(alpha.norm());
            let (v, d1, d2): (Vec<f64>, Vec<f64>, Vec<f64>) = {
                let s: Vec<_> = coordinatewise.iter().map(|s| s.eval(time[f])).collect();
                (
                    s.iter().map(|x| x.0).collect(),
                    s.iter().map(|x| x.1).collect(),
                    s.iter().map(|x| x.2).collect(),
                )
            };
            let qv: [f64; 3] = v.try_into().unwrap();
            let (e, b) = joint.angular_terms(&qv, d1.clone().try_into().unwrap());
            let alpha = e * Vec3::from_column_slice(&d2) + b;
            worst_coordinatewise = worst_coordinatewise
                .max((e * Vec3::from_column_slice(&d1) - omega).norm())
                .max(alpha.norm());
        }
        assert!(worst < 0.05, "orientation: error {worst} rad/s or rad/s²");
        assert!(
            worst_coordinatewise > 1.0,
            "coordinate-wise: error {worst_coordinatewise} against {worst}"
        );
    }
}
