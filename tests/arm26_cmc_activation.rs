//! Thelen 2003 activation dynamics driven by the excitations OpenSim's Computed Muscle
//! Control found for the Arm26 tutorial must reproduce the activations CMC recorded.
//!
//! **Interpolation.** CMC writes its controls as `ControlLinear` curves with `use_steps`
//! true (`Results/arm26_controls.xml`): the value at node t_{i+1} applies on
//! (t_i, t_{i+1}], one node per 0.01 s CMC window. `arm26_controls.sto` samples those steps
//! at the integrator's steps, which include every window boundary (where it records the
//! ending window's value), so holding each sample over the interval that ends at it
//! (`Interpolation::HoldNext`) rebuilds the excitation CMC integrated. `arm26_states.sto`
//! holds the activations on the same time grid; the integration starts from its first row.
//!
//! **Which Thelen.** These reference results were written by OpenSim 2 (`arm26_controls.xml`
//! is `OpenSimDocument Version="20302"`), whose `Thelen2003Muscle` — today's
//! `Thelen2003Muscle_Deprecated` — has constant time constants. Fitting the recorded
//! activations inside each window gives exactly τ = 0.010 s rising and 0.040 s falling,
//! with no (0.5 + 1.5 a) factor. So the check is made twice: with OpenSim 4's
//! `Thelen2003Muscle` form (`ActivationDynamics::Thelen2003`, the model file's class; RMSE
//! ≤ 0.005 required, about 1e-3 found: the difference between the two forms) and with the
//! form that produced the data (`Thelen2003Deprecated`, RMSE ≤ 2e-4 required, under 1e-4
//! found). What remains comes from the first integrator step of each window, whose first
//! stage OpenSim evaluated exactly at the node time, where `ControlLinear` still returns the
//! previous window's value (the fitted τ is off only on those steps, in the direction the
//! control change predicts); that is an artefact of OpenSim's integrator, not of the
//! dynamics. Linear interpolation of the same samples doubles the error of the OpenSim 2 form.
//!
//! Three of the six muscles (TRIlong, BICshort, BRA) sit at CMC's lower bound 0.02 throughout,
//! so their activations stay exactly at 0.02.

use musculo::io::Table;
use musculo::muscle::activation::{ActivationDynamics, Interpolation};
use musculo::{Model, reference};

const RESULTS: &str = "opensim-models/Tutorials/Computed_Muscle_Control/OutputReference/ComputedMuscleControl/Results";
const MODEL: &str = "opensim-models/Models/Arm26/arm26.osim";
const RMSE_LIMIT: f64 = 0.005;
const DEPRECATED_RMSE_LIMIT: f64 = 2e-4;

fn rmse_and_max(a: &[f64], b: &[f64]) -> (f64, f64) {
    let n = a.len() as f64;
    let sum_sq: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    let max = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    ((sum_sq / n).sqrt(), max)
}

#[test]
fn thelen_activation_reproduces_arm26_cmc_activations_within_0_005_rmse() {
    let files = (
        reference::file(MODEL),
        reference::file(&format!("{RESULTS}/arm26_controls.sto")),
        reference::file(&format!("{RESULTS}/arm26_states.sto")),
    );
    let (Some(model_path), Some(controls_path), Some(states_path)) = files else {
        assert!(
            !reference::required(),
            "reference data not found under {} (MUSCULO_REQUIRE_REFERENCE is set)",
            reference::directory().display()
        );
        println!("skipped: reference data not found");
        return;
    };
    let model = Model::from_osim_file(&model_path).unwrap();
    let controls = Table::read(&controls_path).unwrap();
    let states = Table::read(&states_path).unwrap();

    println!(
        "{:<9} {:>7} {:>7} {:>7} | {:>9} {:>9} | {:>9} {:>9} | {:>9}",
        "", "", "", "", "Thelen2003", "", "Deprecated", "", "Deprec."
    );
    println!(
        "{:<9} {:>7} {:>7} {:>7} | {:>9} {:>9} | {:>9} {:>9} | {:>9}",
        "muscle", "τ_act", "τ_deact", "a_min", "RMSE", "max|err|", "RMSE", "max|err|", "RMSE lin."
    );
    let mut muscles = 0;
    for muscle in model.forces.iter().filter(|f| f.is_muscle()) {
        muscles += 1;
        let name = &muscle.name;
        let dynamics = ActivationDynamics::from_muscle(muscle, &model.source).unwrap();
        let ActivationDynamics::Thelen2003 {
            activation_time_constant,
            deactivation_time_constant,
            minimum_activation,
        } = dynamics
        else {
            panic!("{name}: Arm26's muscles are Thelen2003Muscle, got {dynamics:?}");
        };
        // OpenSim 2's form with the same time constants.
        let deprecated = ActivationDynamics::Thelen2003Deprecated {
            activation_time_constant,
            deactivation_time_constant,
        };
        let excitation = controls
            .column(name)
            .unwrap_or_else(|| panic!("{name}: no column in arm26_controls.sto"));
        // OpenSim 2-3 label states `TRIlong.activation`, OpenSim 4 `/forceset/TRIlong/activation`.
        let expected = states
            .column(&format!("{name}.activation"))
            .or_else(|| states.column(&format!("/forceset/{name}/activation")))
            .unwrap_or_else(|| panic!("{name}: no activation column in arm26_states.sto"));

        let error = |dynamics: ActivationDynamics, interpolation| {
            let a = dynamics
                .integrate(
                    &controls.time,
                    &excitation,
                    interpolation,
                    expected[0],
                    &states.time,
                )
                .unwrap();
            rmse_and_max(&a, &expected)
        };
        let (rmse, max) = error(dynamics, Interpolation::HoldNext);
        let (rmse_deprecated, max_deprecated) = error(deprecated, Interpolation::HoldNext);
        let (rmse_deprecated_linear, _) = error(deprecated, Interpolation::Linear);
        println!(
            "{name:<9} {activation_time_constant:>7.3} {deactivation_time_constant:>7.3} \
             {minimum_activation:>7.3} | {rmse:>9.2e} {max:>9.2e} | {rmse_deprecated:>9.2e} \
             {max_deprecated:>9.2e} | {rmse_deprecated_linear:>9.2e}"
        );
        assert!(
            rmse <= RMSE_LIMIT,
            "{name}: RMSE {rmse} exceeds {RMSE_LIMIT}"
        );
        assert!(
            rmse_deprecated <= DEPRECATED_RMSE_LIMIT,
            "{name}: RMSE {rmse_deprecated} of the OpenSim 2 form exceeds {DEPRECATED_RMSE_LIMIT}"
        );
    }
    assert_eq!(muscles, 6, "Arm26 has six muscles");
}
