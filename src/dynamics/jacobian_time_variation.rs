//! Time variation of the reduced motion subspace, d/dt S̃_c, and the rate J̇ of point
//! Jacobians built from it (velocity stage).
//!
//! Column c of the reduced subspace is S̃_c = Σ_{d ∈ joint(c)} Φ_dj s_d (see
//! `Reduction::columns`), so
//!
//! ```text
//! d/dt S̃_c = Σ_d (Φ̇_dj s_d + Φ_dj ṡ_d)
//! ṡ_d      = v_{before d} ×ₘ s_d            (s_d is fixed in the frame axis d is attached to)
//! Φ̇_dj     = Σ_k (∂Φ_dj/∂q_k) q̇_k           (from `ReductionTangents::grad_q`)
//! ```
//!
//! with v_{before d} the spatial velocity of the parent body plus s_d' θ̇_d' of the joint's
//! earlier axes (s_d ×ₘ s_d = 0, so the velocity just after d gives the same ṡ_d).
//!
//! Every rate is taken in the fixed frame that coincides with O now: O is the origin of body
//! 1 and moves with q, but the rates are only ever paired with forces about that same fixed
//! point, or turned into point quantities (which do not depend on the reference point).

use super::reduction::ReductionTangents;
use super::{Data, Stage};
use crate::model::reduction::NONE;
use crate::model::{JointStep, Model};
use crate::spatial::{Motion, Vec3};

/// d/dt of the reduced motion-subspace columns at a velocity-stage `Data`; allocated once per
/// model, [`JacobianTimeVariation::compute`] allocates nothing.
#[derive(Clone, Debug)]
pub struct JacobianTimeVariation {
    /// d/dt S̃_c for every reduced column c (ground axes, about the fixed point O).
    column_rate: Vec<Motion>,
    /// ṡ_d for every full coordinate d.
    dof_rate: Vec<Motion>,
    tangents: ReductionTangents,
    zeros: Vec<f64>,
    computed: bool,
}

impl JacobianTimeVariation {
    /// Allocates the workspace for `model`.
    pub fn new(model: &Model) -> JacobianTimeVariation {
        JacobianTimeVariation {
            column_rate: vec![Motion::ZERO; model.reduction.columns.len()],
            dof_rate: vec![Motion::ZERO; model.n_full()],
            tangents: ReductionTangents::new(model),
            zeros: vec![0.0; model.nq()],
            computed: false,
        }
    }

    /// d/dt S̃_c of every reduced column c from the last [`Self::compute`], in the order of
    /// the reduced columns (tree order: joint by joint, one column per independent coordinate
    /// the joint's axes depend on).
    pub fn column_rate(&self) -> &[Motion] {
        &self.column_rate
    }

    /// The column rates at the state (q, q̇) of `data`, which must be at least at the
    /// velocity stage of [`super::forward_kinematics_velocity`].
    pub fn compute(&mut self, model: &Model, data: &Data) -> crate::Result<()> {
        const ALGORITHM: &str = "JacobianTimeVariation::compute";
        data.require(model, Stage::Velocity, ALGORITHM)?;
        if data.node_grad.first().is_some_and(|g| g.is_nan()) {
            return Err(crate::Error::StageNotComputed {
                algorithm: ALGORITHM,
                needs: "forward_kinematics_velocity (not forward_kinematics_full)",
            });
        }
        self.fits(model)?;
        self.computed = false;
        let r = &model.reduction;
        let nc = r.n_coordinates;
        let ne = r.dep_index.len();
        // ∂Φ/∂q_k for every k (q̈ only enters the θ̈ tangents, which are not used here)
        self.tangents.compute(model, data, &self.zeros);
        let theta_dot = &data.node_vel[nc..];
        // ṡ_d = v_{before d} ×ₘ s_d, the axes visited in the order `poses` places them
        for joint in &model.joints {
            let mut v = data.body_vel[joint.parent_body];
            for step in &joint.steps {
                if let JointStep::Dof(d) = *step {
                    self.dof_rate[d] = v.cross_motion(&data.dof_motion[d]);
                    v.add_scaled(&data.dof_motion[d], theta_dot[d]);
                }
            }
        }
        let cols = &r.columns;
        for c in 0..cols.len() {
            let mut rate = Motion::ZERO;
            for &(d, e) in &cols.terms[cols.start[c]..cols.start[c + 1]] {
                // Φ̇_dj = Σ_k (∂Φ_dj/∂q_k) q̇_k, over the q_k that θ_d depends on (the only
                // k with ∂²θ_d/∂q_j∂q_k ≠ 0)
                let mut phi_dot = 0.0;
                for f in r.phi_row(d) {
                    let k = r.dep_index[f];
                    phi_dot += self.tangents.grad_q[k * ne + e] * data.node_vel[r.independent[k]];
                }
                // d/dt S̃_c += Φ̇_dj s_d + Φ_dj ṡ_d
                rate.add_scaled(&data.dof_motion[d], phi_dot);
                rate.add_scaled(&self.dof_rate[d], data.node_grad[e]);
            }
            self.column_rate[c] = rate;
        }
        self.computed = true;
        Ok(())
    }

    /// The rates d/dt ∂c/∂q_j = Σ_k (∂²c/∂q_j∂q_k) q̇_k of coordinate `c`'s gradient, in the
    /// order of [`Data::coordinate_gradient`] (zero for an independent coordinate). Needs
    /// [`Self::compute`] at the state of `data`.
    pub fn coordinate_gradient_rate<'a>(
        &'a self,
        model: &'a Model,
        data: &'a Data,
        c: usize,
    ) -> impl Iterator<Item = (usize, f64)> + 'a {
        let r = &model.reduction;
        let ne = r.dep_index.len();
        let row = r.dep_start[c]..r.dep_start[c + 1];
        row.clone().map(move |e| {
            let rate = row
                .clone()
                .map(|f| {
                    let k = r.dep_index[f];
                    self.tangents.grad_q[k * ne + e] * data.node_vel[r.independent[k]]
                })
                .sum();
            (r.dep_index[e], rate)
        })
    }

    /// J̇ (3 × n, `out[j]` = column j) of the point of `body` that is at ground position `x`
    /// and moves with ground velocity `xdot` (it may slide over the body; for a body-fixed
    /// point `xdot` = [`Data::point_velocity`]). Needs [`Self::compute`] at the state of
    /// `data`. Column j of J sums ω_c × (x − O) + v_c over the columns c of q_j on the path
    /// from `body` to ground.
    pub fn point_jacobian_rate(
        &self,
        model: &Model,
        data: &Data,
        body: usize,
        x: &Vec3,
        xdot: &Vec3,
        out: &mut [Vec3],
    ) -> crate::Result<()> {
        if !self.computed {
            return Err(crate::Error::StageNotComputed {
                algorithm: "JacobianTimeVariation::point_jacobian_rate",
                needs: "JacobianTimeVariation::compute",
            });
        }
        self.fits(model)?;
        data.fits(model)?;
        if body >= model.bodies.len() {
            return Err(crate::Error::invalid(
                "body",
                format!("index {body} out of range ({} bodies)", model.bodies.len()),
            ));
        }
        if out.len() != model.nq() {
            return Err(crate::Error::invalid(
                "out",
                format!("needs {} columns, has {}", model.nq(), out.len()),
            ));
        }
        out.fill(Vec3::zeros());
        let cols = &model.reduction.columns;
        let offset = x - data.reference_point;
        let mut c = cols.body_last[body];
        while c != NONE {
            let (s, rate) = (&data.col_motion[c], &self.column_rate[c]);
            // d/dt (ω_c × (x − O) + v_c) = ω̇_c × (x − O) + ω_c × ẋ + v̇_c   (O fixed)
            out[cols.q[c]] += rate.ang.cross(&offset) + s.ang.cross(xdot) + rate.lin;
            c = cols.parent[c];
        }
        Ok(())
    }

    fn fits(&self, model: &Model) -> crate::Result<()> {
        if self.column_rate.len() != model.reduction.columns.len()
            || self.dof_rate.len() != model.n_full()
            || self.zeros.len() != model.nq()
        {
            return Err(crate::Error::invalid(
                "jacobian_time_variation",
                format!(
                    "this JacobianTimeVariation was built for another model \
                     (JacobianTimeVariation::new({}) is needed)",
                    model.name
                ),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{
        forward_kinematics, forward_kinematics_acceleration, forward_kinematics_velocity,
        point_jacobian,
    };
    use crate::random::SplitMix64;
    use nalgebra::DMatrix;

    const STATES: usize = 4;
    const H: f64 = 1e-6;

    /// A random state: q inside the coordinate ranges (5 % margin, so that q ± h q̇ stays
    /// inside), q̇ uniform in [−2, 2].
    fn random_state(model: &Model, rng: &mut SplitMix64) -> (Vec<f64>, Vec<f64>) {
        let q = crate::reference::random_q(model, rng, 0.05);
        let qd = (0..model.nq()).map(|_| rng.uniform(-2.0, 2.0)).collect();
        (q, qd)
    }

    fn random_vec3(rng: &mut SplitMix64, a: f64) -> Vec3 {
        Vec3::new(rng.uniform(-a, a), rng.uniform(-a, a), rng.uniform(-a, a))
    }

    /// Two body-fixed points per moving body: the centre of mass and a random point.
    fn points(model: &Model, rng: &mut SplitMix64) -> Vec<(usize, Vec3)> {
        (1..model.bodies.len())
            .flat_map(|b| [model.bodies[b].com_in_body, random_vec3(rng, 0.2)].map(|p| (b, p)))
            .collect()
    }

    /// Bodies that sit below a knee (moved by the knee's spline-driven or coupled axes).
    fn below_knee(model: &Model, b: usize) -> bool {
        ["tibia", "patella", "talus", "calcn", "toes"]
            .iter()
            .any(|n| model.bodies[b].name.starts_with(n))
    }

    fn max_abs_diff(a: &[Vec3], b: &DMatrix<f64>) -> (f64, f64) {
        let (mut diff, mut scale) = (0.0_f64, 0.0_f64);
        for (j, col) in a.iter().enumerate() {
            for i in 0..3 {
                diff = diff.max((col[i] - b[(i, j)]).abs());
                scale = scale.max(b[(i, j)].abs());
            }
        }
        (diff, scale)
    }

    /// Checks `f(model, q, q̇, data at the velocity stage, rates, rng)` at random states of
    /// every model, returning the worst relative error it reports per model; asserts that a
    /// body below the knee was covered and that the knee's Φ̇q̇ is non-zero where the model
    /// has spline-driven knee axes.
    fn for_each_state(
        seed: u64,
        mut f: impl FnMut(&Model, &[f64], &[f64], &Data, &JacobianTimeVariation, &mut SplitMix64) -> f64,
    ) -> Vec<(&'static str, f64)> {
        let mut worst = Vec::new();
        for (name, model) in crate::reference::test_models() {
            assert!(
                (1..model.bodies.len()).any(|b| below_knee(&model, b)),
                "{name}: no body below the knee"
            );
            let mut rng = SplitMix64(seed);
            let mut data = Data::new(&model);
            let mut jtv = JacobianTimeVariation::new(&model);
            let mut w = 0.0_f64;
            let mut knee_phi_dot = 0.0_f64;
            for _ in 0..STATES {
                let (q, qd) = random_state(&model, &mut rng);
                forward_kinematics_velocity(&model, &mut data, &q, &qd).unwrap();
                jtv.compute(&model, &data).unwrap();
                for joint in &model.joints {
                    if below_knee(&model, joint.child_body) {
                        for d in joint.dof_range.clone() {
                            knee_phi_dot = knee_phi_dot.max(data.phi_dot_qd(&model)[d].abs());
                        }
                    }
                }
                w = w.max(f(&model, &q, &qd, &data, &jtv, &mut rng));
            }
            if name != "default" {
                // gait2392 and Rajagopal2016 drive the knee translations by splines of the
                // knee angle (and Rajagopal2016 the patella by a coupler): Φ̇ is exercised.
                assert!(knee_phi_dot > 1e-4, "{name}: knee Φ̇q̇ = {knee_phi_dot}");
            }
            eprintln!("{name}: worst relative error {w:.3e}");
            worst.push((name, w));
        }
        worst
    }

    #[test]
    fn point_jacobian_rate_times_qd_equals_point_bias_acceleration() {
        let zeros_for = |m: &Model| vec![0.0; m.nq()];
        let worst = for_each_state(11, |model, q, qd, data, jtv, rng| {
            let mut acc = Data::new(model);
            forward_kinematics_acceleration(model, &mut acc, q, qd, &zeros_for(model)).unwrap();
            let mut rate = vec![Vec3::zeros(); model.nq()];
            let mut w = 0.0_f64;
            for (b, p) in points(model, rng) {
                let x = data.point_position(b, &p);
                let xdot = data.point_velocity(b, &p);
                jtv.point_jacobian_rate(model, data, b, &x, &xdot, &mut rate)
                    .unwrap();
                let jdot_qd: Vec3 = rate.iter().zip(qd).map(|(c, v)| c * *v).sum();
                // `point_acceleration` returns (α, a_p) with a_p the classical acceleration of
                // the body-fixed point, â_lin + α × (p − O) + ω × v_p; with q̈ = 0 and no
                // gravity it is J̇q̇.
                let a = acc.point_acceleration(b, &p).1;
                w = w.max((jdot_qd - a).norm() / a.norm().max(1.0));
            }
            w
        });
        for (name, w) in worst {
            assert!(
                w < 1e-9,
                "{name}: J̇q̇ differs from the bias acceleration by {w:e}"
            );
        }
    }

    #[test]
    fn point_jacobian_rate_matches_central_difference_along_qd() {
        let worst = for_each_state(23, |model, q, qd, data, jtv, rng| {
            let n = model.nq();
            let (mut plus, mut minus) = (Data::new(model), Data::new(model));
            let step = |s: f64| -> Vec<f64> { q.iter().zip(qd).map(|(a, v)| a + s * v).collect() };
            forward_kinematics(model, &mut plus, &step(H)).unwrap();
            forward_kinematics(model, &mut minus, &step(-H)).unwrap();
            let (mut jp, mut jm) = (DMatrix::zeros(3, n), DMatrix::zeros(3, n));
            let mut rate = vec![Vec3::zeros(); n];
            let mut w = 0.0_f64;
            for (b, p) in points(model, rng) {
                let x = data.point_position(b, &p);
                let xdot = data.point_velocity(b, &p);
                jtv.point_jacobian_rate(model, data, b, &x, &xdot, &mut rate)
                    .unwrap();
                point_jacobian(model, &plus, b, &p, &mut jp).unwrap();
                point_jacobian(model, &minus, b, &p, &mut jm).unwrap();
                // (J(q + h q̇) − J(q − h q̇)) / 2h
                let fd = (&jp - &jm) / (2.0 * H);
                let (diff, scale) = max_abs_diff(&rate, &fd);
                w = w.max(diff / scale.max(1.0));
            }
            w
        });
        for (name, w) in worst {
            assert!(
                w < 1e-6,
                "{name}: J̇ differs from its central difference by {w:e}"
            );
        }
    }

    #[test]
    fn sliding_point_jacobian_rate_matches_central_difference() {
        let worst = for_each_state(37, |model, q, qd, data, jtv, rng| {
            let n = model.nq();
            let (mut plus, mut minus) = (Data::new(model), Data::new(model));
            let step = |s: f64| -> Vec<f64> { q.iter().zip(qd).map(|(a, v)| a + s * v).collect() };
            forward_kinematics(model, &mut plus, &step(H)).unwrap();
            forward_kinematics(model, &mut minus, &step(-H)).unwrap();
            let (mut jp, mut jm) = (DMatrix::zeros(3, n), DMatrix::zeros(3, n));
            let mut rate = vec![Vec3::zeros(); n];
            let mut w = 0.0_f64;
            for (b, p) in points(model, rng) {
                let x = data.point_position(b, &p);
                // a ground velocity unrelated to the body's: the point slides over it
                let xdot = random_vec3(rng, 1.0);
                assert!((xdot - data.point_velocity(b, &p)).norm() > 1e-3);
                jtv.point_jacobian_rate(model, data, b, &x, &xdot, &mut rate)
                    .unwrap();
                // J_body at the body point that coincides with x + s ẋ at q + s q̇
                let jacobian_at = |d: &Data, s: f64, out: &mut DMatrix<f64>| {
                    let (rot, origin) = d.body_pose(b);
                    let local = rot.transpose() * (x + xdot * s - origin);
                    point_jacobian(model, d, b, &local, out).unwrap();
                };
                jacobian_at(&plus, H, &mut jp);
                jacobian_at(&minus, -H, &mut jm);
                let fd = (&jp - &jm) / (2.0 * H);
                let (diff, scale) = max_abs_diff(&rate, &fd);
                w = w.max(diff / scale.max(1.0));
            }
            w
        });
        for (name, w) in worst {
            assert!(
                w < 1e-6,
                "{name}: sliding-point J̇ differs from its central difference by {w:e}"
            );
        }
    }

    #[test]
    fn compute_requires_the_velocity_stage() {
        let model = Model::default_fullbody();
        let mut data = Data::new(&model);
        let mut jtv = JacobianTimeVariation::new(&model);
        let mut rate = vec![Vec3::zeros(); model.nq()];
        let x = Vec3::zeros();
        assert!(matches!(
            jtv.point_jacobian_rate(&model, &data, 1, &x, &x, &mut rate),
            Err(crate::Error::StageNotComputed { .. })
        ));
        forward_kinematics(&model, &mut data, &model.default_q()).unwrap();
        assert!(matches!(
            jtv.compute(&model, &data),
            Err(crate::Error::StageNotComputed { .. })
        ));
        let qd = vec![0.5; model.nq()];
        forward_kinematics_velocity(&model, &mut data, &model.default_q(), &qd).unwrap();
        jtv.compute(&model, &data).unwrap();
        let mut short = vec![Vec3::zeros(); model.nq() - 1];
        assert!(
            jtv.point_jacobian_rate(&model, &data, 1, &x, &x, &mut short)
                .is_err()
        );
        assert!(
            jtv.point_jacobian_rate(&model, &data, model.bodies.len(), &x, &x, &mut rate)
                .is_err()
        );
        jtv.point_jacobian_rate(&model, &data, 1, &x, &x, &mut rate)
            .unwrap();
    }
}
