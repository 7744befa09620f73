//! Dynamics identities on the OpenSim reference models, at 100 random states within the
//! coordinate ranges each:
//! - M is symmetric positive definite;
//! - ID(q, q̇, q̈) = M q̈ + bias (1e-9 relative), G = ID(q, 0, 0) with G computed from the
//!   centre-of-mass Jacobian;
//! - Φ, Φ̇q̇, body/point/COM Jacobians and J̇q̇ agree with central finite differences of
//!   forward kinematics (1e-6);
//! - ½ q̇ᵀ M q̇ equals the sum of the bodies' kinetic energies computed point-mass style;
//! - G agrees with the finite-difference gradient of the potential energy;
//! - the reduced bias equals the brute-force Φᵀ (bias_full + M_full Φ̇ q̇), and M = Φᵀ M_full Φ;
//! - linear and angular momentum equal their definitions.

mod common;
use common::*;
use musculo::model::LoadOptions;
use musculo::spatial::{Vec3, rotation_vector};
use musculo::{Data, Model, dynamics};
use nalgebra::{DMatrix, DVector};
use std::path::Path;

const STATES: usize = 100;
const H: f64 = 1e-6;

fn load(path: &Path) -> Model {
    Model::from_osim_file_with(path, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

/// Largest relative error seen for each identity, for the summary line.
#[derive(Default)]
struct Worst {
    id: f64,
    gravity: f64,
    jac: f64,
    phi: f64,
    jdot: f64,
    ke: f64,
    pe: f64,
    bias_full: f64,
    momentum: f64,
}

fn rel(a: &DVector<f64>, b: &DVector<f64>) -> f64 {
    (a - b).norm() / b.norm().max(1.0)
}

fn check_model(path: &Path, seed: u64) {
    let model = load(path);
    let n = model.nq();
    let nb = model.bodies.len();
    let mut data = Data::new(&model);
    let mut d2 = Data::new(&model);
    let mut rng = Rng::new(seed);
    let mut w = Worst::default();
    let name = path.file_name().unwrap().to_string_lossy().to_string();
    for state in 0..STATES {
        let q = random_q(&model, &mut rng);
        let qd = random_vec(n, 2.0, &mut rng);
        let qdd = random_vec(n, 10.0, &mut rng);
        let ctx = |what: &str| format!("{name} state {state}: {what}");

        // M symmetric positive definite.
        let m = dynamics::crba(&model, &mut data, &q).unwrap().clone();
        let m_full = dynamics::crba_full(&model, &mut data).unwrap().clone();
        assert_eq!(m, m.transpose(), "{}", ctx("M symmetric"));
        assert!(
            m.clone().cholesky().is_some(),
            "{}",
            ctx("M positive definite")
        );

        // ID = M q̈ + bias; G = ID(q, 0, 0).
        let bias = dynamics::nonlinear_effects(&model, &mut data, &q, &qd)
            .unwrap()
            .clone();
        let tau = dynamics::rnea(&model, &mut data, &q, &qd, &qdd)
            .unwrap()
            .clone();
        let e = rel(&tau, &(&m * DVector::from_column_slice(&qdd) + &bias));
        assert!(e <= 1e-9, "{}", ctx(&format!("ID vs M q̈ + bias: {e:e}")));
        w.id = w.id.max(e);
        let zeros = vec![0.0; n];
        let id0 = dynamics::rnea(&model, &mut data, &q, &zeros, &zeros)
            .unwrap()
            .clone();
        let g = dynamics::gravity(&model, &mut data, &q).unwrap().clone();
        let e = rel(&g, &id0);
        assert!(e <= 1e-9, "{}", ctx(&format!("G vs ID(q,0,0): {e:e}")));
        w.gravity = w.gravity.max(e);
        let cor = dynamics::coriolis(&model, &mut data, &q, &qd)
            .unwrap()
            .clone();
        let e = rel(&(&cor + &g), &bias);
        assert!(e <= 1e-9, "{}", ctx(&format!("C q̇ + G vs bias: {e:e}")));

        // Brute force over the full coordinates: M = Φᵀ M_full Φ and
        // bias = Φᵀ (bias_full + M_full Φ̇ q̇).
        dynamics::forward_kinematics_velocity(&model, &mut data, &q, &qd).unwrap();
        let phi = data.phi_matrix(&model);
        let phidot_qd = DVector::from_column_slice(data.phi_dot_qd(&model));
        let theta = data.theta(&model).to_vec();
        let theta_dot = data.theta_dot(&model).to_vec();
        let e = (&m - phi.transpose() * &m_full * &phi).norm() / m.norm();
        assert!(e <= 1e-12, "{}", ctx(&format!("M vs Φᵀ M_full Φ: {e:e}")));
        let nf = model.n_full();
        let bias_full = DVector::from_column_slice(
            dynamics::rnea_full(&model, &mut d2, &theta, &theta_dot, &vec![0.0; nf]).unwrap(),
        );
        let brute = phi.transpose() * (bias_full + &m_full * &phidot_qd);
        let e = rel(&bias, &brute);
        assert!(
            e <= 1e-9,
            "{}",
            ctx(&format!("bias vs Φᵀ(bias_full + M_full Φ̇q̇): {e:e}"))
        );
        w.bias_full = w.bias_full.max(e);

        // Φ and Φ̇q̇ against finite differences of θ(q).
        let theta_at = |d: &mut Data, q: &[f64]| {
            dynamics::forward_kinematics(&model, d, q).unwrap();
            DVector::from_column_slice(d.theta(&model))
        };
        for j in 0..n {
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[j] += H;
            qm[j] -= H;
            let fd = (theta_at(&mut d2, &qp) - theta_at(&mut d2, &qm)) / (2.0 * H);
            let e = (fd - phi.column(j)).amax();
            assert!(
                e <= 1e-6,
                "{}",
                ctx(&format!("Φ column {j} vs finite differences: {e:e}"))
            );
            w.phi = w.phi.max(e);
        }
        let phi_at = |d: &mut Data, q: &[f64]| {
            dynamics::forward_kinematics(&model, d, q).unwrap();
            d.phi_matrix(&model)
        };
        let qdv = DVector::from_column_slice(&qd);
        let shift = |s: f64| -> Vec<f64> { q.iter().zip(&qd).map(|(a, b)| a + s * b).collect() };
        let fd = (phi_at(&mut d2, &shift(H)) - phi_at(&mut d2, &shift(-H))) / (2.0 * H) * &qdv;
        let e = (fd - &phidot_qd).amax();
        assert!(
            e <= 1e-6,
            "{}",
            ctx(&format!("Φ̇q̇ vs finite differences: {e:e}"))
        );
        w.phi = w.phi.max(e);

        // Body, point and COM Jacobians against finite differences of poses.
        let mut jb = DMatrix::zeros(6, n);
        let mut jp = DMatrix::zeros(3, n);
        let poses = |d: &mut Data, q: &[f64]| {
            dynamics::forward_kinematics(&model, d, q).unwrap();
            let p: Vec<_> = (0..nb).map(|b| d.body_pose(b)).collect();
            (p, dynamics::center_of_mass(&model, d).unwrap())
        };
        let mut fd_cols = Vec::with_capacity(n);
        for j in 0..n {
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[j] += H;
            qm[j] -= H;
            fd_cols.push((poses(&mut d2, &qp), poses(&mut d2, &qm)));
        }
        dynamics::forward_kinematics_velocity(&model, &mut data, &q, &qd).unwrap();
        for b in 1..nb {
            dynamics::body_jacobian(&model, &data, b, &mut jb).unwrap();
            let com = model.bodies[b].com_in_body;
            dynamics::point_jacobian(&model, &data, b, &com, &mut jp).unwrap();
            for (j, ((pp, _), (pm, _))) in fd_cols.iter().enumerate() {
                let (rp, op) = pp[b];
                let (rm, om) = pm[b];
                let omega = rotation_vector(&(rp * rm.transpose())) / (2.0 * H);
                let vel = (op - om) / (2.0 * H);
                let vc = ((rp * com + op) - (rm * com + om)) / (2.0 * H);
                for k in 0..3 {
                    let e = (jb[(k, j)] - omega[k])
                        .abs()
                        .max((jb[(3 + k, j)] - vel[k]).abs())
                        .max((jp[(k, j)] - vc[k]).abs());
                    assert!(
                        e <= 1e-6,
                        "{}",
                        ctx(&format!(
                            "Jacobian of body {} column {j}: {e:e}",
                            model.bodies[b].name
                        ))
                    );
                    w.jac = w.jac.max(e);
                }
            }
        }
        let mut jc = DMatrix::zeros(3, n);
        dynamics::center_of_mass_jacobian(&model, &mut data, &mut jc).unwrap();
        for (j, ((_, cp), (_, cm))) in fd_cols.iter().enumerate() {
            let e = ((cp - cm) / (2.0 * H) - jc.column(j)).amax();
            assert!(
                e <= 1e-6,
                "{}",
                ctx(&format!("COM Jacobian column {j}: {e:e}"))
            );
        }

        // J̇q̇ of a body-fixed point: d/dt (J q̇) with q̈ = 0, by central differences along q̇.
        let b = nb - 1;
        let p = Vec3::new(0.03, -0.05, 0.02);
        let jq = |d: &mut Data, q: &[f64]| {
            let mut j = DMatrix::zeros(3, n);
            dynamics::forward_kinematics(&model, d, q).unwrap();
            dynamics::point_jacobian(&model, d, b, &p, &mut j).unwrap();
            j * &qdv
        };
        let fd = (jq(&mut d2, &shift(H)) - jq(&mut d2, &shift(-H))) / (2.0 * H);
        let jdot = dynamics::point_jacobian_dot_qd(&model, &mut data, b, &p).unwrap();
        let e = (Vec3::new(fd[0], fd[1], fd[2]) - jdot).amax();
        assert!(
            e <= 1e-6,
            "{}",
            ctx(&format!("J̇q̇ vs finite differences: {e:e}"))
        );
        w.jdot = w.jdot.max(e);

        // Kinetic energy: ½ q̇ᵀ M q̇ = Σ_b ½ m |v_c|² + ½ ωᵀ R I Rᵀ ω.
        let ke_m = 0.5 * qdv.dot(&(&m * &qdv));
        let mut ke_b = 0.0;
        let mut lin = Vec3::zeros();
        let mut h_about_origin = Vec3::zeros();
        for (bi, body) in model.bodies.iter().enumerate().skip(1) {
            let (r, _) = data.body_pose(bi);
            let (omega, _) = data.body_velocity(bi);
            let vc = data.point_velocity(bi, &body.com_in_body);
            let c = data.point_position(bi, &body.com_in_body);
            let i_world = r * body.inertia_about_com * r.transpose();
            ke_b += 0.5 * body.mass * vc.norm_squared() + 0.5 * omega.dot(&(i_world * omega));
            lin += vc * body.mass;
            h_about_origin += c.cross(&(vc * body.mass)) + i_world * omega;
        }
        let e = (ke_m - ke_b).abs() / ke_b.max(1.0);
        assert!(
            e <= 1e-9,
            "{}",
            ctx(&format!(
                "½ q̇ᵀ M q̇ = {ke_m} vs Σ body kinetic energy {ke_b}"
            ))
        );
        w.ke = w.ke.max(e);
        let ke_lib = dynamics::kinetic_energy(&model, &data).unwrap();
        assert!(
            (ke_lib - ke_b).abs() <= 1e-9 * ke_b.max(1.0),
            "{}",
            ctx("kinetic_energy")
        );

        // Momentum.
        let mo = dynamics::momentum(&model, &data).unwrap();
        let e = (mo.linear - lin)
            .amax()
            .max((mo.angular_about_origin - h_about_origin).amax())
            / lin.norm().max(1.0);
        assert!(e <= 1e-9, "{}", ctx(&format!("momentum: {e:e}")));
        let com = dynamics::center_of_mass(&model, &data).unwrap();
        let h_com = h_about_origin - com.cross(&lin);
        assert!(
            (mo.angular_about_com - h_com).amax() <= 1e-9 * h_com.norm().max(1.0),
            "{}",
            ctx("angular momentum about the COM")
        );
        let lin_j = &jc * &qdv * model.total_mass();
        assert!(
            (Vec3::new(lin_j[0], lin_j[1], lin_j[2]) - lin).amax() <= 1e-9 * lin.norm().max(1.0),
            "{}",
            ctx("p = m J_com q̇")
        );
        w.momentum = w.momentum.max(e);

        // G = ∂V/∂q, V = −Σ m g·c, by central differences.
        let pe_at = |d: &mut Data, q: &[f64]| {
            dynamics::forward_kinematics(&model, d, q).unwrap();
            dynamics::potential_energy(&model, d).unwrap()
        };
        for j in 0..n {
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[j] += H;
            qm[j] -= H;
            let fd = (pe_at(&mut d2, &qp) - pe_at(&mut d2, &qm)) / (2.0 * H);
            let e = (fd - g[j]).abs() / g.amax().max(1.0);
            assert!(
                e <= 1e-6,
                "{}",
                ctx(&format!("G[{j}] = {} vs ∂V/∂q = {fd}", g[j]))
            );
            w.pe = w.pe.max(e);
        }
    }
    eprintln!(
        "{name}: n={n}, {STATES} states; worst relative errors: ID {:.1e}, G {:.1e}, reduced bias {:.1e}, KE {:.1e}, momentum {:.1e}; \
         worst finite-difference gaps: Jacobians {:.1e}, Φ/Φ̇q̇ {:.1e}, J̇q̇ {:.1e}, ∂V/∂q {:.1e}",
        w.id, w.gravity, w.bias_full, w.ke, w.momentum, w.jac, w.phi, w.jdot, w.pe
    );
}

fn check_reference(relative: &str, seed: u64) {
    if let Some(path) = reference_file(relative) {
        check_model(&path, seed);
    }
}

#[test]
fn identities_hold_on_arm26() {
    check_reference("opensim-models/Models/Arm26/arm26.osim", 11);
}

#[test]
fn identities_hold_on_gait10dof18musc() {
    check_reference(
        "opensim-models/Pipelines/Gait10dof18musc/OutputReference/gait10dof18musc.osim",
        12,
    );
}

#[test]
fn identities_hold_on_gait2392() {
    check_reference(
        "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        13,
    );
}

#[test]
fn identities_hold_on_rajagopal2016() {
    check_reference("opensim-models/Models/Rajagopal/Rajagopal2016.osim", 14);
}

#[test]
fn identities_hold_on_rajagopal_lai_uhlrich2023() {
    check_reference(
        "opensim-models/Models/Rajagopal/RajagopalLaiUhlrich2023.osim",
        15,
    );
}

#[test]
fn identities_hold_on_every_other_reference_model() {
    let named = [
        "arm26.osim",
        "gait10dof18musc.osim",
        "gait2392_thelen2003muscle.osim",
        "Rajagopal2016.osim",
        "RajagopalLaiUhlrich2023.osim",
    ];
    let all = reference_models();
    for (i, p) in all.iter().enumerate() {
        let file = p.file_name().unwrap().to_string_lossy();
        let is_named = named.contains(&file.as_ref()) && !p.to_string_lossy().contains("Tutorials");
        if !is_named {
            check_model(p, 100 + i as u64);
        }
    }
}

#[test]
fn identities_hold_on_the_demo_model() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/demo.osim");
    check_model(&path, 7);
}

#[test]
fn identities_hold_on_the_default_full_body_model() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/musculo_fullbody.osim");
    check_model(&path, 17);
}
