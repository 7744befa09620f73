//! The shoulder rhythm in the default model's tables: the glenohumeral centre and the shoulder
//! girdle's muscle points move with the arm's elevation, written with OpenSim's own means.
//!
//! The shoulder joint turns the humerus by `arm_flex` f, `arm_add` a and `arm_rot`; its
//! thoracohumeral elevation θ obeys cos θ = cos f cos a. The rhythm's coordinate is
//!
//!   u = 1 − cos θ = 1 − cos f cos a   (0 with the arm at the side, 1 horizontal, 2 overhead),
//!
//! a dependent coordinate of the shoulder joint held to p(f, a) ≈ u by a
//! `CoordinateCouplerConstraint` with a `MultivariatePolynomialFunction`
//! (`polynomial_couplers.csv`). u rather than θ, because θ is a cone at the arm-at-side pose
//! (no derivative there) and u is smooth. The joint's three translations, along the parent
//! frame's x, y and z, are splines of u (`shoulder_rhythm.csv`): the joint centre's
//! displacement d(u) from its place at rest, so that in the parent frame
//!
//!   x_joint(u) = x_joint(0) + d(u).
//!
//! A girdle-borne path point of `shoulder_rhythm_points.csv` becomes a `MovingPathPoint` whose
//! x, y and z are splines of u; at u = 0 it must equal its fixed row in `path_points.csv`.
//! [`apply`] returns the tables with these rows added, for the rest of the builder to write as
//! it writes the knee's spline-driven translations and gait2392's moving points.

use super::tables::{AxisRow, ModelTables, MovingKnotRow, PolynomialCouplerRow, SplineKnotRow};
use super::{BuildError, inconsistent};

const RHYTHM: &str = "shoulder_rhythm.csv";
const RHYTHM_POINTS: &str = "shoulder_rhythm_points.csv";
const COUPLERS: &str = "polynomial_couplers.csv";

/// How far (m) a rhythm point's value at u = 0 may lie from its fixed row.
const REST_TOLERANCE: f64 = 1e-6;

/// The tables with the rhythm's translation axes, splines, moving points and their knots.
pub fn apply(tables: &ModelTables) -> Result<ModelTables, BuildError> {
    let mut t = tables.clone();
    add_translations(&mut t)?;
    add_moving_points(&mut t)?;
    Ok(t)
}

/// The coupler row that defines `coordinate`.
fn coupler_of<'t>(
    tables: &'t ModelTables,
    coordinate: &str,
) -> Result<&'t PolynomialCouplerRow, BuildError> {
    (tables.polynomial_couplers.iter())
        .find(|c| c.dependent == coordinate)
        .ok_or_else(|| {
            inconsistent(
                RHYTHM,
                format!("`{coordinate}` is no dependent coordinate of {COUPLERS}"),
            )
        })
}

/// Per joint of shoulder_rhythm.csv: translation1..3 along the parent's x, y, z, each a
/// spline `rhythm_<joint>_<axis>` of the joint's rhythm coordinate.
fn add_translations(t: &mut ModelTables) -> Result<(), BuildError> {
    let mut joints: Vec<String> = Vec::new();
    for k in &t.rhythm {
        if !joints.contains(&k.joint) {
            joints.push(k.joint.clone());
        }
    }
    for joint in joints {
        if !t
            .joints
            .iter()
            .any(|j| j.joint == joint && j.kind == "custom")
        {
            return Err(inconsistent(
                RHYTHM,
                format!("{joint}: not a custom joint of joints.csv"),
            ));
        }
        if (t.axes.iter()).any(|a| a.joint == joint && a.slot.starts_with("translation")) {
            return Err(inconsistent(
                RHYTHM,
                format!("{joint}: coordinates.csv already gives it translations"),
            ));
        }
        for (slot, axis, unit) in [
            ("translation1", "x", [1.0, 0.0, 0.0]),
            ("translation2", "y", [0.0, 1.0, 0.0]),
            ("translation3", "z", [0.0, 0.0, 1.0]),
        ] {
            let knots: Vec<_> = (t.rhythm.iter())
                .filter(|k| k.joint == joint && k.axis == axis)
                .cloned()
                .collect();
            let Some(first) = knots.first() else {
                return Err(inconsistent(RHYTHM, format!("{joint}: no {axis} rows")));
            };
            if first.knot != 0.0 || first.value != 0.0 {
                return Err(inconsistent(
                    RHYTHM,
                    format!(
                        "{joint} {axis}: the first knot must be (0, 0): no displacement at rest"
                    ),
                ));
            }
            if knots.iter().any(|k| k.coordinate != first.coordinate) {
                return Err(inconsistent(
                    RHYTHM,
                    format!("{joint} {axis}: one coordinate per axis"),
                ));
            }
            let coupler = coupler_of(t, &first.coordinate)?;
            let introduces = slot == "translation1";
            let spline = format!("rhythm_{joint}_{axis}");
            t.axes.push(AxisRow {
                joint: joint.clone(),
                slot: slot.to_string(),
                coordinate: first.coordinate.clone(),
                axis_x: unit[0],
                axis_y: unit[1],
                axis_z: unit[2],
                function: format!("spline:{spline}"),
                default_value: introduces.then_some(0.0),
                range_min: introduces.then_some(coupler.range_min),
                range_max: introduces.then_some(coupler.range_max),
                locked: introduces.then_some(false),
                source: first.source.clone(),
            });
            t.splines.extend(knots.iter().map(|k| SplineKnotRow {
                spline: spline.clone(),
                x: k.knot,
                y: k.value,
                source: k.source.clone(),
            }));
        }
    }
    Ok(())
}

/// Each (muscle, index) of shoulder_rhythm_points.csv: the fixed path point becomes a moving
/// one with the table's knots.
fn add_moving_points(t: &mut ModelTables) -> Result<(), BuildError> {
    let mut seen: Vec<(String, u32)> = Vec::new();
    for k in &t.rhythm_points {
        let key = (k.muscle.clone(), k.index);
        if !seen.contains(&key) {
            seen.push(key);
        }
    }
    for (muscle, index) in seen {
        let knots: Vec<_> = (t.rhythm_points.iter())
            .filter(|k| k.muscle == muscle && k.index == index)
            .cloned()
            .collect();
        let name = format!("{muscle} point {index}");
        let point = (t.path_points.iter_mut())
            .find(|p| p.muscle == muscle && p.index == index)
            .ok_or_else(|| {
                inconsistent(RHYTHM_POINTS, format!("{name}: not in path_points.csv"))
            })?;
        if point.kind != "fixed" || knots.iter().any(|k| k.body != point.body) {
            return Err(inconsistent(
                RHYTHM_POINTS,
                format!("{name}: must be a fixed point on the same body in path_points.csv"),
            ));
        }
        for (axis, rest) in [("x", point.x), ("y", point.y), ("z", point.z)] {
            let first = knots.iter().find(|k| k.axis == axis);
            let Some(first) = first else {
                return Err(inconsistent(
                    RHYTHM_POINTS,
                    format!("{name}: no {axis} rows"),
                ));
            };
            let at_rest = rest
                .is_some_and(|r| first.knot == 0.0 && (first.value - r).abs() <= REST_TOLERANCE);
            if !at_rest {
                return Err(inconsistent(
                    RHYTHM_POINTS,
                    format!(
                        "{name} {axis}: the first knot must be u = 0 at the fixed location {rest:?}"
                    ),
                ));
            }
        }
        point.kind = "moving".to_string();
        point.x = None;
        point.y = None;
        point.z = None;
        point.coordinate = String::new();
        t.moving_knots.extend(knots.iter().map(|k| MovingKnotRow {
            muscle: k.muscle.clone(),
            index: k.index,
            axis: k.axis.clone(),
            function: k.function.clone(),
            coordinate: k.coordinate.clone(),
            knot: k.knot,
            value: k.value,
        }));
    }
    Ok(())
}
