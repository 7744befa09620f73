//! Q = J_cᵀ λ and ∂Q/∂q from `contact_force_derivatives` against `contact_jacobian` and
//! central differences of J_c(q)ᵀ λ, on the default model, gait2392 and Rajagopal2016 (points
//! on distal and proximal bodies), for body-fixed points and for points offset in ground from
//! a body-fixed carrier (a contact sphere's lowest point).

mod common;
use common::*;
use musculo::dynamics::{
    ContactForceDerivatives, contact_force_derivatives, contact_jacobian, forward_kinematics,
};
use musculo::spatial::Vec3;
use musculo::{Data, Model};
use nalgebra::{DMatrix, DVector};

/// Points on up to six bodies (the last bodies of the tree are the distal ones) with random
/// locations and forces.
fn random_points(model: &Model, rng: &mut Rng) -> (Vec<(usize, Vec3)>, Vec<Vec3>) {
    let nb = model.bodies.len();
    let bodies = [nb - 1, nb - 2, nb / 2, nb / 3, 1, 2];
    let points: Vec<(usize, Vec3)> = bodies
        .iter()
        .map(|&b| {
            let p = random_vec(3, 0.1, rng);
            (b, Vec3::new(p[0], p[1], p[2]))
        })
        .collect();
    let forces = points
        .iter()
        .map(|_| {
            let f = random_vec(3, 300.0, rng);
            Vec3::new(f[0], f[1], f[2])
        })
        .collect();
    (points, forces)
}

/// J_c(q)ᵀ λ with each force on the material point at c_i(q) + g_i: body-fixed location
/// c_i + R_bᵀ g_i at this q.
fn jt_lambda(
    model: &Model,
    data: &mut Data,
    q: &[f64],
    carriers: &[(usize, Vec3)],
    offsets: &[Vec3],
    forces: &[Vec3],
) -> DVector<f64> {
    forward_kinematics(model, data, q).unwrap();
    let points: Vec<(usize, Vec3)> = carriers
        .iter()
        .zip(offsets)
        .map(|((b, c), g)| (*b, c + data.body_pose(*b).0.transpose() * g))
        .collect();
    let points = &points[..];
    let mut jc = DMatrix::zeros(3 * points.len(), model.nq());
    contact_jacobian(model, data, points, &mut jc).unwrap();
    let lambda = DVector::from_iterator(
        3 * forces.len(),
        forces.iter().flat_map(|f| [f.x, f.y, f.z]),
    );
    jc.transpose() * lambda
}

/// (max relative error of Q, of ∂Q/∂q) over random states.
fn worst_errors(model: &Model, states: usize, seed: u64, offset: f64) -> (f64, f64) {
    let n = model.nq();
    let mut data = Data::new(model);
    let mut der = ContactForceDerivatives::new(model);
    let mut rng = Rng::new(seed);
    let h = 1e-6;
    let (mut worst_q, mut worst_d): (f64, f64) = (0.0, 0.0);
    for _ in 0..states {
        let q = random_vec(n, 0.8, &mut rng);
        let (points, forces) = random_points(model, &mut rng);
        let offsets: Vec<Vec3> = points
            .iter()
            .map(|_| Vec3::new(offset / 3.0, -offset, offset / 2.0))
            .collect();
        let given: &[Vec3] = if offset == 0.0 { &[] } else { &offsets };
        contact_force_derivatives(model, &mut data, &q, &points, given, &forces, &mut der).unwrap();
        let (gq, dq) = (der.generalized_force.clone(), der.dq.clone());
        let expected = jt_lambda(model, &mut data, &q, &points, &offsets, &forces);
        worst_q = worst_q.max((&gq - &expected).amax() / expected.amax());
        let scale = dq.amax();
        for j in 0..n {
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[j] += h;
            qm[j] -= h;
            let fd = (jt_lambda(model, &mut data, &qp, &points, &offsets, &forces)
                - jt_lambda(model, &mut data, &qm, &points, &offsets, &forces))
                / (2.0 * h);
            for i in 0..n {
                worst_d = worst_d.max((dq[(i, j)] - fd[i]).abs() / scale);
            }
        }
    }
    (worst_q, worst_d)
}

#[test]
fn contact_force_derivatives_equal_finite_differences_on_every_model() {
    for offset in [0.0, 0.03] {
        let (eq, ed) = worst_errors(&Model::default_fullbody(), 5, 31, offset);
        eprintln!("default model, offset {offset}: Q {eq:.2e}, dQ/dq {ed:.2e}");
        assert!(
            eq < 1e-12 && ed < 1e-6,
            "default model: Q {eq:.2e}, dQ/dq {ed:.2e}"
        );
    }
    for rel in [
        "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
    ] {
        let Some(path) = reference_file(rel) else {
            return;
        };
        let model = Model::from_osim_file(&path).unwrap();
        let (eq, ed) = worst_errors(&model, 5, 32, 0.03);
        eprintln!("{rel}: Q {eq:.2e}, dQ/dq {ed:.2e}");
        assert!(eq < 1e-12 && ed < 1e-6, "{rel}: Q {eq:.2e}, dQ/dq {ed:.2e}");
    }
}

#[test]
fn mismatched_points_and_forces_are_an_error() {
    let model = Model::default_fullbody();
    let mut data = Data::new(&model);
    let mut der = ContactForceDerivatives::new(&model);
    let q = vec![0.0; model.nq()];
    let e = contact_force_derivatives(
        &model,
        &mut data,
        &q,
        &[(1, Vec3::zeros())],
        &[],
        &[],
        &mut der,
    )
    .unwrap_err();
    assert!(e.to_string().contains("0 forces for 1 points"), "{e}");
    let e = contact_force_derivatives(
        &model,
        &mut data,
        &q,
        &[(999, Vec3::zeros())],
        &[],
        &[Vec3::zeros()],
        &mut der,
    )
    .unwrap_err();
    assert!(e.to_string().contains("out of range"), "{e}");
}
