//! Per-frame cost of the Euler–Lagrange loss with all its gradients, beside one
//! inverse-dynamics call on the same states (the peer: the cheap-gradient bound of reverse
//! mode is a small multiple of it) and the full Jacobians of inverse dynamics.
//!
//! Columns, per frame on one core (median over batches of 200 random states, min–max):
//! - `ID`: `dynamics::rnea`;
//! - `VJP`: `RneaVjp::forward` + `backward` with 8 external point forces (uᵀ∂τ/∂q, q̇, q̈, λ);
//! - `loss+grad`: `loss::EulerLagrange::evaluate` with gradients over the batch (rayon pool
//!   of one thread), per frame;
//! - `Jacobians`: `dynamics::rnea_derivatives` (∂τ/∂q, ∂τ/∂q̇, ∂τ/∂q̈ as matrices).
//!
//! And the muscle loss, beside `muscle::path::compute_paths` (lengths and moment arms, the
//! forward pass any use of R(q) pays) on the same states, per frame on one core:
//! - `paths`: `compute_paths` after forward kinematics;
//! - `L_muscle`: `loss::MuscleLoss::evaluate` without gradients;
//! - `L_muscle+grad`: with ∂L/∂q (M by two RNEA VJPs, R by the exact moment-arm rates),
//!   ∂L/∂q̈ and ∂L/∂a.
//!
//! And a motion in the per-joint layout (the demo squat as `musculo augment` writes it, its
//! blocks taken as given), per frame on one core, beside one `dynamics::rnea` call:
//! - `fit`: `augment::layout_inverse::coordinates_from_layout` (q, q̇, q̈, τ from the layout);
//! - `L_euler+grad`: `loss::LayoutEulerLagrange` with gradients (contact forces at the joint
//!   centres, the best couple on each foot);
//! - `VJP`: `augment::layout_inverse_vjp` (those gradients back to every block of the layout).
//!
//! Run: `cargo bench --bench loss` (gait2392 and Rajagopal2016 from MUSCULO_REFERENCE or
//! ../shared/reference when present).

use musculo::dynamics::{self, PointForces, RneaDerivatives, RneaVjp};
use musculo::loss::{
    EulerLagrange, EulerLagrangeBatch, EulerLagrangeOutput, LossContact, MuscleBatch, MuscleLoss,
    MuscleLossOutput,
};
use musculo::muscle::path::{PathData, compute_paths};
use musculo::random::SplitMix64;
use musculo::spatial::Vec3;
use musculo::{Data, Model};
use std::hint::black_box;
use std::time::Instant;

const FRAMES: usize = 200;
const BATCHES: usize = 21;

struct Batch {
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    tau: Vec<f64>,
    lambda: Vec<f64>,
}

fn batch(model: &Model, contacts: usize) -> Batch {
    let mut rng = SplitMix64(7);
    let n = model.nq();
    let mut q = Vec::with_capacity(FRAMES * n);
    for _ in 0..FRAMES {
        for &c in &model.reduction.independent {
            let [lo, hi] = model.coordinates[c].range;
            q.push(rng.uniform(lo, hi));
        }
    }
    let mut draw = |len: usize, a: f64| (0..len).map(|_| rng.uniform(-a, a)).collect::<Vec<_>>();
    Batch {
        q,
        qd: draw(FRAMES * n, 1.0),
        qdd: draw(FRAMES * n, 5.0),
        tau: draw(FRAMES * n, 50.0),
        lambda: draw(FRAMES * 3 * contacts, 300.0),
    }
}

/// Median, min and max per-frame time in µs of `f` run over the batch, `BATCHES` times.
fn time(f: impl FnMut()) -> (f64, f64, f64) {
    time_n(f, BATCHES, FRAMES)
}

/// Median, min and max per-frame time in µs of `f` (one pass over `frames` frames), `runs` times.
fn time_n(mut f: impl FnMut(), runs: usize, frames: usize) -> (f64, f64, f64) {
    f();
    let mut t: Vec<f64> = (0..runs)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64() * 1e6 / frames as f64
        })
        .collect();
    t.sort_by(f64::total_cmp);
    (t[t.len() / 2], t[0], t[t.len() - 1])
}

/// Contact points on the feet: the model's spheres, or 4 points under the heels and toes.
fn contacts(model: &Model) -> Vec<LossContact> {
    if let Ok(set) = musculo::solve::contact::ContactSet::from_model(model) {
        return EulerLagrange::new().with_contact_set(&set).contacts;
    }
    ["calcn_r", "calcn_l", "toes_r", "toes_l"]
        .iter()
        .filter_map(|b| {
            Some(LossContact {
                name: b.to_string(),
                body: model.body_index(b)?,
                location_in_body: Vec3::new(0.05, -0.01, 0.0),
                offset_in_ground: Vec3::new(0.0, -0.03, 0.0),
            })
        })
        .collect()
}

fn bench(name: &str, model: &Model) {
    let n = model.nq();
    let loss = EulerLagrange {
        contacts: contacts(model),
        weights: vec![],
    };
    let p = loss.contacts.len();
    let b = batch(model, p);
    let mut data = Data::new(model);
    let id = time(|| {
        for f in 0..FRAMES {
            let r = f * n..(f + 1) * n;
            black_box(
                dynamics::rnea(
                    model,
                    &mut data,
                    &b.q[r.clone()],
                    &b.qd[r.clone()],
                    &b.qdd[r],
                )
                .unwrap(),
            );
        }
    });
    let carriers: Vec<(usize, Vec3)> = loss
        .contacts
        .iter()
        .map(|c| (c.body, c.location_in_body))
        .collect();
    let offsets: Vec<Vec3> = loss.contacts.iter().map(|c| c.offset_in_ground).collect();
    let mut forces = vec![Vec3::zeros(); p];
    let mut vjp = RneaVjp::new(model);
    let u = vec![0.5; n];
    let vjp_time = time(|| {
        for f in 0..FRAMES {
            let r = f * n..(f + 1) * n;
            for (c, l) in forces
                .iter_mut()
                .zip(b.lambda[f * 3 * p..(f + 1) * 3 * p].chunks(3))
            {
                *c = Vec3::new(l[0], l[1], l[2]);
            }
            let ext = PointForces {
                carriers: &carriers,
                offsets_in_ground: &offsets,
                forces: &forces,
            };
            vjp.forward(
                model,
                &mut data,
                &b.q[r.clone()],
                &b.qd[r.clone()],
                &b.qdd[r],
                &ext,
            )
            .unwrap();
            vjp.backward(model, &data, &u).unwrap();
            black_box(&vjp.dq);
        }
    });
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut out = EulerLagrangeOutput::default();
    let lb = EulerLagrangeBatch {
        frames: FRAMES,
        q: &b.q,
        qd: &b.qd,
        qdd: &b.qdd,
        tau: &b.tau,
        lambda: &b.lambda,
    };
    let loss_time = pool.install(|| time(|| loss.evaluate(model, &lb, true, &mut out).unwrap()));
    let mut der = RneaDerivatives::new(model);
    let jac = time(|| {
        for f in 0..FRAMES {
            let r = f * n..(f + 1) * n;
            dynamics::rnea_derivatives(
                model,
                &mut data,
                &b.q[r.clone()],
                &b.qd[r.clone()],
                &b.qdd[r],
                &mut der,
            )
            .unwrap();
            black_box(&der.dtau_dq);
        }
    });
    let cell = |t: (f64, f64, f64)| format!("{:>7.2} ({:.2}–{:.2})", t.0, t.1, t.2);
    println!(
        "{name:<18} n={n:<3} P={p:<2} ID {}  VJP {} = {:.1}× ID  loss+grad {} = {:.1}× ID  Jacobians {} = {:.1}× ID",
        cell(id),
        cell(vjp_time),
        vjp_time.0 / id.0,
        cell(loss_time),
        loss_time.0 / id.0,
        cell(jac),
        jac.0 / id.0
    );
}

/// Frames and runs of the muscle-loss timing (each frame wraps every muscle path).
const MUSCLE_FRAMES: usize = 40;
const MUSCLE_RUNS: usize = 7;

fn bench_muscle(name: &str, model: &Model) {
    let loss = MuscleLoss::new(model).unwrap();
    let (n, m) = (model.nq(), loss.muscles());
    if m == 0 {
        return;
    }
    let b = batch(model, 0);
    let mut rng = SplitMix64(9);
    let a: Vec<f64> = (0..MUSCLE_FRAMES * m)
        .map(|_| rng.uniform(0.0, 1.0))
        .collect();
    let q = &b.q[..MUSCLE_FRAMES * n];
    let qdd = &b.qdd[..MUSCLE_FRAMES * n];
    let mut data = Data::new(model);
    let mut paths = PathData::new(model, &loss.paths);
    let path_time = time_n(
        || {
            for f in 0..MUSCLE_FRAMES {
                dynamics::forward_kinematics(model, &mut data, &q[f * n..(f + 1) * n]).unwrap();
                compute_paths(model, &data, &loss.paths, &mut paths).unwrap();
                black_box(&paths.moment_arms);
            }
        },
        MUSCLE_RUNS,
        MUSCLE_FRAMES,
    );
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mb = MuscleBatch {
        frames: MUSCLE_FRAMES,
        q,
        qdd,
        a: &a,
    };
    let mut out = MuscleLossOutput::default();
    let mut run = |gradients: bool| {
        pool.install(|| {
            time_n(
                || loss.evaluate(model, &mb, gradients, &mut out).unwrap(),
                MUSCLE_RUNS,
                MUSCLE_FRAMES,
            )
        })
    };
    let value = run(false);
    let grad = run(true);
    let cell = |t: (f64, f64, f64)| format!("{:>8.1} ({:.1}–{:.1})", t.0, t.1, t.2);
    println!(
        "{name:<18} n={n:<3} m={m:<3} paths {}  L_muscle {} = {:.1}× paths  L_muscle+grad {} = {:.1}× paths",
        cell(path_time),
        cell(value),
        value.0 / path_time.0,
        cell(grad),
        grad.0 / path_time.0
    );
}

fn bench_layout() {
    use musculo::augment::chain::{Chain, ChainOptions};
    use musculo::augment::layout::JointLayout;
    use musculo::augment::layout_inverse::{LayoutClip, coordinates_from_layout};
    use musculo::augment::layout_inverse_vjp::{CoordinateGradient, coordinates_from_layout_vjp};
    use musculo::augment::{demo, perturb::Variant};
    use musculo::loss::{LayoutEulerLagrange, LayoutEulerLagrangeBatch, LayoutEulerLagrangeOutput};
    let chain = Chain::default_model(ChainOptions::default()).unwrap();
    let (_, motion) = demo::clips(&chain.model).unwrap().remove(1);
    let v = Variant::identity();
    let run = chain.run(&motion, None, &v).unwrap();
    let model = chain.clip_model(&motion, None, &v).unwrap();
    let get = |name: &str| -> Vec<f64> {
        let a = run.arrays.iter().find(|a| a.name == name).unwrap();
        a.values.iter().map(|&x| f64::from(x)).collect()
    };
    let blocks = [
        "joint_pos",
        "joint_rot",
        "joint_vel",
        "joint_acc",
        "joint_torque",
        "contact_force",
    ]
    .map(get);
    let time = get("time");
    let t = time.len();
    let clip = LayoutClip {
        frames: t,
        rate_hz: (t - 1) as f64 / (time[t - 1] - time[0]),
        joint_pos: &blocks[0],
        joint_rot: &blocks[1],
        joint_vel: &blocks[2],
        joint_acc: &blocks[3],
        joint_torque: &blocks[4],
    };
    let layout = JointLayout::new(&model, 0);
    let set = musculo::augment::chain::contact_set(&model).unwrap();
    let loss = LayoutEulerLagrange::from_contact_set(&model, &set, Vec::new()).unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let runs = 7;
    pool.install(|| {
        let c = coordinates_from_layout(&model, &layout, &clip).unwrap();
        let n = model.nq();
        let mut data = Data::new(&model);
        let id = time_n(
            || {
                for f in 0..t {
                    let r = f * n..(f + 1) * n;
                    black_box(
                        dynamics::rnea(
                            &model,
                            &mut data,
                            &c.q[r.clone()],
                            &c.qd[r.clone()],
                            &c.qdd[r],
                        )
                        .unwrap(),
                    );
                }
            },
            runs,
            t,
        );
        let fit = time_n(
            || {
                black_box(coordinates_from_layout(&model, &layout, &clip).unwrap());
            },
            runs,
            t,
        );
        let batch = LayoutEulerLagrangeBatch {
            frames: t,
            q: &c.q,
            qd: &c.qd,
            qdd: &c.qdd,
            tau: &c.tau,
            contact_force: &blocks[5],
        };
        let mut out = LayoutEulerLagrangeOutput::default();
        let el = time_n(
            || loss.evaluate(&model, &batch, true, &mut out).unwrap(),
            runs,
            t,
        );
        let bar = CoordinateGradient {
            q: &out.grad_q,
            qd: &out.grad_qd,
            qdd: &out.grad_qdd,
            tau: &out.grad_tau,
        };
        let vjp = time_n(
            || {
                black_box(coordinates_from_layout_vjp(&model, &layout, &clip, &c, &bar).unwrap());
            },
            runs,
            t,
        );
        let cell = |x: (f64, f64, f64)| {
            format!(
                "{:>7.1} ({:.1}–{:.1}) = {:.0}× ID",
                x.0,
                x.1,
                x.2,
                x.0 / id.0
            )
        };
        println!(
            "layout, per frame, µs, one core, {t}-frame squat (median, min–max of {runs} runs):\n  \
             ID {:.2}  fit {}  L_euler+grad {}  VJP {}",
            id.0,
            cell(fit),
            cell(el),
            cell(vjp)
        );
    });
}

fn main() {
    println!(
        "per frame, µs, one core: median (min–max) over {BATCHES} batches of {FRAMES} random states"
    );
    bench("musculo_fullbody", &Model::default_fullbody());
    for (name, rel) in [
        (
            "gait2392",
            "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        ),
        (
            "Rajagopal2016",
            "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
        ),
    ] {
        if let Some(path) = musculo::reference::file(rel) {
            bench(name, &Model::from_osim_file(&path).unwrap());
        }
    }
    println!(
        "muscle loss, per frame, µs, one core: median (min–max) over {MUSCLE_RUNS} runs of {MUSCLE_FRAMES} random states"
    );
    bench_muscle("musculo_fullbody", &Model::default_fullbody());
    for (name, rel) in [
        (
            "gait2392",
            "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        ),
        (
            "Rajagopal2016",
            "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
        ),
    ] {
        if let Some(path) = musculo::reference::file(rel) {
            bench_muscle(name, &Model::from_osim_file(&path).unwrap());
        }
    }
    bench_layout();
}
