//! The default full-body model, built from the parameter tables in `data/model/` into
//! OpenSim 4.x XML (`musculo model build`). The output is a pure function of the tables: the
//! same tables give the same bytes, which a test checks against `models/`.
//!
//! Geometry (joint frames, landmarks, markers, contact spheres, the knee's spline-driven
//! translations) comes from public models in their own size and is scaled uniformly by
//! s = H / H_source to the reference subject's height H. Segment masses, centres of mass and
//! inertias come from a published segment table (de Leva 1996): for a body made of segment
//! shares kᵢ,
//!
//!   mᵢ = kᵢ pᵢ M,   cᵢ = s (a + γᵢ (b − a)),   Iᵢ = mᵢ R diag((r_S L)², (r_L L)², (r_T L)²) Rᵀ
//!
//! with M the body mass, pᵢ the segment's mass fraction, a and b its proximal and distal
//! landmarks in the body frame, L = s‖b − a‖, γ the centre-of-mass fraction, r_S, r_T, r_L the
//! radii of gyration about the sagittal (antero-posterior), transverse (medio-lateral) and
//! longitudinal axes, and R = [e_S e_L e_T] the body-frame directions of those axes (e_L along
//! b − a, e_T the body z axis made orthogonal to it, e_S = e_L × e_T). Shares of one body are
//! combined about their common centre of mass (parallel-axis theorem).

mod rhythm;
pub mod tables;

pub use crate::error::{BuildError, TableError};
use crate::spatial::{Mat3, Vec3};
use std::collections::BTreeMap;
use std::fmt::Write;
pub use tables::ModelTables;

fn inconsistent(table: &'static str, message: impl Into<String>) -> BuildError {
    BuildError::Inconsistent {
        table,
        message: message.into(),
    }
}

/// Mass properties of one body in its own frame.
#[derive(Clone, Debug)]
pub struct MassProperties {
    pub mass: f64,
    pub com: Vec3,
    /// About the centre of mass, body axes.
    pub inertia: Mat3,
}

/// The reference subject's mass and height from `reference_subject.csv`.
pub fn reference_subject(tables: &ModelTables) -> Result<(f64, f64), BuildError> {
    let get = |q: &str| {
        tables
            .subject
            .iter()
            .find(|r| r.quantity == q)
            .map(|r| r.value)
            .ok_or_else(|| inconsistent("reference_subject.csv", format!("no `{q}` row")))
    };
    let (mass, height) = (get("mass")?, get("height")?);
    if !(mass > 0.0 && height > 0.0 && mass.is_finite() && height.is_finite()) {
        return Err(inconsistent(
            "reference_subject.csv",
            format!("mass {mass} kg and height {height} m must be positive"),
        ));
    }
    Ok((mass, height))
}

fn scale_for(
    height: f64,
    source_height: f64,
    table: &'static str,
    key: &str,
) -> Result<f64, BuildError> {
    if source_height > 0.0 && source_height.is_finite() {
        Ok(height / source_height)
    } else {
        Err(inconsistent(
            table,
            format!("{key}: source_height {source_height} must be positive"),
        ))
    }
}

/// Every body's mass properties, in the order bodies first appear in `bodies.csv`.
pub fn mass_properties(tables: &ModelTables) -> Result<Vec<(String, MassProperties)>, BuildError> {
    let (total_mass, height) = reference_subject(tables)?;
    let mut out: Vec<(String, Vec<MassProperties>)> = Vec::new();
    for row in &tables.bodies {
        let seg = (tables.segments.iter().find(|s| s.segment == row.segment)).ok_or_else(|| {
            inconsistent(
                "bodies.csv",
                format!("{}: unknown segment `{}`", row.body, row.segment),
            )
        })?;
        let s = scale_for(height, row.source_height, "bodies.csv", &row.body)?;
        let a = Vec3::new(row.proximal_x, row.proximal_y, row.proximal_z) * s;
        let b = Vec3::new(row.distal_x, row.distal_y, row.distal_z) * s;
        let length = (b - a).norm();
        if !(length > 0.0 && row.share > 0.0 && row.share <= 1.0) {
            return Err(inconsistent(
                "bodies.csv",
                format!(
                    "{}/{}: needs distinct landmarks and a share in (0, 1]",
                    row.body, row.segment
                ),
            ));
        }
        let (u0, u1) = (row.slice_start, row.slice_end);
        if !(0.0 <= u0 && u0 < u1 && u1 <= 1.0) {
            return Err(inconsistent(
                "bodies.csv",
                format!(
                    "{}/{}: slice [{u0}, {u1}] must lie in [0, 1]",
                    row.body, row.segment
                ),
            ));
        }
        let whole = u0 == 0.0 && u1 == 1.0;
        // mᵢ = kᵢ pᵢ M; cᵢ = a + γ (b − a), or the middle of a slice [u₀, u₁] of the segment
        let mass = row.share * seg.mass_percent / 100.0 * total_mass;
        let along = if whole {
            seg.com_percent / 100.0
        } else {
            0.5 * (u0 + u1)
        };
        let com = a + (b - a) * along;
        // R = [e_S e_L e_T]: e_L along b − a, e_T = z made orthogonal to e_L, e_S = e_L × e_T
        let e_l = (b - a) / length;
        let z = Vec3::z();
        let e_t = (z - e_l * z.dot(&e_l)).normalize();
        let e_s = e_l.cross(&e_t);
        let rot = Mat3::from_columns(&[e_s, e_l, e_t]);
        // A slice of a segment taken as uniform along its length: about the slice's own centre,
        // (r L)² − L²/12 + (Δu L)²/12 about the two cross axes, so that the slices recombine
        // to the whole segment's m (r L)².
        let cross = |percent: f64| {
            let r2 = (percent / 100.0 * length).powi(2);
            if whole {
                r2
            } else {
                r2 - length * length / 12.0 + ((u1 - u0) * length).powi(2) / 12.0
            }
        };
        let (i_s, i_t) = (
            cross(seg.r_sagittal_percent),
            cross(seg.r_transverse_percent),
        );
        if !(i_s >= 0.0 && i_t >= 0.0) {
            return Err(inconsistent(
                "bodies.csv",
                format!(
                    "{}/{}: the segment's radii of gyration are too small to slice",
                    row.body, row.segment
                ),
            ));
        }
        // Longitudinal: the whole segment's (r_L L)²; a slice's is that of a prism slab with the
        // cross moments above, i_S + i_T − (Δu L)²/6 (always a physical inertia; the slices of
        // a segment then recombine to (r_S² + r_T² − 1/6) L², within a few % of de Leva's r_L).
        let i_l = if whole {
            (seg.r_longitudinal_percent / 100.0 * length).powi(2)
        } else {
            i_s + i_t - ((u1 - u0) * length).powi(2) / 6.0
        };
        let local = Mat3::from_diagonal(&Vec3::new(mass * i_s, mass * i_l, mass * i_t));
        let part = MassProperties {
            mass,
            com,
            inertia: rot * local * rot.transpose(),
        };
        match out.iter_mut().find(|(name, _)| *name == row.body) {
            Some((_, parts)) => parts.push(part),
            None => out.push((row.body.clone(), vec![part])),
        }
    }
    Ok(out
        .into_iter()
        .map(|(name, parts)| (name, combine(&parts)))
        .collect())
}

/// Σ about the common centre of mass: I = Σ Iᵢ + mᵢ (‖dᵢ‖² 1 − dᵢ dᵢᵀ), dᵢ = cᵢ − c.
fn combine(parts: &[MassProperties]) -> MassProperties {
    let mass: f64 = parts.iter().map(|p| p.mass).sum();
    let com = parts
        .iter()
        .fold(Vec3::zeros(), |acc, p| acc + p.com * p.mass)
        / mass;
    let inertia = parts.iter().fold(Mat3::zeros(), |acc, p| {
        let d = p.com - com;
        acc + p.inertia + (Mat3::identity() * d.norm_squared() - d * d.transpose()) * p.mass
    });
    MassProperties { mass, com, inertia }
}

fn v3(x: f64, y: f64, z: f64) -> String {
    format!("{x} {y} {z}")
}

/// Builds the model file's text from the tables.
///
/// The sections in file order: header, bodies (with their wrap objects), joints, coupler
/// constraints, muscles, contact spheres, markers. Each is checked against the tables it
/// refers to as it is written.
pub fn build_osim(tables: &ModelTables) -> Result<String, BuildError> {
    let tables = &rhythm::apply(tables)?;
    let (total_mass, height) = reference_subject(tables)?;
    let bodies = mass_properties(tables)?;
    let known_body = |name: &str| name == "ground" || bodies.iter().any(|(b, _)| b == name);
    let mut x = String::new();
    let w = &mut x;
    write_header(w, tables, total_mass, height);

    let scales = body_scales(tables, height)?;
    let coordinate_joint: BTreeMap<&str, &str> = (tables.axes.iter())
        .filter(|a| !a.coordinate.is_empty())
        .map(|a| (a.coordinate.as_str(), a.joint.as_str()))
        .collect();
    write_body_set(w, tables, &bodies, &scales)?;
    write_joint_set(w, tables, height, &known_body)?;
    write_constraint_set(w, tables)?;
    write_force_set(w, tables, &scales, &coordinate_joint)?;
    write_contact_geometry_set(w, tables, height, &known_body)?;
    write_marker_set(w, tables, height, &known_body)?;
    let _ = writeln!(w, "\t</Model>\n</OpenSimDocument>");
    Ok(x)
}

/// The document and model elements' opening, the credits (reference subject and the tables'
/// sources), gravity, units and ground.
fn write_header(w: &mut String, tables: &ModelTables, total_mass: f64, height: f64) {
    // writing into a String cannot fail
    let _ = writeln!(w, "<?xml version=\"1.0\" encoding=\"UTF-8\" ?>");
    let _ = writeln!(w, "<OpenSimDocument Version=\"40000\">");
    let _ = writeln!(w, "\t<Model name=\"musculo_fullbody\">");
    let mut sources: Vec<&str> = tables.subject.iter().map(|r| r.source.as_str()).collect();
    sources.extend(tables.segments.iter().map(|r| r.source.as_str()));
    sources.extend(tables.joints.iter().map(|r| r.source.as_str()));
    sources.sort_unstable();
    sources.dedup();
    let _ = writeln!(
        w,
        "\t\t<credits>Generated by musculo model build from data/model (reference subject {total_mass} kg, {height} m). Sources: {}</credits>",
        xml_escape(&sources.join("; "))
    );
    let _ = writeln!(w, "\t\t<gravity>0 -9.8066499999999994 0</gravity>");
    let _ = writeln!(w, "\t\t<length_units>meters</length_units>");
    let _ = writeln!(w, "\t\t<force_units>N</force_units>");
    let _ = writeln!(w, "\t\t<Ground name=\"ground\" />");
}

/// `<BodySet>`: each body's mass properties and wrap objects.
fn write_body_set(
    w: &mut String,
    tables: &ModelTables,
    bodies: &[(String, MassProperties)],
    scales: &BTreeMap<&str, f64>,
) -> Result<(), BuildError> {
    let _ = writeln!(w, "\t\t<BodySet name=\"bodyset\">\n\t\t\t<objects>");
    for (name, p) in bodies {
        let i = &p.inertia;
        let _ = writeln!(w, "\t\t\t\t<Body name=\"{name}\">");
        let _ = writeln!(w, "\t\t\t\t\t<mass>{}</mass>", p.mass);
        let _ = writeln!(
            w,
            "\t\t\t\t\t<mass_center>{}</mass_center>",
            v3(p.com.x, p.com.y, p.com.z)
        );
        let _ = writeln!(
            w,
            "\t\t\t\t\t<inertia>{}</inertia>",
            crate::spatial::inertia_text(i)
        );
        write_wrap_objects(w, tables, name, scales[name.as_str()])?;
        let _ = writeln!(w, "\t\t\t\t</Body>");
    }
    let _ = writeln!(w, "\t\t\t</objects>\n\t\t\t<groups />\n\t\t</BodySet>");
    Ok(())
}

/// `<JointSet>`: a custom or weld joint per row of joints.csv, between known bodies.
fn write_joint_set(
    w: &mut String,
    tables: &ModelTables,
    height: f64,
    known_body: &impl Fn(&str) -> bool,
) -> Result<(), BuildError> {
    let splines = spline_knots(tables)?;
    let _ = writeln!(w, "\t\t<JointSet name=\"jointset\">\n\t\t\t<objects>");
    for j in &tables.joints {
        if !known_body(&j.parent) || !known_body(&j.child) {
            return Err(inconsistent(
                "joints.csv",
                format!(
                    "{}: parent `{}` or child `{}` is not a body",
                    j.joint, j.parent, j.child
                ),
            ));
        }
        let s = scale_for(height, j.source_height, "joints.csv", &j.joint)?;
        write_joint(w, tables, j, &splines, s)?;
    }
    let _ = writeln!(w, "\t\t\t</objects>\n\t\t\t<groups />\n\t\t</JointSet>");
    Ok(())
}

/// One joint: sockets, coordinates (custom joints), the two offset frames scaled by `s`, and
/// the spatial transform (custom joints).
fn write_joint(
    w: &mut String,
    tables: &ModelTables,
    j: &tables::JointRow,
    splines: &BTreeMap<&str, (Vec<f64>, Vec<f64>)>,
    s: f64,
) -> Result<(), BuildError> {
    let tag = match j.kind.as_str() {
        "custom" => "CustomJoint",
        "weld" => "WeldJoint",
        other => {
            return Err(inconsistent(
                "joints.csv",
                format!("{}: kind `{other}` (expected custom or weld)", j.joint),
            ));
        }
    };
    let (pf, cf) = (
        format!("{}_offset", j.parent),
        format!("{}_offset", j.child),
    );
    let _ = writeln!(w, "\t\t\t\t<{tag} name=\"{}\">", j.joint);
    let _ = writeln!(
        w,
        "\t\t\t\t\t<socket_parent_frame>{pf}</socket_parent_frame>"
    );
    let _ = writeln!(w, "\t\t\t\t\t<socket_child_frame>{cf}</socket_child_frame>");
    let axes: Vec<_> = tables.axes.iter().filter(|a| a.joint == j.joint).collect();
    if tag == "CustomJoint" {
        write_coordinates(w, &j.joint, &axes)?;
    } else if !axes.is_empty() {
        return Err(inconsistent(
            "coordinates.csv",
            format!("{}: a weld joint has no axes", j.joint),
        ));
    }
    let _ = writeln!(w, "\t\t\t\t\t<frames>");
    for (frame, body, loc, ori) in [
        (
            &pf,
            &j.parent,
            [j.parent_x, j.parent_y, j.parent_z],
            [j.parent_rx, j.parent_ry, j.parent_rz],
        ),
        (
            &cf,
            &j.child,
            [j.child_x, j.child_y, j.child_z],
            [j.child_rx, j.child_ry, j.child_rz],
        ),
    ] {
        write_offset_frame(w, frame, body, [loc[0] * s, loc[1] * s, loc[2] * s], ori);
    }
    let _ = writeln!(w, "\t\t\t\t\t</frames>");
    if tag == "CustomJoint" {
        write_spatial_transform(w, &j.joint, &axes, splines, s)?;
    }
    let _ = writeln!(w, "\t\t\t\t</{tag}>");
    Ok(())
}

/// A `<PhysicalOffsetFrame>` on `body` (ground or a body of the body set).
fn write_offset_frame(w: &mut String, frame: &str, body: &str, loc: [f64; 3], ori: [f64; 3]) {
    let path = if body == "ground" {
        "/ground".to_string()
    } else {
        format!("/bodyset/{body}")
    };
    let _ = writeln!(w, "\t\t\t\t\t\t<PhysicalOffsetFrame name=\"{frame}\">");
    let _ = writeln!(w, "\t\t\t\t\t\t\t<socket_parent>{path}</socket_parent>");
    let _ = writeln!(
        w,
        "\t\t\t\t\t\t\t<translation>{}</translation>",
        v3(loc[0], loc[1], loc[2])
    );
    let _ = writeln!(
        w,
        "\t\t\t\t\t\t\t<orientation>{}</orientation>",
        v3(ori[0], ori[1], ori[2])
    );
    let _ = writeln!(w, "\t\t\t\t\t\t</PhysicalOffsetFrame>");
}

/// `<ConstraintSet>`: a linear coupler q_dep = ratio · q_ind per row of couplers.csv, between
/// known coordinates.
fn write_constraint_set(w: &mut String, tables: &ModelTables) -> Result<(), BuildError> {
    let coordinates: Vec<&str> = (tables.axes.iter())
        .filter(|a| !a.coordinate.is_empty())
        .map(|a| a.coordinate.as_str())
        .collect();
    let _ = writeln!(
        w,
        "\t\t<ConstraintSet name=\"constraintset\">\n\t\t\t<objects>"
    );
    for c in &tables.couplers {
        for name in [&c.dependent, &c.independent] {
            if !coordinates.contains(&name.as_str()) {
                return Err(inconsistent(
                    "couplers.csv",
                    format!("{}: unknown coordinate `{name}`", c.name),
                ));
            }
        }
        let function = format!(
            "<LinearFunction name=\"function\">\n\t\t\t\t\t\t\t<coefficients>{} 0</coefficients>\n\t\t\t\t\t\t</LinearFunction>",
            c.ratio
        );
        write_coupler(w, &c.name, &function, &c.independent, &c.dependent);
    }
    for c in &tables.polynomial_couplers {
        write_polynomial_coupler(w, c, &coordinates)?;
    }
    let _ = writeln!(
        w,
        "\t\t\t</objects>\n\t\t\t<groups />\n\t\t</ConstraintSet>"
    );
    Ok(())
}

/// One `<CoordinateCouplerConstraint>` holding `function` (its XML element) between the
/// space-separated `independent` coordinates and `dependent`.
fn write_coupler(w: &mut String, name: &str, function: &str, independent: &str, dependent: &str) {
    let _ = writeln!(w, "\t\t\t\t<CoordinateCouplerConstraint name=\"{name}\">");
    let _ = writeln!(w, "\t\t\t\t\t<isEnforced>true</isEnforced>");
    let _ = writeln!(w, "\t\t\t\t\t<coupled_coordinates_function>");
    let _ = writeln!(w, "\t\t\t\t\t\t{function}");
    let _ = writeln!(w, "\t\t\t\t\t</coupled_coordinates_function>");
    let _ = writeln!(
        w,
        "\t\t\t\t\t<independent_coordinate_names>{independent}</independent_coordinate_names>"
    );
    let _ = writeln!(
        w,
        "\t\t\t\t\t<dependent_coordinate_name>{dependent}</dependent_coordinate_name>"
    );
    let _ = writeln!(w, "\t\t\t\t</CoordinateCouplerConstraint>");
}

/// A coupler q_dep = p(q_ind…) with OpenSim's `MultivariatePolynomialFunction` (coefficients
/// in OpenSim's term order, as the table gives them; their number (N+1)…(N+d)/d! for order N
/// and d independent coordinates).
fn write_polynomial_coupler(
    w: &mut String,
    c: &tables::PolynomialCouplerRow,
    coordinates: &[&str],
) -> Result<(), BuildError> {
    const TABLE: &str = "polynomial_couplers.csv";
    let independent: Vec<&str> = c.independent.split_whitespace().collect();
    for name in independent.iter().chain([&c.dependent.as_str()]) {
        if !coordinates.contains(name) {
            return Err(inconsistent(
                TABLE,
                format!("{}: unknown coordinate `{name}`", c.name),
            ));
        }
    }
    let coefficients: Vec<f64> = (c.coefficients.split_whitespace())
        .map(|x| x.parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| {
            inconsistent(
                TABLE,
                format!("{}: a coefficient is not a finite number", c.name),
            )
        })?;
    // number of monomials of total order ≤ N in d variables: C(N + d, d)
    let d = independent.len() as u64;
    let n = u64::from(c.order);
    let terms = (1..=d).fold(1u64, |acc, k| acc * (n + k) / k);
    if d == 0 || coefficients.len() as u64 != terms {
        return Err(inconsistent(
            TABLE,
            format!(
                "{}: {} coefficients; order {n} in {d} coordinates needs {terms}",
                c.name,
                coefficients.len()
            ),
        ));
    }
    let list: Vec<String> = coefficients.iter().map(|x| format!("{x}")).collect();
    let function = format!(
        "<MultivariatePolynomialFunction name=\"function\">\n\t\t\t\t\t\t\t<coefficients>{}</coefficients>\n\t\t\t\t\t\t\t<dimension>{d}</dimension>\n\t\t\t\t\t\t\t<order>{n}</order>\n\t\t\t\t\t\t</MultivariatePolynomialFunction>",
        list.join(" ")
    );
    write_coupler(w, &c.name, &function, &independent.join(" "), &c.dependent);
    Ok(())
}

/// `<ContactGeometrySet>`: a contact sphere per row of contacts.csv, scaled to the subject.
fn write_contact_geometry_set(
    w: &mut String,
    tables: &ModelTables,
    height: f64,
    known_body: &impl Fn(&str) -> bool,
) -> Result<(), BuildError> {
    let _ = writeln!(
        w,
        "\t\t<ContactGeometrySet name=\"contactgeometryset\">\n\t\t\t<objects>"
    );
    for c in &tables.contacts {
        if !known_body(&c.body) {
            return Err(inconsistent(
                "contacts.csv",
                format!("{}: unknown body `{}`", c.contact, c.body),
            ));
        }
        let s = scale_for(height, c.source_height, "contacts.csv", &c.contact)?;
        let _ = writeln!(w, "\t\t\t\t<ContactSphere name=\"{}\">", c.contact);
        let _ = writeln!(
            w,
            "\t\t\t\t\t<socket_frame>/bodyset/{}</socket_frame>",
            c.body
        );
        let _ = writeln!(
            w,
            "\t\t\t\t\t<location>{}</location>",
            v3(c.x * s, c.y * s, c.z * s)
        );
        let _ = writeln!(w, "\t\t\t\t\t<orientation>0 0 0</orientation>");
        let _ = writeln!(w, "\t\t\t\t\t<radius>{}</radius>", c.radius * s);
        let _ = writeln!(w, "\t\t\t\t</ContactSphere>");
    }
    let _ = writeln!(
        w,
        "\t\t\t</objects>\n\t\t\t<groups />\n\t\t</ContactGeometrySet>"
    );
    Ok(())
}

/// `<MarkerSet>`: a marker per row of markers.csv, scaled to the subject.
fn write_marker_set(
    w: &mut String,
    tables: &ModelTables,
    height: f64,
    known_body: &impl Fn(&str) -> bool,
) -> Result<(), BuildError> {
    let _ = writeln!(w, "\t\t<MarkerSet name=\"markerset\">\n\t\t\t<objects>");
    for m in &tables.markers {
        if !known_body(&m.body) {
            return Err(inconsistent(
                "markers.csv",
                format!("{}: unknown body `{}`", m.marker, m.body),
            ));
        }
        let s = scale_for(height, m.source_height, "markers.csv", &m.marker)?;
        let _ = writeln!(w, "\t\t\t\t<Marker name=\"{}\">", m.marker);
        let _ = writeln!(
            w,
            "\t\t\t\t\t<socket_parent_frame>/bodyset/{}</socket_parent_frame>",
            m.body
        );
        let _ = writeln!(
            w,
            "\t\t\t\t\t<location>{}</location>",
            v3(m.x * s, m.y * s, m.z * s)
        );
        let _ = writeln!(w, "\t\t\t\t\t<fixed>false</fixed>");
        let _ = writeln!(w, "\t\t\t\t</Marker>");
    }
    let _ = writeln!(w, "\t\t\t</objects>\n\t\t\t<groups />\n\t\t</MarkerSet>");
    Ok(())
}

/// The geometry scale s = H / H_source of every body (its rows must agree).
fn body_scales(tables: &ModelTables, height: f64) -> Result<BTreeMap<&str, f64>, BuildError> {
    let mut scales: BTreeMap<&str, f64> = BTreeMap::new();
    for row in &tables.bodies {
        let s = scale_for(height, row.source_height, "bodies.csv", &row.body)?;
        if let Some(&old) = scales.get(row.body.as_str()) {
            if old != s {
                return Err(inconsistent(
                    "bodies.csv",
                    format!("{}: rows with different source heights", row.body),
                ));
            }
        }
        scales.insert(&row.body, s);
    }
    Ok(scales)
}

fn write_wrap_objects(
    w: &mut String,
    tables: &ModelTables,
    body: &str,
    s: f64,
) -> Result<(), BuildError> {
    let objects: Vec<_> = tables
        .wrap_objects
        .iter()
        .filter(|o| o.body == body)
        .collect();
    if objects.is_empty() {
        return Ok(());
    }
    let need = |v: Option<f64>, what: &str, name: &str| {
        v.filter(|v| *v > 0.0 && v.is_finite()).ok_or_else(|| {
            inconsistent(
                "wrap_objects.csv",
                format!("{name}: `{what}` must be positive"),
            )
        })
    };
    let _ = writeln!(
        w,
        "\t\t\t\t\t<WrapObjectSet name=\"wrapobjectset\">\n\t\t\t\t\t\t<objects>"
    );
    for o in objects {
        let tag = match o.kind.as_str() {
            "cylinder" => "WrapCylinder",
            "sphere" => "WrapSphere",
            "ellipsoid" => "WrapEllipsoid",
            "torus" => "WrapTorus",
            other => {
                return Err(inconsistent(
                    "wrap_objects.csv",
                    format!("{}: type `{other}`", o.name),
                ));
            }
        };
        let _ = writeln!(w, "\t\t\t\t\t\t\t<{tag} name=\"{}\">", o.name);
        let _ = writeln!(
            w,
            "\t\t\t\t\t\t\t\t<xyz_body_rotation>{}</xyz_body_rotation>",
            v3(o.rot_x, o.rot_y, o.rot_z)
        );
        let _ = writeln!(
            w,
            "\t\t\t\t\t\t\t\t<translation>{}</translation>",
            v3(o.tx * s, o.ty * s, o.tz * s)
        );
        let _ = writeln!(w, "\t\t\t\t\t\t\t\t<quadrant>{}</quadrant>", o.quadrant);
        match tag {
            "WrapCylinder" => {
                let _ = writeln!(
                    w,
                    "\t\t\t\t\t\t\t\t<radius>{}</radius>",
                    need(o.radius, "radius", &o.name)? * s
                );
                let _ = writeln!(
                    w,
                    "\t\t\t\t\t\t\t\t<length>{}</length>",
                    need(o.length, "length", &o.name)? * s
                );
            }
            "WrapSphere" => {
                let _ = writeln!(
                    w,
                    "\t\t\t\t\t\t\t\t<radius>{}</radius>",
                    need(o.radius, "radius", &o.name)? * s
                );
            }
            "WrapEllipsoid" => {
                let d = [
                    need(o.dim_x, "dim_x", &o.name)?,
                    need(o.dim_y, "dim_y", &o.name)?,
                    need(o.dim_z, "dim_z", &o.name)?,
                ];
                let _ = writeln!(
                    w,
                    "\t\t\t\t\t\t\t\t<dimensions>{}</dimensions>",
                    v3(d[0] * s, d[1] * s, d[2] * s)
                );
            }
            _ => {
                let _ = writeln!(
                    w,
                    "\t\t\t\t\t\t\t\t<inner_radius>{}</inner_radius>",
                    need(o.radius, "radius", &o.name)? * s
                );
                let _ = writeln!(
                    w,
                    "\t\t\t\t\t\t\t\t<outer_radius>{}</outer_radius>",
                    need(o.dim_x, "dim_x", &o.name)? * s
                );
            }
        }
        let _ = writeln!(w, "\t\t\t\t\t\t\t</{tag}>");
    }
    let _ = writeln!(w, "\t\t\t\t\t\t</objects>\n\t\t\t\t\t</WrapObjectSet>");
    Ok(())
}

/// The muscles as Thelen2003Muscle with their geometry paths; lengths (points, spline values,
/// optimal fiber and tendon slack lengths) scale with the geometry of the bodies they span.
fn write_force_set(
    w: &mut String,
    tables: &ModelTables,
    scales: &BTreeMap<&str, f64>,
    coordinate_joint: &BTreeMap<&str, &str>,
) -> Result<(), BuildError> {
    let mut names: Vec<&str> = Vec::new();
    let _ = writeln!(w, "\t\t<ForceSet name=\"forceset\">\n\t\t\t<objects>");
    for m in &tables.muscles {
        if names.contains(&m.name.as_str()) {
            return Err(inconsistent(
                "muscles.csv",
                format!("{}: listed twice", m.name),
            ));
        }
        names.push(&m.name);
        let (points, s) = muscle_path_points(tables, m, scales)?;
        let muscle = MusclePath {
            tables,
            coordinate_joint,
            muscle: m,
            s,
        };
        let _ = writeln!(w, "\t\t\t\t<Thelen2003Muscle name=\"{}\">", m.name);
        let _ = writeln!(
            w,
            "\t\t\t\t\t<GeometryPath name=\"path\">\n\t\t\t\t\t\t<PathPointSet>\n\t\t\t\t\t\t\t<objects>"
        );
        for p in &points {
            write_path_point(w, &muscle, p)?;
        }
        let _ = writeln!(w, "\t\t\t\t\t\t\t</objects>\n\t\t\t\t\t\t</PathPointSet>");
        write_path_wraps(w, tables, m)?;
        let _ = writeln!(w, "\t\t\t\t\t</GeometryPath>");
        write_muscle_parameters(w, m, s);
        let _ = writeln!(w, "\t\t\t\t</Thelen2003Muscle>");
    }
    let _ = writeln!(w, "\t\t\t</objects>\n\t\t\t<groups />\n\t\t</ForceSet>");
    Ok(())
}

const PATH_POINTS: &str = "path_points.csv";

/// A muscle's path points in order (at least two) and the geometry scale of the bodies they
/// lie on, which must be one.
fn muscle_path_points<'t>(
    tables: &'t ModelTables,
    m: &tables::MuscleRow,
    scales: &BTreeMap<&str, f64>,
) -> Result<(Vec<&'t tables::PathPointRow>, f64), BuildError> {
    let mut points: Vec<_> = tables
        .path_points
        .iter()
        .filter(|p| p.muscle == m.name)
        .collect();
    points.sort_by_key(|p| p.index);
    if points.len() < 2 {
        return Err(inconsistent(
            PATH_POINTS,
            format!("{}: a path needs at least two points", m.name),
        ));
    }
    let mut scale = None;
    for p in &points {
        let s = *scales.get(p.body.as_str()).ok_or_else(|| {
            inconsistent(
                PATH_POINTS,
                format!("{} point {}: unknown body `{}`", m.name, p.index, p.body),
            )
        })?;
        if scale.is_some_and(|old| old != s) {
            return Err(inconsistent(
                PATH_POINTS,
                format!("{}: spans bodies of different geometry scales", m.name),
            ));
        }
        scale = Some(s);
    }
    Ok((points, scale.unwrap_or(1.0)))
}

/// What writing one muscle's path points needs: the tables, the joint of each coordinate, the
/// muscle and its geometry scale s.
struct MusclePath<'a> {
    tables: &'a ModelTables,
    coordinate_joint: &'a BTreeMap<&'a str, &'a str>,
    muscle: &'a tables::MuscleRow,
    s: f64,
}

impl MusclePath<'_> {
    /// The component path `/jointset/<joint>/<coordinate>` of a coordinate the path uses.
    fn coordinate_path(&self, name: &str) -> Result<String, BuildError> {
        self.coordinate_joint
            .get(name)
            .map(|joint| format!("/jointset/{joint}/{name}"))
            .ok_or_else(|| {
                inconsistent(
                    PATH_POINTS,
                    format!("{}: unknown coordinate `{name}`", self.muscle.name),
                )
            })
    }
}

/// One fixed, conditional or moving path point, its location scaled by s.
fn write_path_point(
    w: &mut String,
    mp: &MusclePath,
    p: &tables::PathPointRow,
) -> Result<(), BuildError> {
    let s = mp.s;
    let pname = format!("{}-P{}", mp.muscle.name, p.index);
    let frame = format!(
        "<socket_parent_frame>/bodyset/{}</socket_parent_frame>",
        p.body
    );
    let location = || match (p.x, p.y, p.z) {
        (Some(x), Some(y), Some(z)) => Ok(v3(x * s, y * s, z * s)),
        _ => Err(inconsistent(PATH_POINTS, format!("{pname}: needs x, y, z"))),
    };
    match p.kind.as_str() {
        "fixed" => {
            let _ = writeln!(
                w,
                "\t\t\t\t\t\t\t\t<PathPoint name=\"{pname}\">{frame}<location>{}</location></PathPoint>",
                location()?
            );
        }
        "conditional" => {
            let (Some(lo), Some(hi)) = (p.range_min, p.range_max) else {
                return Err(inconsistent(
                    PATH_POINTS,
                    format!("{pname}: a conditional point needs its range"),
                ));
            };
            let _ = writeln!(
                w,
                "\t\t\t\t\t\t\t\t<ConditionalPathPoint name=\"{pname}\">{frame}<location>{}</location><socket_coordinate>{}</socket_coordinate><range>{lo} {hi}</range></ConditionalPathPoint>",
                location()?,
                mp.coordinate_path(&p.coordinate)?
            );
        }
        "moving" => {
            let _ = writeln!(
                w,
                "\t\t\t\t\t\t\t\t<MovingPathPoint name=\"{pname}\">{frame}"
            );
            for axis in ["x", "y", "z"] {
                write_moving_point_axis(w, mp, p, &pname, axis)?;
            }
            let _ = writeln!(w, "\t\t\t\t\t\t\t\t</MovingPathPoint>");
        }
        other => {
            return Err(inconsistent(
                PATH_POINTS,
                format!("{pname}: type `{other}` (fixed, conditional or moving)"),
            ));
        }
    }
    Ok(())
}

/// One axis of a moving path point: its coordinate and its spline (knots increasing, values
/// scaled by s) from moving_point_functions.csv.
fn write_moving_point_axis(
    w: &mut String,
    mp: &MusclePath,
    p: &tables::PathPointRow,
    pname: &str,
    axis: &str,
) -> Result<(), BuildError> {
    let m = mp.muscle;
    let knots: Vec<_> = (mp.tables.moving_knots.iter())
        .filter(|k| k.muscle == m.name && k.index == p.index && k.axis == axis)
        .collect();
    let Some(first) = knots.first() else {
        return Err(inconsistent(
            "moving_point_functions.csv",
            format!("{pname}: no {axis} function"),
        ));
    };
    if knots.windows(2).any(|k| !(k[1].knot > k[0].knot)) {
        return Err(inconsistent(
            "moving_point_functions.csv",
            format!("{pname} {axis}: knots must increase"),
        ));
    }
    let tag = match first.function.as_str() {
        "SimmSpline" | "NaturalCubicSpline" => first.function.as_str(),
        other => {
            return Err(inconsistent(
                "moving_point_functions.csv",
                format!("{pname} {axis}: function `{other}`"),
            ));
        }
    };
    let xs: Vec<String> = knots.iter().map(|k| format!("{}", k.knot)).collect();
    let ys: Vec<String> = knots
        .iter()
        .map(|k| format!("{}", k.value * mp.s))
        .collect();
    let _ = writeln!(
        w,
        "\t\t\t\t\t\t\t\t\t<socket_{axis}_coordinate>{}</socket_{axis}_coordinate><{axis}_location><{tag} name=\"function\"><x>{}</x><y>{}</y></{tag}></{axis}_location>",
        mp.coordinate_path(&first.coordinate)?,
        xs.join(" "),
        ys.join(" ")
    );
    Ok(())
}

/// The muscle's `<PathWrapSet>` (none when it has no wraps), in wrap order.
fn write_path_wraps(
    w: &mut String,
    tables: &ModelTables,
    m: &tables::MuscleRow,
) -> Result<(), BuildError> {
    let mut wraps: Vec<_> = tables
        .muscle_wraps
        .iter()
        .filter(|r| r.muscle == m.name)
        .collect();
    wraps.sort_by_key(|r| r.order);
    if wraps.is_empty() {
        return Ok(());
    }
    let _ = writeln!(w, "\t\t\t\t\t\t<PathWrapSet>\n\t\t\t\t\t\t\t<objects>");
    for r in wraps {
        if !tables.wrap_objects.iter().any(|o| o.name == r.wrap_object) {
            return Err(inconsistent(
                "muscle_wraps.csv",
                format!("{}: unknown wrap object `{}`", m.name, r.wrap_object),
            ));
        }
        let _ = writeln!(
            w,
            "\t\t\t\t\t\t\t\t<PathWrap name=\"{}-wrap{}\"><wrap_object>{}</wrap_object><method>{}</method><range>{} {}</range></PathWrap>",
            m.name, r.order, r.wrap_object, r.method, r.range_start, r.range_end
        );
    }
    let _ = writeln!(w, "\t\t\t\t\t\t\t</objects>\n\t\t\t\t\t\t</PathWrapSet>");
    Ok(())
}

/// The Hill-type parameters; the lengths scale by s.
fn write_muscle_parameters(w: &mut String, m: &tables::MuscleRow, s: f64) {
    let _ = writeln!(
        w,
        "\t\t\t\t\t<max_isometric_force>{}</max_isometric_force>",
        m.max_isometric_force
    );
    let _ = writeln!(
        w,
        "\t\t\t\t\t<optimal_fiber_length>{}</optimal_fiber_length>",
        m.optimal_fiber_length * s
    );
    let _ = writeln!(
        w,
        "\t\t\t\t\t<tendon_slack_length>{}</tendon_slack_length>",
        m.tendon_slack_length * s
    );
    let _ = writeln!(
        w,
        "\t\t\t\t\t<pennation_angle_at_optimal>{}</pennation_angle_at_optimal>",
        m.pennation_angle
    );
    let _ = writeln!(
        w,
        "\t\t\t\t\t<max_contraction_velocity>{}</max_contraction_velocity>",
        m.max_contraction_velocity
    );
}

fn spline_knots(tables: &ModelTables) -> Result<BTreeMap<&str, (Vec<f64>, Vec<f64>)>, BuildError> {
    let mut map: BTreeMap<&str, (Vec<f64>, Vec<f64>)> = BTreeMap::new();
    for k in &tables.splines {
        let e = map.entry(k.spline.as_str()).or_default();
        if e.0.last().is_some_and(|&last| !(k.x > last)) {
            return Err(inconsistent(
                "joint_splines.csv",
                format!("{}: knots must increase in x", k.spline),
            ));
        }
        e.0.push(k.x);
        e.1.push(k.y);
    }
    Ok(map)
}

fn write_coordinates(
    w: &mut String,
    joint: &str,
    axes: &[&tables::AxisRow],
) -> Result<(), BuildError> {
    let _ = writeln!(w, "\t\t\t\t\t<coordinates>");
    let mut seen: Vec<&str> = Vec::new();
    for a in axes.iter().filter(|a| !a.coordinate.is_empty()) {
        if seen.contains(&a.coordinate.as_str()) {
            continue;
        }
        seen.push(&a.coordinate);
        let (Some(default), Some(min), Some(max)) = (a.default_value, a.range_min, a.range_max)
        else {
            return Err(inconsistent(
                "coordinates.csv",
                format!(
                    "{joint}/{}: the first row of a coordinate needs default_value, range_min, range_max",
                    a.coordinate
                ),
            ));
        };
        if !(min < max && default >= min && default <= max) {
            return Err(inconsistent(
                "coordinates.csv",
                format!(
                    "{joint}/{}: default {default} outside range [{min}, {max}]",
                    a.coordinate
                ),
            ));
        }
        let _ = writeln!(w, "\t\t\t\t\t\t<Coordinate name=\"{}\">", a.coordinate);
        let _ = writeln!(w, "\t\t\t\t\t\t\t<default_value>{default}</default_value>");
        let _ = writeln!(
            w,
            "\t\t\t\t\t\t\t<default_speed_value>0</default_speed_value>"
        );
        let _ = writeln!(w, "\t\t\t\t\t\t\t<range>{min} {max}</range>");
        let _ = writeln!(w, "\t\t\t\t\t\t\t<clamped>false</clamped>");
        let _ = writeln!(
            w,
            "\t\t\t\t\t\t\t<locked>{}</locked>",
            a.locked.unwrap_or(false)
        );
        let _ = writeln!(w, "\t\t\t\t\t\t</Coordinate>");
    }
    let _ = writeln!(w, "\t\t\t\t\t</coordinates>");
    Ok(())
}

const SLOTS: [&str; 6] = [
    "rotation1",
    "rotation2",
    "rotation3",
    "translation1",
    "translation2",
    "translation3",
];

fn write_spatial_transform(
    w: &mut String,
    joint: &str,
    axes: &[&tables::AxisRow],
    splines: &BTreeMap<&str, (Vec<f64>, Vec<f64>)>,
    scale: f64,
) -> Result<(), BuildError> {
    for a in axes {
        if !SLOTS.contains(&a.slot.as_str()) {
            return Err(inconsistent(
                "coordinates.csv",
                format!("{joint}: unknown slot `{}`", a.slot),
            ));
        }
    }
    let _ = writeln!(w, "\t\t\t\t\t<SpatialTransform>");
    // Unlisted slots are fixed (constant 0) but OpenSim still needs each triple of axes to be
    // independent: an unlisted axis is the unit vector, of x, y, z made orthogonal to the
    // triple's listed axes, that keeps the largest part.
    let mut chosen: [Vec<Vec3>; 2] = [Vec::new(), Vec::new()];
    for a in axes {
        let k = SLOTS.iter().position(|s| *s == a.slot).unwrap_or(0);
        chosen[k / 3].push(Vec3::new(a.axis_x, a.axis_y, a.axis_z).normalize());
    }
    let mut completion = |group: usize| -> Vec3 {
        let mut best = Vec3::zeros();
        for candidate in [Vec3::x(), Vec3::y(), Vec3::z()] {
            let mut v = candidate;
            for u in &chosen[group] {
                v -= u * u.dot(&v) / u.norm_squared();
            }
            if v.norm() > best.norm() + 1e-12 {
                best = v;
            }
        }
        let axis = best.normalize();
        chosen[group].push(axis);
        axis
    };
    for (k, slot) in SLOTS.iter().enumerate() {
        let rows: Vec<_> = axes.iter().filter(|a| a.slot == *slot).collect();
        if rows.len() > 1 {
            return Err(inconsistent(
                "coordinates.csv",
                format!("{joint}: slot {slot} given twice"),
            ));
        }
        let translation = k >= 3;
        let _ = writeln!(w, "\t\t\t\t\t\t<TransformAxis name=\"{slot}\">");
        match rows.first() {
            Some(a) => {
                let _ = writeln!(
                    w,
                    "\t\t\t\t\t\t\t<coordinates>{}</coordinates>",
                    a.coordinate
                );
                let _ = writeln!(
                    w,
                    "\t\t\t\t\t\t\t<axis>{}</axis>",
                    v3(a.axis_x, a.axis_y, a.axis_z)
                );
                write_function(w, joint, a, splines, if translation { scale } else { 1.0 })?;
            }
            None => {
                let d = completion(k / 3);
                let d = [d.x, d.y, d.z];
                let _ = writeln!(w, "\t\t\t\t\t\t\t<coordinates></coordinates>");
                let _ = writeln!(w, "\t\t\t\t\t\t\t<axis>{}</axis>", v3(d[0], d[1], d[2]));
                let _ = writeln!(
                    w,
                    "\t\t\t\t\t\t\t<Constant name=\"function\">\n\t\t\t\t\t\t\t\t<value>0</value>\n\t\t\t\t\t\t\t</Constant>"
                );
            }
        }
        let _ = writeln!(w, "\t\t\t\t\t\t</TransformAxis>");
    }
    let _ = writeln!(w, "\t\t\t\t\t</SpatialTransform>");
    Ok(())
}

fn write_function(
    w: &mut String,
    joint: &str,
    a: &tables::AxisRow,
    splines: &BTreeMap<&str, (Vec<f64>, Vec<f64>)>,
    scale: f64,
) -> Result<(), BuildError> {
    let f = a.function.as_str();
    if a.coordinate.is_empty() {
        return Err(inconsistent(
            "coordinates.csv",
            format!("{joint}/{}: an axis row needs a coordinate", a.slot),
        ));
    }
    if f == "identity" || f.starts_with("linear:") {
        let k = match f.strip_prefix("linear:") {
            Some(k) => k.parse::<f64>().map_err(|_| {
                inconsistent(
                    "coordinates.csv",
                    format!("{joint}/{}: bad slope in `{f}`", a.slot),
                )
            })?,
            None => 1.0,
        };
        let _ = writeln!(
            w,
            "\t\t\t\t\t\t\t<LinearFunction name=\"function\">\n\t\t\t\t\t\t\t\t<coefficients>{k} 0</coefficients>\n\t\t\t\t\t\t\t</LinearFunction>"
        );
        Ok(())
    } else if let Some(name) = f.strip_prefix("spline:") {
        let (xs, ys) = splines.get(name).ok_or_else(|| {
            inconsistent(
                "coordinates.csv",
                format!("{joint}/{}: unknown spline `{name}`", a.slot),
            )
        })?;
        let join = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x}"))
                .collect::<Vec<_>>()
                .join(" ")
        };
        let ys: Vec<f64> = ys.iter().map(|y| y * scale).collect();
        let _ = writeln!(
            w,
            "\t\t\t\t\t\t\t<SimmSpline name=\"function\">\n\t\t\t\t\t\t\t\t<x>{}</x>\n\t\t\t\t\t\t\t\t<y>{}</y>\n\t\t\t\t\t\t\t</SimmSpline>",
            join(xs),
            join(&ys)
        );
        Ok(())
    } else {
        Err(inconsistent(
            "coordinates.csv",
            format!(
                "{joint}/{}: function `{f}` (expected identity, linear:K, spline:NAME)",
                a.slot
            ),
        ))
    }
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::tables::*;
    use super::*;
    use crate::model::Model;

    const SRC: &str = "test";

    fn subject(mass: f64, height: f64) -> Vec<SubjectRow> {
        [("mass", mass), ("height", height)]
            .map(|(quantity, value)| SubjectRow {
                quantity: quantity.into(),
                value,
                source: SRC.into(),
            })
            .to_vec()
    }

    fn segment(name: &str, mass_percent: f64, com_percent: f64, r: [f64; 3]) -> SegmentRow {
        SegmentRow {
            segment: name.into(),
            mass_percent,
            com_percent,
            r_sagittal_percent: r[0],
            r_transverse_percent: r[1],
            r_longitudinal_percent: r[2],
            source: SRC.into(),
        }
    }

    fn body(name: &str, segment: &str, share: f64, a: [f64; 3], b: [f64; 3]) -> BodyRow {
        BodyRow {
            body: name.into(),
            segment: segment.into(),
            share,
            proximal_x: a[0],
            proximal_y: a[1],
            proximal_z: a[2],
            distal_x: b[0],
            distal_y: b[1],
            distal_z: b[2],
            slice_start: 0.0,
            slice_end: 1.0,
            source_height: 1.8,
            source: SRC.into(),
        }
    }

    /// A pendulum: ground → link by a hinge about z, one marker, one contact sphere.
    fn pendulum(height: f64) -> ModelTables {
        ModelTables {
            subject: subject(80.0, height),
            segments: vec![
                segment("thigh", 10.0, 40.0, [30.0, 25.0, 20.0]),
                segment("foot", 5.0, 50.0, [25.0, 25.0, 10.0]),
            ],
            bodies: vec![body(
                "link",
                "thigh",
                1.0,
                [0.0, 0.0, 0.0],
                [0.0, -0.5, 0.0],
            )],
            joints: vec![JointRow {
                joint: "hinge".into(),
                kind: "custom".into(),
                parent: "ground".into(),
                child: "link".into(),
                parent_x: 0.0,
                parent_y: 1.0,
                parent_z: 0.0,
                parent_rx: 0.0,
                parent_ry: 0.0,
                parent_rz: 0.0,
                child_x: 0.0,
                child_y: 0.0,
                child_z: 0.0,
                child_rx: 0.0,
                child_ry: 0.0,
                child_rz: 0.0,
                source_height: 1.8,
                source: SRC.into(),
            }],
            axes: vec![AxisRow {
                joint: "hinge".into(),
                slot: "rotation1".into(),
                coordinate: "swing".into(),
                axis_x: 0.0,
                axis_y: 0.0,
                axis_z: 1.0,
                function: "identity".into(),
                default_value: Some(0.0),
                range_min: Some(-1.0),
                range_max: Some(1.0),
                locked: Some(false),
                source: SRC.into(),
            }],
            splines: vec![],
            couplers: vec![],
            polynomial_couplers: vec![],
            rhythm: vec![],
            rhythm_points: vec![],
            markers: vec![MarkerRow {
                marker: "tip".into(),
                body: "link".into(),
                x: 0.0,
                y: -0.5,
                z: 0.0,
                source_height: 1.8,
                source: SRC.into(),
            }],
            contacts: vec![ContactRow {
                contact: "ball".into(),
                body: "link".into(),
                x: 0.0,
                y: -0.5,
                z: 0.0,
                radius: 0.02,
                source_height: 1.8,
                source: SRC.into(),
            }],
            muscles: vec![],
            path_points: vec![],
            moving_knots: vec![],
            wrap_objects: vec![],
            muscle_wraps: vec![],
        }
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * (1.0 + b.abs())
    }

    #[test]
    fn segment_table_gives_mass_com_and_inertia_by_hand() {
        // m = 10 % of 80 kg; L = 0.5 m; c = 0.4 L below the origin;
        // I_x = m (0.3 L)², I_y = m (0.2 L)², I_z = m (0.25 L)² (e_S = x, e_L = −y, e_T = z)
        let xml = build_osim(&pendulum(1.8)).expect("builds");
        let model = Model::from_osim_str(&xml, "pendulum").expect("parses");
        let link = model
            .bodies
            .iter()
            .find(|b| b.name == "link")
            .expect("link");
        let (m, l) = (8.0, 0.5);
        assert!(close(link.mass, m));
        assert!(close(link.com_in_body.y, -0.2) && link.com_in_body.x == 0.0);
        let i = link.inertia_about_com;
        assert!(close(i[(0, 0)], m * (0.3 * l) * (0.3 * l)), "{i}");
        assert!(close(i[(1, 1)], m * (0.2 * l) * (0.2 * l)), "{i}");
        assert!(close(i[(2, 2)], m * (0.25 * l) * (0.25 * l)), "{i}");
    }

    #[test]
    fn geometry_scales_with_height_and_inertia_with_its_square() {
        let full = mass_properties(&pendulum(1.8)).unwrap().remove(0).1;
        let half = mass_properties(&pendulum(0.9)).unwrap().remove(0).1;
        assert!(close(half.mass, full.mass));
        assert!(close(half.com.y, 0.5 * full.com.y));
        assert!(close(half.inertia[(0, 0)], 0.25 * full.inertia[(0, 0)]));
        let xml = build_osim(&pendulum(0.9)).unwrap();
        assert!(
            xml.contains("<translation>0 0.5 0</translation>"),
            "joint location scaled"
        );
        assert!(
            xml.contains("<radius>0.01</radius>"),
            "contact radius scaled"
        );
    }

    #[test]
    fn shares_of_one_body_combine_about_their_common_centre() {
        // two point-like halves (tiny radii) 0.4 m apart: I_z ≈ Σ mᵢ dᵢ² = 2 · (m/2)(0.2)²
        let mut t = pendulum(1.8);
        t.segments.push(segment("dot", 10.0, 50.0, [0.0, 0.0, 0.0]));
        t.bodies = vec![
            body("link", "dot", 0.5, [0.0, -0.01, 0.0], [0.0, 0.01, 0.0]),
            body("link", "dot", 0.5, [0.4, -0.01, 0.0], [0.4, 0.01, 0.0]),
        ];
        let p = mass_properties(&t).unwrap().remove(0).1;
        assert!(close(p.mass, 8.0) && close(p.com.x, 0.2));
        assert!(
            close(p.inertia[(2, 2)], 8.0 * 0.2 * 0.2) && close(p.inertia[(1, 1)], 8.0 * 0.2 * 0.2)
        );
        assert!(p.inertia[(0, 0)].abs() < 1e-15);
    }

    #[test]
    fn slices_of_a_segment_recombine_to_the_whole_segment() {
        // five slices on one body: mass, centre (middle of the segment for uniform slices)
        // and the cross moments equal the whole segment's m (r L)² about that centre; the
        // longitudinal one is the prism's, m (r_S² + r_T² − 1/6) L²
        // (de Leva's middle-trunk radii; a slender segment's could not be sliced uniformly)
        let mut t = pendulum(1.8);
        t.segments
            .push(segment("trunk", 10.0, 45.0, [48.2, 38.3, 46.8]));
        t.bodies = (0..5)
            .map(|k| {
                let mut b = body("link", "trunk", 0.2, [0.0, 0.0, 0.0], [0.0, -0.5, 0.0]);
                (b.slice_start, b.slice_end) = (k as f64 * 0.2, (k + 1) as f64 * 0.2);
                b
            })
            .collect();
        let p = mass_properties(&t).unwrap().remove(0).1;
        let (m, l) = (8.0, 0.5);
        let i = p.inertia;
        assert!(close(p.mass, m) && close(p.com.y, -0.25));
        assert!(close(i[(0, 0)], m * (0.482 * l) * (0.482 * l)), "{i}");
        let prism = 0.482f64.powi(2) + 0.383f64.powi(2) - 1.0 / 6.0;
        assert!(close(i[(1, 1)], m * prism * l * l), "{i}");
        assert!(close(i[(2, 2)], m * (0.383 * l) * (0.383 * l)), "{i}");
        // a slender segment cannot be sliced into uniform parts: an error, not a bad inertia
        t.bodies[0].segment = "thigh".into();
        assert!(
            mass_properties(&t)
                .unwrap_err()
                .to_string()
                .contains("too small to slice")
        );
    }

    #[test]
    fn inconsistent_tables_are_errors_naming_the_row() {
        let mut t = pendulum(1.8);
        t.bodies[0].segment = "wing".into();
        let e = build_osim(&t).unwrap_err().to_string();
        assert!(e.contains("bodies.csv") && e.contains("wing"), "{e}");
        let mut t = pendulum(1.8);
        t.axes[0].range_min = Some(2.0);
        let e = build_osim(&t).unwrap_err().to_string();
        assert!(e.contains("coordinates.csv") && e.contains("swing"), "{e}");
        let mut t = pendulum(1.8);
        t.markers[0].body = "nowhere".into();
        assert!(build_osim(&t).unwrap_err().to_string().contains("nowhere"));
    }

    #[test]
    fn unlisted_rotation_axes_complete_an_independent_basis() {
        let mut t = pendulum(1.8);
        t.axes[0].axis_x = 0.6;
        t.axes[0].axis_y = 0.0;
        t.axes[0].axis_z = 0.8;
        let xml = build_osim(&t).unwrap();
        // parses (OpenSim's and our reader reject dependent rotation axes)
        Model::from_osim_str(&xml, "tilted").expect("independent axes");
    }
}
