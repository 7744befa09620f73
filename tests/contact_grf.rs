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

use common::reference_file;
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
    /// RMS of the unexplained residual on the floating-base translation rows.
    residual_force_rms: f64,
    micros_per_frame: f64,
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
    let (mut q, mut qd, mut qdd) = (vec![0.0; frames * nq], vec![0.0; frames * nq], vec![
        0.0;
        frames * nq
    ]);
    for (f, &t) in times.iter().enumerate() {
        let r = f * nq..(f + 1) * nq;
        let (a, b, c) = (
            &mut q[r.clone()],
            &mut qd[r.clone()],
            &mut qdd[r.clone()],
        );
        prepared.trajectory.eval(t, a, b, c);
    }
    let states = contact::detect(&model, &set, options, &q, &qd, rate).unwrap();
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
    let mut residual2 = 0.0;
    let mut solve_time = 0.0;
    let translation_rows: Vec<usize> = set
        .floating_base
        .iter()
        .enumerate()
        .filter(|(_, j)| model.q_names()[**j].ends_with(['x', 'y', 'z']))
        .map(|(r, _)| r)
        .collect();
    let mut rows = Vec::new();
    for (f, &t) in times.iter().enumerate() {
        let r = f * nq..(f + 1) * nq;
        let id = dynamics::rnea(&model, &mut data, &q[r.clone()], &qd[r.clone()], &qdd[r]).unwrap();
        tau.copy_from_slice(id.as_slice());
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
        for &row in &translation_rows {
            residual2 += frame.residual[row].powi(2) / translation_rows.len() as f64;
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
            line += &format!("  {:7.1} {:7.1}", est.y, meas.y);
        }
        rows.push(line);
    }
    if std::env::var_os("MUSCULO_CONTACT_TRACE").is_some() {
        eprintln!("time   est_r   plate_r   est_l   plate_l (vertical, N)");
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
        micros_per_frame: 1e6 * solve_time / frames as f64,
    })
}

fn report(title: &str, w: &WalkFigures) {
    let pct = |x: f64| 100.0 * x / w.body_weight;
    eprintln!(
        "{title}: {} frames, body weight {:.1} N\n  per-foot RMSE: vertical {:.1} N ({:.2} % BW), \
         anterior-posterior {:.1} N ({:.2} % BW), medio-lateral {:.1} N ({:.2} % BW)\n  \
         COP mean error (foot loaded > 10 % BW): AP {:.1} mm, ML {:.1} mm\n  unexplained \
         floating-base force residual RMS {:.2} N; distribute {:.1} µs/frame",
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
        w.micros_per_frame
    );
}

/// The walks are on a treadmill: speeds are measured relative to the belt, estimated.
fn treadmill() -> ContactOptions {
    let mut o = ContactOptions {
        floor_velocity: None,
        ..ContactOptions::default()
    };
    if let Ok(s) = std::env::var("TUNE") {
        for kv in s.split(',') {
            let (k, v) = kv.split_once('=').unwrap();
            let v: f64 = v.parse().unwrap();
            match k {
                "hon" => o.height_on = v,
                "hoff" => o.height_off = v,
                "hfull" => o.height_full = v,
                "son" => o.speed_on = v,
                "soff" => o.speed_off = v,
                "tt" => o.transition_time = v,
                "mu" => o.friction = Some(v),
                "pct" => o.floor_percentile = v,
                _ => panic!("{k}"),
            }
        }
    }
    o
}

const GAIT2392: &str = "opensim-models/Pipelines/Gait2392_Simbody";
const GAIT10: &str = "opensim-models/Pipelines/Gait10dof18musc/OutputReference";

#[test]
fn vertical_grf_from_kinematics_matches_force_plates_gait2392_walk() {
    let title = "gait2392 walk";
    let Some(w) = walk(
        title,
        &format!("{GAIT2392}/OutputReference/subject01_simbody.osim"),
        &format!("{GAIT2392}/subject01_walk1_ik.mot"),
        &format!("{GAIT2392}/subject01_walk1_grf.xml"),
        &treadmill(),
    ) else {
        return;
    };
    report(title, &w);
    assert!(
        w.vertical_rmse <= 0.05 * w.body_weight,
        "vertical RMSE {:.1} N > 5 % of body weight",
        w.vertical_rmse
    );
}

#[test]
fn vertical_grf_from_kinematics_matches_force_plates_gait10dof18musc_walk() {
    let title = "Gait10dof18musc walk";
    let Some(w) = walk(
        title,
        &format!("{GAIT10}/subject01.osim"),
        &format!("{GAIT10}/IK/subject01_walk_IK.mot"),
        &format!("{GAIT10}/ExperimentalData/subject01_walk_grf.xml"),
        &treadmill(),
    ) else {
        return;
    };
    report(title, &w);
    assert!(
        w.vertical_rmse <= 0.05 * w.body_weight,
        "vertical RMSE {:.1} N > 5 % of body weight",
        w.vertical_rmse
    );
}
