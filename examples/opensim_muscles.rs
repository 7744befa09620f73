//! musculo's muscle quantities at given states, for the OpenSim side-by-side check
//! `validation/opensim/muscles_compare.py`:
//!
//!     cargo run --release --example opensim_muscles -- MODEL.osim STATES.npy INPUTS.npy OUT.npz
//!     cargo run --release --example opensim_muscles -- MODEL.osim --names OUT.json
//!
//! STATES.npy: B × 2n float64, each row q, q̇ in the model's independent coordinates
//! (`Model::q_names` order). INPUTS.npy: B × m × 4 float64, per muscle (in the model's muscle
//! order) the activation a, musculotendon length ℓ, lengthening speed ℓ̇ and fiber length at
//! which to evaluate the force model — OpenSim's own values, so that the force check does not
//! inherit a path difference. OUT.npz holds, B × m each:
//! - `length`, `speed`: musculo's ℓ(q) and ℓ̇ = −rᵀq̇ at STATES;
//! - `fiber_length`, `tendon_force`, `fiber_velocity`, `status` (0 solved, 1 fiber at its lower
//!   bound, 2 no equilibrium, 3 other): the muscle state at INPUTS as OpenSim's
//!   `Model::equilibrateMuscles` defines it — rigid tendons in closed form, elastic tendons at
//!   the force balance with each class's initialisation rule for the fiber velocity
//!   (Thelen: stiffness split; Millard: fiber at rest, `computeFiberEquilibrium(s, false)`;
//!   De Groote–Fregly: tendon at constant length);
//! - `at_fiber_tendon_force`, `at_fiber_fiber_velocity`, `at_fiber_active_fiber_force`: the
//!   state at INPUTS' fiber length (`HillMuscle::state_at_fiber_length`; rigid tendons: the
//!   closed form), i.e. the force model without the equilibrium solve.
//!
//! With `--names` it writes the coordinate and muscle names, in those orders, as JSON.

use musculo::dynamics::{self, Data};
use musculo::muscle::hill::{EquilibriumSettings, MuscleKind, MuscleStatus, VelocitySplit};
use musculo::muscle::path::{PathData, compute_paths};
use musculo::{Model, muscle::MuscleSet};
use ndarray::{Array2, Array3};
use ndarray_npy::{NpzWriter, ReadNpyExt};
use std::fs::File;

fn main() {
    if let Err(e) = run() {
        eprintln!("opensim_muscles: {e}");
        std::process::exit(1);
    }
}

/// The fiber-velocity rule of each class's `computeInitialFiberEquilibrium` in OpenSim 4.6.
fn initial_equilibrium_split(kind: MuscleKind) -> VelocitySplit {
    match kind {
        MuscleKind::Thelen2003 => VelocitySplit::Stiffness,
        MuscleKind::Millard2012Equilibrium => VelocitySplit::Static,
        MuscleKind::DeGrooteFregly2016 => VelocitySplit::RigidTendonVelocity,
    }
}

fn status_code(s: MuscleStatus) -> f64 {
    match s {
        MuscleStatus::Ok => 0.0,
        MuscleStatus::FiberAtLowerBound => 1.0,
        MuscleStatus::NoEquilibrium => 2.0,
        _ => 3.0,
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let usage =
        "usage: opensim_muscles MODEL.osim (STATES.npy INPUTS.npy OUT.npz | --names OUT.json)";
    if args.len() < 4 {
        return Err(usage.into());
    }
    let model = Model::from_osim_file(&args[1])?;
    let set = MuscleSet::new(&model)?;
    if args[2] == "--names" {
        if args.len() != 4 {
            return Err(usage.into());
        }
        let names = serde_json::json!({
            "coordinates": model.q_names(),
            "muscles": set.names().collect::<Vec<_>>(),
        });
        std::fs::write(&args[3], serde_json::to_string_pretty(&names)?)?;
        return Ok(());
    }
    if args.len() != 5 {
        return Err(usage.into());
    }
    let states = Array2::<f64>::read_npy(File::open(&args[2])?)?;
    let inputs = Array3::<f64>::read_npy(File::open(&args[3])?)?;
    let (n, m, b) = (model.nq(), set.len(), states.nrows());
    if states.ncols() != 2 * n {
        return Err(format!(
            "{}: rows of {} values, the model needs 2 × {n}",
            args[2],
            states.ncols()
        )
        .into());
    }
    if inputs.shape() != [b, m, 4] {
        return Err(format!(
            "{}: shape {:?}, expected [{b}, {m}, 4]",
            args[3],
            inputs.shape()
        )
        .into());
    }
    let mut data = Data::new(&model);
    let mut paths = PathData::new(&model, &set.paths);
    let mut out: Vec<Array2<f64>> = (0..9).map(|_| Array2::zeros((b, m))).collect();
    for (k, row) in states.rows().into_iter().enumerate() {
        let row = row.to_vec();
        let (q, qd) = row.split_at(n);
        dynamics::forward_kinematics_velocity(&model, &mut data, q, qd)?;
        compute_paths(&model, &data, &set.paths, &mut paths)?;
        for (i, muscle) in set.muscles.iter().enumerate() {
            let (a, l, v) = (inputs[[k, i, 0]], inputs[[k, i, 1]], inputs[[k, i, 2]]);
            let rigid = muscle.params().ignore_tendon_compliance;
            let at_fiber = if rigid {
                muscle.state_rigid_tendon(a, l, v)
            } else {
                muscle.state_at_fiber_length(a, l, v, inputs[[k, i, 3]])
            };
            let s = if rigid {
                at_fiber
            } else {
                let settings = EquilibriumSettings {
                    velocity_split: Some(initial_equilibrium_split(muscle.kind())),
                    ..Default::default()
                };
                muscle.state_equilibrium(a, l, v, &settings)
            };
            let values = [
                paths.length[i],
                paths.speed[i],
                s.fiber_length,
                s.tendon_force,
                s.fiber_velocity,
                status_code(s.status),
                at_fiber.tendon_force,
                at_fiber.fiber_velocity,
                at_fiber.active_fiber_force,
            ];
            for (o, x) in out.iter_mut().zip(values) {
                o[[k, i]] = x;
            }
        }
    }
    let mut npz = NpzWriter::new(File::create(&args[4])?);
    let names = [
        "length",
        "speed",
        "fiber_length",
        "tendon_force",
        "fiber_velocity",
        "status",
        "at_fiber_tendon_force",
        "at_fiber_fiber_velocity",
        "at_fiber_active_fiber_force",
    ];
    for (name, array) in names.iter().zip(&out) {
        npz.add_array(*name, array)?;
    }
    npz.finish()?;
    Ok(())
}
