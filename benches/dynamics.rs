//! Per-call time of the dynamics algorithms on the reference models, and memory per Data.
//!
//! Each figure is the median (min–max) over repeated batches of calls on the same 100 random
//! states. Beside each musculo algorithm runs a peer computing the same quantity the
//! textbook way in the same process — M by n + 1 inverse-dynamics calls
//! (M e_j = ID(q, q̇, e_j) − bias); the bias by the Lagrangian brute force
//! Φᵀ(bias_full + M_full Φ̇q̇) — and the ratio musculo / peer is printed (< 1: musculo
//! faster). The MuJoCo comparison is `cargo bench --features mujoco` (see docs/src/benchmarks.md).
//!
//! Run: `cargo bench --bench dynamics` (reference data from MUSCULO_REFERENCE or
//! ../shared/reference).

use musculo::{Data, Model, dynamics};
use nalgebra::DMatrix;
use std::hint::black_box;
use std::time::Instant;

const STATES: usize = 100;
const BATCHES: usize = 31;

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

struct States {
    q: Vec<Vec<f64>>,
    qd: Vec<Vec<f64>>,
    qdd: Vec<Vec<f64>>,
}

fn states(model: &Model) -> States {
    let mut rng = Rng(42);
    let n = model.nq();
    let mut s = States {
        q: vec![],
        qd: vec![],
        qdd: vec![],
    };
    for _ in 0..STATES {
        s.q.push(
            model
                .reduction
                .independent
                .iter()
                .map(|&c| {
                    let [lo, hi] = model.coordinates[c].range;
                    lo + (hi - lo) * rng.unit()
                })
                .collect(),
        );
        s.qd.push((0..n).map(|_| 2.0 * rng.unit() - 1.0).collect());
        s.qdd
            .push((0..n).map(|_| 10.0 * rng.unit() - 5.0).collect());
    }
    s
}

/// Nanoseconds per call for each batch of `STATES` calls.
fn time_batches(mut f: impl FnMut(usize)) -> Vec<f64> {
    for i in 0..STATES {
        f(i); // warm-up
    }
    (0..BATCHES)
        .map(|_| {
            let t = Instant::now();
            for i in 0..STATES {
                f(i);
            }
            t.elapsed().as_nanos() as f64 / STATES as f64
        })
        .collect()
}

fn summary(mut v: Vec<f64>) -> (f64, f64, f64) {
    v.sort_by(|a, b| a.total_cmp(b));
    (v[0], v[v.len() / 2], v[v.len() - 1])
}

fn fmt(ns: f64) -> String {
    if ns >= 1e4 {
        format!("{:.1} µs", ns / 1e3)
    } else {
        format!("{:.2} µs", ns / 1e3)
    }
}

fn row(label: &str, ours: Vec<f64>, peer: Option<(&str, Vec<f64>)>) {
    let (lo, med, hi) = summary(ours.clone());
    let mut line = format!(
        "  {label:<34} {:>10}  ({} – {})",
        fmt(med),
        fmt(lo),
        fmt(hi)
    );
    if let Some((name, p)) = peer {
        let ratios: Vec<f64> = ours.iter().zip(&p).map(|(a, b)| a / b).collect();
        let (rlo, rmed, rhi) = summary(ratios);
        let (_, pmed, _) = summary(p);
        line += &format!(
            "   peer {name}: {:>10}  ratio {rmed:.3} ({rlo:.3} – {rhi:.3})",
            fmt(pmed)
        );
    }
    println!("{line}");
}

fn bench_model(label: &str, model: &Model) {
    let s = states(model);
    let n = model.nq();
    let mut data = Data::new(model);
    let mut peer = Data::new(model);
    println!(
        "\n{label}: {} bodies, n = {n} independent coordinates, {} full coordinates; Data = {} bytes",
        model.bodies.len() - 1,
        model.n_full(),
        data.memory_bytes()
    );

    // M: CRBA vs n + 1 inverse dynamics calls.
    let mut m_peer = DMatrix::zeros(n, n);
    let mut unit = vec![0.0; n];
    let mut crba = Vec::new();
    let mut naive = Vec::new();
    for _ in 0..3 {
        crba.extend(time_batches(|i| {
            black_box(dynamics::crba(model, &mut data, &s.q[i]).unwrap());
        }));
        naive.extend(time_batches(|i| {
            let zero = &s.qdd[i][..0];
            let _ = zero;
            let b = dynamics::nonlinear_effects(model, &mut peer, &s.q[i], &s.qd[i])
                .unwrap()
                .clone_owned();
            for j in 0..n {
                unit.fill(0.0);
                unit[j] = 1.0;
                let t = dynamics::rnea(model, &mut peer, &s.q[i], &s.qd[i], &unit).unwrap();
                for k in 0..n {
                    m_peer[(k, j)] = t[k] - b[k];
                }
            }
            black_box(&m_peer);
        }));
    }
    row("M (crba)", crba, Some(("n+1 × rnea", naive)));

    // bias: RNEA with q̈ = 0 vs brute force Φᵀ(bias_full + M_full Φ̇q̇).
    let theta_zero = vec![0.0; model.n_full()];
    let bias = time_batches(|i| {
        black_box(dynamics::nonlinear_effects(model, &mut data, &s.q[i], &s.qd[i]).unwrap());
    });
    let brute = time_batches(|i| {
        dynamics::forward_kinematics(model, &mut peer, &s.q[i]).unwrap();
        let m_full = dynamics::crba_full(model, &mut peer).unwrap().clone_owned();
        dynamics::forward_kinematics_velocity(model, &mut peer, &s.q[i], &s.qd[i]).unwrap();
        let phi = peer.phi_matrix(model);
        let pdq = nalgebra::DVector::from_column_slice(peer.phi_dot_qd(model));
        let th = peer.theta(model).to_vec();
        let thd = peer.theta_dot(model).to_vec();
        let bf = nalgebra::DVector::from_column_slice(
            dynamics::rnea_full(model, &mut peer, &th, &thd, &theta_zero).unwrap(),
        );
        black_box(phi.transpose() * (bf + m_full * pdq));
    });
    row(
        "bias C q̇ + G (rnea, q̈ = 0)",
        bias,
        Some(("Φᵀ(b_full + M_full Φ̇q̇)", brute)),
    );

    row(
        "ID τ(q, q̇, q̈) (rnea)",
        time_batches(|i| {
            black_box(dynamics::rnea(model, &mut data, &s.q[i], &s.qd[i], &s.qdd[i]).unwrap());
        }),
        None,
    );
    row(
        "G (com Jacobian)",
        time_batches(|i| {
            black_box(dynamics::gravity(model, &mut data, &s.q[i]).unwrap());
        }),
        None,
    );
    row(
        "forward kinematics (position)",
        time_batches(|i| {
            dynamics::forward_kinematics(model, &mut data, &s.q[i]).unwrap();
        }),
        None,
    );

    let mut j6 = DMatrix::zeros(6, n);
    let nb = model.bodies.len();
    row(
        "all-body Jacobians (incl. FK)",
        time_batches(|i| {
            dynamics::forward_kinematics(model, &mut data, &s.q[i]).unwrap();
            for b in 1..nb {
                dynamics::body_jacobian(model, &data, b, &mut j6).unwrap();
                black_box(&j6);
            }
        }),
        None,
    );
}

fn main() {
    // `cargo test --benches` runs this binary with --bench absent: keep that quick.
    let quick = !std::env::args().any(|a| a == "--bench");
    let dir = musculo::reference::directory();
    println!(
        "musculo dynamics benchmark: per-call time, median (min – max) over {BATCHES} batches of {STATES} random states"
    );
    let demo = Model::demo();
    if quick {
        let mut d = Data::new(&demo);
        dynamics::crba(&demo, &mut d, &demo.default_q()).unwrap();
        println!("(smoke run; use `cargo bench` for figures)");
        return;
    }
    bench_model("demo", &demo);
    for (label, rel) in [
        (
            "gait2392",
            "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        ),
        (
            "Rajagopal2016",
            "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
        ),
    ] {
        match Model::from_osim_file(dir.join(rel)) {
            Ok(m) => bench_model(label, &m),
            Err(e) => println!("\n{label}: skipped ({e})"),
        }
    }
}
