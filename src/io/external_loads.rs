//! OpenSim ExternalLoads files (`.xml`): the external forces (typically ground-reaction forces
//! from force plates) applied to named bodies, with the columns of a data file that hold
//! each force vector, its point of application and a torque.
//!
//! For an ExternalForce with `force_identifier` "ground_force_v", the force is the columns
//! `ground_force_vx`, `…vy`, `…vz`; the point `…px`, `…py`, `…pz`; the torque
//! `ground_torque_x`, `…y`, `…z` (identifier + x/y/z), as OpenSim names them. Each is
//! expressed in the frame of the body named by `force_expressed_in_body` /
//! `point_expressed_in_body` (usually ground).
//!
//! A `PrescribedForce` (OpenSim 3's way of writing measured loads into the file itself, as in
//! OpenSim's `Gait2392_Simbody/foot_floor_loads.xml`) is read too: a body (`body` in OpenSim
//! 3, `frame_name` in 4), and up to three `FunctionSet`s of three functions of time each —
//! `forceFunctions`, `pointFunctions`, `torqueFunctions` — given in ground when
//! `forceIsGlobal` / `pointIsGlobal` say so (OpenSim's defaults: force global, point not),
//! else in the body's frame. Its functions are any the model reader reads (splines,
//! piecewise-linear, constants, …); without point functions the force acts at the body's
//! origin, as in OpenSim.

use crate::error::Error;
use crate::model::{Arity, Function, FunctionReader, Model};
use roxmltree::Node;
use std::path::{Path, PathBuf};

/// One ExternalForce element.
#[derive(Clone, Debug, PartialEq)]
pub struct ExternalForce {
    pub name: String,
    pub applied_to_body: String,
    pub force_expressed_in_body: String,
    pub point_expressed_in_body: String,
    /// Column-name prefixes; `None` when absent (no force, point or torque from data).
    pub force_identifier: Option<String>,
    pub point_identifier: Option<String>,
    pub torque_identifier: Option<String>,
    /// Line of the element, for messages.
    pub line: u32,
}

/// One PrescribedForce element: a force, its point and a torque on one body, each three
/// functions of time held in the file itself (module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct PrescribedForce {
    pub name: String,
    /// The body the force is applied to.
    pub body: String,
    /// Force and torque in ground (`forceIsGlobal`, true by default), else in the body.
    pub force_is_global: bool,
    /// Point in ground (`pointIsGlobal`, false by default), else in the body.
    pub point_is_global: bool,
    /// x, y, z functions of time; `None` when the set is empty or absent.
    pub force: Option<[Function; 3]>,
    pub point: Option<[Function; 3]>,
    pub torque: Option<[Function; 3]>,
    /// First and last sample time of the functions that have samples (`<x>`), if any.
    pub time_span: Option<[f64; 2]>,
    /// Line of the element, for messages.
    pub line: u32,
}

/// An ExternalLoads file.
#[derive(Clone, Debug, PartialEq)]
pub struct ExternalLoads {
    /// The file read (for messages).
    pub source: String,
    /// The data file (`datafile`): as written by [`ExternalLoads::parse`], resolved relative
    /// to the ExternalLoads file (Windows separators included: [`super::resolve_data_path`])
    /// by [`ExternalLoads::read`].
    pub datafile: Option<PathBuf>,
    pub forces: Vec<ExternalForce>,
    /// The PrescribedForce elements (their functions need no data file).
    pub prescribed: Vec<PrescribedForce>,
}

impl ExternalLoads {
    pub fn read(path: &Path) -> crate::Result<ExternalLoads> {
        let text = crate::text::read_text(path)?;
        let mut loads = Self::parse(&text, &path.display().to_string())?;
        if let Some(d) = &loads.datafile {
            let base = crate::io::setup::base_dir(path);
            loads.datafile = Some(super::resolve_data_path(base, &d.to_string_lossy()));
        }
        Ok(loads)
    }

    pub fn parse(text: &str, source: &str) -> crate::Result<ExternalLoads> {
        let doc = crate::xml::parse(text, source)?;
        let line = |n: roxmltree::Node| doc.text_pos_at(n.range().start).row;
        let err = |n: roxmltree::Node, element: String, message: String| Error::Model {
            file: source.to_string(),
            line: line(n),
            element,
            message,
        };
        let root = doc
            .descendants()
            .find(|n| n.has_tag_name("ExternalLoads"))
            .ok_or_else(|| {
                err(
                    doc.root_element(),
                    "<OpenSimDocument>".into(),
                    "no <ExternalLoads> element".into(),
                )
            })?;
        let text_of = |n: roxmltree::Node, tag: &str| -> Option<String> {
            n.children()
                .find(|c| c.has_tag_name(tag))
                .map(|c| c.text().unwrap_or("").trim().to_string())
                .filter(|s| !s.is_empty() && s != "Unassigned")
        };
        let mut forces = Vec::new();
        let mut prescribed = Vec::new();
        let functions = FunctionReader::new(&doc, source);
        let objects = root.children().find(|c| c.has_tag_name("objects"));
        let mut seen = std::collections::HashMap::new();
        for f in objects
            .iter()
            .flat_map(|o| o.children())
            .filter(|c| c.is_element())
        {
            let name = f.attribute("name").unwrap_or("").to_string();
            let element = format!("{} \"{name}\"", f.tag_name().name());
            if let Some(first) = seen.insert(name.clone(), line(f)) {
                return Err(err(
                    f,
                    element,
                    format!(
                        "a second force named \"{name}\" (the first is at line {first}): the \
                         forces of an ExternalLoads file need distinct names"
                    ),
                ));
            }
            if !f.has_tag_name("ExternalForce") && !f.has_tag_name("PrescribedForce") {
                return Err(err(
                    f,
                    element,
                    "unsupported element: ExternalForce and PrescribedForce are read".into(),
                ));
            }
            let disabled = text_of(f, "isDisabled").is_some_and(|v| v == "true")
                || text_of(f, "appliesForce").is_some_and(|v| v == "false");
            if disabled {
                continue;
            }
            if f.has_tag_name("PrescribedForce") {
                prescribed.push(read_prescribed(&functions, f, name, line(f))?);
                continue;
            }
            let body = text_of(f, "applied_to_body")
                .ok_or_else(|| err(f, element.clone(), "missing <applied_to_body>".into()))?;
            forces.push(ExternalForce {
                name,
                applied_to_body: body,
                force_expressed_in_body: text_of(f, "force_expressed_in_body")
                    .unwrap_or_else(|| "ground".into()),
                point_expressed_in_body: text_of(f, "point_expressed_in_body")
                    .unwrap_or_else(|| "ground".into()),
                force_identifier: text_of(f, "force_identifier"),
                point_identifier: text_of(f, "point_identifier"),
                torque_identifier: text_of(f, "torque_identifier"),
                line: line(f),
            });
        }
        Ok(ExternalLoads {
            source: source.to_string(),
            datafile: text_of(root, "datafile").map(PathBuf::from),
            forces,
            prescribed,
        })
    }

    /// The index of the body of every PrescribedForce, in order, checked against `model`.
    pub fn prescribed_bodies(&self, model: &Model) -> crate::Result<Vec<usize>> {
        self.prescribed
            .iter()
            .map(|f| {
                model.body_index(&f.body).ok_or_else(|| Error::Model {
                    file: self.source.clone(),
                    line: f.line,
                    element: format!("PrescribedForce \"{}\"", f.name),
                    message: format!(
                        "unknown body `{}` (the model has no body of that name)",
                        f.body
                    ),
                })
            })
            .collect()
    }

    /// Checks every body name against `model`, returning their indices (applied-to,
    /// force-expressed-in, point-expressed-in) in force order.
    pub fn bodies(&self, model: &Model) -> crate::Result<Vec<[usize; 3]>> {
        self.forces
            .iter()
            .map(|f| {
                let find = |what: &str, name: &str| {
                    model.body_index(name).ok_or_else(|| Error::Model {
                        file: self.source.clone(),
                        line: f.line,
                        element: format!("ExternalForce \"{}\" > <{what}>", f.name),
                        message: format!(
                            "unknown body `{name}` (the model has no body of that name)"
                        ),
                    })
                };
                Ok([
                    find("applied_to_body", &f.applied_to_body)?,
                    find("force_expressed_in_body", &f.force_expressed_in_body)?,
                    find("point_expressed_in_body", &f.point_expressed_in_body)?,
                ])
            })
            .collect()
    }
}

/// Reads a PrescribedForce element (module documentation).
fn read_prescribed(
    functions: &FunctionReader,
    f: Node,
    name: String,
    line: u32,
) -> crate::Result<PrescribedForce> {
    let child = |tag: &str| f.children().find(|c| c.has_tag_name(tag));
    let text = |tag: &str| {
        child(tag)
            .map(|c| c.text().unwrap_or("").trim())
            .filter(|t| !t.is_empty() && *t != "Unassigned")
    };
    let flag = |tag: &str, default: bool| -> crate::Result<bool> {
        match text(tag) {
            None => Ok(default),
            Some("true") => Ok(true),
            Some("false") => Ok(false),
            Some(other) => Err(functions.err(
                child(tag).unwrap_or(f),
                format!("`{other}` is not `true` or `false`"),
            )),
        }
    };
    // OpenSim 4 names a frame by path (`/bodyset/calcn_r`); OpenSim 3 a body.
    let body = text("frame_name")
        .or_else(|| text("body"))
        .map(|t| t.rsplit('/').next().unwrap_or(t).to_string())
        .ok_or_else(|| {
            functions.err(
                f,
                "missing <body> (OpenSim 3) or <frame_name> (OpenSim 4): the body the force \
                 is applied to",
            )
        })?;
    let mut time_span: Option<[f64; 2]> = None;
    let mut set = |which: &str| -> crate::Result<Option<[Function; 3]>> {
        // OpenSim 3 writes `<FunctionSet name="forceFunctions">`, OpenSim 4 may write the
        // property's own tag.
        let Some(node) = f.children().find(|c| {
            c.has_tag_name(which)
                || (c.has_tag_name("FunctionSet") && c.attribute("name") == Some(which))
        }) else {
            return Ok(None);
        };
        let holder = node
            .children()
            .find(|c| c.has_tag_name("objects"))
            .unwrap_or(node);
        let members: Vec<Node> = holder
            .children()
            .filter(|c| c.is_element() && !c.has_tag_name("groups"))
            .collect();
        match members.len() {
            0 => return Ok(None),
            3 => {}
            n => {
                return Err(functions.err(
                    node,
                    format!("{which} must hold 3 functions (x, y, z), found {n}"),
                ));
            }
        }
        let mut read = |m: Node| -> crate::Result<Function> {
            if !FunctionReader::is_function(m) {
                return Err(
                    functions.err(m, format!("<{}> is not a function", m.tag_name().name()))
                );
            }
            let function = functions.read(m)?;
            if !matches!(function.arity(), Arity::Any | Arity::Exactly(1)) {
                return Err(functions.err(m, "a function of time takes one argument"));
            }
            let knots = m
                .children()
                .find(|c| c.has_tag_name("x"))
                .and_then(|x| x.text())
                .map(|t| t.split_whitespace().filter_map(|v| v.parse::<f64>().ok()));
            if let Some(mut knots) = knots
                && let Some(first) = knots.next()
            {
                let last = knots.next_back().unwrap_or(first);
                let span = time_span.get_or_insert([first, last]);
                *span = [span[0].min(first), span[1].max(last)];
            }
            Ok(function)
        };
        Ok(Some([
            read(members[0])?,
            read(members[1])?,
            read(members[2])?,
        ]))
    };
    let force = set("forceFunctions")?;
    let point = set("pointFunctions")?;
    let torque = set("torqueFunctions")?;
    if force.is_none() && torque.is_none() {
        return Err(functions.err(f, "no force and no torque functions: it applies nothing"));
    }
    Ok(PrescribedForce {
        name,
        body,
        force_is_global: flag("forceIsGlobal", true)?,
        point_is_global: flag("pointIsGlobal", false)?,
        force,
        point,
        torque,
        time_span,
        line,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const XML: &str = r#"<OpenSimDocument Version="40000"><ExternalLoads name="x"><objects>
        <ExternalForce name="right"><applied_to_body> calcn_r </applied_to_body>
          <force_expressed_in_body>ground</force_expressed_in_body><point_expressed_in_body>ground</point_expressed_in_body>
          <force_identifier>ground_force_v</force_identifier><point_identifier>ground_force_p</point_identifier>
          <torque_identifier>ground_torque_</torque_identifier><data_source_name>Unassigned</data_source_name></ExternalForce>
        <ExternalForce name="off"><isDisabled>true</isDisabled><applied_to_body>calcn_l</applied_to_body></ExternalForce>
        </objects><datafile> grf.mot </datafile></ExternalLoads></OpenSimDocument>"#;

    #[test]
    fn reads_forces_identifiers_and_the_data_file() {
        let l = ExternalLoads::parse(XML, "loads.xml").unwrap();
        assert_eq!(l.forces.len(), 1, "disabled forces are dropped");
        let f = &l.forces[0];
        assert_eq!(f.applied_to_body, "calcn_r");
        assert_eq!(f.force_identifier.as_deref(), Some("ground_force_v"));
        assert_eq!(l.datafile, Some(PathBuf::from("grf.mot")));
    }

    #[test]
    fn an_unknown_body_is_an_error_naming_the_force_and_line() {
        let l = ExternalLoads::parse(XML, "loads.xml").unwrap();
        let e = l.bodies(&Model::demo()).unwrap_err().to_string();
        assert!(
            e.contains("loads.xml:2")
                && e.contains("ExternalForce \"right\"")
                && e.contains("calcn_r"),
            "{e}"
        );
    }
}
