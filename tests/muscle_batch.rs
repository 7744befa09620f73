//! The per-frame batch API: all muscles' lengths, speeds, moment arms and forces in one call
//! agree with the muscles computed one by one, and bad arguments are errors.

mod common;
use common::*;
use musculo::muscle::hill::HillMuscle;
use musculo::muscle::{MuscleData, MuscleSet, TendonMode, compute_muscles};
use musculo::{Data, Model, dynamics};
use std::process::Command;

#[test]
fn batch_forces_equal_each_muscle_computed_alone() {
    let Some(p) =
        reference_file("opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim")
    else {
        return;
    };
    let model = Model::from_osim_file(&p).unwrap();
    let set = MuscleSet::new(&model).unwrap();
    assert_eq!(set.len(), 92);
    let mut data = Data::new(&model);
    let mut md = MuscleData::new(&model, &set);
    let mut rng = Rng::new(12);
    for _ in 0..10 {
        let q = random_q(&model, &mut rng);
        let qd = random_vec(model.nq(), 1.0, &mut rng);
        let a: Vec<f64> = (0..set.len()).map(|_| rng.uniform(0.01, 1.0)).collect();
        dynamics::forward_kinematics_velocity(&model, &mut data, &q, &qd).unwrap();
        for tendon in [TendonMode::AsModel, TendonMode::Rigid] {
            for parallel in [false, true] {
                compute_muscles(&model, &data, &set, &a, tendon, parallel, &mut md).unwrap();
                for (k, f) in model.forces.iter().filter(|f| f.is_muscle()).enumerate() {
                    let m = HillMuscle::from_force_element(f).unwrap();
                    let (l, v) = (md.paths.length[k], md.paths.speed[k]);
                    let alone = match tendon {
                        TendonMode::AsModel => m.state(a[k], l, v),
                        TendonMode::Rigid => m.state_rigid_tendon(a[k], l, v),
                    };
                    assert_eq!(md.force[k], alone.tendon_force, "{} ({tendon:?})", m.name());
                    // ℓ̇ = −rᵀ q̇ column by column.
                    let speed: f64 = -(0..model.nq())
                        .map(|j| md.paths.moment_arms[(j, k)] * qd[j])
                        .sum::<f64>();
                    assert!((speed - v).abs() <= 1e-15 * (1.0 + v.abs()));
                }
            }
        }
    }
}

#[test]
fn bad_activations_and_foreign_workspaces_are_errors() {
    let model = Model::demo();
    let set = MuscleSet::new(&model).unwrap();
    let mut data = Data::new(&model);
    let mut md = MuscleData::new(&model, &set);
    dynamics::forward_kinematics(&model, &mut data, &model.default_q()).unwrap();
    assert!(compute_muscles(&model, &data, &set, &[], TendonMode::Rigid, false, &mut md).is_err());
    assert!(
        compute_muscles(
            &model,
            &data,
            &set,
            &[f64::NAN],
            TendonMode::Rigid,
            false,
            &mut md
        )
        .is_err()
    );
    let fresh = Data::new(&model);
    assert!(
        compute_muscles(
            &model,
            &fresh,
            &set,
            &[0.5],
            TendonMode::Rigid,
            false,
            &mut md
        )
        .is_err(),
        "needs forward kinematics first"
    );
}

#[test]
fn muscles_command_writes_lengths_and_moment_arm_files() {
    let (Some(model), Some(motion)) = (
        reference_file("opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim"),
        reference_file("opensim-models/Pipelines/Gait2392_Simbody/subject01_walk1_ik.mot"),
    ) else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("musculo-muscles-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let prefix = dir.join("walk");
    let out = Command::new(env!("CARGO_BIN_EXE_musculo"))
        .args([
            "muscles",
            model.to_str().unwrap(),
            "--coords",
            motion.to_str().unwrap(),
            "-o",
            prefix.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lengths = musculo::io::Table::read(&dir.join("walk_Length.sto")).unwrap();
    assert_eq!(lengths.labels.len(), 92);
    let knee = musculo::io::Table::read(&dir.join("walk_MomentArm_knee_angle_r.sto")).unwrap();
    let semiten = knee.column("semiten_r").unwrap();
    assert!(
        semiten.iter().all(|&r| r < 0.0),
        "a hamstring flexes the knee (negative about knee_angle_r)"
    );
    let vas = knee.column("vas_int_r").unwrap();
    assert!(vas.iter().all(|&r| r > 0.0), "a vastus extends it");
    assert!(
        dir.join("walk_MaxIsometricMoment_knee_angle_r.sto")
            .exists()
    );
    // Lengths follow the motion's rows.
    let motion_rows = musculo::io::Table::read(&motion).unwrap().n_rows();
    assert_eq!(lengths.n_rows(), motion_rows);
    let _ = std::fs::remove_dir_all(&dir);
}
