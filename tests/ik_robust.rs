//! Robust inverse kinematics (`solve::ik::robust`): a marker that disagrees with the others
//! over the clip is down-weighted and named, and the fit of the others stays as it is
//! without it.
//!
//! The Gait2392 walk (`Pipelines/Gait2392_Simbody`, `subject01_simbody.osim` and
//! `subject01_walk1.trc`) with its markers matched by name, every weight 1: clean, with one
//! marker displaced by 100 mm for the whole trial, and with two markers swapped for the
//! whole trial. The reference is the clean fit: the median over frames of the good markers'
//! RMS error within 3 mm of it, every frame's coordinates close to it, and the bad markers
//! the ones named. The table (`--nocapture`) also shows the plain least-squares fit of each
//! case. A second test knows the answer exactly: markers made by forward kinematics from a
//! motion, one of them displaced, give the motion back.

mod common;

use common::reference_file;
use musculo::Model;
use musculo::dynamics::{self, Data};
use musculo::model::MotionType;
use musculo::motion::{self, Motion, ReadOptions};
use musculo::solve::ik::robust::{self as ik_robust, RobustMarkers};
use musculo::solve::ik::{self, IkSettings, IkSolution, IkTasks};
use musculo::spatial::Vec3;

const DIR: &str = "opensim-models/Pipelines/Gait2392_Simbody";

fn robust() -> IkSettings {
    IkSettings {
        robust: Some(RobustMarkers::default()),
        ..IkSettings::default()
    }
}

fn gait2392_walk() -> Option<(Model, Motion)> {
    let model = reference_file(&format!("{DIR}/OutputReference/subject01_simbody.osim"))?;
    let trc = reference_file(&format!("{DIR}/subject01_walk1.trc"))?;
    let model = Model::from_osim_file(&model).unwrap();
    let motion = motion::read(&trc, None, &ReadOptions::default()).unwrap();
    Some((model, motion))
}

/// A bad marker file: the column of `name` moved by `offset` (m) in every frame.
fn displaced(motion: &Motion, name: &str, offset: Vec3) -> Motion {
    let mut out = motion.clone();
    let (i, n) = (motion.index(name).unwrap(), motion.n_targets());
    for f in 0..motion.n_frames() {
        out.positions[f * n + i] += offset;
    }
    out
}

/// A bad marker file: the columns of `a` and `b` swapped in every frame.
fn swapped(motion: &Motion, a: &str, b: &str) -> Motion {
    let mut out = motion.clone();
    let (i, j, n) = (
        motion.index(a).unwrap(),
        motion.index(b).unwrap(),
        motion.n_targets(),
    );
    for f in 0..motion.n_frames() {
        out.positions.swap(f * n + i, f * n + j);
    }
    out
}

fn task_names(model: &Model, tasks: &IkTasks) -> Vec<String> {
    (tasks.markers.iter())
        .map(|t| model.markers[t.marker].name.clone())
        .collect()
}

fn named(names: &[String], s: &IkSolution) -> Vec<String> {
    s.disagreeing
        .iter()
        .map(|d| names[d.task].clone())
        .collect()
}

/// Median over frames of the RMS error of the markers not in `bad`.
fn good_median(names: &[String], s: &IkSolution, bad: &[&str]) -> f64 {
    let nm = names.len();
    let mut per_frame: Vec<f64> = (0..s.n_frames())
        .map(|f| {
            let (mut sum, mut k) = (0.0, 0);
            for (i, name) in names.iter().enumerate() {
                let e = s.marker_error[f * nm + i];
                if !bad.contains(&name.as_str()) && e.is_finite() {
                    sum += e * e;
                    k += 1;
                }
            }
            (sum / k as f64).sqrt()
        })
        .collect();
    ik_robust::median(&mut per_frame)
}

/// The largest difference over frames of the rotational coordinates (rad, and which) and of
/// the translational ones (m).
fn coordinate_gap(model: &Model, a: &IkSolution, b: &IkSolution) -> (f64, String, f64) {
    let n = model.nq();
    let names = model.q_names();
    let (mut rot, mut which, mut tra) = (0.0f64, String::new(), 0.0f64);
    for (k, (x, y)) in a.q.iter().zip(&b.q).enumerate() {
        let c = model.reduction.independent[k % n];
        let d = (x - y).abs();
        // gait2392's pelvis translations read as Coupled (functions in a CustomJoint)
        match model.coordinates[c].motion_type {
            MotionType::Rotational if d > rot => (rot, which) = (d, names[k % n].to_string()),
            MotionType::Rotational => {}
            _ => tra = tra.max(d),
        }
    }
    (rot, which, tra)
}

#[test]
fn gait2392_walk_with_a_displaced_or_swapped_marker_fits_as_the_clean_walk() {
    let Some((model, clean)) = gait2392_walk() else {
        return;
    };
    let tasks = ik::tasks_by_name(&model, &clean);
    assert!(tasks.markers.iter().all(|t| t.weight == 1.0));
    let names = task_names(&model, &tasks);
    let solve = |m: &Motion, settings: &IkSettings| {
        ik::solve_motion(&model, m, &tasks, settings, &|_| {}).unwrap()
    };
    let reference = solve(&clean, &robust());
    let reference_plain = solve(&clean, &IkSettings::default());
    let clean_named = named(&names, &reference);
    println!(
        "Gait2392 walk, {} markers by name (weight 1), {} frames; clean fit names {:?}",
        names.len(),
        reference.n_frames(),
        clean_named
    );
    for w in ik_robust::warnings(&model, &tasks, &reference, "clean") {
        println!("  {w}");
    }
    // the acromia fit worst (64 and 58 mm) but carry most of the trunk's axial rotation: the
    // others cannot outvote them, and the clean walk is fitted as by plain least squares
    assert!(clean_named.is_empty(), "{clean_named:?}");
    assert_eq!(reference, reference_plain);
    let cases: Vec<(&str, Vec<&str>, Motion)> = vec![
        (
            "R.Thigh.Front +100 mm x",
            vec!["R.Thigh.Front"],
            displaced(&clean, "R.Thigh.Front", Vec3::new(0.1, 0.0, 0.0)),
        ),
        (
            "L.Heel +100 mm y",
            vec!["L.Heel"],
            displaced(&clean, "L.Heel", Vec3::new(0.0, 0.1, 0.0)),
        ),
        (
            "R.ASIS +100 mm z",
            vec!["R.ASIS"],
            displaced(&clean, "R.ASIS", Vec3::new(0.0, 0.0, 0.1)),
        ),
        (
            "R.Heel <-> L.Heel",
            vec!["R.Heel", "L.Heel"],
            swapped(&clean, "R.Heel", "L.Heel"),
        ),
        (
            "R.Thigh.Front <-> R.Shank.Front",
            vec!["R.Thigh.Front", "R.Shank.Front"],
            swapped(&clean, "R.Thigh.Front", "R.Shank.Front"),
        ),
    ];
    println!(
        "\nEach fit against the clean walk's fit and the fit without the bad markers, both of \
         the same kind (plain least squares or robust):\n\n| case | fit | good markers' median \
         RMS | vs clean fit | vs fit without the bad markers | largest Δq vs clean fit | \
         largest Δq vs fit without | named |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut failures = Vec::new();
    for (label, bad, motion) in &cases {
        // the reference of the issue: the fit with the bad markers left out
        let kept = IkTasks {
            markers: (tasks.markers.iter())
                .filter(|t| !bad.contains(&model.markers[t.marker].name.as_str()))
                .cloned()
                .collect(),
            coordinates: Vec::new(),
        };
        for (fit, settings, reference) in [
            ("plain", IkSettings::default(), &reference_plain),
            ("robust", robust(), &reference),
        ] {
            let clean_good = good_median(&names, reference, bad);
            let without = ik::solve_motion(&model, &clean, &kept, &settings, &|_| {}).unwrap();
            let without_good = good_median(&task_names(&model, &kept), &without, bad);
            let s = solve(motion, &settings);
            let good = good_median(&names, &s, bad);
            let (rot, which, tra) = coordinate_gap(&model, &s, reference);
            let (rot_w, which_w, tra_w) = coordinate_gap(&model, &s, &without);
            let who = named(&names, &s);
            println!(
                "| {label} | {fit} | {:.2} mm | {:+.2} mm | {:+.2} mm | {:.2}° ({which}), {:.1} mm | {:.3}° ({which_w}), {:.2} mm | {} |",
                good * 1e3,
                (good - clean_good) * 1e3,
                (good - without_good) * 1e3,
                rot.to_degrees(),
                tra * 1e3,
                rot_w.to_degrees(),
                tra_w * 1e3,
                if who.is_empty() {
                    "–".into()
                } else {
                    who.join(", ")
                }
            );
            if fit == "plain" {
                continue;
            }
            for w in ik_robust::warnings(&model, &tasks, &s, "walk.trc") {
                println!("  {w}");
            }
            if (good - clean_good).abs() > 3e-3 || (good - without_good).abs() > 1e-3 {
                failures.push(format!(
                    "{label}: good markers' median {good}, clean {clean_good}, without {without_good}"
                ));
            }
            if rot_w > 0.5f64.to_radians() || tra_w > 1e-3 {
                failures.push(format!(
                    "{label}: coordinates {:.2}° ({which_w}) / {:.2} mm from the fit without",
                    rot_w.to_degrees(),
                    tra_w * 1e3
                ));
            }
            for b in bad {
                if !who.iter().any(|w| w == b) {
                    failures.push(format!("{label}: {b} not named ({who:?})"));
                }
            }
            for w in &who {
                if !bad.contains(&w.as_str()) && !clean_named.contains(w) {
                    failures.push(format!("{label}: good marker {w} named"));
                }
            }
            // the fit figures leave the named markers out
            let worst = s.max_error.iter().copied().fold(0.0, f64::max);
            assert!(worst < 0.1, "{label}: worst kept marker {worst}");
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Markers of every task at the coordinates `q` (frame-major), as a motion.
fn markers_at(model: &Model, tasks: &IkTasks, names: &[String], q: &[f64], rate: f64) -> Motion {
    let mut data = Data::new(model);
    let mut positions = Vec::new();
    for qf in q.chunks(model.nq()) {
        dynamics::forward_kinematics(model, &mut data, qf).unwrap();
        for t in &tasks.markers {
            let m = &model.markers[t.marker];
            positions.push(data.point_position(m.body, &m.location_in_body));
        }
    }
    Motion::uniform("synthetic", names.to_vec(), rate, positions).unwrap()
}

#[test]
fn exact_markers_with_one_displaced_give_the_motion_back() {
    let Some((model, walk)) = gait2392_walk() else {
        return;
    };
    // a motion the model can follow exactly: the walk's own fit, its markers made from it
    let tasks = ik::tasks_by_name(&model, &walk);
    let truth = ik::solve_motion(&model, &walk, &tasks, &IkSettings::default(), &|_| {})
        .unwrap()
        .q;
    let names = task_names(&model, &tasks);
    let exact = markers_at(&model, &tasks, &names, &truth, walk.rate_hz);
    let exact_tasks = ik::tasks_by_name(&model, &exact);
    let solve = |m: &Motion, settings: &IkSettings| {
        ik::solve_motion(&model, m, &exact_tasks, settings, &|_| {}).unwrap()
    };
    // nothing disagrees: the robust fit is the plain fit, bit for bit
    let plain = solve(&exact, &IkSettings::default());
    let clean = solve(&exact, &robust());
    assert!(clean.disagreeing.is_empty());
    assert_eq!(plain, clean);
    // one marker 100 mm off: named, and the motion comes back
    let bad = displaced(&exact, "R.Shank.Front", Vec3::new(0.0, 0.0, 0.1));
    let fit = solve(&bad, &robust());
    let who = named(&names, &fit);
    let gap = (fit.q.iter().zip(&truth))
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let plain_gap = (solve(&bad, &IkSettings::default()).q.iter().zip(&truth))
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    println!(
        "exact markers, R.Shank.Front +100 mm z: named {who:?}; largest coordinate error {gap:.2e} \
         (plain least squares {plain_gap:.2e})"
    );
    assert_eq!(who, ["R.Shank.Front"]);
    // the displaced marker keeps 10⁻³ of its weight: 0.1 mm of pull
    assert!(gap < 1e-3, "{gap}");
    assert!(
        plain_gap > 100.0 * gap,
        "the displaced marker bends the plain fit"
    );
}
