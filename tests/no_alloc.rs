//! No algorithm allocates once its `Data` exists: every per-frame call is counted by a
//! global allocator that records allocations made on the calling thread.

mod common;
#[path = "common/counting_alloc.rs"]
mod counting_alloc;
use common::*;
use counting_alloc::allocations_during;
use musculo::muscle::path::compute_paths;
use musculo::muscle::{MuscleData, MuscleSet, TendonMode, compute_muscles};
use musculo::spatial::Vec3;
use musculo::{Data, Model, dynamics};
use nalgebra::DMatrix;

fn check(model: &Model) {
    let n = model.nq();
    let mut rng = Rng::new(5);
    let q = random_q(model, &mut rng);
    let qd = random_vec(n, 1.0, &mut rng);
    let qdd = random_vec(n, 1.0, &mut rng);
    let theta_dd = vec![0.1; model.n_full()];
    let mut data = Data::new(model);
    let mut j3 = DMatrix::zeros(3, n);
    let mut j6 = DMatrix::zeros(6, n);
    let points = [
        (1usize, Vec3::new(0.1, 0.0, 0.0)),
        (model.bodies.len() - 1, Vec3::zeros()),
    ];
    let mut jc = DMatrix::zeros(6, n);
    let mut jdot = [0.0; 6];
    let mut markers = vec![Vec3::zeros(); model.markers.len()];
    let muscles = MuscleSet::new(model).unwrap();
    let mut md = MuscleData::new(model, &muscles);
    let activation = vec![0.4; muscles.len()];
    let (theta, theta_d) = {
        dynamics::forward_kinematics_velocity(model, &mut data, &q, &qd).unwrap();
        (data.theta(model).to_vec(), data.theta_dot(model).to_vec())
    };
    // The inertia matrices are allocated by their first computation (a workspace for inverse
    // dynamics alone holds no n × n matrix); every later call allocates nothing.
    dynamics::crba(model, &mut data, &q).unwrap();
    dynamics::crba_full(model, &mut data).unwrap();
    let count = allocations_during(|| {
        for _ in 0..3 {
            dynamics::forward_kinematics(model, &mut data, &q).unwrap();
            dynamics::forward_kinematics_velocity(model, &mut data, &q, &qd).unwrap();
            dynamics::forward_kinematics_acceleration(model, &mut data, &q, &qd, &qdd).unwrap();
            dynamics::crba(model, &mut data, &q).unwrap();
            dynamics::rnea(model, &mut data, &q, &qd, &qdd).unwrap();
            dynamics::nonlinear_effects(model, &mut data, &q, &qd).unwrap();
            dynamics::coriolis(model, &mut data, &q, &qd).unwrap();
            dynamics::gravity(model, &mut data, &q).unwrap();
            dynamics::forward_kinematics_velocity(model, &mut data, &q, &qd).unwrap();
            for b in 1..model.bodies.len() {
                dynamics::body_jacobian(model, &data, b, &mut j6).unwrap();
                dynamics::point_jacobian(model, &data, b, &Vec3::new(0.01, 0.02, 0.03), &mut j3)
                    .unwrap();
                dynamics::point_jacobian_dot_qd(model, &mut data, b, &Vec3::zeros()).unwrap();
                dynamics::body_jacobian_dot_qd(model, &mut data, b).unwrap();
            }
            dynamics::contact_jacobian(model, &data, &points, &mut jc).unwrap();
            dynamics::contact_jacobian_dot_qd(model, &mut data, &points, &mut jdot).unwrap();
            dynamics::center_of_mass(model, &data).unwrap();
            dynamics::center_of_mass_jacobian(model, &mut data, &mut j3).unwrap();
            dynamics::kinetic_energy(model, &data).unwrap();
            dynamics::potential_energy(model, &data).unwrap();
            dynamics::momentum(model, &data).unwrap();
            data.marker_positions(model, &mut markers).unwrap();
            dynamics::rnea_full(model, &mut data, &theta, &theta_d, &theta_dd).unwrap();
            dynamics::crba_full(model, &mut data).unwrap();
            dynamics::forward_kinematics_velocity(model, &mut data, &q, &qd).unwrap();
            compute_paths(model, &data, &muscles.paths, &mut md.paths).unwrap();
            compute_muscles(
                model,
                &data,
                &muscles,
                &activation,
                TendonMode::AsModel,
                false,
                &mut md,
            )
            .unwrap();
            compute_muscles(
                model,
                &data,
                &muscles,
                &activation,
                TendonMode::Rigid,
                false,
                &mut md,
            )
            .unwrap();
        }
    });
    assert_eq!(
        count, 0,
        "{}: {count} allocations in per-frame calls",
        model.name
    );
}

#[test]
fn per_frame_algorithms_do_not_allocate() {
    check(&Model::demo());
    for rel in [
        "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
        "opensim-models/Models/Arm26/arm26.osim",
    ] {
        if let Some(p) = reference_file(rel) {
            check(&Model::from_osim_file(p).unwrap());
        }
    }
}

#[test]
fn static_optimization_frames_do_not_allocate() {
    use musculo::model::LoadOptions;
    use musculo::solve::static_optimization::{SoFrame, SoWorkspace, StaticOptimization};
    let dir = "opensim-models/Tutorials/Estimating_Joint_Reaction_Loads";
    let (Some(model), Some(reserves)) = (
        reference_file(&format!("{dir}/subject01_simbody_adjusted_StaticOp.osim")),
        reference_file(&format!("{dir}/gait2392_SO_weak_Residual_Actuators.xml")),
    ) else {
        return;
    };
    let model =
        Model::from_osim_file_with_force_sets(model, &LoadOptions::default(), &[reserves], false)
            .unwrap();
    let so = StaticOptimization::new(&model, Default::default()).unwrap();
    let n = model.nq();
    let mut rng = Rng::new(9);
    let mut data = Data::new(&model);
    let mut ws = SoWorkspace::new(&model, &so);
    let mut frame = SoFrame::new(&so, &model);
    let states: Vec<_> = (0..5)
        .map(|_| {
            let q = random_q(&model, &mut rng);
            let qd = random_vec(n, 0.5, &mut rng);
            let tau = random_vec(n, 20.0, &mut rng);
            (q, qd, tau)
        })
        .collect();
    // Warm up once (first solve), then count.
    dynamics::forward_kinematics_velocity(&model, &mut data, &states[0].0, &states[0].1).unwrap();
    so.solve_frame(&model, &data, &states[0].2, &mut ws, &mut frame)
        .unwrap();
    let count = allocations_during(|| {
        for (q, qd, tau) in &states {
            dynamics::forward_kinematics_velocity(&model, &mut data, q, qd).unwrap();
            so.solve_frame(&model, &data, tau, &mut ws, &mut frame)
                .unwrap();
        }
    });
    assert_eq!(
        count, 0,
        "{count} allocations in static-optimization frames"
    );
}
