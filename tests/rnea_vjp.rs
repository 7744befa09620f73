//! Vector–Jacobian products of inverse dynamics with external point forces against the full
//! Jacobians uᵀ(∂τ_ID/∂x − ∂(J_cᵀλ)/∂x) (themselves tested against finite differences), M u
//! from `crba` and −J_c u from `contact_jacobian`, on the default model, gait2392 and
//! Rajagopal2016, in full and independent coordinates.

mod common;
use common::*;
use musculo::dynamics::{
    ContactForceDerivatives, PointForces, RneaDerivatives, RneaVjp, contact_force_derivatives,
    contact_jacobian, rnea_derivatives, rnea_vjp,
};
use musculo::spatial::Vec3;
use musculo::{Data, Model};
use nalgebra::{DMatrix, DVector};

/// Max relative error over all products at random states.
fn worst_error(model: &Model, seed: u64) -> f64 {
    let (n, nb) = (model.nq(), model.bodies.len());
    let mut rng = Rng::new(seed);
    let mut data = Data::new(model);
    let mut der = RneaDerivatives::new(model);
    let mut cder = ContactForceDerivatives::new(model);
    let mut vjp = RneaVjp::new(model);
    let mut worst: f64 = 0.0;
    let rel = |a: &DVector<f64>, b: &DVector<f64>| (a - b).amax() / b.amax().max(1e-300);
    for _ in 0..4 {
        let q = random_vec(n, 0.8, &mut rng);
        let qd = random_vec(n, 2.0, &mut rng);
        let qdd = random_vec(n, 5.0, &mut rng);
        let u = DVector::from_vec(random_vec(n, 1.0, &mut rng));
        let carriers: Vec<(usize, Vec3)> = [nb - 1, nb - 2, nb / 2, 1]
            .iter()
            .map(|&b| {
                let p = random_vec(3, 0.1, &mut rng);
                (b, Vec3::new(p[0], p[1], p[2]))
            })
            .collect();
        let forces: Vec<Vec3> = carriers
            .iter()
            .map(|_| {
                let f = random_vec(3, 300.0, &mut rng);
                Vec3::new(f[0], f[1], f[2])
            })
            .collect();
        let offsets: Vec<Vec3> = carriers
            .iter()
            .map(|_| Vec3::new(0.01, -0.03, 0.02))
            .collect();
        let ext = PointForces {
            carriers: &carriers,
            offsets_in_ground: &offsets,
            forces: &forces,
        };
        rnea_vjp(
            model,
            &mut data,
            &q,
            &qd,
            &qdd,
            &ext,
            u.as_slice(),
            &mut vjp,
        )
        .unwrap();
        contact_force_derivatives(
            model, &mut data, &q, &carriers, &offsets, &forces, &mut cder,
        )
        .unwrap();
        rnea_derivatives(model, &mut data, &q, &qd, &qdd, &mut der).unwrap();
        // τ of the forward pass = τ_ID − J_cᵀλ
        let expect_tau = data.tau().clone() - &cder.generalized_force;
        worst = worst.max(rel(&vjp.tau, &expect_tau));
        // τ of the forward pass = τ_ID − J_cᵀλ
        let expect_tau = data.tau().clone() - &cder.generalized_force;
        worst = worst.max(rel(&vjp.tau, &expect_tau));
        let expect_q = (&der.dtau_dq - &cder.dq).transpose() * &u;
        let expect_qd = der.dtau_dqd.transpose() * &u;
        let expect_qdd = &der.dtau_dqdd * &u;
        worst = worst
            .max(rel(&vjp.dq, &expect_q))
            .max(rel(&vjp.dqd, &expect_qd))
            .max(rel(&vjp.dqdd, &expect_qdd));
        // −J_c u at the points' current material locations
        let points: Vec<(usize, Vec3)> = carriers
            .iter()
            .zip(&offsets)
            .map(|((b, c), g)| (*b, c + data.body_pose(*b).0.transpose() * g))
            .collect();
        let mut jc = DMatrix::zeros(3 * points.len(), n);
        contact_jacobian(model, &data, &points, &mut jc).unwrap();
        let ju = &jc * &u;
        let got = DVector::from_iterator(
            ju.len(),
            vjp.dforces.iter().flat_map(|v| [-v.x, -v.y, -v.z]),
        );
        worst = worst.max(rel(&got, &ju));
    }
    worst
}

#[test]
fn vector_jacobian_products_equal_the_full_jacobians() {
    let e = worst_error(&Model::default_fullbody(), 51);
    eprintln!("default model: worst {e:.2e}");
    assert!(e < 1e-10, "default model: worst {e:.2e}");
    for rel in [
        "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
    ] {
        let Some(path) = reference_file(rel) else {
            return;
        };
        let model = Model::from_osim_file(&path).unwrap();
        let e = worst_error(&model, 52);
        eprintln!("{rel}: worst {e:.2e}");
        assert!(e < 1e-10, "{rel}: worst {e:.2e}");
    }
}

#[test]
fn bad_external_forces_are_errors() {
    let model = Model::default_fullbody();
    let mut data = Data::new(&model);
    let mut vjp = RneaVjp::new(&model);
    let z = vec![0.0; model.nq()];
    let carriers = [(1, Vec3::zeros())];
    let ext = PointForces {
        carriers: &carriers,
        offsets_in_ground: &[],
        forces: &[],
    };
    let e = rnea_vjp(&model, &mut data, &z, &z, &z, &ext, &z, &mut vjp).unwrap_err();
    assert!(e.to_string().contains("0 forces for 1 points"), "{e}");
    let e = rnea_vjp(
        &model,
        &mut data,
        &z,
        &z,
        &z,
        &PointForces::default(),
        &z[1..],
        &mut vjp,
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("`u`") || e.to_string().contains("u"),
        "{e}"
    );
}
