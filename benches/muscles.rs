//! Per-frame cost of all muscles of a model: musculotendon lengths and the n × m moment-arm
//! matrix (`compute_paths`), and lengths + moment arms + Hill forces (`compute_muscles`),
//! beside the peer a user would otherwise run in the same process — moment arms by central
//! differences of the lengths, 2n extra path evaluations (ratio musculo / peer, < 1: faster).
//!
//! Run: `cargo bench --bench muscles`.

use musculo::muscle::path::{PathData, compute_paths};
use musculo::muscle::{MuscleData, MuscleSet, TendonMode, compute_muscles};
use musculo::{Data, Model, dynamics};
use std::hint::black_box;
use std::time::Instant;

const STATES: usize = 50;
const BATCHES: usize = 21;

fn stats(mut v: Vec<f64>) -> (f64, f64, f64) {
    v.sort_by(|a, b| a.total_cmp(b));
    (v[0], v[v.len() / 2], v[v.len() - 1])
}

fn batch(mut f: impl FnMut(usize)) -> f64 {
    let t = Instant::now();
    for i in 0..STATES {
        f(i);
    }
    t.elapsed().as_nanos() as f64 / STATES as f64 / 1e3
}

fn bench(label: &str, model: &Model) {
    let set = match MuscleSet::new(model) {
        Ok(s) => s,
        Err(e) => {
            println!("\n{label}: skipped ({e})");
            return;
        }
    };
    let n = model.nq();
    let mut s = 1u64;
    let mut unit = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let qs: Vec<Vec<f64>> = (0..STATES)
        .map(|_| {
            model
                .reduction
                .independent
                .iter()
                .map(|&c| {
                    let [lo, hi] = model.coordinates[c].range;
                    // the middle half of each range: typical postures
                    lo + (hi - lo) * (0.25 + 0.5 * unit())
                })
                .collect()
        })
        .collect();
    let qds: Vec<Vec<f64>> = (0..STATES)
        .map(|_| (0..n).map(|_| unit() - 0.5).collect())
        .collect();
    let act = vec![0.3; set.len()];
    let mut data = Data::new(model);
    let mut paths = PathData::new(model, &set.paths);
    let mut md = MuscleData::new(model, &set);
    let mut d2 = Data::new(model);
    let mut p2 = PathData::new(model, &set.paths);
    let (mut a, mut b, mut c, mut e, mut cp) = (vec![], vec![], vec![], vec![], vec![]);
    for _ in 0..BATCHES {
        a.push(batch(|i| {
            dynamics::forward_kinematics_velocity(model, &mut data, &qs[i], &qds[i]).unwrap();
            compute_paths(model, &data, &set.paths, &mut paths).unwrap();
            black_box(&paths.moment_arms);
        }));
        b.push(batch(|i| {
            dynamics::forward_kinematics_velocity(model, &mut data, &qs[i], &qds[i]).unwrap();
            compute_muscles(model, &data, &set, &act, TendonMode::Rigid, false, &mut md).unwrap();
            black_box(&md.force);
        }));
        e.push(batch(|i| {
            dynamics::forward_kinematics_velocity(model, &mut data, &qs[i], &qds[i]).unwrap();
            compute_muscles(
                model,
                &data,
                &set,
                &act,
                TendonMode::AsModel,
                false,
                &mut md,
            )
            .unwrap();
            black_box(&md.force);
        }));
        c.push(batch(|i| {
            dynamics::forward_kinematics_velocity(model, &mut data, &qs[i], &qds[i]).unwrap();
            compute_muscles(model, &data, &set, &act, TendonMode::Rigid, true, &mut md).unwrap();
            black_box(&md.force);
        }));
        cp.push(batch(|i| {
            // peer: lengths at q ± h e_j for every j
            let mut q = qs[i].clone();
            for j in 0..n {
                let h = 1e-6;
                q[j] += h;
                dynamics::forward_kinematics(model, &mut d2, &q).unwrap();
                compute_paths(model, &d2, &set.paths, &mut p2).unwrap();
                q[j] -= 2.0 * h;
                dynamics::forward_kinematics(model, &mut d2, &q).unwrap();
                compute_paths(model, &d2, &set.paths, &mut p2).unwrap();
                q[j] += h;
            }
            black_box(&p2.length);
        }));
    }
    let ratio: Vec<f64> = a.iter().zip(&cp).map(|(x, y)| x / y).collect();
    let (_, am, _) = stats(a.clone());
    let (alo, _, ahi) = stats(a);
    let (blo, bm, bhi) = stats(b);
    let (clo, cm, chi) = stats(c);
    let (elo, em, ehi) = stats(e);
    let (_, pm, _) = stats(cp);
    let (rlo, rm, rhi) = stats(ratio);
    println!("\n{label}: {} muscles, n = {n}", set.len());
    println!(
        "  FK + lengths + moment arms             {am:>8.2} µs ({alo:.2} – {ahi:.2})   peer (differences): {pm:>9.1} µs   ratio {rm:.3} ({rlo:.3} – {rhi:.3})"
    );
    println!("  + forces, rigid tendon                 {bm:>8.2} µs ({blo:.2} – {bhi:.2})");
    println!(
        "  + forces, the model's tendons          {em:>8.2} µs ({elo:.2} – {ehi:.2})   (compliant: equilibrium solve per muscle)"
    );
    println!(
        "  rigid, paths on {} threads             {cm:>8.2} µs ({clo:.2} – {chi:.2})",
        rayon::current_num_threads()
    );
}

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        println!("(smoke run; use `cargo bench --bench muscles` for figures)");
        return;
    }
    println!(
        "musculo muscles per frame: median (min – max) over {BATCHES} batches of {STATES} states"
    );
    let dir = musculo::reference::directory();
    for (label, rel) in [
        (
            "gait2392 (Thelen, via points)",
            "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        ),
        (
            "Rajagopal2016 (Millard, wrap cylinders)",
            "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
        ),
        (
            "Arm26 (Thelen, cylinders and ellipsoids)",
            "opensim-models/Models/Arm26/arm26.osim",
        ),
    ] {
        match Model::from_osim_file(dir.join(rel)) {
            Ok(m) => bench(label, &m),
            Err(e) => println!("\n{label}: skipped ({e})"),
        }
    }
}
