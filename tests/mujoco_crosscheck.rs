//! musculo against MuJoCo, in the same process (cargo feature `mujoco`): each model is
//! exported to MJCF (one MuJoCo joint per full coordinate) and, at 200 random states within
//! the coordinate ranges, MuJoCo's M_full, bias (qfrc_bias = C θ̇ + G), body poses and body
//! Jacobians must equal musculo's full-coordinate values to 1e-9 relative; musculo's reduced
//! M and bias must equal Φᵀ M_mj Φ and Φᵀ (bias_mj + M_mj Φ̇ q̇).
#![cfg(feature = "mujoco")]

mod common;
use common::*;
use musculo::model::LoadOptions;
use musculo::mujoco::MujocoTwin;
use musculo::{Data, Model, dynamics};
use nalgebra::{DMatrix, DVector};
use std::path::Path;

const STATES: usize = 200;
const TOL: f64 = 1e-9;

fn crosscheck(path: &Path, seed: u64) {
    let model = Model::from_osim_file_with(path, &LoadOptions::default()).unwrap();
    let name = path.file_name().unwrap().to_string_lossy().to_string();
    let mut twin = MujocoTwin::new(&model).unwrap_or_else(|e| panic!("{name}: {e}"));
    let (n, nf, nb) = (model.nq(), model.n_full(), model.bodies.len());
    let mut data = Data::new(&model);
    let mut rng = Rng::new(seed);
    let mut m_mj = DMatrix::zeros(nf, nf);
    let mut b_mj = vec![0.0; nf];
    let mut j_mj = DMatrix::zeros(6, nf);
    let mut j_us = DMatrix::zeros(6, nf);
    let mut worst = [0.0f64; 6];
    for state in 0..STATES {
        let q = random_q(&model, &mut rng);
        let qd = random_vec(n, 2.0, &mut rng);
        let ctx =
            |what: &str, e: f64| format!("{name} state {state}: {what}: relative difference {e:e}");

        // Full coordinates, their rates and Φ, Φ̇q̇ from musculo.
        dynamics::forward_kinematics_velocity(&model, &mut data, &q, &qd).unwrap();
        let theta = data.theta(&model).to_vec();
        let theta_dot = data.theta_dot(&model).to_vec();
        let phi = data.phi_matrix(&model);
        let phidot_qd = DVector::from_column_slice(data.phi_dot_qd(&model));

        // Mass matrix.
        twin.mass_matrix(&theta, &mut m_mj);
        dynamics::forward_kinematics(&model, &mut data, &q).unwrap();
        let m_full = dynamics::crba_full(&model, &mut data).unwrap().clone();
        let e = (&m_full - &m_mj).amax() / m_mj.amax();
        assert!(e <= TOL, "{}", ctx("M_full vs MuJoCo", e));
        worst[0] = worst[0].max(e);

        // Body poses and Jacobians (MuJoCo's kinematics ran with the mass matrix).
        for b in 1..nb {
            let (r_mj, p_mj) = twin.body_pose(b);
            let (r, p) = data.body_pose(b);
            let e = (r - r_mj)
                .amax()
                .max((p - p_mj).amax() / p_mj.norm().max(1.0));
            assert!(
                e <= TOL,
                "{}",
                ctx(&format!("pose of {}", model.bodies[b].name), e)
            );
            worst[1] = worst[1].max(e);
            twin.body_jacobian(b, &mut j_mj);
            dynamics::body_jacobian_full(&model, &data, b, &mut j_us).unwrap();
            let e = (&j_us - &j_mj).amax() / j_mj.amax().max(1.0);
            assert!(
                e <= TOL,
                "{}",
                ctx(&format!("Jacobian of {}", model.bodies[b].name), e)
            );
            worst[2] = worst[2].max(e);
        }

        // Bias forces.
        twin.bias(&theta, &theta_dot, &mut b_mj);
        let zeros = vec![0.0; nf];
        let b_full = DVector::from_column_slice(
            dynamics::rnea_full(&model, &mut data, &theta, &theta_dot, &zeros).unwrap(),
        );
        let b_mj_v = DVector::from_column_slice(&b_mj);
        let e = (&b_full - &b_mj_v).amax() / b_mj_v.amax().max(1.0);
        assert!(e <= TOL, "{}", ctx("bias_full vs MuJoCo qfrc_bias", e));
        worst[3] = worst[3].max(e);

        // Reduced quantities against MuJoCo's full ones.
        let m = dynamics::crba(&model, &mut data, &q).unwrap().clone();
        let m_red = phi.transpose() * &m_mj * &phi;
        let e = (&m - &m_red).amax() / m_red.amax();
        assert!(e <= TOL, "{}", ctx("M vs Φᵀ M_mj Φ", e));
        worst[4] = worst[4].max(e);
        let bias = dynamics::nonlinear_effects(&model, &mut data, &q, &qd)
            .unwrap()
            .clone();
        let b_red = phi.transpose() * (&b_mj_v + &m_mj * &phidot_qd);
        let e = (&bias - &b_red).amax() / b_red.amax().max(1.0);
        assert!(e <= TOL, "{}", ctx("bias vs Φᵀ(bias_mj + M_mj Φ̇q̇)", e));
        worst[5] = worst[5].max(e);
    }
    eprintln!(
        "{name}: {STATES} states, n = {n}, n_full = {nf}; worst relative differences to MuJoCo {}: \
         M_full {:.1e}, poses {:.1e}, Jacobians {:.1e}, bias_full {:.1e}, reduced M {:.1e}, reduced bias {:.1e}",
        musculo::mujoco::linked_version(),
        worst[0],
        worst[1],
        worst[2],
        worst[3],
        worst[4],
        worst[5]
    );
}

fn check(relative: &str, seed: u64) {
    if let Some(p) = reference_file(relative) {
        crosscheck(&p, seed);
    }
}

#[test]
fn arm26_matches_mujoco() {
    check("opensim-models/Models/Arm26/arm26.osim", 21);
}

#[test]
fn gait10dof18musc_matches_mujoco() {
    check(
        "opensim-models/Pipelines/Gait10dof18musc/OutputReference/gait10dof18musc.osim",
        22,
    );
}

#[test]
fn gait2392_matches_mujoco() {
    check(
        "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        23,
    );
}

#[test]
fn rajagopal2016_matches_mujoco() {
    check("opensim-models/Models/Rajagopal/Rajagopal2016.osim", 24);
}

#[test]
fn demo_model_matches_mujoco() {
    crosscheck(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("models/demo.osim"),
        25,
    );
}

#[test]
fn every_reference_model_loads_into_mujoco() {
    for p in reference_models() {
        let model = Model::from_osim_file_with(&p, &LoadOptions::default()).unwrap();
        if let Err(e) = MujocoTwin::new(&model) {
            panic!("{}: {e}", p.display());
        }
    }
}

#[test]
fn exported_models_simulate_in_mujoco_with_their_couplings_held() {
    // What a user sees opening the file in MuJoCo's viewer: from the exported default pose
    // (keyframe 0) the model simulates for half a second without blowing up (muscles on: their
    // passive forces move it), and, with actuation off so it falls rigidly, the joint
    // equalities keep each coupled axis on its polynomial (the knee translations follow the
    // knee angle).
    use mujoco_rs::mujoco_c as c;
    use mujoco_rs::wrappers::{MjData, MjModel};
    for rel in [
        "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
    ] {
        let Some(p) = reference_file(rel) else { return };
        let model = Model::from_osim_file(&p).unwrap();
        let xml = musculo::mjcf::to_mjcf(&model).xml;
        for actuation in [true, false] {
            let mut mj = MjModel::from_xml_string(&xml).unwrap();
            if !actuation {
                unsafe {
                    mj.ffi_mut().opt.disableflags |= c::mjtDisableBit::mjDSBL_ACTUATION as i32
                };
            }
            let mut d = MjData::new(&mj);
            unsafe { c::mj_resetDataKeyframe(mj.ffi(), d.ffi_mut(), 0) };
            for _ in 0..250 {
                d.step();
            }
            let qpos: Vec<f64> =
                unsafe { std::slice::from_raw_parts(d.ffi().qpos, model.n_full()) }.to_vec();
            assert!(
                qpos.iter().all(|v| v.is_finite()),
                "{rel}: non-finite state"
            );
            if actuation {
                continue;
            }
            let adr = |n: &str| {
                let name = std::ffi::CString::new(n).unwrap();
                let id = unsafe {
                    c::mj_name2id(mj.ffi(), c::mjtObj::mjOBJ_JOINT as i32, name.as_ptr())
                };
                unsafe { *mj.ffi().jnt_qposadr.add(id as usize) as usize }
            };
            let knee = model
                .dofs
                .iter()
                .find(|d| d.name.ends_with("knee_r/rotation1"))
                .unwrap();
            let angle = qpos[adr(&knee.name)];
            for axis in ["translation1", "translation2"] {
                let tx = model
                    .dofs
                    .iter()
                    .find(|d| d.name.ends_with(&format!("knee_r/{axis}")))
                    .unwrap();
                let (spline, _, _) = tx.function.eval1(angle);
                let got = qpos[adr(&tx.name)];
                assert!(
                    (got - spline).abs() < 2e-4,
                    "{rel}: knee {axis} {got} vs spline {spline} at angle {angle}"
                );
            }
        }
    }
}

/// Tendon lengths and moment arms of the muscles whose paths have only fixed points and no
/// wrap objects: MuJoCo's spatial tendons through the exported sites compute the same ℓ, and
/// MuJoCo's ten_J (∂ℓ/∂θ) reduced by Φ gives the moment arms r = −Φᵀ ∂ℓ/∂θ.
fn tendon_crosscheck(path: &Path, seed: u64) {
    use musculo::model::PathPointKind;
    use musculo::muscle::path::{PathData, PathSet, compute_paths};
    let model = Model::from_osim_file_with(path, &LoadOptions::default()).unwrap();
    let name = path.file_name().unwrap().to_string_lossy().to_string();
    let mut twin = MujocoTwin::new(&model).unwrap();
    let set = PathSet::new(&model).unwrap();
    let simple: Vec<(usize, usize)> = set
        .paths
        .iter()
        .enumerate()
        .filter(|(_, p)| {
            let gp = model.forces[p.force].path.as_ref().unwrap();
            gp.wraps.is_empty()
                && gp
                    .points
                    .iter()
                    .all(|pt| matches!(pt.kind, PathPointKind::Fixed))
        })
        .map(|(k, p)| (k, twin.tendon_index(&p.name).unwrap()))
        .collect();
    assert!(
        !simple.is_empty(),
        "{name}: no muscle with fixed points only"
    );
    let (n, nf) = (model.nq(), model.n_full());
    let mut data = Data::new(&model);
    let mut pd = PathData::new(&model, &set);
    let mut lengths = vec![0.0; twin.tendon_count()];
    let mut jac = DMatrix::zeros(twin.tendon_count(), nf);
    let mut rng = Rng::new(seed);
    let (mut worst_l, mut worst_r) = (0.0f64, 0.0f64);
    for _ in 0..STATES {
        let q = random_q(&model, &mut rng);
        dynamics::forward_kinematics(&model, &mut data, &q).unwrap();
        compute_paths(&model, &data, &set, &mut pd).unwrap();
        let phi = data.phi_matrix(&model);
        twin.tendons(data.theta(&model), &mut lengths, &mut jac);
        for &(k, t) in &simple {
            let e = (pd.length[k] - lengths[t]).abs() / lengths[t];
            assert!(
                e <= TOL,
                "{name}: length of {}: {} vs MuJoCo {}",
                set.paths[k].name,
                pd.length[k],
                lengths[t]
            );
            worst_l = worst_l.max(e);
            let r_mj = -(jac.row(t) * &phi);
            for j in 0..n {
                let e = (pd.moment_arms[(j, k)] - r_mj[j]).abs() / r_mj.amax().max(1e-3);
                assert!(
                    e <= TOL,
                    "{name}: moment arm of {} about {}: {} vs MuJoCo {}",
                    set.paths[k].name,
                    model.q_names()[j],
                    pd.moment_arms[(j, k)],
                    r_mj[j]
                );
                worst_r = worst_r.max(e);
            }
        }
    }
    eprintln!(
        "{name}: {} fixed-point muscles, {STATES} states: worst relative differences to MuJoCo ten_length {worst_l:.1e}, moment arms {worst_r:.1e}",
        simple.len()
    );
}

#[test]
fn fixed_point_muscle_lengths_and_moment_arms_match_mujoco_tendons() {
    for (rel, seed) in [
        (
            "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
            31,
        ),
        (
            "opensim-models/Pipelines/Gait10dof18musc/OutputReference/gait10dof18musc.osim",
            32,
        ),
        ("opensim-models/Models/Rajagopal/Rajagopal2016.osim", 33),
    ] {
        if let Some(p) = reference_file(rel) {
            tendon_crosscheck(&p, seed);
        }
    }
}

#[test]
fn default_full_body_model_matches_mujoco() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/musculo_fullbody.osim");
    crosscheck(&path, 27);
    // its fixed-point muscles (the 210 lumbar fascicles among them) against MuJoCo's tendons
    tendon_crosscheck(&path, 34);
}
