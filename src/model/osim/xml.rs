//! Small helpers over roxmltree for reading OpenSim XML with error context: every error
//! names the file, the line and the element (as a path of named ancestors).

use crate::error::Error;
use crate::model::{RawElement, Warning, WarningKind};
use crate::spatial::Vec3;
use roxmltree::{Document, Node};

pub type XNode<'a, 'i> = Node<'a, 'i>;

/// Parsing context: the document, its file name, and the warnings collected so far.
pub struct Ctx<'a, 'i> {
    pub doc: std::marker::PhantomData<&'a Document<'i>>,
    pub file: &'a str,
    pub warnings: Vec<Warning>,
    pub visual: usize,
    /// The document is older than Version 30500: whitespace in a component name is removed
    /// with a warning instead of refused, as OpenSim does.
    pub legacy_whitespace_in_names: bool,
    /// Byte offset of the start of every line, for line numbers by binary search.
    line_starts: Vec<usize>,
}

/// The characters OpenSim 4 refuses in a component name (`ComponentPath`'s invalid
/// characters: the path separator `/`, and `\\ * +`, space, tab, newline).
pub const INVALID_NAME_CHARS: &str = "/\\*+ \t\n";

/// Display-only elements: skipped and counted, never needed for dynamics.
pub const VISUAL_TAGS: &[&str] = &[
    "FrameGeometry",
    "attached_geometry",
    "Appearance",
    "SurfaceProperties",
    "Mesh",
    "Brick",
    "Sphere",
    "Cylinder",
    "Ellipsoid",
    "Cone",
    "Arrow",
    "Line",
    "Torus",
    "visible",
    "geometry",
    "GeometrySet",
    "DisplayGeometry",
    "VisibleObject",
];

impl<'a, 'i> Ctx<'a, 'i> {
    pub fn new(doc: &'a Document<'i>, file: &'a str) -> Self {
        let text = doc.input_text();
        let line_starts = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        Ctx {
            doc: std::marker::PhantomData,
            file,
            warnings: Vec::new(),
            visual: 0,
            legacy_whitespace_in_names: false,
            line_starts,
        }
    }

    /// 1-based line of the element's start.
    pub fn line(&self, node: XNode) -> u32 {
        self.line_starts
            .partition_point(|&s| s <= node.range().start) as u32
    }

    /// `JointSet > CustomJoint "knee_r" > SpatialTransform > TransformAxis "translation1"`.
    pub fn describe(&self, node: XNode) -> String {
        let mut parts: Vec<String> = node
            .ancestors()
            .filter(|n| n.is_element())
            .take_while(|n| {
                n.tag_name().name() != "Model" && n.tag_name().name() != "OpenSimDocument"
            })
            .filter(|n| n.tag_name().name() != "objects")
            .map(|n| match n.attribute("name") {
                Some(name) => format!("{} \"{}\"", n.tag_name().name(), name),
                None => format!("<{}>", n.tag_name().name()),
            })
            .collect();
        parts.reverse();
        if parts.is_empty() {
            format!("<{}>", node.tag_name().name())
        } else {
            parts.join(" > ")
        }
    }

    pub fn err(&self, node: XNode, message: impl Into<String>) -> Error {
        Error::Model {
            file: self.file.to_string(),
            line: self.line(node),
            element: self.describe(node),
            message: message.into(),
        }
    }

    pub fn warn(&mut self, node: XNode, message: impl Into<String>) {
        self.warn_kind(node, WarningKind::NotUsed, message);
    }

    pub fn warn_kind(&mut self, node: XNode, kind: WarningKind, message: impl Into<String>) {
        let w = Warning {
            line: self.line(node),
            element: self.describe(node),
            message: message.into(),
            kind,
        };
        self.warnings.push(w);
    }

    /// Warns about an element the parser does not know at this place.
    pub fn unknown(&mut self, node: XNode) {
        if VISUAL_TAGS.contains(&node.tag_name().name()) {
            self.visual += 1;
        } else {
            self.warn(node, "element not recognised by musculo; ignored");
        }
    }

    /// The text of the child element `tag`, trimmed.
    pub fn text(&self, node: XNode<'a, 'i>, tag: &str) -> Option<&'a str> {
        child(node, tag).map(|c| c.text().unwrap_or("").trim())
    }

    /// A required child's text.
    pub fn req_text(&self, node: XNode<'a, 'i>, tag: &str) -> Result<&'a str, Error> {
        self.text(node, tag)
            .ok_or_else(|| self.err(node, format!("missing <{tag}>")))
    }

    pub fn numbers(&self, node: XNode, tag: &str, text: &str) -> Result<Vec<f64>, Error> {
        text.split_whitespace()
            .map(|t| {
                let v: f64 = t
                    .parse()
                    .map_err(|_| self.err(node, format!("<{tag}>: `{t}` is not a number")))?;
                if v.is_finite() {
                    Ok(v)
                } else {
                    Err(self.err(node, format!("<{tag}>: `{t}` is not a finite number")))
                }
            })
            .collect()
    }

    /// Optional list of numbers in child `tag` (empty if absent).
    pub fn vec_opt(&self, node: XNode<'a, 'i>, tag: &str) -> Result<Option<Vec<f64>>, Error> {
        match child(node, tag) {
            None => Ok(None),
            Some(c) => self.numbers(c, tag, c.text().unwrap_or("")).map(Some),
        }
    }

    /// A number in child `tag`, or `default` when the child is absent.
    pub fn f64_or(&self, node: XNode<'a, 'i>, tag: &str, default: f64) -> Result<f64, Error> {
        match child(node, tag) {
            None => Ok(default),
            Some(c) => {
                let v = self.numbers(c, tag, c.text().unwrap_or(""))?;
                if v.len() != 1 {
                    return Err(self.err(
                        c,
                        format!("<{tag}> must hold one number, found {}", v.len()),
                    ));
                }
                Ok(v[0])
            }
        }
    }

    pub fn req_f64(&self, node: XNode<'a, 'i>, tag: &str) -> Result<f64, Error> {
        if child(node, tag).is_none() {
            return Err(self.err(node, format!("missing <{tag}>")));
        }
        self.f64_or(node, tag, 0.0)
    }

    /// A 3-vector in child `tag`, or `default`.
    pub fn vec3_or(&self, node: XNode<'a, 'i>, tag: &str, default: Vec3) -> Result<Vec3, Error> {
        match child(node, tag) {
            None => Ok(default),
            Some(c) => {
                let v = self.numbers(c, tag, c.text().unwrap_or(""))?;
                if v.len() != 3 {
                    return Err(
                        self.err(c, format!("<{tag}> must hold 3 numbers, found {}", v.len()))
                    );
                }
                Ok(Vec3::new(v[0], v[1], v[2]))
            }
        }
    }

    pub fn bool_or(&self, node: XNode<'a, 'i>, tag: &str, default: bool) -> Result<bool, Error> {
        match child(node, tag) {
            None => Ok(default),
            Some(c) => match c.text().unwrap_or("").trim() {
                "true" | "1" => Ok(true),
                "false" | "0" => Ok(false),
                other => Err(self.err(c, format!("<{tag}>: `{other}` is not true or false"))),
            },
        }
    }

    /// The `name` attribute of a component (body, joint, coordinate, force, path point,
    /// marker, frame, …): required, and without the characters OpenSim 4 refuses in component
    /// names (see [`check_component_name`](Self::check_component_name)).
    pub fn name(&mut self, node: XNode) -> Result<String, Error> {
        let name = self.object_name(node)?;
        self.check_component_name(node, name)
    }

    /// The `name` attribute of an OpenSim object that is not a component (a `TransformAxis`),
    /// whose name is no element of a component path: required, not otherwise checked.
    pub fn object_name(&self, node: XNode) -> Result<String, Error> {
        match node.attribute("name") {
            Some(n) if !n.trim().is_empty() => Ok(n.trim().to_string()),
            _ => Err(self.err(node, "missing or empty `name` attribute")),
        }
    }

    /// Refuses a component name holding one of [`INVALID_NAME_CHARS`], as OpenSim 4 does
    /// when it reads the model (`Component::finalizeFromProperties` throws
    /// `InvalidComponentName`): `/` is the separator of component paths, so `a/b` would name
    /// a different component, and as a coordinate or muscle name it would make output file
    /// names leave their folder. In a document older than Version 30500 OpenSim instead removes
    /// whitespace from the name, with a warning; so does this reader.
    pub fn check_component_name(&mut self, node: XNode, name: String) -> Result<String, Error> {
        let name = if self.legacy_whitespace_in_names && name.contains(char::is_whitespace) {
            let stripped: String = name.chars().filter(|c| !c.is_whitespace()).collect();
            self.warn(
                node,
                format!(
                    "name \"{name}\" contains whitespace, which OpenSim 4 does not allow in \
                     names; renamed \"{stripped}\" as OpenSim renames it in files older than \
                     Version 30500"
                ),
            );
            stripped
        } else {
            name
        };
        if let Some(bad) = name.chars().find(|c| INVALID_NAME_CHARS.contains(*c)) {
            return Err(self.err(
                node,
                format!(
                    "name \"{}\" contains {}: OpenSim forbids `/`, `\\`, `*`, `+`, spaces, \
                     tabs and line breaks in component names (`/` separates the names \
                     in a component path)",
                    name.escape_debug(),
                    match bad {
                        ' ' => "a space".to_string(),
                        '\t' => "a tab".to_string(),
                        '\n' => "a line break".to_string(),
                        c => format!("`{c}`"),
                    }
                ),
            ));
        }
        Ok(name)
    }

    /// A verbatim copy of an element tree.
    pub fn raw(&self, node: XNode) -> RawElement {
        RawElement {
            tag: node.tag_name().name().to_string(),
            name: node.attribute("name").map(str::to_string),
            text: node
                .children()
                .filter(|c| c.is_text())
                .filter_map(|c| c.text())
                .collect::<String>()
                .trim()
                .to_string(),
            line: self.line(node),
            children: elements(node).map(|c| self.raw(c)).collect(),
        }
    }
}

/// Element children of `node`.
pub fn elements<'a, 'i>(node: XNode<'a, 'i>) -> impl Iterator<Item = XNode<'a, 'i>> {
    node.children().filter(|c| c.is_element())
}

/// The first element child with this tag.
pub fn child<'a, 'i>(node: XNode<'a, 'i>, tag: &str) -> Option<XNode<'a, 'i>> {
    node.children()
        .find(|c| c.is_element() && c.tag_name().name() == tag)
}

/// The members of a set: the children of its `<objects>` element (or of the set itself when
/// it has no `<objects>`), skipping `<groups>`.
pub fn set_members<'a, 'i>(set: XNode<'a, 'i>) -> Vec<XNode<'a, 'i>> {
    match child(set, "objects") {
        Some(objs) => elements(objs).collect(),
        None => elements(set)
            .filter(|c| c.tag_name().name() != "groups")
            .collect(),
    }
}
