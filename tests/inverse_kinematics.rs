//! Inverse kinematics (`solve::ik`) against known answers: synthetic marker positions made
//! by forward kinematics from a known motion must give that motion back.

mod common;

use common::Rng;
use musculo::Model;
use musculo::dynamics::{self, Data};
use musculo::model::MotionType;
use musculo::motion::Motion;
use musculo::solve::ik::{self, IkSettings};

/// The 22 SMPL joint-centre markers of the default model (named as HumanML3D's joints).
const SMPL: [&str; 22] = musculo::motion::humanml3d::JOINT_NAMES;

/// A smooth motion inside the middle 70 % of every coordinate's range (elbows kept bent so
/// the humerus' axial rotation is seen by the wrist).
fn smooth_motion(model: &Model, frames: usize, rate: f64, seed: u64) -> Vec<f64> {
    let mut rng = Rng::new(seed);
    let n = model.nq();
    let params: Vec<(f64, f64, f64, f64)> = model
        .reduction
        .independent
        .iter()
        .map(|&c| {
            let coord = &model.coordinates[c];
            let [mut lo, mut hi] = coord.range;
            if coord.name.starts_with("pelvis_t") {
                (lo, hi) = (-0.3, 0.3);
            }
            // The heading's range spans several turns; a pose repeats every turn.
            if coord.name == "pelvis_rotation" {
                (lo, hi) = (-1.5, 1.5);
            }
            if coord.name.starts_with("elbow_flex") {
                (lo, hi) = (0.4, 2.2);
            }
            let mid = 0.5 * (lo + hi);
            let amp = 0.35 * (hi - lo);
            (
                mid + rng.uniform(-0.3, 0.3) * amp,
                0.6 * amp,
                rng.uniform(0.5, 2.0),
                rng.uniform(0.0, std::f64::consts::TAU),
            )
        })
        .collect();
    let mut q = Vec::with_capacity(frames * n);
    for f in 0..frames {
        let t = f as f64 / rate;
        for (j, &(mid, amp, w, ph)) in params.iter().enumerate() {
            let mut v = mid + amp * (w * t + ph).sin();
            if model.coordinates[model.reduction.independent[j]].name == "pelvis_ty" {
                v += 0.93;
            }
            q.push(v);
        }
    }
    q
}

fn synthetic_targets(model: &Model, names: &[&str], q: &[f64], rate: f64) -> Motion {
    let n = model.nq();
    let idx: Vec<usize> = names
        .iter()
        .map(|m| model.markers.iter().position(|k| k.name == *m).unwrap())
        .collect();
    let mut data = Data::new(model);
    let mut pos = Vec::new();
    for qf in q.chunks(n) {
        dynamics::forward_kinematics(model, &mut data, qf).unwrap();
        for &i in &idx {
            let m = &model.markers[i];
            pos.push(data.point_position(m.body, &m.location_in_body));
        }
    }
    Motion::uniform(
        "synthetic",
        names.iter().map(|s| s.to_string()).collect(),
        rate,
        pos,
    )
    .unwrap()
}

#[test]
fn joint_centre_round_trip_recovers_the_default_model_coordinates() {
    let model = Model::default_fullbody();
    let (frames, rate) = (60, 20.0);
    let q_true = smooth_motion(&model, frames, rate, 7);
    let targets = synthetic_targets(&model, &SMPL, &q_true, rate);
    let tasks = ik::tasks_by_name(&model, &targets);
    assert_eq!(tasks.markers.len(), 22);
    let settings = IkSettings::default();
    let sol = ik::solve_motion(&model, &targets, &tasks, &settings, &|_| {}).unwrap();
    let n = model.nq();
    let names = model.q_names();
    let mut worst = vec![0.0f64; n];
    for f in 0..frames {
        for j in 0..n {
            worst[j] = worst[j].max((sol.q[f * n + j] - q_true[f * n + j]).abs());
        }
    }
    let mut failures = Vec::new();
    for j in 0..n {
        let c = model.reduction.independent[j];
        let translational = model.coordinates[c].motion_type == MotionType::Translational;
        let (lim, unit, scale) = if translational {
            (0.5e-3, "mm", 1e3)
        } else {
            (0.1f64.to_radians(), "deg", 57.29577951308232)
        };
        println!(
            "{:>20}: max error {:.2e} {unit}",
            names[j],
            worst[j] * scale
        );
        if worst[j] > lim {
            failures.push(names[j]);
        }
    }
    let rmse = sol.rmse.iter().cloned().fold(0.0, f64::max);
    println!(
        "worst frame marker RMSE {rmse:.2e} m, iterations {:?}",
        &sol.iterations[..5]
    );
    assert!(failures.is_empty(), "not recovered: {failures:?}");
}
