//! musculo against MuJoCo, side by side in one process (cargo feature `mujoco`):
//! `cargo bench --features mujoco --bench vs_mujoco` after `eval "$(scripts/setup-mujoco.sh)"`.
//!
//! For each model, the same 100 random states are run through
//! - M: musculo `crba(q)` (reduced, including θ = φ(q) and Φ) and `forward_kinematics_full` +
//!   `crba_full(θ)` vs MuJoCo mj_kinematics + mj_comPos + mj_crb + mj_fullM at qpos = θ;
//! - bias: musculo `nonlinear_effects(q, q̇)` and `rnea_full(θ, θ̇, 0)` vs MuJoCo mj_kinematics +
//!   mj_comPos + mj_comVel + mj_rne(flg_acc = 0) (mj_rne needs the first three);
//! - inverse dynamics: musculo `rnea(q, q̇, q̈)` and `rnea_full` vs the same MuJoCo stages with
//!   mj_rne(flg_acc = 1).
//!
//! Batches of the two engines alternate; each batch gives a ratio musculo / MuJoCo of the
//! per-call times, and min / median / max over the batches are printed (< 1: musculo faster).

use musculo::mujoco::MujocoTwin;
use musculo::{Data, Model, dynamics};
use std::hint::black_box;
use std::time::Instant;

const STATES: usize = 100;
const BATCHES: usize = 41;

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

struct State {
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    theta: Vec<f64>,
    theta_dot: Vec<f64>,
    theta_ddot: Vec<f64>,
}

fn states(model: &Model) -> Vec<State> {
    let mut rng = Rng(7);
    let n = model.nq();
    let mut data = Data::new(model);
    (0..STATES)
        .map(|_| {
            let q: Vec<f64> = model
                .reduction
                .independent
                .iter()
                .map(|&c| {
                    let [lo, hi] = model.coordinates[c].range;
                    lo + (hi - lo) * rng.unit()
                })
                .collect();
            let qd: Vec<f64> = (0..n).map(|_| 2.0 * rng.unit() - 1.0).collect();
            let qdd: Vec<f64> = (0..n).map(|_| 10.0 * rng.unit() - 5.0).collect();
            dynamics::forward_kinematics_acceleration(model, &mut data, &q, &qd, &qdd).unwrap();
            let phi = data.phi_matrix(model);
            let theta_ddot = (&phi * nalgebra::DVector::from_column_slice(&qdd)
                + nalgebra::DVector::from_column_slice(data.phi_dot_qd(model)))
            .as_slice()
            .to_vec();
            State {
                theta: data.theta(model).to_vec(),
                theta_dot: data.theta_dot(model).to_vec(),
                q,
                qd,
                qdd,
                theta_ddot,
            }
        })
        .collect()
}

/// Per-call nanoseconds of one batch over all states.
fn batch(mut f: impl FnMut(usize)) -> f64 {
    let t = Instant::now();
    for i in 0..STATES {
        f(i);
    }
    t.elapsed().as_nanos() as f64 / STATES as f64
}

fn stats(mut v: Vec<f64>) -> (f64, f64, f64) {
    v.sort_by(|a, b| a.total_cmp(b));
    (v[0], v[v.len() / 2], v[v.len() - 1])
}

/// Alternates batches of `ours` and `theirs`; prints medians and the ratio statistics.
fn compare(label: &str, mut ours: impl FnMut(usize), mut theirs: impl FnMut(usize)) -> f64 {
    for i in 0..STATES {
        ours(i);
        theirs(i);
    }
    let (mut a, mut b, mut r) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..BATCHES {
        let x = batch(&mut ours);
        let y = batch(&mut theirs);
        a.push(x);
        b.push(y);
        r.push(x / y);
    }
    let (_, am, _) = stats(a);
    let (_, bm, _) = stats(b);
    let (rlo, rmed, rhi) = stats(r);
    println!(
        "  {label:<44} musculo {:>7.2} µs   MuJoCo {:>7.2} µs   ratio {rmed:.2} ({rlo:.2} – {rhi:.2})",
        am / 1e3,
        bm / 1e3
    );
    rmed
}

fn bench(label: &str, model: &Model) {
    let s = states(model);
    let mut data = Data::new(model);
    let mut twin = match MujocoTwin::new(model) {
        Ok(t) => t,
        Err(e) => {
            println!("\n{label}: skipped ({e})");
            return;
        }
    };
    let nf = model.n_full();
    let zeros = vec![0.0; nf];
    println!(
        "\n{label}: n = {} independent coordinates, {} full coordinates (MuJoCo nv = {nf}); Data = {} bytes",
        model.nq(),
        nf,
        data.memory_bytes()
    );
    compare(
        "M: crba(q) | kinematics+comPos+crb+fullM",
        |i| {
            black_box(dynamics::crba(model, &mut data, &s[i].q).unwrap());
        },
        |i| {
            twin.set_state(&s[i].theta, &zeros);
            twin.mass_matrix_stages();
        },
    );
    let mut d2 = Data::new(model);
    compare(
        "M_full: fk_full+crba_full(θ) | same",
        |i| {
            dynamics::forward_kinematics_full(model, &mut d2, &s[i].theta, &zeros).unwrap();
            black_box(dynamics::crba_full(model, &mut d2).unwrap());
        },
        |i| {
            twin.set_state(&s[i].theta, &zeros);
            twin.mass_matrix_stages();
        },
    );
    compare(
        "bias: nonlinear_effects(q,q̇) | kin+comPos+comVel+rne",
        |i| {
            black_box(dynamics::nonlinear_effects(model, &mut data, &s[i].q, &s[i].qd).unwrap());
        },
        |i| {
            twin.set_state(&s[i].theta, &s[i].theta_dot);
            twin.bias_stages();
        },
    );
    compare(
        "bias_full: rnea_full(θ,θ̇,0) | same",
        |i| {
            black_box(
                dynamics::rnea_full(model, &mut d2, &s[i].theta, &s[i].theta_dot, &zeros).unwrap(),
            );
        },
        |i| {
            twin.set_state(&s[i].theta, &s[i].theta_dot);
            twin.bias_stages();
        },
    );
    compare(
        "ID: rnea(q,q̇,q̈) | kin+comPos+comVel+rne(acc)",
        |i| {
            black_box(dynamics::rnea(model, &mut data, &s[i].q, &s[i].qd, &s[i].qdd).unwrap());
        },
        |i| {
            twin.set_state(&s[i].theta, &s[i].theta_dot);
            twin.inverse_dynamics_stages(&s[i].theta_ddot);
        },
    );
}

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        println!("(smoke run; use `cargo bench --features mujoco --bench vs_mujoco` for figures)");
        return;
    }
    println!(
        "musculo vs MuJoCo {} — per-call medians over {BATCHES} alternating batches of {STATES} random states; ratio = musculo / MuJoCo",
        musculo::mujoco::linked_version()
    );
    let dir = musculo::reference::directory();
    for (label, rel) in [
        ("Arm26", "opensim-models/Models/Arm26/arm26.osim"),
        (
            "Gait10dof18musc",
            "opensim-models/Pipelines/Gait10dof18musc/OutputReference/gait10dof18musc.osim",
        ),
        (
            "Gait2392",
            "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        ),
        (
            "Rajagopal2016",
            "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
        ),
    ] {
        match Model::from_osim_file(dir.join(rel)) {
            Ok(m) => bench(label, &m),
            Err(e) => println!("\n{label}: skipped ({e})"),
        }
    }
}
