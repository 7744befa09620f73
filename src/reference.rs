//! Locating the public reference data (`../shared/reference`) that tests, benchmarks and
//! validation read in place. The directory comes from `MUSCULO_REFERENCE` or defaults to
//! `../shared/reference` beside this repository.

use std::path::PathBuf;

/// The reference data directory: `$MUSCULO_REFERENCE`, else `<repo>/../shared/reference`.
pub fn directory() -> PathBuf {
    match std::env::var_os("MUSCULO_REFERENCE") {
        Some(p) if !p.is_empty() => PathBuf::from(p),
        _ => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/reference"),
    }
}

/// True when `MUSCULO_REQUIRE_REFERENCE=1`: a missing reference file is then a failure
/// instead of a skip.
pub fn required() -> bool {
    std::env::var("MUSCULO_REQUIRE_REFERENCE")
        .is_ok_and(|v| v == "1" || v.eq_ignore_ascii_case("true"))
}

/// The path of a reference file (relative to the reference directory), if it exists.
pub fn file(relative: &str) -> Option<PathBuf> {
    let p = directory().join(relative);
    p.exists().then_some(p)
}

/// For unit tests: the embedded default model, then gait2392 and Rajagopal2016 where the
/// reference data has them ("skipped: reference data not found" for a missing one, a failure
/// under [`required`]).
#[cfg(test)]
pub(crate) fn test_models() -> Vec<(&'static str, crate::Model)> {
    let mut out = vec![("default", crate::Model::default_fullbody())];
    for (name, relative) in [
        (
            "gait2392",
            "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        ),
        (
            "Rajagopal2016",
            "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
        ),
    ] {
        match file(relative) {
            Some(p) => out.push((
                name,
                crate::Model::from_osim_file(&p)
                    .unwrap_or_else(|e| panic!("{relative} does not load: {e}")),
            )),
            None if required() => {
                panic!("reference file {relative} not found and MUSCULO_REQUIRE_REFERENCE is set")
            }
            None => eprintln!("skipped: reference data not found ({relative})"),
        }
    }
    out
}

/// For unit tests: independent coordinates drawn uniformly inside their ranges, a fraction
/// `margin` of each range kept clear at both ends (so that small steps stay inside).
#[cfg(test)]
pub(crate) fn random_q(
    model: &crate::Model,
    rng: &mut crate::random::SplitMix64,
    margin: f64,
) -> Vec<f64> {
    model
        .reduction
        .independent
        .iter()
        .map(|&c| {
            let [lo, hi] = model.coordinates[c].range;
            let m = margin * (hi - lo);
            rng.uniform(lo + m, hi - m)
        })
        .collect()
}

/// For unit tests: a clip in the per-joint layout, `t` frames at `rate` Hz, of a smooth
/// motion — translational coordinates at constant speed (so that differences of the root's
/// centre are exact), the others mid-range plus a sine of a quarter of their half-range —
/// with random forces at `contacts` (ground axes, N), τ = τ_ID − Σ J_iᵀ λ_i; then, with
/// `noise` > 0, every block disturbed so that they disagree as a generated motion's do.
/// Returns the blocks [joint_pos, joint_rot, joint_vel, joint_acc, joint_torque,
/// contact_force] (T × J × 3 each) and τ (T × n).
#[cfg(test)]
pub(crate) fn layout_motion(
    model: &crate::Model,
    t: usize,
    rate: f64,
    contacts: &[crate::loss::LossContact],
    noise: f64,
) -> ([Vec<f64>; 6], Vec<f64>) {
    use crate::augment::layout::{JointFrame, JointLayout};
    use crate::dynamics::{self, Data};
    use crate::loss::{EulerLagrange, EulerLagrangeBatch, EulerLagrangeOutput};
    use crate::model::MotionType;
    use crate::random::SplitMix64;
    use crate::spatial::Vec3;
    let n = model.nq();
    let layout = JointLayout::new(model, 0);
    let mut rng = SplitMix64(7);
    let waves: Vec<(f64, f64, f64, f64, bool)> = model
        .reduction
        .independent
        .iter()
        .map(|&c| {
            let coordinate = &model.coordinates[c];
            let [lo, hi] = coordinate.range;
            let half = (0.5 * (hi - lo)).min(1.0);
            (
                0.5 * (lo + hi),
                0.25 * half,
                rng.uniform(1.0, 4.0),
                rng.uniform(0.0, 6.0),
                coordinate.motion_type == MotionType::Translational,
            )
        })
        .collect();
    let loss = EulerLagrange {
        contacts: contacts.to_vec(),
        weights: Vec::new(),
    };
    let mut data = Data::new(model);
    let mut ws = layout.workspace(model);
    let mut frame = JointFrame::new(&layout);
    let mut blocks: [Vec<f64>; 6] = Default::default();
    let mut taus = Vec::new();
    for f in 0..t {
        let s = f as f64 / rate;
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for (j, &(mid, amp, w, ph, linear)) in waves.iter().enumerate() {
            if linear {
                q[j] = mid + amp * w * s;
                qd[j] = amp * w;
            } else {
                q[j] = mid + amp * (w * s + ph).sin();
                qd[j] = amp * w * (w * s + ph).cos();
                qdd[j] = -amp * w * w * (w * s + ph).sin();
            }
        }
        let lambda: Vec<f64> = (0..3 * contacts.len())
            .map(|i| {
                if i % 3 == 1 {
                    rng.uniform(50.0, 400.0)
                } else {
                    rng.uniform(-60.0, 60.0)
                }
            })
            .collect();
        // τ = τ_ID − Σ J_iᵀ λ_i: the residual of the loss at τ = 0
        let zero = vec![0.0; n];
        let mut out = EulerLagrangeOutput::default();
        let batch = EulerLagrangeBatch {
            frames: 1,
            q: &q,
            qd: &qd,
            qdd: &qdd,
            tau: &zero,
            lambda: &lambda,
        };
        loss.evaluate(model, &batch, false, &mut out).unwrap();
        let tau = out.residual;
        let mut body_contact = vec![Vec3::zeros(); model.bodies.len()];
        for (c, l) in contacts.iter().zip(lambda.chunks(3)) {
            body_contact[c.body] += Vec3::new(l[0], l[1], l[2]);
        }
        dynamics::forward_kinematics_acceleration(model, &mut data, &q, &qd, &qdd).unwrap();
        layout
            .frame(model, &data, &tau, &body_contact, &mut ws, &mut frame)
            .unwrap();
        for (block, (values, scale)) in blocks.iter_mut().zip([
            (&frame.pos, 0.005),
            (&frame.rot, 0.03),
            (&frame.vel, 0.1),
            (&frame.acc, 0.5),
            (&frame.torque, 1.0),
            (&frame.contact, 5.0),
        ]) {
            for v in values {
                block.extend(v.iter().map(|x| x + noise * scale * rng.uniform(-1.0, 1.0)));
            }
        }
        taus.extend(tau);
    }
    (blocks, taus)
}

/// For unit tests: the first five blocks of [`layout_motion`] as a layout clip.
#[cfg(test)]
pub(crate) fn layout_clip(
    t: usize,
    rate: f64,
    x: &[Vec<f64>],
) -> crate::augment::layout_inverse::LayoutClip<'_> {
    crate::augment::layout_inverse::LayoutClip {
        frames: t,
        rate_hz: rate,
        joint_pos: &x[0],
        joint_rot: &x[1],
        joint_vel: &x[2],
        joint_acc: &x[3],
        joint_torque: &x[4],
    }
}

/// For unit tests: two contact points under each foot body the model has (calcn, toes), in
/// body coordinates.
#[cfg(test)]
pub(crate) fn foot_contacts(model: &crate::Model) -> Vec<crate::loss::LossContact> {
    let mut out = Vec::new();
    for (b, body) in model.bodies.iter().enumerate() {
        if ["calcn_r", "calcn_l", "toes_r", "toes_l"].contains(&body.name.as_str()) {
            for (k, x) in [-0.03, 0.06].into_iter().enumerate() {
                out.push(crate::loss::LossContact {
                    name: format!("{}_{k}", body.name),
                    body: b,
                    location_in_body: crate::spatial::Vec3::new(x, -0.01, 0.0),
                    offset_in_ground: crate::spatial::Vec3::zeros(),
                });
            }
        }
    }
    out
}
