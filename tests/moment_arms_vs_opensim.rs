//! Moment arms against OpenSim's own results. OpenSim's static optimization balances, at
//! every frame, the generalized forces of the muscles (plus reserve and residual actuators)
//! against inverse dynamics of the same kinematics with the measured ground-reaction forces.
//! With OpenSim's solution forces F_k and musculo's moment arms r_jk and inverse dynamics τ_j,
//!   Σ_k r_jk F_k + reserve_j = τ_j
//! must therefore hold on every coordinate a muscle crosses: RMSE ≤ 2% of the coordinate's
//! peak |τ|.
//!
//! Kinematics are prepared as OpenSim's Analyze tool does for static optimization (quintic
//! natural splines, q̈ from the spline of the speeds); the external forces are the values the
//! force file records for each frame (OpenSim records the force in ground and the point in
//! the frame of the body it is applied to).

mod common;
use common::*;
use musculo::io::Table;
use musculo::model::LoadOptions;
use musculo::muscle::path::{PathData, PathSet, compute_paths};
use musculo::solve::kinematics::{CoordinateTrajectory, Differentiation, KinematicsOptions};
use musculo::spatial::Vec3;
use musculo::{Data, Model, dynamics};

struct Row {
    coordinate: String,
    peak: f64,
    rmse: f64,
}

fn check(rows: &[Row], limit: f64) {
    eprintln!(
        "  {:<22} {:>10} {:>10} {:>8}",
        "coordinate", "peak |τ|", "RMSE", "% peak"
    );
    for r in rows {
        eprintln!(
            "  {:<22} {:>10.3} {:>10.4} {:>7.2}%",
            r.coordinate,
            r.peak,
            r.rmse,
            100.0 * r.rmse / r.peak
        );
    }
    for r in rows {
        assert!(
            r.rmse <= limit * r.peak,
            "{}: RMSE {:.4} > {:.0}% of peak {:.3}",
            r.coordinate,
            r.rmse,
            100.0 * limit,
            r.peak
        );
    }
}

#[test]
fn muscle_moments_balance_inverse_dynamics_with_opensim_so_forces_gait2392() {
    let dir = "opensim-models/Tutorials/Estimating_Joint_Reaction_Loads";
    let (Some(model_file), Some(kin_file), Some(force_file)) = (
        reference_file(&format!("{dir}/subject01_simbody_adjusted_StaticOp.osim")),
        reference_file(&format!("{dir}/subject01_walk1_Kinematics.sto")),
        reference_file(&format!(
            "{dir}/OutputReference/ResultsStaticOptimization/subject01_StaticOptimization_force.sto"
        )),
    ) else {
        return;
    };
    let model = Model::from_osim_file_with(&model_file, &LoadOptions::default()).unwrap();
    let kinematics = Table::read(&kin_file).unwrap();
    let forces = Table::read(&force_file).unwrap();
    let traj = CoordinateTrajectory::from_table(
        &model,
        &kinematics,
        &kin_file.display().to_string(),
        &KinematicsOptions {
            lowpass_hz: None,
            differentiation: Differentiation::SplineOfSpeeds,
        },
    )
    .unwrap();
    let set = PathSet::new(&model).unwrap();
    let n = model.nq();
    let mut data = Data::new(&model);
    let mut pd = PathData::new(&model, &set);
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let col = |label: &str| {
        forces
            .column_index(label)
            .unwrap_or_else(|| panic!("no column {label}"))
    };
    let muscle_cols: Vec<usize> = set.paths.iter().map(|p| col(&p.name)).collect();
    let feet = [
        ("calcn_r", "calcn_r_right_foot_"),
        ("calcn_l", "calcn_l_left_foot_"),
    ];
    // Which coordinates a muscle crosses: a non-zero moment arm somewhere.
    let mut crossed = vec![false; n];
    let mut err2 = vec![0.0; n];
    let mut peak = vec![0.0f64; n];
    for r in 0..forces.n_rows() {
        let t = forces.time[r];
        traj.eval(t, &mut q, &mut qd, &mut qdd);
        let mut tau = dynamics::rnea(&model, &mut data, &q, &qd, &qdd)
            .unwrap()
            .as_slice()
            .to_vec();
        let mut external = vec![0.0; n];
        for (body, prefix) in feet {
            let v = |s: &str| forces.value(r, col(&format!("{prefix}{s}"))).unwrap();
            let f = Vec3::new(v("Fx"), v("Fy"), v("Fz"));
            let b = model.body_index(body).unwrap();
            let p = data.point_position(b, &Vec3::new(v("px"), v("py"), v("pz")));
            let m = Vec3::new(v("Tx"), v("Ty"), v("Tz"));
            dynamics::add_body_wrench(&model, &data, b, &p, &f, &m, &mut external).unwrap();
        }
        for j in 0..n {
            tau[j] -= external[j];
        }
        compute_paths(&model, &data, &set, &mut pd).unwrap();
        for j in 0..n {
            let mut moment = 0.0;
            for (k, &c) in muscle_cols.iter().enumerate() {
                let rjk = pd.moment_arms[(j, k)];
                if rjk.abs() > 1e-9 {
                    crossed[j] = true;
                }
                moment += rjk * forces.value(r, c).unwrap();
            }
            err2[j] += (moment - tau[j]).powi(2);
            peak[j] = peak[j].max(tau[j].abs());
        }
    }
    let names = model.q_names();
    let rows: Vec<Row> = (0..n)
        .filter(|&j| crossed[j])
        .map(|j| Row {
            coordinate: names[j].to_string(),
            peak: peak[j],
            rmse: (err2[j] / forces.n_rows() as f64).sqrt(),
        })
        .collect();
    eprintln!(
        "gait2392 walk, {} frames: Σ r F (musculo r, OpenSim SO forces) vs musculo inverse dynamics",
        forces.n_rows()
    );
    check(&rows, 0.02);
}

#[test]
fn muscle_moments_balance_inverse_dynamics_with_opensim_so_forces_arm26() {
    // Arm26 static optimization (OpenSim's tutorial, physiological and non-physiological):
    // kinematics from its IK, low-pass filtered at 6 Hz as the setup file says; no external
    // loads and no reserve actuators, so the six muscles carry both coordinates' moments.
    let dir = "opensim-models/Tutorials/Computed_Muscle_Control/OutputReference";
    let (Some(model_file), Some(kin_file)) = (
        reference_file("opensim-models/Models/Arm26/arm26.osim"),
        reference_file(&format!(
            "{dir}/InverseKinematics/arm26_InverseKinematics.mot"
        )),
    ) else {
        return;
    };
    let model = Model::from_osim_file(&model_file).unwrap();
    let kinematics = Table::read(&kin_file).unwrap();
    let traj = CoordinateTrajectory::from_table(
        &model,
        &kinematics,
        &kin_file.display().to_string(),
        &KinematicsOptions {
            lowpass_hz: Some(6.0),
            differentiation: Differentiation::SplineOfSpeeds,
        },
    )
    .unwrap();
    let set = PathSet::new(&model).unwrap();
    for variant in ["PhysiologicalResults", "NonphysiologicalResults"] {
        let Some(force_file) = reference_file(&format!(
            "{dir}/StaticOptimization/{variant}/arm26_StaticOptimization_force.sto"
        )) else {
            return;
        };
        let forces = Table::read(&force_file).unwrap();
        let n = model.nq();
        let mut data = Data::new(&model);
        let mut pd = PathData::new(&model, &set);
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let cols: Vec<usize> = set
            .paths
            .iter()
            .map(|p| forces.column_index(&p.name).unwrap())
            .collect();
        let mut err2 = vec![0.0; n];
        let mut peak = vec![0.0f64; n];
        for r in 0..forces.n_rows() {
            traj.eval(forces.time[r], &mut q, &mut qd, &mut qdd);
            let tau = dynamics::rnea(&model, &mut data, &q, &qd, &qdd)
                .unwrap()
                .as_slice()
                .to_vec();
            compute_paths(&model, &data, &set, &mut pd).unwrap();
            for j in 0..n {
                let moment: f64 = cols
                    .iter()
                    .enumerate()
                    .map(|(k, &c)| pd.moment_arms[(j, k)] * forces.value(r, c).unwrap())
                    .sum();
                err2[j] += (moment - tau[j]).powi(2);
                peak[j] = peak[j].max(tau[j].abs());
            }
        }
        let names = model.q_names();
        let rows: Vec<Row> = (0..n)
            .map(|j| Row {
                coordinate: names[j].to_string(),
                peak: peak[j],
                rmse: (err2[j] / forces.n_rows() as f64).sqrt(),
            })
            .collect();
        eprintln!("arm26 {variant}, {} frames:", forces.n_rows());
        check(&rows, 0.02);
    }
}
