//! `evaluate`: each metric responds to the artefact it measures, by the amount the physics
//! says, on clips written by the augmentation chain (the demo clips of the default model):
//! lifting raises Float by the lift and nothing else, sinking raises Penetrate, sliding the
//! stance feet raises Skate, doubling τ raises the actuation error and the residual, noise on
//! q̈ raises the residual; the reserve share recomputed from the file's muscle forces equals
//! the chain's own figure; the trajectory metrics see a displaced target.

mod common;

use common::{musculo_cli, reference_file};
use musculo::augment::chain::{Chain, ChainOptions};
use musculo::augment::demo;
use musculo::augment::output;
use musculo::augment::perturb::Variant;
use musculo::evaluate::{
    Capacity, CapacityCurves, ClipMetrics, Control, EvaluateOptions, evaluate_clip, summarize,
};
use musculo::loss::tensor_file::TensorFrames;
use musculo::{Data, Model, dynamics};

struct Clip {
    name: String,
    model: Model,
    frames: TensorFrames,
    reserve_share: f64,
}

/// The demo clips through the chain, written and read back as tensor files.
fn clips() -> Vec<Clip> {
    let chain = Chain::new(
        musculo::DEFAULT_MODEL_OSIM.to_string(),
        "models/musculo_fullbody.osim".into(),
        ChainOptions::default(),
    )
    .unwrap();
    // one folder per call: the tests run in parallel
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("musculo-evaluate-{}-{call}", std::process::id()));
    let mut out = Vec::new();
    for (name, motion) in demo::clips(&chain.model).unwrap() {
        let v = Variant::identity();
        let run = chain.run(&motion, None, &v).unwrap();
        let model = chain.clip_model(&motion, None, &v).unwrap();
        output::write_clip(&dir, &name, &run.arrays).unwrap();
        let frames = TensorFrames::read(&output::npz_path(&dir, &name), &model).unwrap();
        out.push(Clip {
            name,
            model,
            frames,
            reserve_share: run.quality.reserve_share,
        });
    }
    let _ = std::fs::remove_dir_all(dir);
    out
}

fn coordinate(model: &Model, name: &str) -> usize {
    model.q_names().iter().position(|n| *n == name).unwrap()
}

fn eval(
    c: &Clip,
    frames: &TensorFrames,
    reference: Option<&TensorFrames>,
    o: &EvaluateOptions,
) -> ClipMetrics {
    evaluate_clip(
        &c.model,
        &c.name,
        frames,
        reference,
        None,
        Capacity::PerFrame,
        o,
    )
    .unwrap()
}

/// Every metric but those named, equal in `a` and `b` (to `tol` relative).
fn same_except(a: &ClipMetrics, b: &ClipMetrics, except: &[&str], tol: f64) {
    let close = |x: f64, y: f64| (x - y).abs() <= tol * (1.0 + x.abs().max(y.abs()));
    let opt = |x: Option<f64>, y: Option<f64>| match (x, y) {
        (Some(x), Some(y)) => close(x, y),
        (None, None) => true,
        _ => false,
    };
    let fields: [(&str, bool); 12] = [
        ("skate", close(a.skate, b.skate)),
        ("skate_speed", close(a.skate_speed, b.skate_speed)),
        ("float", close(a.float, b.float)),
        ("penetrate", close(a.penetrate, b.penetrate)),
        (
            "support_fraction",
            close(a.support_fraction, b.support_fraction),
        ),
        (
            "contact_force_error",
            opt(a.contact_force_error, b.contact_force_error),
        ),
        (
            "actuation_excess",
            opt(a.actuation_excess, b.actuation_excess),
        ),
        ("actuation_error", opt(a.actuation_error, b.actuation_error)),
        ("reserve_share", opt(a.reserve_share, b.reserve_share)),
        (
            "activation_excess",
            opt(a.activation_excess, b.activation_excess),
        ),
        ("el_residual", opt(a.el_residual, b.el_residual)),
        ("actuation_peak", opt(a.actuation_peak, b.actuation_peak)),
    ];
    for (name, equal) in fields {
        if !except.contains(&name) {
            assert!(equal, "{}: {name} changed\n{a:?}\n{b:?}", a.clip);
        }
    }
}

#[test]
fn each_metric_responds_to_its_artefact_by_the_expected_amount() {
    for c in clips() {
        let n = c.model.nq();
        let (ty, tx) = (
            coordinate(&c.model, "pelvis_ty"),
            coordinate(&c.model, "pelvis_tx"),
        );
        let t_count = c.frames.frames;
        let base0 = eval(&c, &c.frames, Some(&c.frames), &EvaluateOptions::default());
        // the floor just under the deepest sphere: the clip as given neither penetrates nor
        // (by more than its stance heights) floats
        let o = EvaluateOptions {
            floor_height: Some(-base0.penetrate_max),
            ..EvaluateOptions::default()
        };
        let base = eval(&c, &c.frames, Some(&c.frames), &o);
        println!("{}: {base:?}", c.name);
        assert_eq!(base.penetrate, 0.0);
        assert_eq!(base.contact_force_error, Some(0.0));
        assert_eq!(base.actuation_error, Some(0.0));
        assert!(base.el_residual.unwrap() < 1e-5, "{}", c.name);
        // feet flat on the floor: no skating. (Marching in place lifts each foot forward at
        // about 1 m/s through the 5 cm band, which GMD's thresholds count as skating.)
        if c.name != "march" {
            assert!(base.skate < 0.05, "{}: {}", c.name, base.skate);
        }

        // lifted 5 cm: Float + 0.05 exactly, nothing else
        let mut lifted = c.frames.clone();
        for f in 0..t_count {
            lifted.q[f * n + ty] += 0.05;
        }
        let up = eval(&c, &lifted, Some(&c.frames), &o);
        assert!(
            (up.float - base.float - 0.05).abs() < 1e-9,
            "{}: float {} → {}",
            c.name,
            base.float,
            up.float
        );
        same_except(&base, &up, &["float"], 1e-6);

        // sunk 5 cm: every frame's lowest sphere goes 5 cm deeper, so (all its heights above
        // this floor being below 5 cm) Penetrate = 0.05 − the mean height over all frames
        let mut sunk = c.frames.clone();
        for f in 0..t_count {
            sunk.q[f * n + ty] -= 0.05;
        }
        let down = eval(&c, &sunk, Some(&c.frames), &o);
        if base.support_fraction == 1.0 && base.float_max < 0.05 {
            assert!(
                (down.penetrate - (0.05 - base.float)).abs() < 1e-9,
                "{}: penetrate {} vs {}",
                c.name,
                down.penetrate,
                0.05 - base.float
            );
            assert_eq!(down.float, 0.0);
        }
        assert!(down.penetrate > 0.04, "{}: {}", c.name, down.penetrate);
        same_except(&base, &down, &["float", "penetrate"], 1e-6);

        // slid at 1 m/s along x: every in-contact speed v becomes |v + 1 x̂| ∈ [1 − v, 1 + v]
        let mut slid = c.frames.clone();
        for f in 0..t_count {
            slid.q[f * n + tx] += f as f64 / base.rate_hz;
            slid.qd[f * n + tx] += 1.0;
        }
        let slide = eval(&c, &slid, Some(&c.frames), &o);
        assert!(
            (slide.skate_speed - 1.0).abs() <= base.skate_speed + 1e-6,
            "{}: {} (was {})",
            c.name,
            slide.skate_speed,
            base.skate_speed
        );
        assert!(slide.skate > 0.9, "{}: skate {}", c.name, slide.skate);
        same_except(&base, &slide, &["skate", "skate_speed"], 1e-6);
        // … on a treadmill whose belt runs at that 1 m/s, or with the floor's velocity taken
        // from the clip itself, the slide is gone: the metrics of the clip at rest
        let belt = EvaluateOptions {
            floor_velocity: Some(musculo::spatial::Vec3::new(1.0, 0.0, 0.0)),
            ..o.clone()
        };
        same_except(&base, &eval(&c, &slid, Some(&c.frames), &belt), &[], 1e-6);
        let own = EvaluateOptions {
            floor_velocity: None,
            ..o.clone()
        };
        let (still, moving) = (
            eval(&c, &c.frames, Some(&c.frames), &own),
            eval(&c, &slid, Some(&c.frames), &own),
        );
        println!(
            "{}: floor velocity from the clip — skate {:.3} → {:.3} (at rest {:.3}), slid {:.3}",
            c.name, base.skate, still.skate, base.skate, moving.skate
        );
        same_except(&still, &moving, &[], 1e-6);

        // τ × 2: the error against the reference is RMS(τ_joints)/mass, and r = −τ
        let mut doubled = c.frames.clone();
        doubled.tau.iter_mut().for_each(|t| *t *= 2.0);
        let twice = eval(&c, &doubled, Some(&c.frames), &o);
        let set = musculo::solve::contact::ContactSet::from_model(&c.model).unwrap();
        let joints: Vec<usize> = (0..n).filter(|j| !set.floating_base.contains(j)).collect();
        let rms = (c
            .frames
            .tau
            .chunks(n)
            .map(|t| joints.iter().map(|&j| t[j] * t[j]).sum::<f64>())
            .sum::<f64>()
            / (t_count * joints.len()) as f64)
            .sqrt();
        let expected = rms / base.body_mass;
        let got = twice.actuation_error.unwrap();
        assert!(
            (got - expected).abs() < 1e-9 * expected,
            "{got} vs {expected}"
        );
        assert!(twice.actuation_excess.unwrap() >= base.actuation_excess.unwrap());
        let mut data = Data::new(&c.model);
        let mut relative = |qdd_noise: &[f64], tau: &[f64]| -> f64 {
            // ‖r_t‖/‖τ_ID,t‖ with r_t = τ_ID − τ − J_cᵀλ ≈ (τ_ID − τ_ID,file) + (τ_file − τ)
            let mut v: Vec<f64> = (0..t_count)
                .map(|f| {
                    let r = f * n..(f + 1) * n;
                    let qdd: Vec<f64> = c.frames.qdd[r.clone()]
                        .iter()
                        .zip(&qdd_noise[r.clone()])
                        .map(|(a, b)| a + b)
                        .collect();
                    let id = dynamics::rnea(
                        &c.model,
                        &mut data,
                        &c.frames.q[r.clone()],
                        &c.frames.qd[r.clone()],
                        &qdd,
                    )
                    .unwrap()
                    .clone();
                    let id0 = dynamics::rnea(
                        &c.model,
                        &mut data,
                        &c.frames.q[r.clone()],
                        &c.frames.qd[r.clone()],
                        &c.frames.qdd[r.clone()],
                    )
                    .unwrap()
                    .clone();
                    let res: f64 = (0..n)
                        .map(|j| {
                            (id[j] - id0[j] + c.frames.tau[f * n + j] - tau[f * n + j]).powi(2)
                        })
                        .sum::<f64>()
                        .sqrt();
                    res / id.norm()
                })
                .collect();
            v.sort_by(f64::total_cmp);
            if v.len() % 2 == 1 {
                v[v.len() / 2]
            } else {
                0.5 * (v[v.len() / 2 - 1] + v[v.len() / 2])
            }
        };
        let zero = vec![0.0; t_count * n];
        let expected = relative(&zero, &doubled.tau);
        let got = twice.el_residual.unwrap();
        assert!(
            (got - expected).abs() < 1e-4 * expected,
            "{got} vs {expected}"
        );
        same_except(
            &base,
            &twice,
            &[
                "actuation_excess",
                "actuation_error",
                "actuation_peak",
                "el_residual",
                "reserve_share",
            ],
            1e-6,
        );

        // noise on q̈ (uniform in ±0.5 rad/s² or m/s², seeded): the residual becomes ‖M δ‖ / ‖τ_ID‖
        let mut rng = musculo::random::SplitMix64(7);
        let noise: Vec<f64> = (0..t_count * n).map(|_| rng.uniform(-0.5, 0.5)).collect();
        let mut noisy = c.frames.clone();
        noisy.qdd.iter_mut().zip(&noise).for_each(|(a, b)| *a += b);
        let shaken = eval(&c, &noisy, Some(&c.frames), &o);
        let expected = relative(&noise, &c.frames.tau);
        let got = shaken.el_residual.unwrap();
        assert!(
            (got - expected).abs() < 1e-4 * expected,
            "{got} vs {expected}"
        );
        assert!(got > 100.0 * base.el_residual.unwrap());

        // the reserve share from τ − R F of the file = the chain's own (from its SO reserves)
        let share = base.reserve_share.unwrap();
        assert!(
            (share - c.reserve_share).abs() < 1e-3 * c.reserve_share.max(1e-3),
            "{}: {share} vs {}",
            c.name,
            c.reserve_share
        );
        // ground forces 10 % larger: Σ_g ‖0.1 F_g‖ / BW per frame
        let mut heavier = c.frames.clone();
        heavier.grf.iter_mut().for_each(|v| *v *= 1.1);
        let loaded = eval(&c, &heavier, Some(&c.frames), &o);
        let weight = base.body_mass * c.model.gravity.norm();
        let expected = c
            .frames
            .grf
            .chunks(3)
            .map(|f| 0.1 * (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt())
            .sum::<f64>()
            / weight
            / t_count as f64;
        let got = loaded.contact_force_error.unwrap();
        assert!(
            (got - expected).abs() < 1e-9 * expected.max(1e-9),
            "{got} vs {expected}"
        );
    }
}

#[test]
fn trajectory_metrics_see_a_displaced_target() {
    let c = clips().remove(0);
    let (n, nj, t_count) = (c.model.nq(), c.model.joints.len(), c.frames.frames);
    // the clip's own joint centres at every 10th frame, for the right wrist's joint
    let mut data = Data::new(&c.model);
    let mut control = Control {
        frames: t_count,
        joint_pos: vec![0.0; t_count * nj * 3],
        mask: vec![false; t_count * nj],
    };
    let wrist = c
        .model
        .joints
        .iter()
        .position(|j| j.name.contains("radiocarp") || j.name.contains("wrist"))
        .unwrap_or(nj - 1);
    for f in (0..t_count).step_by(10) {
        dynamics::forward_kinematics(&c.model, &mut data, &c.frames.q[f * n..(f + 1) * n]).unwrap();
        let joint = &c.model.joints[wrist];
        let p = data.point_position(joint.child_body, &joint.child_offset.pos);
        let i = f * nj + wrist;
        control.mask[i] = true;
        control.joint_pos[3 * i..3 * i + 3].copy_from_slice(p.as_slice());
    }
    let o = EvaluateOptions::default();
    let m = evaluate_clip(
        &c.model,
        &c.name,
        &c.frames,
        None,
        Some(&control),
        Capacity::PerFrame,
        &o,
    )
    .unwrap();
    assert_eq!(m.trajectory_failed, Some(false));
    assert!(m.trajectory_error.unwrap() < 1e-9);
    // one target 0.6 m away: that sample fails, the clip fails
    control.joint_pos[3 * wrist + 1] += 0.6;
    let m = evaluate_clip(
        &c.model,
        &c.name,
        &c.frames,
        None,
        Some(&control),
        Capacity::PerFrame,
        &o,
    )
    .unwrap();
    let samples = control.mask.iter().filter(|m| **m).count() as f64;
    assert_eq!(m.trajectory_failed, Some(true));
    assert!((m.location_failure.unwrap() - 1.0 / samples).abs() < 1e-12);
    assert!((m.trajectory_error.unwrap() - 0.6 / samples).abs() < 1e-9);
    let s = summarize(&[
        m.clone(),
        ClipMetrics {
            trajectory_failed: Some(false),
            frames: 10,
            ..m
        },
    ]);
    assert_eq!(s.trajectory, Some(0.5));
}

#[test]
fn bad_inputs_are_errors_naming_the_clip() {
    let c = clips().remove(0);
    let o = EvaluateOptions::default();
    let mut short = c.frames.clone();
    short.frames = 1;
    let e = evaluate_clip(&c.model, "x", &short, None, None, Capacity::PerFrame, &o)
        .unwrap_err()
        .to_string();
    assert!(e.contains("x") && e.contains("frame"), "{e}");
    let mut reference = c.frames.clone();
    reference.frames -= 1;
    let e = evaluate_clip(
        &c.model,
        "walk",
        &c.frames,
        Some(&reference),
        None,
        Capacity::PerFrame,
        &o,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("walk") && e.contains("reference"), "{e}");
    let bad = EvaluateOptions {
        skate_window: 4,
        ..o
    };
    assert!(
        evaluate_clip(
            &c.model,
            "x",
            &c.frames,
            None,
            None,
            Capacity::PerFrame,
            &bad
        )
        .is_err()
    );
}

/// Real data through `musculo augment` and `musculo evaluate` (CLI): the C3D trials with their
/// force plates (the measured loads enter the residual through `external`) and the HumanML3D
/// sample. The Euler–Lagrange residual of what augment wrote is zero, as the physics says; the
/// other figures are printed (docs/src/guide/evaluation.md).
#[test]
fn real_clips_have_a_zero_residual_and_print_their_figures() {
    let (Some(c3d), Some(hml)) = (
        reference_file("c3d"),
        reference_file("humanml3d/new_joints_012314.npy"),
    ) else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("musculo-evaluate-real-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (plates, hml_out) = (dir.join("plates"), dir.join("hml"));
    let runs = [
        (
            "augment --input {} --map c3d_lower_body --force-plates --opensim-files --out {}",
            &c3d,
            &plates,
        ),
        (
            "augment --input {} --opensim-files --out {}",
            &hml,
            &hml_out,
        ),
    ];
    for (pattern, input, out) in runs {
        let (ok, _, err) = musculo_cli(pattern, &[input, out]);
        assert!(ok, "{err}");
    }
    // the motion file itself (through the chain without muscles) gives the figures of its
    // augmented tensors
    let (raw, tensors) = (dir.join("raw.json"), dir.join("tensors.json"));
    for (input, json) in [(&hml, &raw), (&hml_out, &tensors)] {
        let (ok, _, err) = musculo_cli("evaluate --input {} --out {}", &[input, json]);
        assert!(ok, "{err}");
    }
    let clip = |p: &std::path::PathBuf| -> serde_json::Value {
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
        v["clips"][0].clone()
    };
    let (a, b) = (clip(&raw), clip(&tensors));
    // (not the capacities: per frame for a motion file, the strength curves for tensors)
    for key in [
        "frames",
        "skate",
        "skate_speed",
        "float",
        "penetrate",
        "support_fraction",
        "el_residual",
    ] {
        let (x, y) = (a[key].as_f64().unwrap(), b[key].as_f64().unwrap());
        assert!(
            (x - y).abs() <= 1e-6 * (1.0 + x.abs()),
            "{key}: motion file {x}, tensors {y}"
        );
    }
    for out in [&plates, &hml_out] {
        for floor in ["0", "clip"] {
            let json = dir.join("m.json");
            let (ok, stdout, err) = musculo_cli(
                &format!("evaluate --input {{}} --floor {floor} --out {{}}"),
                &[out, &json],
            );
            assert!(ok, "{err}");
            println!(
                "{} (floor {floor}): {}",
                out.display(),
                stdout.lines().next().unwrap_or("")
            );
            let report: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
            for clip in report["clips"].as_array().unwrap() {
                let r = clip["el_residual"].as_f64().unwrap();
                assert!(r < 1e-6, "{}: {r:e}", clip["clip"]);
            }
        }
    }
    let _ = std::fs::remove_dir_all(dir);
}

/// The joint strength curves equal the capacities computed at the same poses (the default pose
/// with one coordinate at either end of its range, where the curves have samples), and the
/// knee extensors' capacity is that of a human knee.
#[test]
fn strength_curves_equal_the_capacity_at_their_samples() {
    use musculo::muscle::MuscleSet;
    use musculo::muscle::path::{PathData, compute_paths};
    let model = Model::default_fullbody();
    let set = musculo::augment::chain::contact_set(&model).unwrap();
    let curves = CapacityCurves::new(&model, &set.floating_base).unwrap();
    let muscles = MuscleSet::new(&model).unwrap();
    let mut paths = PathData::new(&model, &muscles.paths);
    let mut data = Data::new(&model);
    let mut f_iso = vec![0.0; muscles.muscles.len()];
    let mut checked = 0;
    for (j, &c) in model.reduction.independent.iter().enumerate() {
        if set.floating_base.contains(&j) {
            assert!(curves.at(j, 0.0).is_none());
            continue;
        }
        let [lo, hi] = model.coordinates[c].range;
        for v in [lo, hi] {
            let Some((up, down)) = curves.at(j, v) else {
                continue;
            };
            let mut q = model.default_q();
            q[j] = v;
            dynamics::forward_kinematics(&model, &mut data, &q).unwrap();
            compute_paths(&model, &data, &muscles.paths, &mut paths).unwrap();
            musculo::evaluate::isometric_forces(&muscles, &paths, &mut f_iso);
            let (u, d) = musculo::evaluate::capacity_at(&paths, &f_iso, j);
            assert!((up - u).abs() <= 1e-9 * (1.0 + u) && (down - d).abs() <= 1e-9 * (1.0 + d));
            checked += 1;
        }
    }
    assert!(checked >= 40, "{checked}");
    // at 60° of knee flexion (knee_angle_r = −60°; a positive moment extends): human maximum
    // voluntary isometric knee-extension moments are 150–300 N·m, flexion moments about half
    // of that; the curves have every agonist fully active and no antagonist, so their upper
    // limits are 1.5 × the voluntary ones (as in data/check/max_isometric_moments.csv)
    let knee = model
        .q_names()
        .iter()
        .position(|n| *n == "knee_angle_r")
        .unwrap();
    let (ext, flex) = curves.at(knee, -60f64.to_radians()).unwrap();
    println!("knee_angle_r at −60°: extension {ext:.0} N·m, flexion {flex:.0} N·m");
    assert!(
        (150.0..=450.0).contains(&ext) && (50.0..=300.0).contains(&flex),
        "{ext} {flex}"
    );
}

/// A generated motion often comes in the per-joint layout only: its coordinates are fitted
/// from the joint rotations, and its kinematic metrics equal those of the full file; its
/// residual is formed from the layout's contact forces (at the joint centres, the best couple
/// on each foot: `loss::layout`), and not at all without them.
#[test]
fn a_layout_only_file_gives_the_kinematic_metrics_of_the_full_file() {
    let chain = Chain::new(
        musculo::DEFAULT_MODEL_OSIM.to_string(),
        "models/musculo_fullbody.osim".into(),
        ChainOptions::default(),
    )
    .unwrap();
    let (name, motion) = demo::clips(&chain.model).unwrap().remove(1);
    let v = Variant::identity();
    let run = chain.run(&motion, None, &v).unwrap();
    let model = chain.clip_model(&motion, None, &v).unwrap();
    let dir = std::env::temp_dir().join(format!("musculo-evaluate-layout-{}", std::process::id()));
    output::write_clip(&dir, &name, &run.arrays).unwrap();
    let keep = [
        "joint_pos",
        "joint_rot",
        "joint_vel",
        "joint_acc",
        "joint_torque",
        "muscle_act",
        "time",
    ];
    let layout: Vec<_> = run
        .arrays
        .iter()
        .filter(|a| keep.contains(&a.name))
        .cloned()
        .collect();
    output::write_clip(&dir, "layout", &layout).unwrap();
    let o = EvaluateOptions::default();
    let read = |clip: &str| TensorFrames::read(&output::npz_path(&dir, clip), &model).unwrap();
    let (full, only) = (read(&name), read("layout"));
    let a = evaluate_clip(&model, "full", &full, None, None, Capacity::PerFrame, &o).unwrap();
    let b = evaluate_clip(&model, "layout", &only, None, None, Capacity::PerFrame, &o).unwrap();
    println!("full: {a:?}\nlayout only: {b:?}");
    assert!(a.el_residual.is_some() && b.el_residual.is_none());
    assert!(
        b.layout_fit_error.unwrap() < 1e-5,
        "{:?}",
        b.layout_fit_error
    );
    for (x, y, what) in [
        (a.float, b.float, "float"),
        (a.penetrate, b.penetrate, "penetrate"),
        (a.skate, b.skate, "skate"),
        (a.skate_speed, b.skate_speed, "skate speed"),
        (a.support_fraction, b.support_fraction, "support"),
    ] {
        assert!((x - y).abs() < 1e-4 * (1.0 + x.abs()), "{what}: {x} vs {y}");
    }
    assert!((a.actuation_peak.unwrap() - b.actuation_peak.unwrap()).abs() < 1e-3);
    let with_forces: Vec<_> = run
        .arrays
        .iter()
        .filter(|a| keep.contains(&a.name) || a.name == "contact_force")
        .cloned()
        .collect();
    output::write_clip(&dir, "layout_forces", &with_forces).unwrap();
    let c = evaluate_clip(
        &model,
        "layout_forces",
        &read("layout_forces"),
        None,
        None,
        Capacity::PerFrame,
        &o,
    )
    .unwrap();
    println!(
        "EL residual (median ‖r‖/‖τ_ID‖): {:?} full, {:?} layout with its contact forces",
        a.el_residual, c.el_residual
    );
    assert!(c.el_residual.unwrap() < 1e-3, "{:?}", c.el_residual);
    let _ = std::fs::remove_dir_all(dir);
}

/// Without muscles the chain computes the same kinematics, torques and contacts, and leaves
/// the muscle arrays out.
#[test]
fn the_chain_without_muscles_gives_the_same_dynamics() {
    let with = Chain::new(
        musculo::DEFAULT_MODEL_OSIM.to_string(),
        "models/musculo_fullbody.osim".into(),
        ChainOptions::default(),
    )
    .unwrap();
    let without = Chain::new(
        with.xml.clone(),
        with.source.clone(),
        ChainOptions {
            muscles: false,
            ..ChainOptions::default()
        },
    )
    .unwrap();
    let (_, motion) = demo::clips(&with.model).unwrap().remove(0);
    let v = Variant::identity();
    let (a, b) = (
        with.run(&motion, None, &v).unwrap(),
        without.run(&motion, None, &v).unwrap(),
    );
    for name in [
        "q",
        "qd",
        "qdd",
        "tau",
        "contact_point_force",
        "grf",
        "joint_torque",
        "time",
    ] {
        let get = |o: &musculo::augment::chain::ClipOutput| {
            o.arrays
                .iter()
                .find(|x| x.name == name)
                .map(|x| x.values.clone())
        };
        assert_eq!(get(&a), get(&b), "{name}");
        assert!(get(&b).is_some(), "{name}");
    }
    for name in ["muscle_act", "muscle_force", "excitation", "x"] {
        assert!(b.arrays.iter().all(|x| x.name != name), "{name}");
    }
}

/// OpenSim's gait2392 walk was recorded on a treadmill: with the floor at rest its stance feet
/// slide at the belt's speed; with the floor's velocity taken from the clip (`--floor-velocity
/// clip`) or given, they stand still on the belt.
#[test]
fn a_treadmill_walk_skates_only_against_a_floor_at_rest() {
    let dir = "opensim-models/Pipelines/Gait2392_Simbody";
    let (Some(model), Some(trc)) = (
        reference_file(&format!("{dir}/OutputReference/subject01_simbody.osim")),
        reference_file(&format!("{dir}/subject01_walk1.trc")),
    ) else {
        return;
    };
    let out = std::env::temp_dir().join(format!("musculo-treadmill-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).unwrap();
    let run = |velocity: &str| -> serde_json::Value {
        let json = out.join("m.json");
        let (ok, _, err) = musculo_cli(
            &format!(
                "evaluate --input {{}} --model {{}} --floor clip --floor-velocity {velocity} \
                 --out {{}}"
            ),
            &[&trc, &model, &json],
        );
        assert!(ok, "{err}");
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        v["clips"][0].clone()
    };
    let (rest, own) = (run("0,0,0"), run("clip"));
    let f = |c: &serde_json::Value, k: &str| c[k].as_f64().unwrap();
    println!(
        "gait2392 treadmill walk: floor at rest skate {:.3}, {:.3} m/s; floor velocity from the \
         clip skate {:.3}, {:.3} m/s",
        f(&rest, "skate"),
        f(&rest, "skate_speed"),
        f(&own, "skate"),
        f(&own, "skate_speed")
    );
    assert!(f(&rest, "skate_speed") > 0.8, "{rest}");
    assert!(f(&own, "skate_speed") < 0.1, "{own}");
    assert!(f(&own, "skate") < 0.1 && f(&rest, "skate") > 0.2);
    let (ok, _, err) = musculo_cli(
        "evaluate --input {} --floor-velocity 1,2 --out {}",
        &[&trc, &out.join("bad.json")],
    );
    assert!(!ok && err.contains("--floor-velocity"), "{err}");
    let _ = std::fs::remove_dir_all(out);
}

/// A variant that changes the body (mass scale, carried load) gets its own `.osim` with
/// `--opensim-files`: its bodies weigh what the manifest says, and `evaluate` judges the clip on
/// it (zero residual) where the base model would leave the load's weight unexplained.
#[test]
fn body_changing_variants_are_judged_on_their_own_model() {
    let dir = std::env::temp_dir().join(format!("musculo-variants-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (out, json) = (dir.join("aug"), dir.join("m.json"));
    let (ok, _, err) = musculo_cli(
        "augment --demo --variants 2 --opensim-files --out {}",
        &[&out],
    );
    assert!(ok, "{err}");
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    let base = Model::default_fullbody();
    let base_mass: f64 = base.bodies.iter().map(|b| b.mass).sum();
    let mut variants = 0;
    for clip in manifest["clips"].as_array().unwrap() {
        let name = clip["clip"].as_str().unwrap();
        let v = &clip["variant"];
        let (scale, load) = (
            v["mass_scale"].as_f64().unwrap(),
            v["load_kg"].as_f64().unwrap(),
        );
        if scale == 1.0 && load == 0.0 {
            continue;
        }
        variants += 1;
        let xml = std::fs::read_to_string(out.join(format!("{name}.osim"))).unwrap();
        let model = Model::from_osim_str(&xml, name).unwrap();
        let mass: f64 = model.bodies.iter().map(|b| b.mass).sum();
        assert!(
            (mass - (base_mass * scale + load)).abs() < 1e-9 * mass,
            "{name}: {mass} kg, expected {base_mass} × {scale} + {load}"
        );
    }
    assert_eq!(variants, 3);
    let (ok, _, err) = musculo_cli("evaluate --input {} --out {}", &[&out, &json]);
    assert!(ok, "{err}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    for clip in report["clips"].as_array().unwrap() {
        let r = clip["el_residual"].as_f64().unwrap();
        assert!(r < 1e-6, "{}: {r:e}", clip["clip"]);
    }
    // the base model given: the variant's body is rebuilt from it (its identity says how)
    let default_model = dir.join("default.osim");
    std::fs::write(&default_model, musculo::DEFAULT_MODEL_OSIM).unwrap();
    let (ok, _, err) = musculo_cli(
        "evaluate --input {} --model {} --out {}",
        &[&out.join("march_v1.npz"), &default_model, &json],
    );
    assert!(ok, "{err}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rebuilt = report["clips"][0]["el_residual"].as_f64().unwrap();
    assert!(rebuilt < 1e-6, "{rebuilt:e}");
    // the same variant's arrays without their identity, judged on the base model: the
    // residual is the body change, and a warning says the file did not name its model
    let bare = dir.join("bare");
    let arrays = musculo::motion::npy::read_npz_f32(&out.join("march_v1.npz")).unwrap();
    let views: Vec<_> = arrays.iter().map(|(k, a)| (k.as_str(), a.view())).collect();
    std::fs::create_dir_all(&bare).unwrap();
    musculo::motion::npy::write_npz(&bare.join("march_v1.npz"), &views, false).unwrap();
    let (ok, _, err) = musculo_cli(
        "evaluate --input {} --model {} --out {}",
        &[&bare.join("march_v1.npz"), &default_model, &json],
    );
    assert!(ok, "{err}");
    assert!(
        err.contains("does not say which model it belongs to"),
        "{err}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let on_base = report["clips"][0]["el_residual"].as_f64().unwrap();
    println!(
        "march_v1 on its own model: residual < 1e-6; without its identity on the base model {on_base:.3}"
    );
    assert!(on_base > 1e-3, "{on_base}");
    let _ = std::fs::remove_dir_all(dir);
}

/// A generated motion's faults the other metrics can miss: a knee bent to −480° is flagged
/// (its share of samples, the coordinate and value), and rates q̇, q̈ that agree with the
/// torques but not with q itself leave the decoded residual at zero while the residual from q
/// alone — checked against finite differences and inverse dynamics computed here — shows them.
#[test]
fn generated_faults_beyond_range_and_inconsistent_rates_are_flagged() {
    let c = clips().into_iter().next().unwrap();
    let model = &c.model;
    let n = model.nq();
    let t_count = c.frames.frames;
    let o = EvaluateOptions::default();
    let base = eval(&c, &c.frames, None, &o);
    println!(
        "{}: range share {}, EL residual {:.1e} (decoded), {:.1e} (from q)",
        c.name,
        base.range_share,
        base.el_residual.unwrap(),
        base.el_residual_from_q.unwrap()
    );
    assert_eq!(base.range_share, 0.0, "{:?}", base.range_worst);
    assert!(base.range_worst.is_none());
    // the knee at −480° in 7 frames
    let knee = coordinate(model, "knee_angle_r");
    let mut bent = c.frames.clone();
    let bad_frames = [3, 4, 5, 10, 11, 12, 13];
    for &f in &bad_frames {
        bent.q[f * n + knee] = (-480.0f64).to_radians();
    }
    let m = eval(&c, &bent, None, &o);
    let set = musculo::augment::chain::contact_set(model).unwrap();
    let joints = n - set.floating_base.len();
    let share = bad_frames.len() as f64 / (t_count * joints) as f64;
    assert!(
        (m.range_share - share).abs() < 1e-12,
        "{} vs {share}",
        m.range_share
    );
    let worst = m.range_worst.as_ref().unwrap();
    assert_eq!(worst.coordinate, "knee_angle_r");
    assert!((worst.value.to_degrees() + 480.0).abs() < 1e-9, "{worst:?}");
    let [lo, _] = model.coordinates[model.reduction.independent[knee]].range;
    assert!((worst.excess - (lo - worst.value)).abs() < 1e-12);
    let summary = summarize(&[base.clone(), m.clone()]);
    assert_eq!(summary.beyond_range_clips, 1);
    let line: Vec<String> = summary
        .columns()
        .iter()
        .map(|(k, v)| format!("{k} {v}"))
        .collect();
    let line = line.join(", ");
    println!("{line}");
    assert!(line.contains("beyond range 1 of 2 clips"), "{line}");
    assert!(line.contains("knee_angle_r -480.0°"), "{line}");

    // decoded rates at rest (q̇ = q̈ = 0) with the torques that hold each pose: consistent
    // with τ, not with q
    let mut data = Data::new(model);
    let mut still = c.frames.clone();
    still.lambda.clear();
    still.contacts = 0;
    still.qd = vec![0.0; t_count * n];
    still.qdd = vec![0.0; t_count * n];
    for f in 0..t_count {
        let r = f * n..(f + 1) * n;
        let tau = dynamics::rnea(
            model,
            &mut data,
            &still.q[r.clone()],
            &still.qd[r.clone()],
            &still.qdd[r.clone()],
        )
        .unwrap()
        .clone();
        still.tau[r].copy_from_slice(tau.as_slice());
    }
    let s = eval(&c, &still, None, &o);
    // q̇, q̈ by differences here (uniform steps: central inside, one-sided q̇ and the
    // neighbour's q̈ at the ends), then r = ID(q, q̇, q̈) − τ relative to ‖ID‖
    let h = (c.frames.time[t_count - 1] - c.frames.time[0]) / (t_count - 1) as f64;
    let q = |f: usize, j: usize| still.q[f * n + j];
    let mut relative = Vec::new();
    for f in 0..t_count {
        let (mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n]);
        for j in 0..n {
            let inner = f.clamp(1, t_count - 2);
            qdd[j] = (q(inner + 1, j) - 2.0 * q(inner, j) + q(inner - 1, j)) / (h * h);
            qd[j] = if f == 0 {
                (q(1, j) - q(0, j)) / h
            } else if f == t_count - 1 {
                (q(f, j) - q(f - 1, j)) / h
            } else {
                (q(f + 1, j) - q(f - 1, j)) / (2.0 * h)
            };
        }
        let id = dynamics::rnea(model, &mut data, &still.q[f * n..(f + 1) * n], &qd, &qdd)
            .unwrap()
            .clone();
        let r: f64 = (0..n)
            .map(|j| (id[j] - still.tau[f * n + j]).powi(2))
            .sum::<f64>()
            .sqrt();
        relative.push(r / id.norm());
    }
    relative.sort_by(f64::total_cmp);
    let k = t_count / 2;
    let expected = if t_count % 2 == 1 {
        relative[k]
    } else {
        0.5 * (relative[k - 1] + relative[k])
    };
    let (decoded, from_q) = (s.el_residual.unwrap(), s.el_residual_from_q.unwrap());
    println!(
        "rates at rest: EL residual {decoded:.1e} (decoded), {from_q:.3} (from q; {expected:.3} here)"
    );
    assert!(decoded < 1e-9, "{decoded:e}");
    // (the file's times are float32: its steps differ from h by ~10⁻⁵ relative)
    assert!(
        (from_q - expected).abs() <= 1e-4 * expected,
        "{from_q} vs {expected}"
    );
    assert!(from_q > 10.0 * base.el_residual_from_q.unwrap(), "{from_q}");
}
