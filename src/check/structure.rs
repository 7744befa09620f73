//! Checks of the model's skeleton: connectivity, masses and inertias, coordinate ranges.

use super::{Check, CheckOptions, Family, Status, SubjectKind};
use crate::model::{Model, MotionType};

#[allow(clippy::too_many_arguments)]
fn check(
    family: Family,
    name: &str,
    kind: SubjectKind,
    subject: &str,
    pass: bool,
    value: Option<f64>,
    unit: &'static str,
    limit: String,
    message: String,
) -> Check {
    Check {
        family,
        name: name.to_string(),
        subject_kind: kind,
        subject: subject.to_string(),
        status: if pass { Status::Pass } else { Status::Fail },
        value,
        unit,
        limit,
        message,
    }
}

/// Every body reaches ground through exactly one joint per body, without cycles; every
/// attached element names an existing body.
pub(super) fn connectivity(model: &Model, out: &mut Vec<Check>) {
    let nb = model.bodies.len();
    for (b, body) in model.bodies.iter().enumerate().skip(1) {
        let joints_in: Vec<&str> = model
            .joints
            .iter()
            .filter(|j| j.child_body == b)
            .map(|j| j.name.as_str())
            .collect();
        // Walk to ground; more than nb steps is a cycle.
        let (mut at, mut steps, mut reached) = (b, 0usize, false);
        while steps <= nb {
            match model.bodies.get(at).and_then(|x| x.parent) {
                Some(0) => {
                    reached = true;
                    break;
                }
                Some(p) => at = p,
                None => break,
            }
            steps += 1;
        }
        let consistent = body.joint.is_some_and(|j| {
            model
                .joints
                .get(j)
                .is_some_and(|jt| jt.child_body == b && Some(jt.parent_body) == body.parent)
        });
        let pass = joints_in.len() == 1 && reached && consistent;
        let message = if pass {
            format!(
                "joint `{}`, {} joint(s) from ground",
                joints_in[0],
                steps + 1
            )
        } else if joints_in.len() != 1 {
            format!(
                "moved by {} joints ({}); a body needs exactly one",
                joints_in.len(),
                joints_in.join(", ")
            )
        } else if !reached {
            "does not reach ground (orphan body or cycle)".to_string()
        } else {
            "the body's joint and parent disagree with the joint list".to_string()
        };
        out.push(check(
            Family::Connectivity,
            "joined to ground once",
            SubjectKind::Body,
            &body.name,
            pass,
            Some(joints_in.len() as f64),
            "joints",
            "= 1, reaching ground".into(),
            message,
        ));
    }
    // Attached elements: name the offenders.
    let mut attached: Vec<(&str, Vec<String>, usize)> = Vec::new();
    let bad = |b: usize| b >= nb;
    attached.push((
        "markers on bodies",
        model
            .markers
            .iter()
            .filter(|m| bad(m.body))
            .map(|m| m.name.clone())
            .collect(),
        model.markers.len(),
    ));
    attached.push((
        "wrap objects on bodies",
        model
            .wrap_objects
            .iter()
            .filter(|w| bad(w.body))
            .map(|w| w.name.clone())
            .collect(),
        model.wrap_objects.len(),
    ));
    attached.push((
        "contact geometry on bodies",
        model
            .contact_geometry
            .iter()
            .filter(|c| bad(c.body))
            .map(|c| c.name.clone())
            .collect(),
        model.contact_geometry.len(),
    ));
    let mut points = 0;
    let mut bad_points = Vec::new();
    for f in &model.forces {
        for p in f.path.iter().flat_map(|p| p.points.iter()) {
            points += 1;
            if bad(p.body) {
                bad_points.push(format!("{}/{}", f.name, p.name));
            }
        }
    }
    attached.push(("path points on bodies", bad_points, points));
    for (name, offenders, total) in attached {
        out.push(check(
            Family::Connectivity,
            name,
            SubjectKind::Model,
            &model.name,
            offenders.is_empty(),
            Some(offenders.len() as f64),
            "orphans",
            "= 0".into(),
            if offenders.is_empty() {
                format!("{total} attached")
            } else {
                format!("not on any body: {}", offenders.join(", "))
            },
        ));
    }
}

/// Masses > 0; inertias finite, symmetric, positive definite, triangle inequality.
pub(super) fn mass_inertia(model: &Model, out: &mut Vec<Check>) {
    for body in model.bodies.iter().skip(1) {
        out.push(check(
            Family::MassInertia,
            "mass > 0",
            SubjectKind::Body,
            &body.name,
            body.mass > 0.0 && body.mass.is_finite(),
            Some(body.mass),
            "kg",
            "> 0".into(),
            String::new(),
        ));
        let i = body.inertia_about_com;
        let asym = (i - i.transpose()).abs().max();
        let finite = i.iter().all(|v| v.is_finite());
        let scale = i.abs().max().max(f64::MIN_POSITIVE);
        let symmetric = finite && asym <= 1e-9 * scale;
        // Principal moments, ascending.
        let mut p = if finite {
            let e = nalgebra::SymmetricEigen::new((i + i.transpose()) * 0.5).eigenvalues;
            [e[0], e[1], e[2]]
        } else {
            [f64::NAN; 3]
        };
        p.sort_by(f64::total_cmp);
        let pd = symmetric && p[0] > 0.0;
        out.push(check(
            Family::MassInertia,
            "inertia positive definite",
            SubjectKind::Body,
            &body.name,
            pd,
            Some(p[0]),
            "kg m²",
            "smallest principal moment > 0".into(),
            if !finite {
                "inertia is not finite".into()
            } else if !symmetric {
                format!("inertia is not symmetric (|I - Iᵀ| = {asym:.3e})")
            } else {
                format!("principal moments {:.4e}, {:.4e}, {:.4e}", p[0], p[1], p[2])
            },
        ));
        // I₁ + I₂ ≥ I₃ for the two smallest against the largest (relative tolerance 1e-9,
        // as the reader's).
        let margin = p[0] + p[1] - p[2];
        out.push(check(
            Family::MassInertia,
            "inertia triangle inequality",
            SubjectKind::Body,
            &body.name,
            finite && margin >= -1e-9 * p[2].abs(),
            Some(margin),
            "kg m²",
            "I₁ + I₂ − I₃ ≥ 0".into(),
            format!("principal moments {:.4e}, {:.4e}, {:.4e}", p[0], p[1], p[2]),
        ));
    }
}

/// min < max, default inside, range within plausible limits.
pub(super) fn coordinates(model: &Model, options: &CheckOptions, out: &mut Vec<Check>) {
    for c in &model.coordinates {
        let [lo, hi] = c.range;
        out.push(check(
            Family::Coordinates,
            "range min < max",
            SubjectKind::Coordinate,
            &c.name,
            lo < hi,
            Some(hi - lo),
            unit_of(c.motion_type),
            "max − min > 0".into(),
            format!("range [{lo}, {hi}]"),
        ));
        let tol = 1e-9 * (1.0 + lo.abs().max(hi.abs()));
        out.push(check(
            Family::Coordinates,
            "default value in range",
            SubjectKind::Coordinate,
            &c.name,
            c.default_value >= lo - tol && c.default_value <= hi + tol,
            Some(c.default_value),
            unit_of(c.motion_type),
            format!("[{lo}, {hi}]"),
            String::new(),
        ));
        let limit = match c.motion_type {
            MotionType::Translational => options.max_translation,
            // Coupled coordinates (OpenSim: driving rotations and translations) are angles
            // in every published model (knee_angle, knee_angle_beta).
            MotionType::Rotational | MotionType::Coupled => options.max_rotation,
        };
        let extent = lo.abs().max(hi.abs());
        out.push(check(
            Family::Coordinates,
            "range plausible",
            SubjectKind::Coordinate,
            &c.name,
            extent <= limit,
            Some(extent),
            unit_of(c.motion_type),
            format!("|min|, |max| ≤ {limit:.4}"),
            match c.motion_type {
                MotionType::Coupled => "coupled coordinate, held to the angle limit".into(),
                _ => String::new(),
            },
        ));
    }
}

fn unit_of(m: MotionType) -> &'static str {
    match m {
        MotionType::Translational => "m",
        _ => "rad",
    }
}
