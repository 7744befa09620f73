//! A model's mass properties written back into its OpenSim file: the text with every body's
//! `<mass>`, `<mass_center>` and `<inertia>` (about the mass centre, body axes:
//! `Ixx Iyy Izz Ixy Ixz Iyz`) set to a [`Model`]'s values, everything else verbatim — for a
//! model whose bodies were changed after it was read (a perturbed variant's mass scaling or
//! carried load), so that OpenSim and `musculo evaluate` see the body the motion was computed
//! on.

use super::frames::{child, text_node};
use super::markers::splice;
use crate::error::Error;
use crate::model::Model;
use roxmltree::Node;

/// `xml` (read as `source`) with the mass, mass centre and inertia of each of `model`'s bodies
/// (matched by name; every body but ground must be in the file).
pub fn set_inertial_properties(xml: &str, source: &str, model: &Model) -> crate::Result<String> {
    let doc = super::parse_document(xml, source)?;
    let mut parts = Vec::new();
    let mut written = vec![false; model.bodies.len()];
    for n in doc.descendants().filter(|n| {
        n.has_tag_name("Body")
            && n.parent_element()
                .is_some_and(|p| p.has_tag_name("objects"))
    }) {
        let name = n.attribute("name").unwrap_or("").trim();
        let Some(b) = model.body_index(name).filter(|&b| b > 0) else {
            continue;
        };
        let body = &model.bodies[b];
        let (c, i) = (body.com_in_body, &body.inertia_about_com);
        let values = [
            ("mass", format!("{}", body.mass)),
            ("mass_center", format!("{} {} {}", c.x, c.y, c.z)),
            ("inertia", crate::spatial::inertia_text(i)),
        ];
        for (tag, text) in values {
            let target = child(n, tag)
                .and_then(text_node)
                .ok_or_else(|| missing(&doc, n, source, tag))?;
            parts.push((target.range(), text));
        }
        written[b] = true;
    }
    if let Some(b) = (1..model.bodies.len()).find(|&b| !written[b]) {
        return Err(Error::invalid(
            "model",
            format!(
                "body `{}` is not in the model file {source}",
                model.bodies[b].name
            ),
        ));
    }
    Ok(splice(xml, parts))
}

fn missing(doc: &roxmltree::Document, n: Node, source: &str, tag: &str) -> Error {
    Error::Model {
        file: source.to_string(),
        line: doc.text_pos_at(n.range().start).row,
        element: format!("Body \"{}\"", n.attribute("name").unwrap_or("")),
        message: format!("no <{tag}> to rewrite"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rewritten_file_reads_back_to_the_changed_bodies() {
        let xml = crate::DEFAULT_MODEL_OSIM;
        let mut model = Model::from_osim_str(xml, "default").unwrap();
        let femur = model.body_index("femur_r").unwrap();
        model.bodies[femur].mass *= 1.3;
        model.bodies[femur].com_in_body.y -= 0.01;
        model.bodies[femur].inertia_about_com[(0, 1)] = 0.002;
        model.bodies[femur].inertia_about_com[(1, 0)] = 0.002;
        let text = set_inertial_properties(xml, "default", &model).unwrap();
        let back = Model::from_osim_str(&text, "rewritten").unwrap();
        for (a, b) in model.bodies.iter().zip(&back.bodies) {
            assert_eq!(a.name, b.name);
            assert_eq!(a.mass, b.mass, "{}", a.name);
            assert_eq!(a.com_in_body, b.com_in_body, "{}", a.name);
            assert_eq!(a.inertia_about_com, b.inertia_about_com, "{}", a.name);
        }
        // only the femur's three elements changed
        let changed = xml
            .lines()
            .zip(text.lines())
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(changed, 3);
        assert_eq!(xml.lines().count(), text.lines().count());
    }
}
