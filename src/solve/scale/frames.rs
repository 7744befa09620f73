//! The model file's components located in its XML: component paths, physical frames
//! resolved to their base body (following `socket_parent` chains of offset frames), and small
//! element helpers shared by the scaling and marker code.

use crate::spatial::{Transform, Vec3};
use roxmltree::{Document, Node};
use std::collections::HashMap;

/// The component path of an element: the names of its named ancestors below `<Model>`
/// (`/jointset/hip_r/pelvis_offset`); an unnamed set is named by its lower-case tag.
pub(super) fn component_path(n: Node) -> String {
    let mut parts: Vec<String> = Vec::new();
    for a in n.ancestors().filter(Node::is_element) {
        let tag = a.tag_name().name();
        if tag == "Model" || tag == "OpenSimDocument" {
            break;
        }
        match a.attribute("name").map(str::trim) {
            Some(name) if !name.is_empty() => parts.push(name.to_string()),
            _ if tag.ends_with("Set") => parts.push(tag.to_ascii_lowercase()),
            _ => {}
        }
    }
    parts.reverse();
    format!("/{}", parts.join("/"))
}

/// The first non-blank text child of an element.
pub(super) fn text_node<'a, 'i>(n: Node<'a, 'i>) -> Option<Node<'a, 'i>> {
    n.children()
        .find(|c| c.is_text() && !c.text().unwrap_or("").trim().is_empty())
}

pub(super) fn child<'a, 'i>(n: Node<'a, 'i>, tag: &str) -> Option<Node<'a, 'i>> {
    n.children().find(|c| c.is_element() && c.has_tag_name(tag))
}

pub(super) fn line_of(doc: &Document, n: Node) -> u32 {
    doc.text_pos_at(n.range().start).row
}

/// Numbers of an element's text (None if one is not a number).
pub(super) fn numbers(n: Node) -> Option<Vec<f64>> {
    n.text()
        .unwrap_or("")
        .split_whitespace()
        .map(|t| t.parse().ok())
        .collect()
}

/// A frame of the model file: a body (or ground), or an offset from another frame.
struct FrameDef {
    body: Option<String>,
    /// For an offset frame: its own path (owner of the socket) and `socket_parent`.
    parent: Option<(String, String)>,
    offset: Transform,
}

/// The physical frames of a model file, resolved to their base body.
pub(super) struct Frames {
    defs: HashMap<String, FrameDef>,
}

impl Frames {
    pub(super) fn new(doc: &Document) -> Frames {
        let mut defs = HashMap::new();
        for n in doc.descendants().filter(Node::is_element) {
            let tag = n.tag_name().name();
            if !matches!(tag, "Ground" | "Body" | "PhysicalOffsetFrame") {
                continue;
            }
            // (built only for frames: walking every element's ancestors cost more than the
            // rest of this pass)
            let path = component_path(n);
            match tag {
                "Ground" => {
                    defs.insert(
                        path,
                        FrameDef {
                            body: Some("ground".into()),
                            parent: None,
                            offset: Transform::identity(),
                        },
                    );
                }
                "Body"
                    if n.parent_element()
                        .is_some_and(|p| p.has_tag_name("objects")) =>
                {
                    let name = n.attribute("name").unwrap_or("").trim().to_string();
                    defs.insert(
                        path,
                        FrameDef {
                            body: Some(name),
                            parent: None,
                            offset: Transform::identity(),
                        },
                    );
                }
                "PhysicalOffsetFrame" => {
                    let vec = |tag: &str| {
                        child(n, tag)
                            .and_then(numbers)
                            .filter(|v| v.len() == 3)
                            .map(|v| Vec3::new(v[0], v[1], v[2]))
                            .unwrap_or_else(Vec3::zeros)
                    };
                    let socket = child(n, "socket_parent")
                        .and_then(|s| s.text())
                        .unwrap_or("")
                        .trim()
                        .to_string();
                    defs.insert(
                        path.clone(),
                        FrameDef {
                            body: None,
                            parent: Some((path, socket)),
                            offset: Transform::from_translation_xyz_body(
                                vec("translation"),
                                vec("orientation"),
                            ),
                        },
                    );
                }
                _ => {}
            }
        }
        Frames { defs }
    }

    /// The base body of the frame `socket` names (relative to the component at `owner`)
    /// and the pose of that frame in the body.
    pub(super) fn resolve(&self, owner: &str, socket: &str) -> Result<(String, Transform), String> {
        self.resolve_depth(owner, socket.trim(), 0)
    }

    fn resolve_depth(
        &self,
        owner: &str,
        socket: &str,
        depth: usize,
    ) -> Result<(String, Transform), String> {
        if depth > 64 {
            return Err(format!("offset frames form a cycle through `{socket}`"));
        }
        let abs = crate::model::resolve_path(owner, socket);
        let key = if self.defs.contains_key(&abs) {
            abs
        } else if !socket.contains('/') && !socket.is_empty() {
            // Files of older OpenSim versions name frames by their bare name.
            let hits: Vec<&String> = (self.defs.keys())
                .filter(|p| p.rsplit('/').next() == Some(socket))
                .collect();
            match hits.len() {
                1 => hits[0].clone(),
                0 => return Err(format!("no frame or body `{socket}`")),
                _ => return Err(format!("frame name `{socket}` is ambiguous")),
            }
        } else {
            return Err(format!("no frame or body at `{abs}`"));
        };
        let def = &self.defs[&key];
        if let Some(body) = &def.body {
            return Ok((body.clone(), Transform::identity()));
        }
        let (own, parent) = def.parent.as_ref().expect("offset frames have a parent");
        let (body, x) = self.resolve_depth(own, parent, depth + 1)?;
        Ok((body, x.compose(&def.offset)))
    }
}
