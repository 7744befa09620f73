//! Applying a [`ScaleSet`] to a model file's text, as OpenSim 4.6's `Model::scale` does
//! (component by component; the laws are listed in the [module documentation](super)).
//!
//! Every scaled quantity is found by its element, its owner's frame is resolved to a base
//! body (following `socket_parent` chains of offset frames), and the numbers of the element
//! are rewritten in place. Nothing else in the file changes.

use super::frames::{Frames, child, component_path, line_of, numbers, text_node};
use super::{ScaleOptions, ScaleSet, ScaledModel};
use crate::error::Error;
use crate::model::{Model, MotionType};
use crate::muscle::path::{PathData, PathSet, compute_paths};
use crate::spatial::{Mat3, Vec3, rotation_body_fixed_xyz};
use roxmltree::{Document, Node};
use std::collections::HashMap;
use std::fmt::Write;
use std::ops::Range;

/// How an element's numbers change.
#[derive(Clone, Debug)]
pub(super) enum Op {
    /// Multiply token k by `f[k % f.len()]`.
    Mul(Vec<f64>),
    /// Replace the tokens by these values.
    Set(Vec<f64>),
}

/// An edit of the text of one element.
#[derive(Clone, Debug)]
pub(super) struct Edit {
    pub range: Range<usize>,
    pub op: Op,
}

pub(super) const FUNCTION_TAGS: [&str; 11] = [
    "Constant",
    "LinearFunction",
    "PolynomialFunction",
    "SimmSpline",
    "NaturalCubicSpline",
    "natCubicSpline",
    "GCVSpline",
    "PiecewiseLinearFunction",
    "PiecewiseConstantFunction",
    "MultiplierFunction",
    "MultivariatePolynomialFunction",
];
const WRAP_OBJECTS: [&str; 4] = ["WrapSphere", "WrapCylinder", "WrapEllipsoid", "WrapTorus"];
const PATH_POINTS: [&str; 3] = ["PathPoint", "ConditionalPathPoint", "MovingPathPoint"];
const FRAMES: [&str; 3] = ["Body", "Ground", "PhysicalOffsetFrame"];

/// Force classes whose `extendPostScale` rescales length properties by the path-length ratio
/// ℓ_after / ℓ_before at the default pose (OpenSim 4.6), and those properties.
const POST_SCALE: [(&str, &[&str]); 12] = [
    (
        "Thelen2003Muscle",
        &["optimal_fiber_length", "tendon_slack_length"],
    ),
    (
        "Millard2012EquilibriumMuscle",
        &["optimal_fiber_length", "tendon_slack_length"],
    ),
    (
        "Millard2012AccelerationMuscle",
        &["optimal_fiber_length", "tendon_slack_length"],
    ),
    (
        "DeGrooteFregly2016Muscle",
        &["optimal_fiber_length", "tendon_slack_length"],
    ),
    (
        "MeyerFregly2016Muscle",
        &["optimal_fiber_length", "tendon_slack_length"],
    ),
    (
        "Thelen2003Muscle_Deprecated",
        &["optimal_fiber_length", "tendon_slack_length"],
    ),
    (
        "Schutte1993Muscle_Deprecated",
        &["optimal_fiber_length", "tendon_slack_length"],
    ),
    (
        "Delp1990Muscle_Deprecated",
        &["optimal_fiber_length", "tendon_slack_length"],
    ),
    ("Ligament", &["resting_length"]),
    ("PathSpring", &["resting_length"]),
    ("ExpressionBasedPathForce", &["resting_length"]),
    ("Blankevoort1991Ligament", &["slack_length"]),
];

/// OpenSim 4.6's `Body::scaleInertialProperties`: the inertia about the mass centre (body
/// axes) after scaling the body by `f`. `mass_before` is the mass read from the file and
/// `mass_after` the mass after this step (`mass_before · |fx fy fz|` when `scale_mass`).
///
/// - mass ≤ ε: zero.
/// - fx = fy = fz = s (numerically): I · s², times |s³| when the mass is scaled.
/// - otherwise the body is taken as a uniform cylinder along the axis of its smallest
///   diagonal moment a: radius² r² = 2 I_aa / m, length² L² = 12 (I_bb − m r²/4) / m (b the
///   first other axis), each floored at 0; with L' = L f_a and r'² = r² f_b f_c, the diagonal
///   becomes I'_aa = m' r'²/2, I'_bb = I'_cc = m' (L'²/12 + r'²/4); products I_ij × f_i f_j
///   (× |fx fy fz| when the mass is scaled).
pub fn scale_inertia(
    inertia: &Mat3,
    f: Vec3,
    mass_before: f64,
    mass_after: f64,
    scale_mass: bool,
) -> Mat3 {
    let mass_factor = (f.x * f.y * f.z).abs();
    let tol = f64::EPSILON.powf(0.875);
    let equal = |a: f64, b: f64| (a - b).abs() <= tol * a.abs().max(b.abs()).max(1.0);
    let mut i = *inertia;
    if mass_after <= f64::EPSILON {
        return Mat3::zeros();
    }
    if equal(f.x, f.y) && equal(f.y, f.z) {
        if scale_mass {
            i *= mass_factor;
        }
        return i * (f.x * f.x);
    }
    let axis = if i[(0, 0)] <= i[(1, 1)] {
        if i[(0, 0)] <= i[(2, 2)] { 0 } else { 2 }
    } else if i[(1, 1)] <= i[(2, 2)] {
        1
    } else {
        2
    };
    let term = 2.0 * i[(axis, axis)] / mass_before;
    let radius = if term < 0.0 { 0.0 } else { term.sqrt() };
    let other = if axis == 0 { 1 } else { 0 };
    let term = 12.0 * (i[(other, other)] - 0.25 * mass_before * radius * radius) / mass_before;
    let length = if term < 0.0 { 0.0 } else { term.sqrt() } * f[axis];
    let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
    let r2 = radius * f[b] * radius * f[c];
    let m = mass_after;
    for k in 0..3 {
        i[(k, k)] = if k == axis {
            0.5 * m * r2
        } else {
            m * (length * length / 12.0 + 0.25 * r2)
        };
    }
    for r in 0..3 {
        for c in 0..3 {
            if r != c {
                i[(r, c)] *= f[r] * f[c];
                if scale_mass {
                    i[(r, c)] *= mass_factor;
                }
            }
        }
    }
    i
}

/// A body's mass properties as written, and where.
struct BodyMass {
    name: String,
    mass: f64,
    inertia: Mat3,
    mass_text: Option<Range<usize>>,
    inertia_text: Option<Range<usize>>,
    factors: Option<Vec3>,
}

/// The numbers to write for an inertia matrix (`Ixx Iyy Izz Ixy Ixz Iyz`).
fn inertia_values(i: &Mat3) -> Vec<f64> {
    crate::spatial::inertia_six(i).to_vec()
}

struct Scaler<'a, 'd, 'i> {
    doc: &'d Document<'i>,
    source: &'a str,
    model: &'a Model,
    scales: &'a ScaleSet,
    options: &'a ScaleOptions,
    frames: Frames,
    edits: Vec<Edit>,
}

impl<'a, 'd, 'i> Scaler<'a, 'd, 'i> {
    fn error(&self, n: Node, message: impl Into<String>) -> Error {
        Error::Model {
            file: self.source.to_string(),
            line: line_of(self.doc, n),
            element: format!(
                "{} \"{}\"",
                n.tag_name().name(),
                n.attribute("name").unwrap_or("")
            ),
            message: message.into(),
        }
    }

    /// Multiplies the numbers of `n`'s text by `f` (cycled).
    fn mul(&mut self, n: Option<Node>, f: Vec<f64>) {
        if let Some(t) = n.and_then(text_node) {
            self.edits.push(Edit {
                range: t.range(),
                op: Op::Mul(f),
            });
        }
    }

    /// The factors of the base body of the frame `socket` (relative to `owner`'s path).
    fn socket_factors(&self, owner: Node, socket: Option<Node>) -> crate::Result<Option<Vec3>> {
        let Some(socket) = socket.and_then(|s| s.text()).map(str::trim) else {
            return Ok(None);
        };
        // an absolute socket path does not depend on the owner's (whose formatting walks all
        // its ancestors: most sockets of a model are absolute)
        let owner_path = if socket.starts_with('/') {
            String::new()
        } else {
            component_path(owner)
        };
        let (body, _) = self
            .frames
            .resolve(&owner_path, socket)
            .map_err(|m| self.error(owner, m))?;
        Ok(self.scales.get(&body))
    }

    /// The factors of the body that `frame` (a Body, Ground or PhysicalOffsetFrame element)
    /// is based on.
    fn frame_factors(&self, frame: Node) -> crate::Result<Option<Vec3>> {
        let (body, _) = self
            .frames
            .resolve("/", &component_path(frame))
            .map_err(|m| self.error(frame, m))?;
        Ok(self.scales.get(&body))
    }

    /// Scales a function element (the child of a TransformAxis or of `x_location`) by `k`.
    fn function(&mut self, holder: Node, k: f64, skip_identity: bool) -> crate::Result<()> {
        let mut f = holder
            .children()
            .find(|c| c.is_element() && FUNCTION_TAGS.contains(&c.tag_name().name()));
        if f.is_none()
            && let Some(w) = child(holder, "function")
        {
            f = w.children().find(Node::is_element);
        }
        let Some(f) = f else {
            return match holder.children().find(Node::is_element) {
                Some(other) => Err(self.error(
                    other,
                    "cannot scale this function type (OpenSim wraps it in a \
                     MultiplierFunction; musculo only rewrites numbers)",
                )),
                None => Ok(()),
            };
        };
        let tag = f.tag_name().name();
        let target = match tag {
            "LinearFunction" => {
                let c = child(f, "coefficients");
                if skip_identity && c.and_then(numbers).as_deref() == Some(&[1.0, 0.0][..]) {
                    return Ok(());
                }
                c
            }
            "Constant" => child(f, "value"),
            // every term scales with its coefficient: k f = Σ_t (k c_t) x^(e_t)
            "PolynomialFunction" | "MultivariatePolynomialFunction" => child(f, "coefficients"),
            "MultiplierFunction" => Some(child(f, "scale").ok_or_else(|| {
                self.error(f, "a MultiplierFunction without <scale> cannot be rescaled")
            })?),
            _ => child(f, "y"),
        };
        self.mul(target, vec![k]);
        Ok(())
    }

    fn body_mass(&self, b: Node) -> crate::Result<BodyMass> {
        let name = b.attribute("name").unwrap_or("").trim().to_string();
        let mass_node = child(b, "mass");
        let mass = match mass_node {
            Some(n) => match numbers(n).as_deref() {
                Some([m]) => *m,
                _ => return Err(self.error(n, "<mass> is not one number")),
            },
            None => 0.0,
        };
        let inertia_node = child(b, "inertia");
        let inertia = match inertia_node {
            Some(n) => match numbers(n).as_deref() {
                Some(&[xx, yy, zz, xy, xz, yz]) => Mat3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz),
                _ => return Err(self.error(n, "<inertia> is not six numbers")),
            },
            None => Mat3::zeros(),
        };
        Ok(BodyMass {
            factors: self.scales.get(&name),
            name,
            mass,
            inertia,
            mass_text: mass_node.and_then(text_node).map(|t| t.range()),
            inertia_text: inertia_node.and_then(text_node).map(|t| t.range()),
        })
    }

    fn wrap_object(&mut self, w: Node) -> crate::Result<()> {
        let Some(frame) = w
            .ancestors()
            .skip(1)
            .find(|a| FRAMES.contains(&a.tag_name().name()))
        else {
            return Err(self.error(w, "a wrap object outside any frame"));
        };
        let Some(f) = self.frame_factors(frame)? else {
            return Ok(());
        };
        self.mul(child(w, "translation"), vec![f.x, f.y, f.z]);
        let angles = child(w, "xyz_body_rotation")
            .and_then(numbers)
            .filter(|v| v.len() == 3)
            .map(|v| Vec3::new(v[0], v[1], v[2]))
            .unwrap_or_else(Vec3::zeros);
        let r = rotation_body_fixed_xyz(angles);
        // |R e_k ∘ f|: the stretch of the wrap frame's axis k
        let stretch = |k: usize| r.column(k).component_mul(&f).norm();
        match w.tag_name().name() {
            "WrapSphere" => self.mul(child(w, "radius"), vec![f.sum() / 3.0]),
            "WrapCylinder" => {
                self.mul(child(w, "radius"), vec![0.5 * (stretch(0) + stretch(1))]);
                self.mul(child(w, "length"), vec![stretch(2)]);
            }
            "WrapEllipsoid" => {
                self.mul(
                    child(w, "dimensions"),
                    vec![stretch(0), stretch(1), stretch(2)],
                );
            }
            _ => {
                let k = 0.5 * (stretch(0) + stretch(1));
                self.mul(child(w, "inner_radius"), vec![k]);
                self.mul(child(w, "outer_radius"), vec![k]);
            }
        }
        Ok(())
    }

    fn coupler(&mut self, c: Node) -> crate::Result<()> {
        let Some(dep) = child(c, "dependent_coordinate_name").and_then(|n| n.text()) else {
            return Ok(());
        };
        let Some(ci) = self.model.coordinate_index(dep.trim()) else {
            return Err(self.error(c, format!("no coordinate `{}`", dep.trim())));
        };
        let coordinate = &self.model.coordinates[ci];
        if coordinate.motion_type != MotionType::Translational {
            return Ok(());
        }
        let parent = self.model.joints[coordinate.joint].parent_body;
        let Some(f) = self.scales.get(&self.model.bodies[parent].name) else {
            return Ok(());
        };
        if f.x != f.y || f.x != f.z {
            return Err(self.error(
                c,
                "a translational coupler cannot be scaled non-uniformly (OpenSim refuses too)",
            ));
        }
        self.mul(child(c, "scale_factor"), vec![f.x]);
        Ok(())
    }

    fn collect(&mut self) -> crate::Result<Vec<BodyMass>> {
        let translational: Vec<&str> = (self.model.coordinates.iter())
            .filter(|c| c.motion_type == MotionType::Translational)
            .map(|c| c.name.as_str())
            .collect();
        let mut bodies = Vec::new();
        let doc = self.doc;
        for n in doc.descendants().filter(Node::is_element) {
            let tag = n.tag_name().name();
            let parent_tag = n
                .parent_element()
                .map(|p| p.tag_name().name())
                .unwrap_or("");
            match tag {
                "Body" if parent_tag == "objects" => {
                    let mass = self.body_mass(n)?;
                    if let Some(f) = mass.factors {
                        self.mul(child(n, "mass_center"), vec![f.x, f.y, f.z]);
                    }
                    bodies.push(mass);
                }
                "PhysicalOffsetFrame" => {
                    if let Some(f) = self.socket_factors(n, child(n, "socket_parent"))? {
                        self.mul(child(n, "translation"), vec![f.x, f.y, f.z]);
                    }
                }
                "attached_geometry" if FRAMES.contains(&parent_tag) => {
                    let frame = n.parent_element().expect("attached_geometry has a parent");
                    if let Some(f) = self.frame_factors(frame)? {
                        for g in n.children().filter(Node::is_element) {
                            self.mul(child(g, "scale_factors"), vec![f.x, f.y, f.z]);
                        }
                    }
                }
                "CustomJoint" => {
                    let Some(f) = self.socket_factors(n, child(n, "socket_parent_frame"))? else {
                        continue;
                    };
                    let Some(st) = child(n, "SpatialTransform") else {
                        continue;
                    };
                    for axis in st.children().filter(|a| a.has_tag_name("TransformAxis")) {
                        if !axis
                            .attribute("name")
                            .is_some_and(|a| a.starts_with("translation"))
                        {
                            continue;
                        }
                        let a = child(axis, "axis")
                            .and_then(numbers)
                            .filter(|v| v.len() == 3)
                            .ok_or_else(|| self.error(axis, "<axis> is not three numbers"))?;
                        // OpenSim: |axis| · f (a weighted sum, not a norm)
                        let k = a[0].abs() * f.x + a[1].abs() * f.y + a[2].abs() * f.z;
                        self.function(axis, k, true)?;
                    }
                }
                t if PATH_POINTS.contains(&t) => {
                    let Some(f) = self.socket_factors(n, child(n, "socket_parent_frame"))? else {
                        continue;
                    };
                    self.mul(child(n, "location"), vec![f.x, f.y, f.z]);
                    if t == "MovingPathPoint" {
                        for (k, axis) in ["x", "y", "z"].into_iter().enumerate() {
                            let has = child(n, &format!("socket_{axis}_coordinate"))
                                .and_then(|s| s.text())
                                .is_some_and(|s| !s.trim().is_empty());
                            if let (true, Some(h)) = (has, child(n, &format!("{axis}_location"))) {
                                self.function(h, f[k], false)?;
                            }
                        }
                    }
                }
                "Marker" => {
                    if let Some(f) = self.socket_factors(n, child(n, "socket_parent_frame"))? {
                        self.mul(child(n, "location"), vec![f.x, f.y, f.z]);
                    }
                }
                t if WRAP_OBJECTS.contains(&t) => self.wrap_object(n)?,
                "CoordinateCouplerConstraint" => self.coupler(n)?,
                t if t.starts_with("Contact") && self.options.contact_geometry => {
                    if let Some(f) = self.socket_factors(n, child(n, "socket_frame"))? {
                        self.mul(child(n, "location"), vec![f.x, f.y, f.z]);
                        if t == "ContactSphere" {
                            self.mul(child(n, "radius"), vec![f.sum() / 3.0]);
                        }
                    }
                }
                "Coordinate" => {
                    let name = n.attribute("name").unwrap_or("");
                    if let Some(s) = self.options.translational_coordinates
                        && translational.contains(&name)
                    {
                        self.mul(child(n, "default_value"), vec![s]);
                        self.mul(child(n, "range"), vec![s]);
                    }
                }
                _ => {}
            }
        }
        Ok(bodies)
    }

    /// Mass and inertia edits: per-body scaling, then all masses × M / Σm when a subject
    /// mass is given. Returns the total mass after scaling.
    fn masses(&mut self, bodies: &[BodyMass]) -> crate::Result<f64> {
        let scale_mass = !self.options.preserve_mass_distribution;
        let mut after: Vec<(f64, Mat3)> = Vec::with_capacity(bodies.len());
        for b in bodies {
            after.push(match b.factors {
                Some(f) => {
                    let m = if scale_mass {
                        b.mass * (f.x * f.y * f.z).abs()
                    } else {
                        b.mass
                    };
                    (m, scale_inertia(&b.inertia, f, b.mass, m, scale_mass))
                }
                None => (b.mass, b.inertia),
            });
        }
        let mut total: f64 = after.iter().map(|a| a.0).sum();
        if let Some(target) = self.options.subject_mass {
            if !(target > 0.0 && target.is_finite()) {
                return Err(Error::invalid(
                    "subject_mass",
                    format!("{target} kg must be positive and finite"),
                ));
            }
            if total > 0.0 {
                let k = target / total;
                for a in &mut after {
                    a.0 *= k;
                    a.1 *= k;
                }
                total = after.iter().map(|a| a.0).sum();
            }
        }
        for (b, (m, i)) in bodies.iter().zip(&after) {
            if *m == b.mass && *i == b.inertia {
                continue;
            }
            if let Some(r) = &b.mass_text {
                self.edits.push(Edit {
                    range: r.clone(),
                    op: Op::Set(vec![*m]),
                });
            }
            if let Some(r) = &b.inertia_text {
                self.edits.push(Edit {
                    range: r.clone(),
                    op: Op::Set(inertia_values(i)),
                });
            } else if *i != Mat3::zeros() {
                return Err(Error::invalid(
                    "model",
                    format!("body `{}` has no <inertia> element to rewrite", b.name),
                ));
            }
        }
        Ok(total)
    }
}

/// Path lengths of every force with a geometry path at the model's default pose.
pub(super) fn path_lengths(model: &Model) -> crate::Result<HashMap<String, f64>> {
    let set = PathSet::new(model)?;
    let mut data = crate::Data::new(model);
    crate::dynamics::forward_kinematics(model, &mut data, &model.default_q())?;
    let mut paths = PathData::new(model, &set);
    compute_paths(model, &data, &set, &mut paths)?;
    Ok(set
        .paths
        .iter()
        .map(|p| p.name.clone())
        .zip(paths.length.iter().copied())
        .collect())
}

/// See [`super::scale_osim`].
pub(super) fn scale(
    xml: &str,
    source: &str,
    model: &Model,
    scales: &ScaleSet,
    options: &ScaleOptions,
) -> crate::Result<ScaledModel> {
    scales.validate(model)?;
    let doc = super::parse_document(xml, source)?;
    let mut s = Scaler {
        doc: &doc,
        source,
        model,
        scales,
        options,
        frames: Frames::new(&doc),
        edits: Vec::new(),
    };
    let bodies = s.collect()?;
    let total_mass = s.masses(&bodies)?;
    // Pass 1: geometry and masses; pass 2: lengths by the measured path-length ratio.
    let geometry = apply(xml, source, &s.edits)?;
    let mut scaled = Model::from_osim_str_with(&geometry, source, &options.load)?;
    let before = path_lengths(model)?;
    let after = path_lengths(&scaled)?;
    let mut ratios = Vec::new();
    // (force, its tags) whose lengths pass 2 rescales, for patching `scaled` in place.
    let mut rescaled: Vec<(Node, &[&str], f64)> = Vec::new();
    for force in doc.descendants().filter(|n| {
        n.is_element()
            && n.parent_element()
                .is_some_and(|p| p.has_tag_name("objects"))
            && n.ancestors().any(|a| a.has_tag_name("ForceSet"))
    }) {
        let Some((_, tags)) = POST_SCALE
            .iter()
            .find(|(class, _)| force.has_tag_name(*class))
        else {
            continue;
        };
        let name = force.attribute("name").unwrap_or("");
        let (Some(l0), Some(l1)) = (before.get(name), after.get(name)) else {
            return Err(s.error(force, "no geometry path to measure for its length scaling"));
        };
        if *l0 > 0.0 {
            let ratio = l1 / l0;
            ratios.push((name.to_string(), ratio));
            for tag in *tags {
                s.mul(child(force, tag), vec![ratio]);
            }
            rescaled.push((force, tags, ratio));
        }
    }
    let xml = apply(xml, source, &s.edits)?;
    // Pass 2 changes only the rescaled length properties, which the parsed model keeps as
    // the text of its force elements: write the same numbers there instead of parsing the
    // whole file again (tests/scale_tool.rs checks the result equals a fresh parse).
    let model = if patch_lengths(&mut scaled, &rescaled) {
        scaled
    } else {
        Model::from_osim_str_with(&xml, source, &options.load)?
    };
    Ok(ScaledModel {
        xml,
        model,
        length_ratios: ratios,
        total_mass,
    })
}

/// Multiplies, in the force elements of `model`, the text of each listed length property by
/// its ratio, formatted as [`apply`] writes it. False (nothing or part done: parse the text
/// instead) when a force is not found exactly once by name and class, or a value is not a
/// number.
fn patch_lengths(model: &mut Model, rescaled: &[(Node, &[&str], f64)]) -> bool {
    for (force, tags, ratio) in rescaled {
        let name = force.attribute("name").unwrap_or("");
        let kind = force.tag_name().name();
        let mut found = model
            .forces
            .iter_mut()
            .filter(|f| f.name == name && f.kind == kind);
        let (Some(element), None) = (found.next(), found.next()) else {
            return false;
        };
        for tag in tags.iter() {
            let Some(raw) = std::sync::Arc::make_mut(&mut element.raw)
                .children
                .iter_mut()
                .find(|c| c.tag == *tag)
            else {
                continue;
            };
            let mut values = Vec::new();
            for token in raw.text.split_whitespace() {
                let Ok(x) = token.parse::<f64>() else {
                    return false;
                };
                values.push(format!("{}", x * ratio));
            }
            raw.text = values.join(" ");
        }
    }
    true
}

/// The text with every edit applied (numbers written in Rust's shortest round-trip form).
pub(super) fn apply(xml: &str, source: &str, edits: &[Edit]) -> crate::Result<String> {
    let mut sorted: Vec<&Edit> = edits.iter().collect();
    sorted.sort_by_key(|e| e.range.start);
    for w in sorted.windows(2) {
        if w[1].range.start < w[0].range.end {
            return Err(Error::Model {
                file: source.to_string(),
                line: line_number(xml, w[1].range.start),
                element: String::new(),
                message: "one value would be scaled twice (overlapping components)".into(),
            });
        }
    }
    let mut out = String::with_capacity(xml.len() + xml.len() / 16);
    let mut at = 0;
    for e in sorted {
        out.push_str(&xml[at..e.range.start]);
        let text = &xml[e.range.clone()];
        let lead = &text[..text.len() - text.trim_start().len()];
        let trail = &text[text.trim_end().len()..];
        out.push_str(lead);
        // the values written straight into the text, separated by one space (writing to a
        // String cannot fail)
        match &e.op {
            Op::Set(v) => {
                for (k, x) in v.iter().enumerate() {
                    let sep = if k == 0 { "" } else { " " };
                    let _ = write!(out, "{sep}{x}");
                }
            }
            Op::Mul(f) => {
                for (k, token) in text.split_whitespace().enumerate() {
                    let x: f64 = token.parse().map_err(|_| Error::Model {
                        file: source.to_string(),
                        line: line_number(xml, e.range.start),
                        element: String::new(),
                        message: format!("`{token}` is not a number"),
                    })?;
                    let sep = if k == 0 { "" } else { " " };
                    let _ = write!(out, "{sep}{}", x * f[k % f.len()]);
                }
            }
        }
        out.push_str(trail);
        at = e.range.end;
    }
    out.push_str(&xml[at..]);
    Ok(out)
}

pub(super) fn line_number(xml: &str, byte: usize) -> u32 {
    xml[..byte].bytes().filter(|b| *b == b'\n').count() as u32 + 1
}
