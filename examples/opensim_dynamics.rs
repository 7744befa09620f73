//! musculo's rigid-body quantities at given states, for the OpenSim side-by-side check
//! `validation/opensim/dynamics_compare.py`:
//!
//!     cargo run --release --example opensim_dynamics -- MODEL.osim STATES.npy OUT.npz
//!     cargo run --release --example opensim_dynamics -- MODEL.osim --names OUT.json
//!
//! STATES.npy: B × 3n float64, each row q, q̇, q̈ in the model's independent coordinates
//! (`Model::q_names` order, radians and metres). OUT.npz holds, per state,
//! - `M` (B × n × n): the mass matrix in those coordinates, M = Φᵀ M_θ Φ with Φ = ∂θ/∂q;
//! - `tau` (B × n): inverse dynamics τ = M q̈ + C q̇ + G, gravity included;
//! - `markers` (B × m × 3): marker positions in ground;
//! - `J` (B × m × 3 × n): marker Jacobians ∂x/∂q.
//!
//! With `--names` it writes the coordinate and marker names, in that order, as JSON.

use musculo::dynamics::{self, point_jacobian};
use musculo::spatial::Vec3;
use musculo::{Data, Model};
use nalgebra::DMatrix;
use ndarray::{Array2, Array3, Array4};
use ndarray_npy::{NpzWriter, ReadNpyExt};
use std::fs::File;

fn main() {
    if let Err(e) = run() {
        eprintln!("opensim_dynamics: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 4 {
        return Err(
            "usage: opensim_dynamics MODEL.osim (STATES.npy OUT.npz | --names OUT.json)".into(),
        );
    }
    let model = Model::from_osim_file(&args[1])?;
    let names = serde_json::json!({
        "coordinates": model.q_names(),
        "markers": model.markers.iter().map(|mk| mk.name.as_str()).collect::<Vec<_>>(),
    });
    if args[2] == "--names" {
        std::fs::write(&args[3], serde_json::to_string_pretty(&names)?)?;
        return Ok(());
    }
    let states = Array2::<f64>::read_npy(File::open(&args[2])?)?;
    let (n, m) = (model.nq(), model.markers.len());
    if states.ncols() != 3 * n {
        return Err(format!(
            "{}: rows of {} values, the model needs 3 × {n}",
            args[2],
            states.ncols()
        )
        .into());
    }
    let b = states.nrows();
    let mut mass = Array3::<f64>::zeros((b, n, n));
    let mut tau = Array2::<f64>::zeros((b, n));
    let mut markers = Array3::<f64>::zeros((b, m, 3));
    let mut jac = Array4::<f64>::zeros((b, m, 3, n));
    let mut data = Data::new(&model);
    let mut positions = vec![Vec3::zeros(); m];
    let mut jm = DMatrix::zeros(3, n);
    for (k, row) in states.rows().into_iter().enumerate() {
        let row = row.to_vec();
        let (q, rest) = row.split_at(n);
        let (qd, qdd) = rest.split_at(n);
        let t = dynamics::rnea(&model, &mut data, q, qd, qdd)?;
        for j in 0..n {
            tau[[k, j]] = t[j];
        }
        let mm = dynamics::crba(&model, &mut data, q)?;
        for i in 0..n {
            for j in 0..n {
                mass[[k, i, j]] = mm[(i, j)];
            }
        }
        dynamics::forward_kinematics(&model, &mut data, q)?;
        data.marker_positions(&model, &mut positions)?;
        for (i, mk) in model.markers.iter().enumerate() {
            point_jacobian(&model, &data, mk.body, &mk.location_in_body, &mut jm)?;
            for a in 0..3 {
                markers[[k, i, a]] = positions[i][a];
                for j in 0..n {
                    jac[[k, i, a, j]] = jm[(a, j)];
                }
            }
        }
    }
    let mut npz = NpzWriter::new(File::create(&args[3])?);
    npz.add_array("M", &mass)?;
    npz.add_array("tau", &tau)?;
    npz.add_array("markers", &markers)?;
    npz.add_array("J", &jac)?;
    npz.finish()?;
    Ok(())
}
