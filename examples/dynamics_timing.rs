//! musculo's per-call time for the mass matrix, the bias forces and inverse dynamics, for the
//! side-by-side timing against Pinocchio in `validation/pinocchio/speed.py`:
//!
//!     cargo run --release --example dynamics_timing -- MODEL.osim [--states STATES.npy]
//!         [--count N] [--batches K] [--full OUT.npz]
//!
//! Quantities, in musculo's independent coordinates q (`Model::q_names` order):
//! - `M`: `dynamics::crba(q)`, M = Φᵀ M_θ Φ with θ = φ(q), Φ = ∂θ/∂q (couplers
//!   included);
//! - `bias`: `dynamics::nonlinear_effects(q, q̇)` = C q̇ + G (inverse dynamics at q̈ = 0);
//! - `ID`: `dynamics::rnea(q, q̇, q̈)` = M q̈ + C q̇ + G;
//!
//! and the same in the full coordinates θ (one per movable transform axis, the coordinates of the
//! MJCF that `musculo export-mjcf` writes): `M_full` (`forward_kinematics_full` + `crba_full`),
//! `bias_full` and `ID_full` (`rnea_full` with θ̈ = 0 and with θ̈ = Φ q̈ + Φ̇ q̇), and
//! `ID_derivatives_full` (`rnea_derivatives_full`: ∂τ/∂θ and ∂τ/∂θ̇), and in q
//! `ID_derivatives` (`rnea_derivatives`: ∂τ/∂q, ∂τ/∂q̇ and ∂τ/∂q̈ = M), and `ID_vjp`
//! (`RneaVjp::forward` + `backward`: τ and uᵀ∂τ/∂q, uᵀ∂τ/∂q̇, uᵀ∂τ/∂q̈ for one weight vector u,
//! what the gradient of a loss Σ‖r‖² needs).
//!
//! States: the rows of STATES.npy (B × 3n float64, each row q, q̇, q̈), or else N random states
//! (default 100; seed fixed): q uniform over each independent coordinate's range, q̇ uniform in
//! [−1, 1], q̈ uniform in [−5, 5]. Each quantity runs K batches (default 41) of one call per
//! state, after one warm-up batch; a batch gives a per-call time (its duration / B), and the JSON
//! printed on stdout has the median, min and max of those over the batches, in µs, with the
//! model's sizes, total mass and the full coordinates' names.
//!
//! With `--full OUT.npz` it also writes the states in full coordinates, for running a peer on
//! the same configurations: `theta`, `theta_dot`, `theta_ddot` (B × n_full), and at the first
//! state the full mass matrix `M_full` (n_full × n_full), inverse dynamics `tau_full`
//! (n_full, gravity included) and its derivatives `dtau_dtheta`, `dtau_dtheta_dot`.

use musculo::{Data, Model, dynamics};
use nalgebra::DVector;
use ndarray::{Array1, Array2};
use ndarray_npy::{NpzWriter, ReadNpyExt};
use std::fs::File;
use std::hint::black_box;
use std::time::Instant;

/// SplitMix64: the same generator as `benches/vs_mujoco.rs`.
struct Rng(u64);
impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// One state in independent coordinates and the same state in full coordinates.
struct State {
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    theta: Vec<f64>,
    theta_dot: Vec<f64>,
    theta_ddot: Vec<f64>,
}

struct Options {
    model: String,
    states: Option<String>,
    count: usize,
    batches: usize,
    full: Option<String>,
}

fn main() {
    if let Err(e) = run() {
        eprintln!("dynamics_timing: {e}");
        std::process::exit(1);
    }
}

fn parse_args() -> Result<Options, String> {
    const USAGE: &str = "usage: dynamics_timing MODEL.osim [--states STATES.npy] [--count N] \
                         [--batches K] [--full OUT.npz]";
    let mut args = std::env::args().skip(1);
    let mut o = Options {
        model: String::new(),
        states: None,
        count: 100,
        batches: 41,
        full: None,
    };
    while let Some(a) = args.next() {
        let mut value = || {
            args.next()
                .ok_or_else(|| format!("{a} needs a value; {USAGE}"))
        };
        match a.as_str() {
            "--states" => o.states = Some(value()?),
            "--full" => o.full = Some(value()?),
            "--count" | "--batches" => {
                let v = value()?;
                let n: usize = v
                    .parse()
                    .ok()
                    .filter(|&n| n > 0)
                    .ok_or_else(|| format!("{a} {v}: not a positive integer"))?;
                if a == "--count" {
                    o.count = n;
                } else {
                    o.batches = n;
                }
            }
            "-h" | "--help" => return Err(USAGE.into()),
            _ if a.starts_with('-') || !o.model.is_empty() => {
                return Err(format!("unexpected argument {a}; {USAGE}"));
            }
            _ => o.model = a,
        }
    }
    if o.model.is_empty() {
        return Err(USAGE.into());
    }
    Ok(o)
}

/// Rows (q, q̇, q̈) from STATES.npy, or `count` random ones.
fn independent_states(model: &Model, o: &Options) -> Result<Vec<[Vec<f64>; 3]>, String> {
    let n = model.nq();
    if let Some(path) = &o.states {
        let file = File::open(path).map_err(|e| format!("{path}: {e}"))?;
        let a = Array2::<f64>::read_npy(file).map_err(|e| format!("{path}: {e}"))?;
        if a.ncols() != 3 * n || a.nrows() == 0 {
            return Err(format!(
                "{path}: {} × {}, the model needs B × 3·{n} (rows q, q̇, q̈)",
                a.nrows(),
                a.ncols()
            ));
        }
        return Ok(a
            .rows()
            .into_iter()
            .map(|r| {
                let r = r.to_vec();
                [r[..n].to_vec(), r[n..2 * n].to_vec(), r[2 * n..].to_vec()]
            })
            .collect());
    }
    let mut rng = Rng(7);
    Ok((0..o.count)
        .map(|_| {
            let q = model
                .reduction
                .independent
                .iter()
                .map(|&c| {
                    let [lo, hi] = model.coordinates[c].range;
                    lo + (hi - lo) * rng.unit()
                })
                .collect();
            let qd = (0..n).map(|_| 2.0 * rng.unit() - 1.0).collect();
            let qdd = (0..n).map(|_| 10.0 * rng.unit() - 5.0).collect();
            [q, qd, qdd]
        })
        .collect())
}

/// Adds θ = φ(q), θ̇ = Φ q̇, θ̈ = Φ q̈ + Φ̇ q̇.
fn with_full(model: &Model, rows: Vec<[Vec<f64>; 3]>) -> musculo::Result<Vec<State>> {
    let mut data = Data::new(model);
    rows.into_iter()
        .map(|[q, qd, qdd]| {
            dynamics::forward_kinematics_acceleration(model, &mut data, &q, &qd, &qdd)?;
            let phi = data.phi_matrix(model);
            let theta_ddot = &phi * DVector::from_column_slice(&qdd)
                + DVector::from_column_slice(data.phi_dot_qd(model));
            Ok(State {
                theta: data.theta(model).to_vec(),
                theta_dot: data.theta_dot(model).to_vec(),
                theta_ddot: theta_ddot.as_slice().to_vec(),
                q,
                qd,
                qdd,
            })
        })
        .collect()
}

/// Per-call µs: median, min and max over `batches` batches of one call per state.
fn time_calls(
    states: usize,
    batches: usize,
    mut call: impl FnMut(usize) -> musculo::Result<()>,
) -> musculo::Result<serde_json::Value> {
    for i in 0..states {
        call(i)?;
    }
    let mut per_call = Vec::with_capacity(batches);
    for _ in 0..batches {
        let t = Instant::now();
        for i in 0..states {
            call(i)?;
        }
        per_call.push(t.elapsed().as_secs_f64() * 1e6 / states as f64);
    }
    per_call.sort_by(|a, b| a.total_cmp(b));
    Ok(serde_json::json!({
        "median": per_call[per_call.len() / 2],
        "min": per_call[0],
        "max": per_call[per_call.len() - 1],
    }))
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let o = parse_args()?;
    let model = Model::from_osim_file(&o.model)?;
    let s = with_full(&model, independent_states(&model, &o)?)?;
    let (b, nf) = (s.len(), model.n_full());
    let zeros = vec![0.0; nf];
    let mut data = Data::new(&model);
    let k = o.batches;

    let m = time_calls(b, k, |i| {
        black_box(dynamics::crba(&model, &mut data, &s[i].q)?);
        Ok(())
    })?;
    let bias = time_calls(b, k, |i| {
        black_box(dynamics::nonlinear_effects(
            &model, &mut data, &s[i].q, &s[i].qd,
        )?);
        Ok(())
    })?;
    let id = time_calls(b, k, |i| {
        black_box(dynamics::rnea(
            &model, &mut data, &s[i].q, &s[i].qd, &s[i].qdd,
        )?);
        Ok(())
    })?;
    let m_full = time_calls(b, k, |i| {
        dynamics::forward_kinematics_full(&model, &mut data, &s[i].theta, &zeros)?;
        black_box(dynamics::crba_full(&model, &mut data)?);
        Ok(())
    })?;
    let bias_full = time_calls(b, k, |i| {
        black_box(dynamics::rnea_full(
            &model,
            &mut data,
            &s[i].theta,
            &s[i].theta_dot,
            &zeros,
        )?);
        Ok(())
    })?;
    let id_full = time_calls(b, k, |i| {
        let st = &s[i];
        black_box(dynamics::rnea_full(
            &model,
            &mut data,
            &st.theta,
            &st.theta_dot,
            &st.theta_ddot,
        )?);
        Ok(())
    })?;

    let mut der = dynamics::RneaDerivatives::new(&model);
    let id_derivatives_full = time_calls(b, k, |i| {
        let st = &s[i];
        dynamics::rnea_derivatives_full(
            &model,
            &mut data,
            &st.theta,
            &st.theta_dot,
            &st.theta_ddot,
            &mut der,
        )?;
        black_box(&der.dtau_dtheta);
        Ok(())
    })?;

    let id_derivatives = time_calls(b, k, |i| {
        let st = &s[i];
        dynamics::rnea_derivatives(&model, &mut data, &st.q, &st.qd, &st.qdd, &mut der)?;
        black_box(&der.dtau_dq);
        Ok(())
    })?;

    let mut vjp = dynamics::RneaVjp::new(&model);
    let weights = vec![0.5; model.nq()];
    let id_vjp = time_calls(b, k, |i| {
        let st = &s[i];
        let none = dynamics::PointForces::default();
        vjp.forward(&model, &mut data, &st.q, &st.qd, &st.qdd, &none)?;
        vjp.backward(&model, &data, &weights)?;
        black_box(&vjp.dq);
        Ok(())
    })?;

    if let Some(path) = &o.full {
        let rows =
            |f: fn(&State) -> &Vec<f64>| Array2::from_shape_fn((b, nf), |(i, j)| f(&s[i])[j]);
        dynamics::forward_kinematics_full(&model, &mut data, &s[0].theta, &zeros)?;
        let mf = dynamics::crba_full(&model, &mut data)?.clone();
        let tau = dynamics::rnea_full(
            &model,
            &mut data,
            &s[0].theta,
            &s[0].theta_dot,
            &s[0].theta_ddot,
        )?;
        let tau = Array1::from_vec(tau.to_vec());
        let mut npz = NpzWriter::new(File::create(path).map_err(|e| format!("{path}: {e}"))?);
        npz.add_array("theta", &rows(|s| &s.theta))?;
        npz.add_array("theta_dot", &rows(|s| &s.theta_dot))?;
        npz.add_array("theta_ddot", &rows(|s| &s.theta_ddot))?;
        npz.add_array(
            "M_full",
            &Array2::from_shape_fn((nf, nf), |(i, j)| mf[(i, j)]),
        )?;
        npz.add_array("tau_full", &tau)?;
        dynamics::rnea_derivatives_full(
            &model,
            &mut data,
            &s[0].theta,
            &s[0].theta_dot,
            &s[0].theta_ddot,
            &mut der,
        )?;
        let mat = |m: &nalgebra::DMatrix<f64>| Array2::from_shape_fn((nf, nf), |(i, j)| m[(i, j)]);
        npz.add_array("dtau_dtheta", &mat(&der.dtau_dtheta))?;
        npz.add_array("dtau_dtheta_dot", &mat(&der.dtau_dtheta_dot))?;
        npz.finish()?;
    }

    let report = serde_json::json!({
        "model": o.model,
        "nq": model.nq(),
        "n_full": nf,
        "total_mass": model.total_mass(),
        "states": b,
        "batches": k,
        "full_names": model.dofs.iter().map(|d| d.name.as_str()).collect::<Vec<_>>(),
        "per_call_us": {
            "M": m, "bias": bias, "ID": id,
            "M_full": m_full, "bias_full": bias_full, "ID_full": id_full, "ID_derivatives_full": id_derivatives_full,
            "ID_derivatives": id_derivatives,
            "ID_vjp": id_vjp,
        },
    });
    println!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}
