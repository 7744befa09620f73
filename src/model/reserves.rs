//! Reserve and residual actuators for static optimization, written as an OpenSim force-set
//! file (`musculo model reserves`, `models/musculo_fullbody_reserves.xml`).
//!
//! Static optimization asks, per frame, for actuator controls x with Σ_k r_jk F_k x_k = τ_j on
//! every independent coordinate j. Muscles alone cannot always do that: no muscle crosses a
//! coordinate (the forearm's `pro_sup` in a model without pronators), the data ask for more
//! than the muscles give, or the coordinate is the floating base, which no internal force can
//! move. OpenSim's gait examples therefore pair a model with a force set of
//!
//! - **residual actuators** on the floating base (the root body whose joint to ground has
//!   translations): for a six-degree-of-freedom root, three PointActuators `FX`, `FY`, `FZ`
//!   at the body's centre of mass along the ground axes and three TorqueActuators `MX`, `MY`,
//!   `MZ` about them (body A the root, body B ground). Their generalized forces are
//!   [J_pᵀ e_i, J_ωᵀ e_i], which span the root's six rows wherever its Jacobian is regular.
//!   A root with fewer coordinates (a planar pelvis) gets one CoordinateActuator
//!   `<coordinate>_residual` per independent coordinate instead;
//! - **reserve actuators**: one CoordinateActuator `<coordinate>_reserve` on every other
//!   independent coordinate.
//!
//! With every actuator's controls unbounded, the equality has a solution at every frame. The
//! optimal forces are small (1 N or N·m by default, OpenSim's "weak" convention): the
//! objective Σ xᵖ then charges a reserve heavily per N·m, so the muscles carry what they can
//! and the reserves measure what is left.

use super::{Model, MotionType};
use std::fmt::Write;

/// Optimal forces of the generated actuators.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReserveOptions {
    /// Optimal force of each joint reserve (N·m for a rotation, N for a translation).
    pub reserve_optimal_force: f64,
    /// Optimal force of each floating-base residual (N for forces, N·m for torques).
    pub residual_optimal_force: f64,
}

impl Default for ReserveOptions {
    fn default() -> Self {
        ReserveOptions {
            reserve_optimal_force: 1.0,
            residual_optimal_force: 1.0,
        }
    }
}

/// One generated actuator, before it is written as XML.
#[derive(Clone, Debug, PartialEq)]
pub enum ReserveActuator {
    /// A CoordinateActuator on a coordinate (`Model::coordinates` index).
    Coordinate {
        name: String,
        coordinate: usize,
        optimal_force: f64,
    },
    /// A PointActuator at `body`'s centre of mass along ground `axis` (0, 1, 2).
    Force {
        name: String,
        body: usize,
        axis: usize,
        optimal_force: f64,
    },
    /// A TorqueActuator on `body` (reacting on ground) about ground `axis` (0, 1, 2).
    Torque {
        name: String,
        body: usize,
        axis: usize,
        optimal_force: f64,
    },
}

impl ReserveActuator {
    /// The actuator's name in the force set.
    pub fn name(&self) -> &str {
        match self {
            ReserveActuator::Coordinate { name, .. }
            | ReserveActuator::Force { name, .. }
            | ReserveActuator::Torque { name, .. } => name,
        }
    }
}

/// The residual and reserve actuators of `model` (see the module documentation), residuals
/// first, then reserves in coordinate order. Errors on an optimal force that is not finite
/// and positive.
pub fn reserve_actuators(
    model: &Model,
    options: &ReserveOptions,
) -> crate::Result<Vec<ReserveActuator>> {
    for (argument, value) in [
        ("reserve_optimal_force", options.reserve_optimal_force),
        ("residual_optimal_force", options.residual_optimal_force),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return Err(crate::Error::InvalidArgument {
                argument,
                message: format!("must be finite and positive, got {value}"),
            });
        }
    }
    let independent_of = |joint: usize| -> Vec<usize> {
        model.joints[joint]
            .coordinates
            .iter()
            .copied()
            .filter(|&c| model.reduction.independent.contains(&c))
            .collect()
    };
    // floating bases: joints to ground with an independent translation
    let mut floating = Vec::new();
    for (j, joint) in model.joints.iter().enumerate() {
        let coordinates = independent_of(j);
        let translates = coordinates
            .iter()
            .any(|&c| model.coordinates[c].motion_type == MotionType::Translational);
        if joint.parent_body == 0 && translates {
            floating.push((j, coordinates));
        }
    }
    let several = floating.len() > 1;
    let mut actuators = Vec::new();
    let mut residual_coordinates = Vec::new();
    for (j, coordinates) in &floating {
        let body = model.joints[*j].child_body;
        let count = |t: MotionType| {
            (coordinates.iter())
                .filter(|&&c| model.coordinates[c].motion_type == t)
                .count()
        };
        residual_coordinates.extend(coordinates.iter().copied());
        let six = coordinates.len() == 6
            && count(MotionType::Translational) == 3
            && count(MotionType::Rotational) == 3;
        if six {
            let prefix = if several {
                format!("{}_", model.bodies[body].name)
            } else {
                String::new()
            };
            let optimal_force = options.residual_optimal_force;
            for (axis, letter) in ["X", "Y", "Z"].into_iter().enumerate() {
                actuators.push(ReserveActuator::Force {
                    name: format!("{prefix}F{letter}"),
                    body,
                    axis,
                    optimal_force,
                });
            }
            for (axis, letter) in ["X", "Y", "Z"].into_iter().enumerate() {
                actuators.push(ReserveActuator::Torque {
                    name: format!("{prefix}M{letter}"),
                    body,
                    axis,
                    optimal_force,
                });
            }
        } else {
            for &c in coordinates {
                actuators.push(ReserveActuator::Coordinate {
                    name: format!("{}_residual", model.coordinates[c].name),
                    coordinate: c,
                    optimal_force: options.residual_optimal_force,
                });
            }
        }
    }
    for &c in &model.reduction.independent {
        if !residual_coordinates.contains(&c) {
            actuators.push(ReserveActuator::Coordinate {
                name: format!("{}_reserve", model.coordinates[c].name),
                coordinate: c,
                optimal_force: options.reserve_optimal_force,
            });
        }
    }
    Ok(actuators)
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// `v` in Rust's shortest round-trip form (read back exactly), without a negative zero.
fn number(v: f64) -> String {
    let s = format!("{v}");
    if s == "-0" { "0".into() } else { s }
}

/// The actuators of [`reserve_actuators`] as an OpenSim 4 force-set file (every control
/// unbounded). `model_label` names the model in the file's header comment. The text is a
/// pure function of the model and the options.
pub fn reserve_force_set(
    model: &Model,
    model_label: &str,
    options: &ReserveOptions,
) -> crate::Result<String> {
    let actuators = reserve_actuators(model, options)?;
    let mut xml = String::new();
    let unit = |axis: usize| {
        let mut v = ["0"; 3];
        v[axis] = "1";
        v.join(" ")
    };
    let _ = writeln!(xml, "<?xml version=\"1.0\" encoding=\"UTF-8\" ?>");
    let _ = writeln!(xml, "<OpenSimDocument Version=\"40000\">");
    let _ = writeln!(
        xml,
        "\t<!--Residual and reserve actuators for static optimization with {}, generated by \
         `musculo model reserves`: residuals on the floating base, one reserve \
         CoordinateActuator per other independent coordinate, controls unbounded.-->",
        xml_escape(model_label).replace("--", "- -"),
    );
    let _ = writeln!(
        xml,
        "\t<ForceSet name=\"{}_reserves\">",
        xml_escape(&model.name)
    );
    let _ = writeln!(xml, "\t\t<objects>");
    let controls =
        "\t\t\t\t<min_control>-Inf</min_control>\n\t\t\t\t<max_control>Inf</max_control>";
    for a in &actuators {
        match a {
            ReserveActuator::Coordinate {
                name,
                coordinate,
                optimal_force,
            } => {
                let _ = writeln!(
                    xml,
                    "\t\t\t<CoordinateActuator name=\"{}\">\n{controls}\n\t\t\t\t<coordinate>{}</coordinate>\n\t\t\t\t<optimal_force>{}</optimal_force>\n\t\t\t</CoordinateActuator>",
                    xml_escape(name),
                    xml_escape(&model.coordinates[*coordinate].name),
                    number(*optimal_force)
                );
            }
            ReserveActuator::Force {
                name,
                body,
                axis,
                optimal_force,
            } => {
                let c = model.bodies[*body].com_in_body;
                let _ = writeln!(
                    xml,
                    "\t\t\t<PointActuator name=\"{}\">\n{controls}\n\t\t\t\t<body>{}</body>\n\t\t\t\t<point>{} {} {}</point>\n\t\t\t\t<point_is_global>false</point_is_global>\n\t\t\t\t<direction>{}</direction>\n\t\t\t\t<force_is_global>true</force_is_global>\n\t\t\t\t<optimal_force>{}</optimal_force>\n\t\t\t</PointActuator>",
                    xml_escape(name),
                    xml_escape(&model.bodies[*body].name),
                    number(c[0]),
                    number(c[1]),
                    number(c[2]),
                    unit(*axis),
                    number(*optimal_force)
                );
            }
            ReserveActuator::Torque {
                name,
                body,
                axis,
                optimal_force,
            } => {
                let _ = writeln!(
                    xml,
                    "\t\t\t<TorqueActuator name=\"{}\">\n{controls}\n\t\t\t\t<bodyA>{}</bodyA>\n\t\t\t\t<bodyB>{}</bodyB>\n\t\t\t\t<axis>{}</axis>\n\t\t\t\t<torque_is_global>true</torque_is_global>\n\t\t\t\t<optimal_force>{}</optimal_force>\n\t\t\t</TorqueActuator>",
                    xml_escape(name),
                    xml_escape(&model.bodies[*body].name),
                    xml_escape(&model.bodies[0].name),
                    unit(*axis),
                    number(*optimal_force)
                );
            }
        }
    }
    let _ = writeln!(xml, "\t\t</objects>");
    let _ = writeln!(xml, "\t\t<groups />");
    let _ = writeln!(xml, "\t</ForceSet>");
    let _ = writeln!(xml, "</OpenSimDocument>");
    Ok(xml)
}
