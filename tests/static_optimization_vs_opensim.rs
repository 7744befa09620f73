//! Static optimization against OpenSim's own StaticOptimization results, run from the same
//! setup files (model, force-set files, kinematics, external loads, cutoff, time range, step
//! interval, exponent, muscle physiology).
//!
//! Rows are compared one to one (same count, same times): per actuator the RMSE of the
//! activation and of the force over the trial is printed with the peak of OpenSim's values.
//! Requirements: Gait2392 walk, mean activation RMSE over muscles ≤ 0.03, none above 0.1, and
//! every muscle's force RMSE ≤ 5% of its peak force; Arm26, every activation RMSE ≤ 0.02.

mod common;
use common::*;
use musculo::Model;
use musculo::io::Table;
use musculo::io::setup::AnalyzeSetup;
use musculo::model::LoadOptions;
use musculo::solve::external_loads::ExternalLoadSet;
use musculo::solve::static_optimization::{
    SoRun, SoRunOptions, StaticOptimization, StaticOptimizationOptions, run_static_optimization,
};
use std::path::{Path, PathBuf};

struct Row {
    name: String,
    is_muscle: bool,
    peak_activation: f64,
    activation_rmse: f64,
    peak_force: f64,
    force_rmse: f64,
}

/// Runs the Analyze setup `setup_path` with `model_path` (the setup's model file is not in the
/// reference layout), `coordinates` (the same, when given) and, when given, another
/// `use_muscle_physiology` than the setup's.
fn run(
    setup_path: &Path,
    model_path: &Path,
    coordinates: Option<PathBuf>,
    strict: bool,
    use_muscle_physiology: Option<bool>,
    muscle_min_control: Option<f64>,
) -> (Model, StaticOptimization, SoRun) {
    let setup = AnalyzeSetup::read(setup_path).unwrap();
    let so_setup = setup
        .static_optimization
        .clone()
        .expect("a StaticOptimization analysis");
    let model = Model::from_osim_file_with_force_sets(
        model_path,
        &LoadOptions { strict },
        &setup.force_set_files,
        setup.replace_force_set,
    )
    .unwrap();
    let mut so = StaticOptimization::new(
        &model,
        StaticOptimizationOptions {
            activation_exponent: so_setup.activation_exponent,
            use_muscle_physiology: use_muscle_physiology.unwrap_or(so_setup.use_muscle_physiology),
            ..Default::default()
        },
    )
    .unwrap();
    if let Some(min) = muscle_min_control {
        for k in 0..so.actuators.len() {
            if so.actuators[k].muscle.is_some() {
                let max = so.actuators[k].max_control;
                so.set_control_bounds(k, min, max).unwrap();
            }
        }
    }
    let coordinates_path = coordinates.unwrap_or_else(|| setup.coordinates_file.clone().unwrap());
    let table = Table::read(&coordinates_path).unwrap();
    let loads = setup
        .external_loads_file
        .as_deref()
        .map(|p| ExternalLoadSet::read(&model, p).unwrap());
    let result = run_static_optimization(
        &model,
        &so,
        &table,
        &coordinates_path.display().to_string(),
        loads.as_ref(),
        &SoRunOptions {
            lowpass_hz: setup.lowpass_cutoff_hz,
            time_range: match (setup.initial_time, setup.final_time) {
                (Some(a), Some(b)) => Some([a, b]),
                _ => None,
            },
            step_interval: so_setup.step_interval,
        },
        &mut |_, _| {},
    )
    .unwrap();
    (model, so, result)
}

fn compare(
    so: &StaticOptimization,
    ours: &SoRun,
    activation_file: &Path,
    force_file: &Path,
) -> Vec<Row> {
    let ref_act = Table::read(activation_file).unwrap();
    let ref_force = Table::read(force_file).unwrap();
    assert_eq!(
        ours.activation.n_rows(),
        ref_act.n_rows(),
        "musculo computed {} rows, OpenSim {}",
        ours.activation.n_rows(),
        ref_act.n_rows()
    );
    for (r, (&a, &b)) in ours.activation.time.iter().zip(&ref_act.time).enumerate() {
        assert!((a - b).abs() < 1e-6, "row {r}: time {a} vs OpenSim's {b}");
    }
    let n = ref_act.n_rows() as f64;
    let mut rows = Vec::new();
    for (k, act) in so.actuators.iter().enumerate() {
        let ca = ref_act
            .column_index(&act.name)
            .unwrap_or_else(|| panic!("OpenSim's activations have no column {}", act.name));
        let cf = ref_force
            .column_index(&act.name)
            .unwrap_or_else(|| panic!("OpenSim's forces have no column {}", act.name));
        let fk = ours.force.column_index(&act.name).unwrap();
        let (mut ea, mut ef, mut pa, mut pf) = (0.0, 0.0, 0.0f64, 0.0f64);
        for r in 0..ref_act.n_rows() {
            let (a, a_ref) = (
                ours.activation.value(r, k).unwrap(),
                ref_act.value(r, ca).unwrap(),
            );
            let (f, f_ref) = (
                ours.force.value(r, fk).unwrap(),
                ref_force.value(r, cf).unwrap(),
            );
            ea += (a - a_ref).powi(2);
            ef += (f - f_ref).powi(2);
            pa = pa.max(a_ref.abs());
            pf = pf.max(f_ref.abs());
        }
        rows.push(Row {
            name: act.name.clone(),
            is_muscle: act.muscle.is_some(),
            peak_activation: pa,
            activation_rmse: (ea / n).sqrt(),
            peak_force: pf,
            force_rmse: (ef / n).sqrt(),
        });
    }
    rows
}

fn print(title: &str, run: &SoRun, rows: &[Row]) {
    eprintln!(
        "{title}: {} frames, {} QP iterations, {} frame(s) not solved exactly",
        run.activation.n_rows(),
        run.iterations,
        run.problems.len()
    );
    eprintln!(
        "  {:<16} {:>9} {:>9} {:>11} {:>10} {:>7}",
        "actuator", "peak a", "RMSE a", "peak F", "RMSE F", "% peak"
    );
    for r in rows {
        eprintln!(
            "  {:<16} {:>9.4} {:>9.4} {:>11.2} {:>10.3} {:>6.2}%",
            r.name,
            r.peak_activation,
            r.activation_rmse,
            r.peak_force,
            r.force_rmse,
            100.0 * r.force_rmse / r.peak_force.max(1e-12)
        );
    }
}

#[test]
fn static_optimization_matches_opensim_gait2392_walk() {
    let dir = "opensim-models/Tutorials/Estimating_Joint_Reaction_Loads";
    let out = format!("{dir}/OutputReference/ResultsStaticOptimization");
    let (Some(setup), Some(model), Some(activation), Some(force)) = (
        reference_file(&format!("{dir}/setup_static_optimization.xml")),
        reference_file(&format!("{dir}/subject01_simbody_adjusted_StaticOp.osim")),
        reference_file(&format!(
            "{out}/subject01_StaticOptimization_activation.sto"
        )),
        reference_file(&format!("{out}/subject01_StaticOptimization_force.sto")),
    ) else {
        return;
    };
    // The setup names subject01_simbody_adjusted.osim; the folder holds the model prepared
    // for this analysis under another name.
    eprintln!(
        "model: {} (the setup's model_file is not in the folder)",
        model.display()
    );
    let (_, so, result) = run(&setup, &model, None, false, None, None);
    let rows = compare(&so, &result, &activation, &force);
    print("gait2392 walk", &result, &rows);
    let muscles: Vec<&Row> = rows.iter().filter(|r| r.is_muscle).collect();
    let mean = muscles.iter().map(|r| r.activation_rmse).sum::<f64>() / muscles.len() as f64;
    let worst = muscles
        .iter()
        .max_by(|a, b| a.activation_rmse.total_cmp(&b.activation_rmse))
        .unwrap();
    eprintln!(
        "  muscles: mean activation RMSE {mean:.4}, worst {} {:.4}",
        worst.name, worst.activation_rmse
    );
    assert!(mean <= 0.03, "mean activation RMSE {mean}");
    assert!(
        worst.activation_rmse <= 0.1,
        "{}: activation RMSE {}",
        worst.name,
        worst.activation_rmse
    );
    for r in &muscles {
        assert!(
            r.force_rmse <= 0.05 * r.peak_force,
            "{}: force RMSE {:.3} N > 5% of peak {:.3} N",
            r.name,
            r.force_rmse,
            r.peak_force
        );
    }
}

#[test]
fn static_optimization_matches_opensim_arm26() {
    let dir = "opensim-models/Tutorials/Computed_Muscle_Control/OutputReference";
    let (Some(setup), Some(model), Some(kinematics)) = (
        reference_file(&format!(
            "{dir}/StaticOptimization/arm26_Setup_StaticOptimization.xml"
        )),
        reference_file("opensim-models/Models/Arm26/arm26.osim"),
        reference_file(&format!(
            "{dir}/InverseKinematics/arm26_InverseKinematics.mot"
        )),
    ) else {
        return;
    };
    let mut failures = Vec::new();
    for (variant, physiology) in [
        ("PhysiologicalResults", true),
        ("NonphysiologicalResults", false),
    ] {
        let (Some(activation), Some(force)) = (
            reference_file(&format!(
                "{dir}/StaticOptimization/{variant}/arm26_StaticOptimization_activation.sto"
            )),
            reference_file(&format!(
                "{dir}/StaticOptimization/{variant}/arm26_StaticOptimization_force.sto"
            )),
        ) else {
            return;
        };
        // One setup file serves both variants in the tutorial, with the flag switched.
        let (_, so, result) = run(
            &setup,
            &model,
            Some(kinematics.clone()),
            true,
            Some(physiology),
            Some(0.0),
        );
        let rows = compare(&so, &result, &activation, &force);
        print(&format!("arm26 {variant}"), &result, &rows);
        for r in &rows {
            if r.activation_rmse > 0.02 {
                failures.push(format!(
                    "{variant} {}: activation RMSE {}",
                    r.name, r.activation_rmse
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
