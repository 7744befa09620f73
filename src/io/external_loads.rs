//! OpenSim ExternalLoads files (`.xml`): the external forces (typically ground-reaction forces
//! from force plates) applied to named bodies, with the columns of a data file that hold
//! each force vector, its point of application and a torque.
//!
//! For an ExternalForce with `force_identifier` "ground_force_v", the force is the columns
//! `ground_force_vx`, `…vy`, `…vz`; the point `…px`, `…py`, `…pz`; the torque
//! `ground_torque_x`, `…y`, `…z` (identifier + x/y/z), as OpenSim names them. Each is
//! expressed in the frame of the body named by `force_expressed_in_body` /
//! `point_expressed_in_body` (usually ground).

use crate::error::Error;
use crate::model::Model;
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

/// An ExternalLoads file.
#[derive(Clone, Debug, PartialEq)]
pub struct ExternalLoads {
    /// The file read (for messages).
    pub source: String,
    /// The data file (`datafile`), resolved relative to the ExternalLoads file.
    pub datafile: Option<PathBuf>,
    pub forces: Vec<ExternalForce>,
}

impl ExternalLoads {
    pub fn read(path: &Path) -> crate::Result<ExternalLoads> {
        let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut loads = Self::parse(&text, &path.display().to_string())?;
        if let Some(d) = &loads.datafile {
            if d.is_relative() {
                loads.datafile = Some(path.parent().unwrap_or(Path::new(".")).join(d));
            }
        }
        Ok(loads)
    }

    pub fn parse(text: &str, source: &str) -> crate::Result<ExternalLoads> {
        let doc = roxmltree::Document::parse(text).map_err(|e| Error::Xml {
            file: source.to_string(),
            line: e.pos().row,
            column: e.pos().col,
            message: e.to_string(),
        })?;
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
        let objects = root.children().find(|c| c.has_tag_name("objects"));
        for f in objects
            .iter()
            .flat_map(|o| o.children())
            .filter(|c| c.is_element())
        {
            let name = f.attribute("name").unwrap_or("").to_string();
            let element = format!("{} \"{name}\"", f.tag_name().name());
            if !f.has_tag_name("ExternalForce") {
                return Err(err(
                    f,
                    element,
                    "unsupported element: only ExternalForce is read".into(),
                ));
            }
            let disabled = text_of(f, "isDisabled").is_some_and(|v| v == "true")
                || text_of(f, "appliesForce").is_some_and(|v| v == "false");
            if disabled {
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
        })
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
