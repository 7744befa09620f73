//! Ground reaction forces from kinematics alone against force plates, on every trial at hand
//! with plates: OpenSim's Rajagopal treadmill run (100 Hz), the Gait2392 and Gait10dof18musc
//! treadmill walks (60 Hz) and the C3D overground walks walking2/walking5 (two plates).
//!
//! Each trial goes through the augment chain twice with the same IK: once with its plates as
//! measured loads (the chain then reports the plates' forces per foot in `grf`) and once with
//! the contact estimate and the chain's default options — nothing told about the trial
//! (treadmill or not, gait or run). Per foot: vertical, anteroposterior and mediolateral RMSE
//! in % of body weight, the ratio of peak vertical forces, and the timing of foot strike and
//! toe-off (crossings of 5 % body weight by the plate and by the estimate). Overground, a foot
//! is compared only around its plate stances (from 0.1 s before each strike to 0.1 s after its
//! toe-off), and only around stances wholly on a plate: every point of the foot that touches
//! the floor (its lowest point within 3 cm of it) lies within the plate's corners (1 cm
//! margin). A stance partly off its plate is counted and left out: the plate does not see all
//! that foot carries.
//!
//! `cargo test --release --test grf_from_markers -- --nocapture` prints the table of the
//! docs/src/guide/contact.md, "Against force plates".

mod common;

use common::reference_file;
use musculo::Model;
use musculo::augment::chain::{Chain, ChainOptions, ClipOutput, MeasuredLoads, contact_set};
use musculo::augment::perturb::Variant;
use musculo::dynamics::{self, Data};
use musculo::io::scale_setup::ScaleSetup;
use musculo::motion::c3d::{C3d, lab_to_opensim};
use musculo::motion::skeleton::SkeletonMap;
use musculo::motion::{self, Format, Motion, ReadOptions};
use musculo::solve::scale::tool::{self, ToolOptions};
use musculo::spatial::Vec3;
use std::path::PathBuf;

const G: f64 = 9.80665;

/// One trial: the model's text and source, the markers, an optional skeleton map, its plates.
struct Trial {
    name: &'static str,
    xml: Option<(String, String)>,
    motion: Motion,
    map: Option<SkeletonMap>,
    loads: MeasuredLoads,
    /// Plates cover the whole walkway (a treadmill): every frame compares.
    whole_trial: bool,
}

/// Figures of one foot.
#[derive(Debug, Default, Clone)]
struct FootFigures {
    vertical: f64,
    ap: f64,
    ml: f64,
    peak_ratio: f64,
    /// Estimated minus measured event times, s.
    strikes: Vec<f64>,
    toe_offs: Vec<f64>,
    /// Plate stances with no estimated strike within 0.15 s, and estimated stances with no
    /// plate stance within 0.15 s.
    missed: usize,
    spurious: usize,
    frames: usize,
    /// Plate stances left out because the foot was partly off the plate.
    off_plate: usize,
}

fn rajagopal_run() -> Option<Trial> {
    let dir = "opensim-models/Pipelines/Rajagopal";
    let setup = reference_file(&format!("{dir}/Scale/scale_setup_run.xml"))?;
    let generic = reference_file("opensim-models/Models/Rajagopal/Rajagopal2016.osim")?;
    let trc = reference_file(&format!("{dir}/ExpData/motion_capture_run.trc"))?;
    let loads = reference_file(&format!("{dir}/ID/grf_run.xml"))?;
    let setup = ScaleSetup::read(&setup).unwrap();
    let scaled = tool::run(
        &setup,
        &ToolOptions {
            model_file: Some(generic.clone()),
            ..ToolOptions::default()
        },
    )
    .unwrap();
    let (xml, _) = scaled.final_model();
    Some(Trial {
        name: "Rajagopal run (treadmill, 100 Hz)",
        xml: Some((xml.to_string(), generic.display().to_string())),
        motion: motion::read(&trc, None, &ReadOptions::default()).unwrap(),
        map: None,
        loads: MeasuredLoads::ExternalLoads(loads),
        whole_trial: true,
    })
}

fn opensim_walk(name: &'static str, model: &str, trc: &str, loads: &str) -> Option<Trial> {
    let model = reference_file(model)?;
    let trc = reference_file(trc)?;
    let loads = reference_file(loads)?;
    Some(Trial {
        name,
        xml: Some((
            std::fs::read_to_string(&model).unwrap(),
            model.display().to_string(),
        )),
        motion: motion::read(&trc, None, &ReadOptions::default()).unwrap(),
        map: None,
        loads: MeasuredLoads::ExternalLoads(loads),
        whole_trial: true,
    })
}

fn c3d_walk(name: &'static str, file: &str) -> Option<Trial> {
    let path: PathBuf = reference_file(file)?;
    let motion = motion::read(&path, Some(Format::C3d), &ReadOptions::default()).unwrap();
    Some(Trial {
        name,
        xml: None,
        map: SkeletonMap::builtin_matching(&motion),
        motion,
        loads: MeasuredLoads::ForcePlates(path),
        whole_trial: false,
    })
}

fn trials() -> Vec<Trial> {
    let g2392 = "opensim-models/Pipelines/Gait2392_Simbody";
    let g10 = "opensim-models/Pipelines/Gait10dof18musc";
    [
        rajagopal_run(),
        opensim_walk(
            "Gait2392 walk (treadmill, 60 Hz)",
            &format!("{g2392}/OutputReference/subject01_simbody.osim"),
            &format!("{g2392}/subject01_walk1.trc"),
            &format!("{g2392}/subject01_walk1_grf.xml"),
        ),
        opensim_walk(
            "Gait10dof18musc walk (treadmill, 60 Hz)",
            &format!("{g10}/OutputReference/subject01.osim"),
            &format!("{g10}/ExperimentalData/subject01_walk.trc"),
            &format!("{g10}/ExperimentalData/subject01_walk_grf.xml"),
        ),
        c3d_walk("C3D walking2 (overground)", "c3d/walking2.c3d"),
        c3d_walk("C3D walking5 (overground)", "c3d/walking5.c3d"),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// Upward crossings (strikes) and downward crossings (toe-offs) of `level` by a series,
/// interpolated between frames (times in s).
fn crossings(v: &[f64], times: &[f64], level: f64) -> (Vec<f64>, Vec<f64>) {
    let (mut up, mut down) = (Vec::new(), Vec::new());
    for t in 1..v.len() {
        let (a, b) = (v[t - 1] - level, v[t] - level);
        if (a < 0.0) != (b < 0.0) {
            let s = a / (a - b);
            let time = times[t - 1] + s * (times[t] - times[t - 1]);
            if b >= 0.0 {
                up.push(time)
            } else {
                down.push(time)
            }
        }
    }
    (up, down)
}

/// Nearest-event differences `estimate − measured` within `window`; the unmatched counts.
fn pair(measured: &[f64], estimate: &[f64], window: f64) -> (Vec<f64>, usize, usize) {
    let mut used = vec![false; estimate.len()];
    let mut diffs = Vec::new();
    let mut missed = 0;
    for &m in measured {
        let best = (0..estimate.len())
            .filter(|&k| !used[k])
            .min_by(|&a, &b| (estimate[a] - m).abs().total_cmp(&(estimate[b] - m).abs()));
        match best {
            Some(k) if (estimate[k] - m).abs() <= window => {
                used[k] = true;
                diffs.push(estimate[k] - m);
            }
            _ => missed += 1,
        }
    }
    (diffs, missed, used.iter().filter(|u| !**u).count())
}

fn array<'a>(out: &'a ClipOutput, name: &str) -> &'a [f32] {
    &out.arrays.iter().find(|a| a.name == name).unwrap().values
}

/// Per-foot figures of one trial (foot groups in the chain's order).
fn compare(
    trial: &Trial,
    model: &Model,
    measured: &ClipOutput,
    estimated: &ClipOutput,
) -> Vec<FootFigures> {
    let weight = measured.quality.body_mass * G;
    let times: Vec<f64> = array(measured, "time").iter().map(|&t| t as f64).collect();
    let frames = times.len();
    let (gm, ge) = (array(measured, "grf"), array(estimated, "grf"));
    let groups = gm.len() / (3 * frames);
    let dt = (times[frames - 1] - times[0]) / (frames - 1) as f64;
    let level = 0.05 * weight;
    let on_plates: Vec<Vec<bool>> = if trial.whole_trial {
        vec![vec![true; frames]; groups]
    } else {
        feet_on_plates(trial, model, estimated, groups)
    };
    // Overground the model's mass is not the subject's (a C3D file does not say it): the
    // plates are expressed in the subject's body weight, from momentum over a stride of
    // steady walking — both feet's vertical impulses sum to W·T over a stride and are equal,
    // so W = 2 ∫F dt / T over a stance wholly on a plate, T the stride time between that
    // foot's strikes (as the estimate places them) — and then in the model's.
    let mut plate_scale = 1.0;
    if !trial.whole_trial {
        for g in 0..groups {
            let mv: Vec<f64> = (0..frames)
                .map(|f| gm[(f * groups + g) * 3 + 1] as f64)
                .collect();
            let ev: Vec<f64> = (0..frames)
                .map(|f| ge[(f * groups + g) * 3 + 1] as f64)
                .collect();
            let (strikes, _) = crossings(&ev, &times, level);
            if strikes.len() < 2 {
                continue;
            }
            let stride = (strikes[strikes.len() - 1] - strikes[0]) / (strikes.len() - 1) as f64;
            let loaded: Vec<usize> = (0..frames).filter(|&f| mv[f] > level).collect();
            let (Some(&a), Some(&b)) = (loaded.first(), loaded.last()) else {
                continue;
            };
            let whole =
                (a..=b).all(|f| mv[f] > level && on_plates[g][f]) && a > 0 && b + 1 < frames;
            if whole {
                let impulse: f64 = mv[a..=b].iter().sum::<f64>() * dt;
                let subject = 2.0 * impulse / stride;
                println!(
                    "{}: subject weight from plate stance of foot {g}: {:.0} N ({:.1} kg; \
                     model {:.1} kg), stride {:.3} s",
                    trial.name,
                    subject,
                    subject / G,
                    weight / G,
                    stride
                );
                plate_scale = weight / subject;
                break;
            }
        }
    }
    let gm: Vec<f32> = gm.iter().map(|&v| v * plate_scale as f32).collect();
    let gm = &gm[..];
    (0..groups)
        .map(|g| {
            let series = |a: &[f32], c: usize| -> Vec<f64> {
                (0..frames)
                    .map(|f| a[(f * groups + g) * 3 + c] as f64)
                    .collect()
            };
            let (mv, ev) = (series(gm, 1), series(ge, 1));
            let (m_up, m_down) = crossings(&mv, &times, level);
            let (e_up, e_down) = crossings(&ev, &times, level);
            // frames compared: all on a treadmill; overground, around each plate stance
            // wholly on a plate
            let mut off_plate = 0;
            let compared: Vec<bool> = if trial.whole_trial {
                vec![true; frames]
            } else {
                let mut keep = vec![false; frames];
                let margin = (0.1 / dt).round() as usize;
                let loaded: Vec<bool> = mv.iter().map(|&v| v > level).collect();
                let on_plate = &on_plates[g];
                let mut f = 0;
                while f < frames {
                    if !loaded[f] {
                        f += 1;
                        continue;
                    }
                    let start = f;
                    while f < frames && loaded[f] {
                        f += 1;
                    }
                    if (start..f).all(|k| on_plate[k]) {
                        let lo = start.saturating_sub(margin);
                        let hi = (f + margin).min(frames);
                        keep[lo..hi].iter_mut().for_each(|k| *k = true);
                    } else {
                        off_plate += 1;
                    }
                }
                keep
            };
            let in_compared = |t: &f64| {
                let f = (((t - times[0]) / dt).round() as usize).min(frames - 1);
                compared[f]
            };
            let rms = |c: usize| {
                let (m, e) = (series(gm, c), series(ge, c));
                let (mut s, mut n) = (0.0, 0);
                for f in (0..frames).filter(|&f| compared[f]) {
                    s += (m[f] - e[f]).powi(2);
                    n += 1;
                }
                (s / n.max(1) as f64).sqrt() / weight
            };
            let peak = |v: &[f64]| {
                (0..frames)
                    .filter(|&f| compared[f])
                    .map(|f| v[f])
                    .fold(0.0f64, f64::max)
            };
            let e_up: Vec<f64> = e_up.into_iter().filter(in_compared).collect();
            let e_down: Vec<f64> = e_down.into_iter().filter(in_compared).collect();
            let (strikes, missed, spurious) = pair(&m_up, &e_up, 0.15);
            let (toe_offs, _, _) = pair(&m_down, &e_down, 0.15);
            FootFigures {
                vertical: rms(1),
                ap: rms(0),
                ml: rms(2),
                peak_ratio: peak(&ev) / peak(&mv),
                strikes,
                toe_offs,
                missed,
                spurious,
                frames: compared.iter().filter(|c| **c).count(),
                off_plate,
            }
        })
        .collect()
}

/// Per foot group and frame: whether every point of the group that touches the floor (lowest
/// point within 3 cm of the lowest of all points) lies on one of the trial's plates (its
/// corners in the floor plane, 1 cm margin). Poses from the estimate's `q`.
fn feet_on_plates(trial: &Trial, model: &Model, out: &ClipOutput, groups: usize) -> Vec<Vec<bool>> {
    let MeasuredLoads::ForcePlates(path) = &trial.loads else {
        unreachable!("overground trials are C3D files")
    };
    let c3d = C3d::read(path).unwrap();
    // plate rectangles in the floor plane (x, z of OpenSim's frame)
    let plates: Vec<[Vec3; 4]> = c3d
        .plates
        .iter()
        .map(|p| p.corners.map(|c| lab_to_opensim(&c)))
        .collect();
    let inside = |x: &Vec3, c: &[Vec3; 4]| {
        // inside a convex quadrilateral (either winding), 1 cm margin
        let mut sign = 0.0;
        for k in 0..4 {
            let (a, b) = (c[k], c[(k + 1) % 4]);
            let edge = Vec3::new(b.x - a.x, 0.0, b.z - a.z);
            let rel = Vec3::new(x.x - a.x, 0.0, x.z - a.z);
            let cross = edge.z * rel.x - edge.x * rel.z;
            let distance = cross / edge.norm();
            if sign == 0.0 {
                sign = distance.signum();
            }
            if distance * sign < -0.01 {
                return false;
            }
        }
        true
    };
    let set = contact_set(model).unwrap();
    let q = array(out, "q");
    let nq = model.nq();
    let mut data = Data::new(model);
    let mut on = vec![Vec::new(); groups];
    for qf in q.chunks(nq) {
        let qf: Vec<f64> = qf.iter().map(|&v| v as f64).collect();
        dynamics::forward_kinematics(model, &mut data, &qf).unwrap();
        let positions: Vec<(usize, Vec3)> = set
            .points
            .iter()
            .enumerate()
            .map(|(p, point)| {
                let x = data.point_position(point.body, &point.location_in_body);
                (p, x - Vec3::y() * point.radius)
            })
            .collect();
        let lowest = positions
            .iter()
            .map(|(_, x)| x.y)
            .fold(f64::INFINITY, f64::min);
        for (g, on) in on.iter_mut().enumerate() {
            on.push(
                positions
                    .iter()
                    .filter(|(p, x)| set.group_of(*p) == g && x.y <= lowest + 0.03)
                    .all(|(_, x)| plates.iter().any(|c| inside(x, c))),
            );
        }
    }
    on
}

fn mean_abs(v: &[f64]) -> f64 {
    v.iter().map(|x| x.abs()).sum::<f64>() / v.len().max(1) as f64
}

#[test]
fn vertical_ground_reaction_from_markers_alone_matches_the_plates() {
    let trials = trials();
    if trials.is_empty() {
        return;
    }
    println!(
        "| trial | foot | frames | vertical RMSE % BW | AP % BW | ML % BW | peak ratio | \
         strike Δ ms (mean abs, worst) | toe-off Δ ms (mean abs, worst) | stances missed / spurious | \
         plate stances partly off the plate | floor detected |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut worst = Vec::new();
    for trial in &trials {
        let options = ChainOptions {
            muscles: false,
            ..ChainOptions::default()
        };
        let chain = match &trial.xml {
            Some((xml, source)) => Chain::new(xml.clone(), source.clone(), options).unwrap(),
            None => Chain::default_model(options).unwrap(),
        };
        let v = Variant::identity();
        let map = trial.map.as_ref();
        let measured = chain
            .run_with_loads(&trial.motion, map, &v, Some(&trial.loads))
            .unwrap();
        let estimated = chain.run(&trial.motion, map, &v).unwrap();
        let model = chain.clip_model(&trial.motion, map, &v).unwrap();
        let feet = compare(trial, &model, &measured, &estimated);
        let rate = estimated.quality.rate_hz;
        let belt = estimated.quality.belt_velocity;
        let floor = if estimated.quality.treadmill {
            format!(
                "treadmill, {:.2} m/s",
                (belt[0] * belt[0] + belt[2] * belt[2]).sqrt()
            )
        } else {
            "at rest".to_string()
        };
        // treadmills are told apart from floors at rest without a flag
        assert_eq!(
            estimated.quality.treadmill, trial.whole_trial,
            "{}",
            trial.name
        );
        for (g, foot) in feet.iter().enumerate() {
            if foot.frames == 0 {
                println!(
                    "| {} | {} | no stance wholly on a plate ({} partly off) ||||||||| {} |",
                    trial.name,
                    if g == 0 { "right" } else { "left" },
                    foot.off_plate,
                    floor
                );
                continue;
            }
            let worst_ms = |v: &[f64]| v.iter().map(|x| x.abs()).fold(0.0, f64::max) * 1e3;
            println!(
                "| {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.2} | {:.0}, {:.0} | {:.0}, {:.0} | {} / {} | {} | {} |",
                trial.name,
                if g == 0 { "right" } else { "left" },
                foot.frames,
                100.0 * foot.vertical,
                100.0 * foot.ap,
                100.0 * foot.ml,
                foot.peak_ratio,
                mean_abs(&foot.strikes) * 1e3,
                worst_ms(&foot.strikes),
                mean_abs(&foot.toe_offs) * 1e3,
                worst_ms(&foot.toe_offs),
                foot.missed,
                foot.spurious,
                foot.off_plate,
                floor
            );
            worst.push((
                trial.name,
                g,
                foot.clone(),
                rate,
                estimated.warnings.clone(),
            ));
        }
    }
    // The limits: the literature's ≈ 5 % of body weight for walking; 8 % for running, whose
    // impacts a 6 Hz low-pass filter of the kinematics cannot follow; strikes within one
    // frame of the plates. Overground, the estimate carries what the default model's lower-
    // body marker set makes of the walk (its body mass from the plates): 11 %.
    for (name, g, foot, rate, _) in &worst {
        let limit = if name.starts_with("Rajagopal") {
            0.08
        } else if name.starts_with("C3D") {
            0.11
        } else {
            0.05
        };
        if foot.frames == 0 {
            continue;
        }
        assert!(
            foot.vertical <= limit,
            "{name} foot {g}: {} > {limit}",
            foot.vertical
        );
        assert!(
            (0.9..=1.1).contains(&foot.peak_ratio),
            "{name} foot {g}: {}",
            foot.peak_ratio
        );
        // within one frame at 60–100 Hz (10 ms at higher rates): a detected contact starts
        // on a frame, so its force crosses 5 % BW up to a frame after the plate's crossing,
        // plus the crossing's interpolation within that frame (a quarter frame allowed)
        let frame = (1.0 / rate).max(0.010);
        assert!(
            mean_abs(&foot.strikes) <= 1.25 * frame,
            "{name} foot {g}: {:?}",
            foot.strikes
        );
        assert_eq!(foot.spurious, 0, "{name} foot {g}");
        assert!(foot.missed <= 1, "{name} foot {g}: {}", foot.missed);
    }
}
