//! ∂τ/∂θ and ∂τ/∂θ̇ of inverse dynamics in full coordinates, and ∂τ/∂q, ∂τ/∂q̇, ∂τ/∂q̈ in
//! the independent coordinates, against central finite differences of `rnea_full` and
//! `rnea` on the default model, gait2392 and Rajagopal2016 (spline-driven knee axes, the
//! walker knee and patella couplers included) at random states.

mod common;
use common::*;
use musculo::dynamics::{
    RneaDerivatives, crba, rnea, rnea_derivatives, rnea_derivatives_full, rnea_full,
};
use musculo::{Data, Model};

/// max |analytic − central difference| / max |analytic| over both Jacobians.
fn worst_relative_error(model: &Model, states: usize, seed: u64) -> f64 {
    let nf = model.n_full();
    let mut data = Data::new(model);
    let mut der = RneaDerivatives::new(model);
    let mut rng = Rng::new(seed);
    let h = 1e-6;
    let mut worst: f64 = 0.0;
    for _ in 0..states {
        let th = random_vec(nf, 1.0, &mut rng);
        let thd = random_vec(nf, 2.0, &mut rng);
        let thdd = random_vec(nf, 5.0, &mut rng);
        rnea_derivatives_full(model, &mut data, &th, &thd, &thdd, &mut der).unwrap();
        let (dq, dv) = (der.dtau_dtheta.clone(), der.dtau_dtheta_dot.clone());
        let scale = dq.amax().max(dv.amax());
        let mut tau =
            |t: &[f64], td: &[f64]| rnea_full(model, &mut data, t, td, &thdd).unwrap().to_vec();
        for j in 0..nf {
            let (mut tp, mut tm) = (th.clone(), th.clone());
            tp[j] += h;
            tm[j] -= h;
            let (fp, fm) = (tau(&tp, &thd), tau(&tm, &thd));
            let (mut vp, mut vm) = (thd.clone(), thd.clone());
            vp[j] += h;
            vm[j] -= h;
            let (gp, gm) = (tau(&th, &vp), tau(&th, &vm));
            for d in 0..nf {
                let fd_q = (fp[d] - fm[d]) / (2.0 * h);
                let fd_v = (gp[d] - gm[d]) / (2.0 * h);
                worst = worst
                    .max((dq[(d, j)] - fd_q).abs() / scale)
                    .max((dv[(d, j)] - fd_v).abs() / scale);
            }
        }
    }
    worst
}

/// The same for the independent coordinates: max relative error of ∂τ/∂q and ∂τ/∂q̇ against
/// central differences of `rnea`, and of ∂τ/∂q̈ against `crba`.
fn worst_reduced_error(model: &Model, states: usize, seed: u64) -> f64 {
    let n = model.nq();
    let mut data = Data::new(model);
    let mut der = RneaDerivatives::new(model);
    let mut rng = Rng::new(seed);
    let h = 1e-6;
    let mut worst: f64 = 0.0;
    for _ in 0..states {
        let q = random_vec(n, 0.8, &mut rng);
        let qd = random_vec(n, 2.0, &mut rng);
        let qdd = random_vec(n, 5.0, &mut rng);
        rnea_derivatives(model, &mut data, &q, &qd, &qdd, &mut der).unwrap();
        let tau0 = data.tau().clone();
        let (dq, dv, da) = (
            der.dtau_dq.clone(),
            der.dtau_dqd.clone(),
            der.dtau_dqdd.clone(),
        );
        let scale = dq.amax().max(dv.amax());
        let m = crba(model, &mut data, &q).unwrap().clone();
        worst = worst.max((&da - &m).amax() / m.amax());
        let t0 = rnea(model, &mut data, &q, &qd, &qdd).unwrap().clone();
        worst = worst.max((&tau0 - &t0).amax() / t0.amax());
        let mut tau = |q: &[f64], qd: &[f64]| rnea(model, &mut data, q, qd, &qdd).unwrap().clone();
        for j in 0..n {
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[j] += h;
            qm[j] -= h;
            let fd_q = (tau(&qp, &qd) - tau(&qm, &qd)) / (2.0 * h);
            let (mut vp, mut vm) = (qd.clone(), qd.clone());
            vp[j] += h;
            vm[j] -= h;
            let fd_v = (tau(&q, &vp) - tau(&q, &vm)) / (2.0 * h);
            for i in 0..n {
                worst = worst
                    .max((dq[(i, j)] - fd_q[i]).abs() / scale)
                    .max((dv[(i, j)] - fd_v[i]).abs() / scale);
            }
        }
    }
    worst
}

#[test]
fn reduced_derivatives_equal_finite_differences_on_every_model() {
    let e = worst_reduced_error(&Model::default_fullbody(), 5, 21);
    eprintln!("default model: worst relative error {e:.2e}");
    assert!(e < 1e-6, "default model: worst relative error {e:.2e}");
    for rel in [
        "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
    ] {
        let Some(path) = reference_file(rel) else {
            return;
        };
        let model = Model::from_osim_file(&path).unwrap();
        let e = worst_reduced_error(&model, 5, 22);
        eprintln!("{rel}: worst relative error {e:.2e}");
        assert!(e < 1e-6, "{rel}: worst relative error {e:.2e}");
    }
}

#[test]
fn derivatives_equal_finite_differences_on_the_default_model() {
    let e = worst_relative_error(&Model::default_fullbody(), 5, 11);
    eprintln!("default model: worst relative error {e:.2e}");
    assert!(e < 1e-6, "worst relative error {e:.2e}");
}

#[test]
fn derivatives_equal_finite_differences_on_gait2392_and_rajagopal2016() {
    for rel in [
        "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
    ] {
        let Some(path) = reference_file(rel) else {
            return;
        };
        let model = Model::from_osim_file(&path).unwrap();
        let e = worst_relative_error(&model, 5, 12);
        eprintln!("{rel}: worst relative error {e:.2e}");
        assert!(e < 1e-6, "{rel}: worst relative error {e:.2e}");
    }
}

#[test]
fn a_workspace_for_another_model_is_an_error() {
    let model = Model::default_fullbody();
    let mut der = RneaDerivatives::new(&Model::demo());
    let mut data = Data::new(&model);
    let z = vec![0.0; model.n_full()];
    let e = rnea_derivatives_full(&model, &mut data, &z, &z, &z, &mut der).unwrap_err();
    assert!(e.to_string().contains("another model"), "{e}");
}
