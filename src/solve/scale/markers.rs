//! The model's marker set through the Scale tool, and the files it writes:
//!
//! - [`merge_marker_set`]: `GenericModelMaker`'s `marker_set_file` — each marker of the file
//!   replaces the model's marker of the same name or joins the set (OpenSim's
//!   `Model::updateMarkerSet`: a replaced marker moves to the end of the set). Markers are
//!   written in the OpenSim 4 form (`socket_parent_frame`, `location`, `fixed`); an
//!   OpenSim 3 `<body>` becomes `/bodyset/<body>`.
//! - [`keep_markers`]: `MarkerPlacer` drops the model markers absent from the static trial.
//! - [`set_marker_locations`]: the placed markers' new locations.
//! - [`marker_set_file`], [`scale_set_file`]: OpenSim `MarkerSet` and `ScaleSet` documents
//!   (`output_marker_file`, `output_scale_file`).
//!
//! Apart from the marker set, the text of the model is kept byte for byte.

use super::ScaleSet;
use super::frames::{Frames, child, component_path, text_node};
use crate::error::Error;
use crate::io::scale_setup::{MarkerDef, MarkerParent};
use crate::model::Model;
use crate::spatial::Vec3;
use roxmltree::{Document, Node};
use std::ops::Range;

/// XML-escapes an attribute or text value.
fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The `<MarkerSet>` directly under `<Model>`.
fn marker_set<'a, 'i>(doc: &'a Document<'i>) -> Option<Node<'a, 'i>> {
    let model = doc
        .root_element()
        .children()
        .find(|c| c.has_tag_name("Model"))?;
    child(model, "MarkerSet")
}

/// The markers of the model's marker set (element nodes).
fn marker_nodes<'a, 'i>(doc: &'a Document<'i>) -> Vec<Node<'a, 'i>> {
    marker_set(doc)
        .and_then(|s| child(s, "objects"))
        .map(|o| o.children().filter(|c| c.has_tag_name("Marker")).collect())
        .unwrap_or_default()
}

/// The indentation (tabs/spaces) of the line holding byte `at`.
fn indent_at(xml: &str, at: usize) -> &str {
    let start = xml[..at].rfind('\n').map_or(0, |i| i + 1);
    let line = &xml[start..at];
    &line[..line.len() - line.trim_start().len()]
}

/// An element's range widened to its whole line(s) when it stands alone on them.
fn line_range(xml: &str, r: Range<usize>) -> Range<usize> {
    let start = xml[..r.start].rfind('\n').map_or(0, |i| i + 1);
    let end = xml[r.end..].find('\n').map_or(xml.len(), |i| r.end + i + 1);
    if xml[start..r.start].trim().is_empty() && xml[r.end..end].trim().is_empty() {
        start..end
    } else {
        r
    }
}

/// Replaces byte ranges (sorted, disjoint) by new text.
pub(super) fn splice(xml: &str, mut parts: Vec<(Range<usize>, String)>) -> String {
    parts.sort_by_key(|p| p.0.start);
    let mut out = String::with_capacity(xml.len());
    let mut at = 0;
    for (r, text) in parts {
        out.push_str(&xml[at..r.start]);
        out.push_str(&text);
        at = r.end;
    }
    out.push_str(&xml[at..]);
    out
}

/// One marker in OpenSim 4 form, each line starting with `indent`.
fn marker_xml(name: &str, frame: &str, location: Vec3, fixed: bool, indent: &str) -> String {
    format!(
        "{indent}<Marker name=\"{}\">\n{indent}\t<socket_parent_frame>{}</socket_parent_frame>\n\
         {indent}\t<location>{} {} {}</location>\n{indent}\t<fixed>{fixed}</fixed>\n\
         {indent}</Marker>\n",
        escape(name),
        escape(frame),
        location.x,
        location.y,
        location.z
    )
}

/// GenericModelMaker: the model text with the markers of a marker-set file merged in
/// (same name: replaced and moved to the end; new name: appended). `model` is `xml`
/// parsed; a marker whose body or frame is not in the model is an error at its line.
pub fn merge_marker_set(
    xml: &str,
    source: &str,
    model: &Model,
    markers: &[MarkerDef],
) -> crate::Result<String> {
    let doc = super::parse_document(xml, source)?;
    let frames = Frames::new(&doc);
    let mut parts: Vec<(Range<usize>, String)> = Vec::new();
    let existing = marker_nodes(&doc);
    for n in &existing {
        let name = n.attribute("name").unwrap_or("");
        if markers.iter().any(|m| m.name == name) {
            parts.push((line_range(xml, n.range()), String::new()));
        }
    }
    let set = marker_set(&doc);
    let objects = set.and_then(|s| child(s, "objects"));
    let base = match (set, objects) {
        (_, Some(o)) => indent_at(xml, o.range().start).to_string(),
        (Some(s), None) => indent_at(xml, s.range().start).to_string() + "\t",
        (None, None) => "\t\t".to_string(),
    };
    let inner = format!("{base}\t");
    let mut new_markers = String::new();
    for m in markers {
        let frame = match &m.parent {
            MarkerParent::Body(b) => {
                if model.body_index(b).is_none() {
                    return Err(m.place.error(format!("no body \"{b}\" in {source}")));
                }
                if b == "ground" {
                    "/ground".to_string()
                } else {
                    format!("/bodyset/{b}")
                }
            }
            MarkerParent::Frame(f) => {
                frames
                    .resolve(&format!("/markerset/{}", m.name), f)
                    .map_err(|e| m.place.error(format!("{e} in {source}")))?;
                f.clone()
            }
        };
        new_markers.push_str(&marker_xml(&m.name, &frame, m.location, m.fixed, &inner));
    }
    match (set, objects) {
        (_, Some(o)) if o.children().any(|c| c.is_element() || c.is_text()) => {
            // before `</objects>`, on its own line
            let close = xml[o.range()]
                .rfind("</objects>")
                .map(|i| o.range().start + i);
            let close = close.ok_or_else(|| Error::Model {
                file: source.to_string(),
                line: super::apply::line_number(xml, o.range().start),
                element: "MarkerSet > objects".into(),
                message: "cannot find `</objects>`".into(),
            })?;
            let line_start = xml[..close].rfind('\n').map_or(0, |i| i + 1);
            let at = if xml[line_start..close].trim().is_empty() {
                line_start
            } else {
                new_markers.insert(0, '\n');
                close
            };
            parts.push((at..at, new_markers));
        }
        (_, Some(o)) => {
            parts.push((
                o.range(),
                format!("<objects>\n{new_markers}{base}</objects>"),
            ));
        }
        (Some(s), None) => {
            let close = xml[s.range()]
                .rfind("</MarkerSet>")
                .map(|i| s.range().start + i);
            let text = format!(
                "\t<objects>\n{new_markers}{base}</objects>\n{}",
                indent_at(xml, s.range().start)
            );
            match close {
                Some(c) => parts.push((c..c, text)),
                None => parts.push((
                    s.range(),
                    format!("<MarkerSet name=\"markerset\">\n{base}{text}</MarkerSet>"),
                )),
            }
        }
        (None, None) => {
            let model_node = doc
                .root_element()
                .children()
                .find(|c| c.has_tag_name("Model"));
            let Some(model_node) = model_node else {
                return Err(Error::Model {
                    file: source.to_string(),
                    line: 1,
                    element: "OpenSimDocument".into(),
                    message: "no <Model> element".into(),
                });
            };
            let close = xml[model_node.range()]
                .rfind("</Model>")
                .map(|i| model_node.range().start + i);
            let Some(close) = close else {
                return Err(Error::Model {
                    file: source.to_string(),
                    line: 1,
                    element: "Model".into(),
                    message: "cannot find `</Model>`".into(),
                });
            };
            parts.push((
                close..close,
                format!(
                    "\t<MarkerSet name=\"markerset\">\n{base}<objects>\n{new_markers}{base}</objects>\n\
                     {base}<groups />\n\t\t</MarkerSet>\n\t"
                ),
            ));
        }
    }
    Ok(splice(xml, parts))
}

/// MarkerPlacer's first step: the model text without the markers for which `keep` is false.
/// Returns the text and the names dropped.
pub fn keep_markers(
    xml: &str,
    source: &str,
    keep: impl Fn(&str) -> bool,
) -> crate::Result<(String, Vec<String>)> {
    let doc = super::parse_document(xml, source)?;
    let mut parts = Vec::new();
    let mut dropped = Vec::new();
    for n in marker_nodes(&doc) {
        let name = n.attribute("name").unwrap_or("");
        if !keep(name) {
            parts.push((line_range(xml, n.range()), String::new()));
            dropped.push(name.to_string());
        }
    }
    Ok((splice(xml, parts), dropped))
}

/// The pose of each model marker's parent frame in its body, by marker name (for writing a
/// location given in the body back in the marker's own frame).
pub fn marker_frames(
    xml: &str,
    source: &str,
) -> crate::Result<Vec<(String, crate::spatial::Transform)>> {
    let doc = super::parse_document(xml, source)?;
    let frames = Frames::new(&doc);
    let mut out = Vec::new();
    for n in marker_nodes(&doc) {
        let socket = child(n, "socket_parent_frame")
            .and_then(|s| s.text())
            .unwrap_or("");
        let (_, x) = frames
            .resolve(&component_path(n), socket)
            .map_err(|e| Error::Model {
                file: source.to_string(),
                line: doc.text_pos_at(n.range().start).row,
                element: format!("Marker \"{}\"", n.attribute("name").unwrap_or("")),
                message: e,
            })?;
        out.push((n.attribute("name").unwrap_or("").to_string(), x));
    }
    Ok(out)
}

/// The model text with the named markers' `location` (in their parent frame) replaced.
pub fn set_marker_locations(
    xml: &str,
    source: &str,
    locations: &[(String, Vec3)],
) -> crate::Result<String> {
    let doc = super::parse_document(xml, source)?;
    let mut parts = Vec::new();
    for n in marker_nodes(&doc) {
        let name = n.attribute("name").unwrap_or("");
        let Some((_, p)) = locations.iter().find(|(m, _)| m == name) else {
            continue;
        };
        let text = child(n, "location")
            .and_then(text_node)
            .ok_or_else(|| Error::Model {
                file: source.to_string(),
                line: doc.text_pos_at(n.range().start).row,
                element: format!("Marker \"{name}\""),
                message: "no <location> to rewrite".into(),
            })?;
        parts.push((text.range(), format!("{} {} {}", p.x, p.y, p.z)));
    }
    Ok(splice(xml, parts))
}

/// The model's marker set as an OpenSim `MarkerSet` document (`output_marker_file`),
/// markers copied verbatim from the model text.
pub fn marker_set_file(xml: &str, source: &str) -> crate::Result<String> {
    let doc = super::parse_document(xml, source)?;
    let body = match marker_set(&doc) {
        Some(s) => {
            let indent = indent_at(xml, s.range().start);
            let text = &xml[s.range()];
            // re-indent to one tab under OpenSimDocument
            text.lines()
                .map(|l| l.strip_prefix(indent).unwrap_or(l))
                .map(|l| format!("\t{l}"))
                .collect::<Vec<_>>()
                .join("\n")
        }
        None => "\t<MarkerSet name=\"markerset\">\n\t\t<objects />\n\t\t<groups />\n\t</MarkerSet>"
            .to_string(),
    };
    Ok(format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\" ?>\n<OpenSimDocument Version=\"40600\">\n{}\n</OpenSimDocument>\n",
        body
    ))
}

/// An OpenSim `ScaleSet` document (`output_scale_file`) listing, as OpenSim's ModelScaler
/// does, ground, every body (in file order) and every offset frame — each with its factors
/// from `scales`, 1 1 1 otherwise (OpenSim never uses an offset frame's entry).
pub fn scale_set_file(scales: &ScaleSet, xml: &str, source: &str) -> crate::Result<String> {
    let doc = super::parse_document(xml, source)?;
    let mut names: Vec<String> = vec!["ground".into()];
    for n in doc.descendants().filter(Node::is_element) {
        let is_body = n.has_tag_name("Body")
            && n.parent_element()
                .is_some_and(|p| p.has_tag_name("objects"));
        if is_body || n.has_tag_name("PhysicalOffsetFrame") {
            names.push(n.attribute("name").unwrap_or("").to_string());
        }
    }
    let mut out = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\" ?>\n<OpenSimDocument Version=\"40600\">\n\
         \t<ScaleSet name=\"ScaleSet\">\n\t\t<objects>\n",
    );
    for name in names {
        let f = scales.get(&name).unwrap_or(Vec3::new(1.0, 1.0, 1.0));
        out.push_str(&format!(
            "\t\t\t<Scale>\n\t\t\t\t<scales> {} {} {}</scales>\n\t\t\t\t<segment>{}</segment>\n\
             \t\t\t\t<apply>true</apply>\n\t\t\t</Scale>\n",
            f.x,
            f.y,
            f.z,
            escape(&name)
        ));
    }
    out.push_str("\t\t</objects>\n\t\t<groups />\n\t</ScaleSet>\n</OpenSimDocument>\n");
    Ok(out)
}

/// The model text with the `<Model name="…">` attribute set to `name` (OpenSim's Scale tool
/// names the scaled model after the setup).
pub fn rename_model(xml: &str, source: &str, name: &str) -> crate::Result<String> {
    let doc = super::parse_document(xml, source)?;
    let Some(model) = doc
        .root_element()
        .children()
        .find(|c| c.has_tag_name("Model"))
    else {
        return Ok(xml.to_string());
    };
    let Some(attr) = model.attributes().find(|a| a.name() == "name") else {
        return Ok(xml.to_string());
    };
    Ok(splice(xml, vec![(attr.range_value(), escape(name))]))
}
