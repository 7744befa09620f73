//! Ground contact forces from kinematics alone (`musculo::solve::contact`) against force
//! plates, exactness on the floating-base rows, and bad input.
//!
//! Walks: the OpenSim models' subject01 treadmill walk (Gait2392_Simbody and Gait10dof18musc
//! pipelines): the stored IK coordinates, prepared as OpenSim's ID tool prepares them (6 Hz
//! low-pass, quintic splines), inverse dynamics without external loads, contacts detected and
//! distributed, compared frame by frame with `subject01_walk1_grf.mot` (the same plates for
//! both models). Neither model has ContactSpheres: the points are the heel, metatarsal heads and
//! toe tip of each foot from `data/contacts/gait2392_feet.json` (see its description), scaled
//! to the subject's foot.

mod common;

#[path = "common/counting_alloc.rs"]
mod counting_alloc;
use common::reference_file;
use counting_alloc::allocations;
use musculo::Model;
use musculo::dynamics::{self, Data};
use musculo::io::Table;
use musculo::solve::contact::{
    self, ContactFrame, ContactOptions, ContactPoint, ContactSet, ContactWorkspace, GroupWrench,
    ground_reaction,
};
use musculo::solve::external_loads::ExternalLoadSet;
use musculo::solve::inverse_dynamics::prepare_coordinates;
use musculo::solve::kinematics::Differentiation;
use musculo::solve::qp::QpStatus;
use musculo::spatial::Vec3;

/// Figures of one walk; errors per foot pooled over both feet and all frames.
struct WalkFigures {
    frames: usize,
    body_weight: f64,
    vertical_rmse: f64,
    ap_rmse: f64,
    ml_rmse: f64,
    /// Mean |COP error| (AP, ML) over frames where both the plate and the estimate carry
    /// more than 10 % of body weight on that foot.
    cop_ap: f64,
    cop_ml: f64,
    /// RMS of the unexplained residual on the floating-base translation and rotation rows.
    residual_force_rms: f64,
    residual_moment_rms: f64,
    micros_per_frame: f64,
    detect_micros_per_frame: f64,
}

fn gait_contact_set(model: &Model) -> ContactSet {
    let points = contact::points_from_json(
        model,
        contact::GAIT2392_FEET_JSON,
        "data/contacts/gait2392_feet.json",
        None,
    )
    .unwrap();
    ContactSet::from_points(model, points).unwrap()
}

fn walk(
    title: &str,
    model_rel: &str,
    ik_rel: &str,
    grf_rel: &str,
    options: &ContactOptions,
) -> Option<WalkFigures> {
    let (Some(model_path), Some(ik_path), Some(grf_path)) = (
        reference_file(model_rel),
        reference_file(ik_rel),
        reference_file(grf_rel),
    ) else {
        return None;
    };
    let model = Model::from_osim_file(&model_path).unwrap();
    let set = gait_contact_set(&model);
    let loads = ExternalLoadSet::read(&model, &grf_path).unwrap();
    let table = Table::read(&ik_path).unwrap();
    let source = ik_path.display().to_string();
    let mut warnings = Vec::new();
    let prepared = prepare_coordinates(
        &model,
        &table,
        &source,
        Some(6.0),
        Differentiation::SecondDerivative,
        &mut warnings,
    )
    .unwrap();
    // the recorded IK rows within the plates' recording
    let times: Vec<f64> = table
        .time
        .iter()
        .copied()
        .filter(|&t| t >= loads.time_span[0] - 1e-9 && t <= loads.time_span[1] + 1e-9)
        .collect();
    let rate = (times.len() - 1) as f64 / (times[times.len() - 1] - times[0]);
    let nq = model.nq();
    let frames = times.len();
    let (mut q, mut qd, mut qdd) = (
        vec![0.0; frames * nq],
        vec![0.0; frames * nq],
        vec![0.0; frames * nq],
    );
    for (f, &t) in times.iter().enumerate() {
        let r = f * nq..(f + 1) * nq;
        let (a, b, c) = (&mut q[r.clone()], &mut qd[r.clone()], &mut qdd[r.clone()]);
        prepared.trajectory.eval(t, a, b, c);
    }
    let t0 = std::time::Instant::now();
    let states = contact::detect(&model, &set, options, &q, &qd, &qdd, rate).unwrap();
    let detect_micros = 1e6 * t0.elapsed().as_secs_f64() / frames as f64;
    let set = set.with_floor(states.floor);
    eprintln!(
        "{title}: {frames} frames at {rate:.1} Hz ({:.3}–{:.3} s), floor {:.4} m, floor velocity \
         ({:.3}, {:.3}, {:.3}) m/s",
        times[0],
        times[frames - 1],
        states.floor,
        states.floor_velocity.x,
        states.floor_velocity.y,
        states.floor_velocity.z
    );

    let body_weight = model.total_mass() * model.gravity.norm();
    let mut data = Data::new(&model);
    let mut workspace = ContactWorkspace::new(&model, &set);
    let mut frame = ContactFrame::new(&model, &set);
    let mut wrenches = vec![GroupWrench::default(); set.groups().len()];
    let mut tau = vec![0.0; nq];
    let feet: Vec<(usize, usize)> = ["foot_r", "foot_l"]
        .iter()
        .map(|g| {
            let group = set.groups().iter().position(|x| x == g).unwrap();
            let body = model.body_index(&format!("calcn_{}", &g[5..])).unwrap();
            let plate = loads
                .forces
                .iter()
                .position(|f| f.applied_to_body == body)
                .unwrap();
            (group, plate)
        })
        .collect();
    let (mut e_v, mut e_ap, mut e_ml, mut n_e) = (0.0, 0.0, 0.0, 0.0);
    let (mut cop_ap, mut cop_ml, mut n_cop) = (0.0, 0.0, 0.0_f64);
    let (mut residual2, mut residual_moment2) = (0.0, 0.0);
    let mut solve_time = 0.0;
    let n_rotational = set.floating_base_rotational.iter().filter(|r| **r).count() as f64;
    let mut rows = Vec::new();
    for (f, &t) in times.iter().enumerate() {
        let r = f * nq..(f + 1) * nq;
        let id = dynamics::rnea(&model, &mut data, &q[r.clone()], &qd[r.clone()], &qdd[r]).unwrap();
        tau.copy_from_slice(id.as_slice());
        let allocated_before = allocations();
        let t0 = std::time::Instant::now();
        workspace
            .distribute(
                &model,
                &data,
                &set,
                options,
                states.frame(f),
                &tau,
                &mut frame,
            )
            .unwrap();
        solve_time += t0.elapsed().as_secs_f64();
        ground_reaction(&set, &frame, &mut wrenches).unwrap();
        assert_eq!(
            allocations(),
            allocated_before,
            "t = {t}: distribute and ground_reaction allocated"
        );
        if let Some(mu) = options.friction {
            // every force inside the pyramid: f_n ≥ 0, |f_t1|, |f_t2| ≤ μ f_n
            let (t1, t2) = set.floor_tangents();
            for fp in &frame.forces {
                let normal = fp.dot(&set.floor_normal);
                let slack = 1e-9 * body_weight;
                assert!(normal >= -slack, "t = {t}: normal force {normal}");
                assert!(fp.dot(&t1).abs() <= mu * normal + slack, "t = {t}: {fp:?}");
                assert!(fp.dot(&t2).abs() <= mu * normal + slack, "t = {t}: {fp:?}");
            }
        }
        for (row, &rotational) in set.floating_base_rotational.iter().enumerate() {
            let r2 = frame.residual[row].powi(2);
            if rotational {
                residual_moment2 += r2 / n_rotational;
            } else {
                residual2 += r2 / (set.floating_base.len() as f64 - n_rotational);
            }
        }
        let mut line = format!("{t:.3}");
        for &(group, plate) in &feet {
            let measured = loads.wrench(&data, plate, t);
            let (est, meas) = (wrenches[group].force, measured.force_in_ground);
            e_v += (est.y - meas.y).powi(2);
            e_ap += (est.x - meas.x).powi(2);
            e_ml += (est.z - meas.z).powi(2);
            n_e += 1.0;
            if meas.y > 0.1 * body_weight && est.y > 0.1 * body_weight {
                cop_ap += (wrenches[group].cop.x - measured.point_in_ground.x).abs();
                cop_ml += (wrenches[group].cop.z - measured.point_in_ground.z).abs();
                n_cop += 1.0;
            }
            line += &format!(
                "  {:7.1} {:7.1} {:6.1} {:6.1}",
                est.y, meas.y, est.z, meas.z
            );
        }
        rows.push(line);
    }
    if std::env::var_os("MUSCULO_CONTACT_TRACE").is_some() {
        eprintln!("time  vertical est_r plate_r, medio-lateral est_r plate_r, the same for l (N)");
        rows.iter().for_each(|l| eprintln!("{l}"));
    }
    Some(WalkFigures {
        frames,
        body_weight,
        vertical_rmse: (e_v / n_e).sqrt(),
        ap_rmse: (e_ap / n_e).sqrt(),
        ml_rmse: (e_ml / n_e).sqrt(),
        cop_ap: cop_ap / n_cop.max(1.0),
        cop_ml: cop_ml / n_cop.max(1.0),
        residual_force_rms: (residual2 / frames as f64).sqrt(),
        residual_moment_rms: (residual_moment2 / frames as f64).sqrt(),
        micros_per_frame: 1e6 * solve_time / frames as f64,
        detect_micros_per_frame: detect_micros,
    })
}

fn report(title: &str, w: &WalkFigures) {
    let pct = |x: f64| 100.0 * x / w.body_weight;
    eprintln!(
        "{title}: {} frames, body weight {:.1} N\n  per-foot RMSE: vertical {:.1} N ({:.2} % BW), \
         anterior-posterior {:.1} N ({:.2} % BW), medio-lateral {:.1} N ({:.2} % BW)\n  \
         COP mean error (foot loaded > 10 % BW): AP {:.1} mm, ML {:.1} mm\n  unexplained \
         floating-base residual RMS {:.2} N, {:.2} N·m\n  detect {:.1} µs/frame, distribute {:.1} µs/frame",
        w.frames,
        w.body_weight,
        w.vertical_rmse,
        pct(w.vertical_rmse),
        w.ap_rmse,
        pct(w.ap_rmse),
        w.ml_rmse,
        pct(w.ml_rmse),
        1e3 * w.cop_ap,
        1e3 * w.cop_ml,
        w.residual_force_rms,
        w.residual_moment_rms,
        w.detect_micros_per_frame,
        w.micros_per_frame
    );
}

/// The walks are on a treadmill: speeds are measured relative to the belt, estimated.
fn treadmill() -> ContactOptions {
    ContactOptions {
        floor_velocity: None,
        ..ContactOptions::default()
    }
}

fn treadmill_exact() -> ContactOptions {
    ContactOptions {
        floor_velocity: None,
        ..exact()
    }
}

const GAIT2392: &str = "opensim-models/Pipelines/Gait2392_Simbody";
const GAIT10: &str = "opensim-models/Pipelines/Gait10dof18musc/OutputReference";

#[test]
fn vertical_grf_from_kinematics_matches_force_plates_gait2392_walk() {
    let title = "gait2392 walk";
    // the IK the ID setup names (OutputReference's copy also holds marker and GRF columns)
    let (model, ik, grf) = (
        &format!("{GAIT2392}/OutputReference/subject01_simbody.osim"),
        &format!("{GAIT2392}/subject01_walk1_ik.mot"),
        &format!("{GAIT2392}/subject01_walk1_grf.xml"),
    );
    let Some(w) = walk(title, model, ik, grf, &treadmill()) else {
        return;
    };
    report(title, &w);
    assert!(
        w.vertical_rmse <= 0.05 * w.body_weight,
        "vertical RMSE {:.1} N > 5 % of body weight",
        w.vertical_rmse
    );
    // for comparison (no assertion): no friction cone, moment rows reproduced exactly
    let exact_title = format!("{title}, no friction cone, moment rows exact");
    if let Some(e) = walk(&exact_title, model, ik, grf, &treadmill_exact()) {
        report(&exact_title, &e);
    }
}

#[test]
fn vertical_grf_from_kinematics_matches_force_plates_gait10dof18musc_walk() {
    let title = "Gait10dof18musc walk";
    let (model, ik, grf) = (
        &format!("{GAIT10}/subject01.osim"),
        &format!("{GAIT10}/IK/subject01_walk_IK.mot"),
        &format!("{GAIT10}/ExperimentalData/subject01_walk_grf.xml"),
    );
    let Some(w) = walk(title, model, ik, grf, &treadmill()) else {
        return;
    };
    report(title, &w);
    assert!(
        w.vertical_rmse <= 0.05 * w.body_weight,
        "vertical RMSE {:.1} N > 5 % of body weight",
        w.vertical_rmse
    );
    // for comparison (no assertion): no friction cone, moment rows reproduced exactly
    let exact_title = format!("{title}, no friction cone, moment rows exact");
    if let Some(e) = walk(&exact_title, model, ik, grf, &treadmill_exact()) {
        report(&exact_title, &e);
    }
}

/// Exact mode: every point active, no friction cone, both residual weights high.
fn exact() -> ContactOptions {
    ContactOptions {
        friction: None,
        residual_moment_weight: 1e8,
        ..ContactOptions::default()
    }
}

/// Distributes `tau` at `q` (kinematics in `data`) with every factor 1.
fn distribute_all(
    model: &Model,
    set: &ContactSet,
    data: &mut Data,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    options: &ContactOptions,
) -> (Vec<f64>, ContactFrame) {
    let tau = dynamics::rnea(model, data, q, qd, qdd)
        .unwrap()
        .as_slice()
        .to_vec();
    let mut workspace = ContactWorkspace::new(model, set);
    let mut frame = ContactFrame::new(model, set);
    let factor = vec![1.0; set.points.len()];
    workspace
        .distribute(model, data, set, options, &factor, &tau, &mut frame)
        .unwrap();
    (tau, frame)
}

#[test]
fn standing_pose_all_points_reproduce_the_floating_base_rows_and_body_weight() {
    let model = Model::default_fullbody();
    let set = ContactSet::from_model(&model).unwrap();
    assert_eq!(set.points.len(), 8, "the default model's ContactSpheres");
    assert_eq!(set.groups(), ["foot_r", "foot_l"]);
    assert_eq!(set.floating_base.len(), 6);
    let nq = model.nq();
    let q = model.default_q();
    let mut data = Data::new(&model);
    let zeros = vec![0.0; nq];
    let (tau, frame) = distribute_all(&model, &set, &mut data, &q, &zeros, &zeros, &exact());
    assert_eq!(frame.status, QpStatus::Solved);

    // the floating-base rows: Σ J_cᵀλ = τ_ID
    let scale = set
        .floating_base
        .iter()
        .map(|&j| tau[j].abs())
        .fold(0.0, f64::max);
    for (r, &j) in set.floating_base.iter().enumerate() {
        assert!(
            (frame.generalized[j] - tau[j]).abs() <= 1e-6 * scale,
            "row {}: J_cᵀλ {} vs τ {}",
            model.q_names()[j],
            frame.generalized[j],
            tau[j]
        );
        assert!(frame.residual[r].abs() <= 1e-6 * scale);
    }
    // Newton: Σ f = m g (static), independent of the Jacobians
    let weight = model.total_mass() * model.gravity.norm();
    let total: Vec3 = frame.forces.iter().sum();
    assert!(
        (total.y - weight).abs() <= 1e-6 * weight,
        "vertical {} vs m g {weight}",
        total.y
    );
    assert!(total.x.abs() <= 1e-6 * weight && total.z.abs() <= 1e-6 * weight);
    // Euler: the contact forces have no moment about the centre of mass
    let com = dynamics::center_of_mass(&model, &data).unwrap();
    let moment: Vec3 = frame
        .forces
        .iter()
        .zip(&frame.points)
        .map(|(f, p)| (p - com).cross(f))
        .sum();
    assert!(
        moment.norm() <= 1e-6 * weight,
        "moment about the COM {moment:?}"
    );
    // J_cᵀλ recomputed from the forces as body wrenches (spatial-force projection)
    let mut generalized = vec![0.0; nq];
    for (p, point) in set.points.iter().enumerate() {
        dynamics::add_body_wrench(
            &model,
            &data,
            point.body,
            &frame.points[p],
            &frame.forces[p],
            &Vec3::zeros(),
            &mut generalized,
        )
        .unwrap();
    }
    for j in 0..nq {
        assert!((generalized[j] - frame.generalized[j]).abs() <= 1e-9 * weight);
    }
    // the contact points are the spheres' lowest points, on the floor at the default pose
    for p in &frame.points {
        assert!(p.y.abs() < 0.01, "contact point at height {}", p.y);
    }
    // both feet carry load; the plates' sum is the total; COPs on the floor plane
    let mut wrenches = vec![GroupWrench::default(); 2];
    ground_reaction(&set, &frame, &mut wrenches).unwrap();
    for w in &wrenches {
        assert!(w.loaded && w.force.y > 0.3 * weight, "{w:?}");
        assert_eq!(w.cop.y, 0.0);
    }
    assert!((wrenches[0].force.y + wrenches[1].force.y - weight).abs() <= 1e-6 * weight);
    eprintln!(
        "standing: right {:.2} N, left {:.2} N (m g {weight:.2} N), QP iterations {}",
        wrenches[0].force.y, wrenches[1].force.y, frame.iterations
    );
}

#[test]
fn accelerating_pose_all_points_reproduce_the_floating_base_rows() {
    // standing pose with joint accelerations: the rows change, all points still balance them
    let model = Model::default_fullbody();
    let set = ContactSet::from_model(&model).unwrap();
    let nq = model.nq();
    let q = model.default_q();
    let mut rng = common::Rng::new(11);
    let qd: Vec<f64> = (0..nq).map(|_| rng.uniform(-0.3, 0.3)).collect();
    let mut qdd: Vec<f64> = (0..nq).map(|_| rng.uniform(-1.0, 1.0)).collect();
    for &j in &set.floating_base {
        qdd[j] = 0.0;
    }
    let mut data = Data::new(&model);
    let (tau, frame) = distribute_all(&model, &set, &mut data, &q, &qd, &qdd, &exact());
    assert_eq!(frame.status, QpStatus::Solved);
    let scale = set
        .floating_base
        .iter()
        .map(|&j| tau[j].abs())
        .fold(0.0, f64::max);
    for (r, &j) in set.floating_base.iter().enumerate() {
        assert!(
            frame.residual[r].abs() <= 1e-6 * scale,
            "row {}: residual {} (τ {})",
            model.q_names()[j],
            frame.residual[r],
            tau[j]
        );
    }
    // a quick timing on the default model with the default options (no assertion): factors
    // ramping as in a load transfer, warm-started from frame to frame
    let mut workspace = ContactWorkspace::new(&model, &set);
    let mut frame = ContactFrame::new(&model, &set);
    let options = ContactOptions::default();
    let mut factor = vec![1.0; set.points.len()];
    let calls = 2000;
    let t0 = std::time::Instant::now();
    for k in 0..calls {
        let s = 0.5 + 0.5 * (k as f64 * 0.05).sin();
        factor[..4].iter_mut().for_each(|f| *f = s);
        factor[4..].iter_mut().for_each(|f| *f = 1.0 - s);
        workspace
            .distribute(&model, &data, &set, &options, &factor, &tau, &mut frame)
            .unwrap();
    }
    eprintln!(
        "default model ({} coordinates, {} points): distribute {:.1} µs/frame",
        nq,
        set.points.len(),
        1e6 * t0.elapsed().as_secs_f64() / calls as f64
    );
}

#[test]
fn a_frame_in_the_air_gets_no_force_and_the_whole_residual() {
    let model = Model::default_fullbody();
    let set = ContactSet::from_model(&model).unwrap();
    let nq = model.nq();
    let ty = model.q_index("pelvis_ty").unwrap();
    // 10 frames standing, then the body rises 0.3 m over 20 frames at 60 Hz
    let rate = 60.0;
    let frames = 30;
    let mut q = Vec::with_capacity(frames * nq);
    let mut qd = vec![0.0; frames * nq];
    for f in 0..frames {
        let mut qf = model.default_q();
        if f >= 10 {
            qf[ty] += 0.3 * (f - 9) as f64 / 20.0;
            qd[f * nq + ty] = 0.3 / 20.0 * rate;
        }
        q.extend(qf);
    }
    let options = ContactOptions {
        floor_height: Some(0.0),
        ..ContactOptions::default()
    };
    let qdd = vec![0.0; q.len()];
    let states = contact::detect(&model, &set, &options, &q, &qd, &qdd, rate).unwrap();
    assert!((0..8).all(|p| states.in_contact[p]), "standing: in contact");
    assert!(states.factor.iter().all(|f| (0.0..=1.0).contains(f)));
    let last = frames - 1;
    assert!(states.frame(last).iter().all(|&f| f == 0.0), "in the air");
    assert!(states.height[last * 8..].iter().all(|&h| h > 0.25));

    let mut data = Data::new(&model);
    let r = last * nq..(last + 1) * nq;
    let tau = dynamics::rnea(&model, &mut data, &q[r.clone()], &qd[r], &vec![0.0; nq])
        .unwrap()
        .as_slice()
        .to_vec();
    let mut workspace = ContactWorkspace::new(&model, &set);
    let mut frame = ContactFrame::new(&model, &set);
    workspace
        .distribute(
            &model,
            &data,
            &set,
            &ContactOptions::default(),
            states.frame(last),
            &tau,
            &mut frame,
        )
        .unwrap();
    assert!(frame.forces.iter().all(|f| *f == Vec3::zeros()));
    assert!(frame.generalized.iter().all(|&g| g == 0.0));
    for (r, &j) in set.floating_base.iter().enumerate() {
        assert_eq!(frame.residual[r], tau[j]);
    }
    // the vertical residual is the weight
    let weight = model.total_mass() * model.gravity.norm();
    let ty_row = set.floating_base.iter().position(|&j| j == ty).unwrap();
    assert!((frame.residual[ty_row] - weight).abs() <= 1e-9 * weight);
    let mut wrenches = vec![GroupWrench::default(); 2];
    ground_reaction(&set, &frame, &mut wrenches).unwrap();
    assert!(
        wrenches
            .iter()
            .all(|w| !w.loaded && w.force == Vec3::zeros())
    );
}

/// A pendulum hinged to ground: no floating root, no ContactSphere.
fn pendulum() -> Model {
    let xml = common::osim(
        &common::body(
            "link",
            1.0,
            [0.0, -0.5, 0.0],
            [0.1, 0.1, 0.1, 0.0, 0.0, 0.0],
        ),
        &common::joint(
            "PinJoint",
            "hinge",
            "/ground",
            [0.0, 1.0, 0.0],
            "/bodyset/link",
            &[common::coordinate("swing", [-3.0, 3.0])],
            "",
        ),
        "",
        [0.0, -9.81, 0.0],
    );
    Model::from_osim_str(&xml, "<pendulum>").unwrap()
}

#[test]
fn bad_input_is_an_error_naming_the_argument() {
    let invalid = |e: musculo::Error| common::expect_invalid_argument(e);
    // models without ContactSpheres or without a floating root
    let p = pendulum();
    let e = ContactSet::from_model(&p).unwrap_err().to_string();
    assert!(e.contains("no ContactSphere") && e.contains("test"), "{e}");
    let point = ContactPoint {
        name: "tip".into(),
        body: 1,
        location_in_body: Vec3::new(0.0, -1.0, 0.0),
        radius: 0.0,
        group: "tip".into(),
    };
    let e = ContactSet::from_points(&p, vec![point.clone()])
        .unwrap_err()
        .to_string();
    assert!(e.contains("floating root") && e.contains("hinge"), "{e}");

    let model = Model::default_fullbody();
    let nq = model.nq();
    // bad points
    for (edit, needle) in [
        (
            Box::new(|p: &mut ContactPoint| p.body = 0) as Box<dyn Fn(&mut ContactPoint)>,
            "ground",
        ),
        (
            Box::new(|p: &mut ContactPoint| p.body = 999),
            "out of range",
        ),
        (Box::new(|p: &mut ContactPoint| p.radius = -0.1), "radius"),
        (
            Box::new(|p: &mut ContactPoint| p.location_in_body.x = f64::NAN),
            "not finite",
        ),
    ] {
        let mut bad = point.clone();
        edit(&mut bad);
        let (argument, message) = invalid(ContactSet::from_points(&model, vec![bad]).unwrap_err());
        assert_eq!(argument, "points");
        assert!(message.contains(needle), "{message}");
    }
    let e = ContactSet::from_points(&model, vec![]).unwrap_err();
    assert_eq!(invalid(e).0, "points");
    // JSON points
    for (json, needle) in [
        ("{", "document"),
        (r#"{"points": 3}"#, "points"),
        (
            r#"{"points": [{"name": "a", "body": "nobody", "location": [0,0,0], "radius": 0}]}"#,
            "nobody",
        ),
        (
            r#"{"points": [{"name": "a", "body": "calcn_r", "location": [0,0], "radius": 0}]}"#,
            "points[0].location",
        ),
    ] {
        let e = contact::points_from_json(&model, json, "pts.json", None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("pts.json") && e.contains(needle), "{e}");
    }

    let set = ContactSet::from_model(&model).unwrap();
    let options = ContactOptions::default();
    let q1 = model.default_q();
    let q: Vec<f64> = (0..3).flat_map(|_| q1.clone()).collect();
    let qd = vec![0.0; q.len()];
    let detect = |q: &[f64], qd: &[f64], rate: f64, o: &ContactOptions| {
        let qdd = vec![0.0; q.len()];
        invalid(contact::detect(&model, &set, o, q, qd, &qdd, rate).unwrap_err())
    };
    assert_eq!(detect(&q[1..], &qd[1..], 60.0, &options).0, "q");
    assert_eq!(detect(&[], &[], 60.0, &options).0, "q");
    assert_eq!(detect(&q, &qd[1..], 60.0, &options).0, "qd");
    assert_eq!(detect(&q, &qd, 0.0, &options).0, "rate_hz");
    assert_eq!(detect(&q, &qd, f64::NAN, &options).0, "rate_hz");
    let mut nan = q.clone();
    nan[2 * nq + 4] = f64::NAN;
    let (argument, message) = detect(&nan, &qd, 60.0, &options);
    assert_eq!(argument, "q");
    assert!(message.contains("frame 2") && message.contains(model.q_names()[4]));
    let mut nan = qd.clone();
    nan[5] = f64::INFINITY;
    assert_eq!(detect(&q, &nan, 60.0, &options).0, "qd");
    let bad_options = ContactOptions {
        height_scale: 0.0,
        ..ContactOptions::default()
    };
    assert_eq!(detect(&q, &qd, 60.0, &bad_options).0, "height_scale");
    let bad_options = ContactOptions {
        demand_scale: f64::NAN,
        ..ContactOptions::default()
    };
    assert_eq!(detect(&q, &qd, 60.0, &bad_options).0, "demand_scale");
    let bad_options = ContactOptions {
        floor_motion: contact::FloorMotion::Treadmill { speed: Some(-1.0) },
        ..ContactOptions::default()
    };
    assert_eq!(detect(&q, &qd, 60.0, &bad_options).0, "floor_motion");
    let bad_options = ContactOptions {
        friction: Some(f64::NAN),
        ..ContactOptions::default()
    };
    assert_eq!(detect(&q, &qd, 60.0, &bad_options).0, "friction");

    // distribute
    let mut data = Data::new(&model);
    let mut workspace = ContactWorkspace::new(&model, &set);
    let mut frame = ContactFrame::new(&model, &set);
    let factor = vec![1.0; 8];
    let tau = vec![0.0; nq];
    // before any kinematics
    let e = workspace
        .distribute(&model, &data, &set, &options, &factor, &tau, &mut frame)
        .unwrap_err();
    assert!(
        matches!(e, musculo::Error::StageNotComputed { .. }),
        "{e:?}"
    );
    dynamics::forward_kinematics(&model, &mut data, &q1).unwrap();
    let mut distribute = |factor: &[f64], tau: &[f64], set: &ContactSet| {
        invalid(
            workspace
                .distribute(&model, &data, set, &options, factor, tau, &mut frame)
                .unwrap_err(),
        )
    };
    assert_eq!(distribute(&factor, &tau[1..], &set).0, "tau");
    let mut nan = tau.clone();
    nan[3] = f64::NAN;
    assert_eq!(distribute(&factor, &nan, &set).0, "tau");
    assert_eq!(distribute(&factor[1..], &tau, &set).0, "factor");
    assert_eq!(distribute(&[1.5; 8], &tau, &set).0, "factor");
    assert_eq!(distribute(&[f64::NAN; 8], &tau, &set).0, "factor");
    let smaller = ContactSet::from_points(&model, set.points[..4].to_vec()).unwrap();
    assert_eq!(distribute(&factor[..4], &tau, &smaller).0, "set");
    let mut small_frame = ContactFrame::new(&model, &smaller);
    let e = workspace
        .distribute(
            &model,
            &data,
            &set,
            &options,
            &factor,
            &tau,
            &mut small_frame,
        )
        .unwrap_err();
    assert_eq!(invalid(e).0, "out");
    // ground_reaction
    let mut one = vec![GroupWrench::default(); 1];
    assert_eq!(
        invalid(ground_reaction(&set, &frame, &mut one).unwrap_err()).0,
        "out"
    );
    let mut two = vec![GroupWrench::default(); 2];
    assert_eq!(
        invalid(ground_reaction(&set, &small_frame, &mut two).unwrap_err()).0,
        "frame"
    );
}

/// A body standing still on a belt that carries it backward at speed v: the stance feet move
/// together at −v. At v = 1 m/s the floor is detected as a treadmill moving at −1 m/s (and
/// the feet in contact throughout); at 0.1 m/s, below `belt_speed_min`, as a floor at rest;
/// `floor_velocity` given (an overground run) or a treadmill of given speed override it.
#[test]
fn a_belt_under_still_feet_is_detected_as_a_treadmill() {
    let model = Model::default_fullbody();
    let set = ContactSet::from_model(&model).unwrap();
    let nq = model.nq();
    let tx = model.q_index("pelvis_tx").unwrap();
    let rate = 100.0;
    let frames = 100;
    let carried = |v: f64| {
        let mut q = Vec::with_capacity(frames * nq);
        let mut qd = vec![0.0; frames * nq];
        for f in 0..frames {
            let mut qf = model.default_q();
            qf[tx] -= v * f as f64 / rate;
            qd[f * nq + tx] = -v;
            q.extend(qf);
        }
        let qdd = vec![0.0; q.len()];
        (q, qd, qdd)
    };
    let options = ContactOptions {
        floor_height: Some(0.0),
        ..ContactOptions::default()
    };
    let (q, qd, qdd) = carried(1.0);
    let states = contact::detect(&model, &set, &options, &q, &qd, &qdd, rate).unwrap();
    assert!(states.treadmill);
    assert!((states.floor_velocity - Vec3::new(-1.0, 0.0, 0.0)).norm() < 1e-9);
    assert_eq!(states.group_frames(0), frames);
    assert_eq!(states.group_frames(1), frames);
    assert!(states.demand.iter().all(|d| (d - 1.0).abs() < 1e-9));
    let (q, qd, qdd) = carried(0.1);
    let states = contact::detect(&model, &set, &options, &q, &qd, &qdd, rate).unwrap();
    assert!(!states.treadmill && states.floor_velocity == Vec3::zeros());
    let (q, qd, qdd) = carried(1.0);
    let still = ContactOptions {
        floor_velocity: Some(Vec3::zeros()),
        ..options.clone()
    };
    let states = contact::detect(&model, &set, &still, &q, &qd, &qdd, rate).unwrap();
    assert!(!states.treadmill);
    let given = ContactOptions {
        floor_motion: contact::FloorMotion::Treadmill { speed: Some(1.5) },
        ..options
    };
    let states = contact::detect(&model, &set, &given, &q, &qd, &qdd, rate).unwrap();
    assert!(states.treadmill);
    assert!((states.floor_velocity - Vec3::new(-1.5, 0.0, 0.0)).norm() < 1e-9);
}

/// A wide stance (feet about 1 m apart) held still, with the right foot fitted 3–4 cm above
/// the floor over the middle 40 of 100 frames, as a poorly fitted foot is: kinematics
/// alone put that foot in the air, but the body's weight lies midway between the feet, far
/// outside the left foot alone, so the balance evidence keeps both feet in contact. With
/// the balance evidence off (σ_b huge) the right foot is in the air in those frames.
#[test]
fn a_foot_fitted_above_the_floor_under_a_centred_body_stays_in_contact() {
    let model = Model::default_fullbody();
    let set = ContactSet::from_model(&model).unwrap();
    let nq = model.nq();
    let (add_r, add_l) = (
        model.q_index("hip_adduction_r").unwrap(),
        model.q_index("hip_adduction_l").unwrap(),
    );
    let frames = 100;
    let mut q = Vec::with_capacity(frames * nq);
    for f in 0..frames {
        let mut qf = model.default_q();
        qf[add_l] = (-30.0f64).to_radians();
        // the right leg abducted 4° more in the middle frames: its foot 3–4 cm up
        qf[add_r] = if (30..70).contains(&f) {
            -34.0f64
        } else {
            -30.0
        }
        .to_radians();
        q.extend(qf);
    }
    let (qd, qdd) = (vec![0.0; q.len()], vec![0.0; q.len()]);
    let states = contact::detect(
        &model,
        &set,
        &ContactOptions::default(),
        &q,
        &qd,
        &qdd,
        100.0,
    )
    .unwrap();
    let right = set.groups().iter().position(|g| g.ends_with("_r")).unwrap();
    let left = 1 - right;
    let heel_r = set.points.iter().position(|p| p.name == "heel_r").unwrap();
    let lifted = states.height[50 * set.points.len() + heel_r] - states.height[heel_r];
    assert!((0.03..0.04).contains(&lifted), "right heel {lifted} m up");
    assert_eq!(states.group_frames(left), frames);
    assert_eq!(states.group_frames(right), frames);
    let no_balance = ContactOptions {
        balance_scale: 1e9,
        ..ContactOptions::default()
    };
    let states = contact::detect(&model, &set, &no_balance, &q, &qd, &qdd, 100.0).unwrap();
    assert_eq!(states.group_frames(left), frames);
    assert_eq!(states.group_frames(right), frames - 40);
}

/// Kneeling: the default model's pelvis lowered until the knee centres are 5 cm above the
/// floor, the right knee bent 90° — the shanks' bodies are reported (their origins are the
/// knees), the feet are not (nor, pushed through the floor, their own bodies); standing,
/// nothing is.
#[test]
fn kneeling_brings_the_shanks_down_to_the_floor_and_standing_does_not() {
    let model = Model::default_fullbody();
    let set = ContactSet::from_model(&model).unwrap();
    let mut data = Data::new(&model);
    let standing = model.default_q();
    dynamics::forward_kinematics(&model, &mut data, &standing).unwrap();
    let tibia_r = model.body_index("tibia_r").unwrap();
    let knee = data.body_pose(tibia_r).1.y;
    assert!(
        contact::low_bodies(&model, &set, 0.1, &standing)
            .unwrap()
            .is_empty()
    );
    let mut kneeling = standing.clone();
    kneeling[model.q_index("pelvis_ty").unwrap()] -= knee - 0.05;
    kneeling[model.q_index("knee_angle_r").unwrap()] = (-90.0f64).to_radians();
    let q: Vec<f64> = [standing.clone(), kneeling.clone(), kneeling, standing].concat();
    let low = contact::low_bodies(&model, &set, 0.1, &q).unwrap();
    let names: Vec<&str> = low
        .iter()
        .map(|l| model.bodies[l.body].name.as_str())
        .collect();
    assert_eq!(names, ["tibia_r", "tibia_l"], "{low:?}");
    for l in &low {
        assert_eq!((l.frames, l.first, l.last), (2, 1, 2));
        // the straight knee at 5 cm; the bent one's centre slides lower with the knee's
        // coupled translation
        assert!(l.lowest > 0.0 && l.lowest <= 0.05 + 1e-9, "{}", l.lowest);
    }
    assert!(
        contact::low_bodies(&model, &set, f64::NAN, &q)
            .unwrap_err()
            .to_string()
            .contains("height")
    );
}
