//! OpenSim Scale tool setup files (`ScaleTool`, OpenSim 3 and 4 versions) and the marker-set
//! files they name.
//!
//! A `ScaleTool` holds three parts, each optional:
//!
//! - `GenericModelMaker`: the unscaled `model_file` and a `marker_set_file` whose markers
//!   replace (same name) or join the model's markers before anything else happens.
//! - `ModelScaler`: `scaling_order` (`measurements`, `manualScale`, singly or both in any
//!   order), a `MeasurementSet` (per measurement: marker pairs and the bodies and axes it
//!   scales), a manual `ScaleSet` (per body: three factors), the static trial `marker_file`
//!   and the `time_range` over which marker-pair distances are averaged,
//!   `preserve_mass_distribution`, and the outputs `output_model_file`, `output_scale_file`.
//! - `MarkerPlacer`: an `IKTaskSet` (marker and coordinate weights of the static-pose IK),
//!   the static trial `marker_file`, a `coordinate_file` for `from_file` coordinate tasks,
//!   the `time_range` averaged, `max_marker_movement`, and the outputs `output_model_file`,
//!   `output_marker_file`, `output_motion_file`.
//!
//! As in OpenSim, file names are relative to the setup file's folder, `Unassigned` or an
//! empty value means "not set", a set given as `<MeasurementSet file="m.xml"/>` (also
//! `ScaleSet`, `IKTaskSet`) is read from that file (relative to the setup's folder), and
//! `<mass>` ≤ 0 means "keep the scaled model's mass". Every measurement, marker pair, body
//! scale, manual scale and task keeps its file and line ([`Place`]) so that the scaling can
//! name them in errors.
//!
//! Informational settings (`height`, `age`, `notes`) are read silently; elements that
//! musculo does not know are returned as [`SetupWarning`]s. Malformed values (a word where a
//! number belongs, an axis other than X/Y/Z, a marker pair of three markers, a scaling step
//! other than `measurements`/`manualScale`) are [`Error::Model`] naming the file, line and
//! element.

use crate::error::Error;
use crate::io::setup::{Reader, SetupWarning, base_dir, parse_xml, read_text};
use crate::spatial::Vec3;
use roxmltree::Node;
use std::path::{Path, PathBuf};

/// Where an element was read: file and 1-based line.
#[derive(Clone, Debug, PartialEq)]
pub struct Place {
    pub file: String,
    pub line: u32,
    /// The element, e.g. `Measurement "thigh" > MarkerPair`.
    pub element: String,
}

impl Place {
    /// An [`Error::Model`] at this place.
    pub fn error(&self, message: impl Into<String>) -> Error {
        Error::Model {
            file: self.file.clone(),
            line: self.line,
            element: self.element.clone(),
            message: message.into(),
        }
    }

    /// A [`SetupWarning`] at this place.
    pub fn warning(&self, message: impl Into<String>) -> SetupWarning {
        SetupWarning {
            file: self.file.clone(),
            line: self.line,
            element: self.element.clone(),
            message: message.into(),
        }
    }
}

/// One step of `scaling_order`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScalingStep {
    Measurements,
    ManualScale,
}

/// Two markers whose distance measures a segment.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerPair {
    pub markers: [String; 2],
    pub place: Place,
}

/// A body scaled by a measurement, along the flagged axes (X, Y, Z).
#[derive(Clone, Debug, PartialEq)]
pub struct BodyAxes {
    pub body: String,
    pub axes: [bool; 3],
    pub place: Place,
}

/// A `Measurement`: factor = mean over its pairs of experimental / model distance.
#[derive(Clone, Debug, PartialEq)]
pub struct Measurement {
    pub name: String,
    pub apply: bool,
    pub pairs: Vec<MarkerPair>,
    pub bodies: Vec<BodyAxes>,
    pub place: Place,
}

/// A manual `Scale`: a body's three factors.
#[derive(Clone, Debug, PartialEq)]
pub struct ManualScale {
    pub body: String,
    pub factors: Vec3,
    pub apply: bool,
    pub place: Place,
}

/// Where an `IKCoordinateTask` takes its target value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CoordinateValue {
    /// The coordinate's default value in the model.
    Default,
    /// The task's `value` (radians or metres).
    Manual(f64),
    /// The `coordinate_file` at the static pose's time.
    FromFile,
}

/// An `IKMarkerTask` or `IKCoordinateTask`.
#[derive(Clone, Debug, PartialEq)]
pub enum IkTask {
    Marker {
        name: String,
        apply: bool,
        weight: f64,
        place: Place,
    },
    Coordinate {
        name: String,
        apply: bool,
        weight: f64,
        value: CoordinateValue,
        place: Place,
    },
}

/// `GenericModelMaker`.
#[derive(Clone, Debug, PartialEq)]
pub struct GenericModelMaker {
    pub model_file: Option<PathBuf>,
    pub marker_set_file: Option<PathBuf>,
    pub place: Place,
}

/// `ModelScaler`, with OpenSim's defaults for absent properties.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelScaler {
    pub apply: bool,
    pub scaling_order: Vec<ScalingStep>,
    pub measurements: Vec<Measurement>,
    pub manual: Vec<ManualScale>,
    pub marker_file: Option<PathBuf>,
    /// `time_range` (default −1 −1: only the first frame, as OpenSim's frame search gives).
    pub time_range: [f64; 2],
    pub preserve_mass_distribution: bool,
    pub output_model_file: Option<PathBuf>,
    pub output_scale_file: Option<PathBuf>,
    pub place: Place,
}

/// `MarkerPlacer`, with OpenSim's defaults for absent properties.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerPlacer {
    pub apply: bool,
    pub tasks: Vec<IkTask>,
    pub marker_file: Option<PathBuf>,
    pub coordinate_file: Option<PathBuf>,
    pub time_range: [f64; 2],
    pub output_model_file: Option<PathBuf>,
    pub output_marker_file: Option<PathBuf>,
    pub output_motion_file: Option<PathBuf>,
    /// `max_marker_movement` (m); None when negative (no limit).
    pub max_marker_movement: Option<f64>,
    pub place: Place,
}

/// The settings of an OpenSim `ScaleTool`.
#[derive(Clone, Debug, PartialEq)]
pub struct ScaleSetup {
    /// The setup file read.
    pub source: PathBuf,
    /// The tool's `name` (OpenSim names the scaled model after it).
    pub name: String,
    /// Subject mass (kg); None when absent or ≤ 0.
    pub mass: Option<f64>,
    /// `height` as written (OpenSim: mm, informational).
    pub height: Option<f64>,
    pub generic_model_maker: Option<GenericModelMaker>,
    pub model_scaler: Option<ModelScaler>,
    pub marker_placer: Option<MarkerPlacer>,
    pub warnings: Vec<SetupWarning>,
}

/// Where a marker of a marker-set file is attached.
#[derive(Clone, Debug, PartialEq)]
pub enum MarkerParent {
    /// OpenSim 3: `<body>` names a body.
    Body(String),
    /// OpenSim 4: `<socket_parent_frame>` is a frame path such as `/bodyset/torso`.
    Frame(String),
}

/// A marker of a `MarkerSet` file.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerDef {
    pub name: String,
    pub parent: MarkerParent,
    /// Location in the parent frame (m).
    pub location: Vec3,
    pub fixed: bool,
    pub place: Place,
}

impl ScaleSetup {
    /// Reads a `ScaleTool` setup file.
    pub fn read(path: &Path) -> crate::Result<ScaleSetup> {
        let text = read_text(path)?;
        Self::parse(&text, path)
    }

    /// Parses a `ScaleTool` setup; `path` names it and anchors relative paths.
    pub fn parse(text: &str, path: &Path) -> crate::Result<ScaleSetup> {
        let doc = parse_xml(text, path)?;
        let r = Reader::new(&doc, path);
        let tool = r.tool_element()?;
        if !tool.has_tag_name("ScaleTool") {
            return Err(r.error(
                tool,
                format!("expected a ScaleTool, found <{}>", tool.tag_name().name()),
            ));
        }
        let mut s = ScaleSetup {
            source: path.to_path_buf(),
            name: tool.attribute("name").unwrap_or("").to_string(),
            mass: None,
            height: None,
            generic_model_maker: None,
            model_scaler: None,
            marker_placer: None,
            warnings: Vec::new(),
        };
        let base = base_dir(path).to_path_buf();
        for n in tool.children().filter(Node::is_element) {
            match n.tag_name().name() {
                "mass" => s.mass = Some(r.number(n)?).filter(|m| *m > 0.0),
                "height" => s.height = Some(r.number(n)?).filter(|h| *h > 0.0),
                "age" | "notes" | "defaults" => {}
                "GenericModelMaker" => {
                    s.generic_model_maker = Some(generic_model_maker(&r, n, &mut s.warnings)?)
                }
                "ModelScaler" => {
                    s.model_scaler = Some(model_scaler(&r, n, &base, &mut s.warnings)?)
                }
                "MarkerPlacer" => {
                    s.marker_placer = Some(marker_placer(&r, n, &base, &mut s.warnings)?)
                }
                _ => s
                    .warnings
                    .push(r.warning(n, "unknown ScaleTool setting, ignored")),
            }
        }
        Ok(s)
    }
}

fn place(r: &Reader, n: Node) -> Place {
    let w = r.warning(n, "");
    Place {
        file: w.file,
        line: w.line,
        element: w.element,
    }
}

fn generic_model_maker(
    r: &Reader,
    g: Node,
    warnings: &mut Vec<SetupWarning>,
) -> crate::Result<GenericModelMaker> {
    let mut out = GenericModelMaker {
        model_file: None,
        marker_set_file: None,
        place: place(r, g),
    };
    for n in g.children().filter(Node::is_element) {
        match n.tag_name().name() {
            "model_file" => out.model_file = r.path(n),
            "marker_set_file" => out.marker_set_file = r.path(n),
            _ => warnings.push(r.warning(n, "unknown GenericModelMaker setting, ignored")),
        }
    }
    Ok(out)
}

/// `time_range`: two numbers, start ≤ end.
fn time_range(r: &Reader, n: Node) -> crate::Result<[f64; 2]> {
    let v = r.numbers(n, 2)?;
    if v[0] > v[1] {
        return Err(r.error(n, format!("[{}, {}] is not a time range", v[0], v[1])));
    }
    Ok([v[0], v[1]])
}

fn model_scaler(
    r: &Reader,
    m: Node,
    base: &Path,
    warnings: &mut Vec<SetupWarning>,
) -> crate::Result<ModelScaler> {
    let mut out = ModelScaler {
        apply: true,
        scaling_order: Vec::new(),
        measurements: Vec::new(),
        manual: Vec::new(),
        marker_file: None,
        time_range: [-1.0, -1.0],
        preserve_mass_distribution: false,
        output_model_file: None,
        output_scale_file: None,
        place: place(r, m),
    };
    for n in m.children().filter(Node::is_element) {
        match n.tag_name().name() {
            "apply" => out.apply = r.boolean(n)?,
            "scaling_order" => {
                for w in Reader::words(n) {
                    out.scaling_order.push(match w.as_str() {
                        "measurements" => ScalingStep::Measurements,
                        "manualScale" => ScalingStep::ManualScale,
                        _ => {
                            return Err(r.error(
                                n,
                                format!(
                                    "`{w}` is not a scaling step (expected `measurements` or \
                                     `manualScale`)"
                                ),
                            ));
                        }
                    });
                }
            }
            "MeasurementSet" => {
                with_set(r, n, base, warnings, &mut |r, o, w| {
                    if o.has_tag_name("Measurement") {
                        out.measurements.push(measurement(r, o, w)?);
                    } else {
                        w.push(r.warning(o, "not a Measurement, ignored"));
                    }
                    Ok(())
                })?;
            }
            "ScaleSet" => {
                with_set(r, n, base, warnings, &mut |r, o, w| {
                    if o.has_tag_name("Scale") {
                        out.manual.push(manual_scale(r, o, w)?);
                    } else {
                        w.push(r.warning(o, "not a Scale, ignored"));
                    }
                    Ok(())
                })?;
            }
            "marker_file" => out.marker_file = r.path(n),
            "time_range" => out.time_range = time_range(r, n)?,
            "preserve_mass_distribution" => out.preserve_mass_distribution = r.boolean(n)?,
            "output_model_file" => out.output_model_file = r.path(n),
            "output_scale_file" => out.output_scale_file = r.path(n),
            _ => warnings.push(r.warning(n, "unknown ModelScaler setting, ignored")),
        }
    }
    Ok(out)
}

/// A visitor of a set's members.
type Visit<'v> = dyn FnMut(&Reader, Node, &mut Vec<SetupWarning>) -> crate::Result<()> + 'v;

/// Visits the members of a set element (`<objects>` children), reading them from the file
/// named by a `file` attribute when there is one, as OpenSim does.
fn with_set(
    r: &Reader,
    set: Node,
    base: &Path,
    warnings: &mut Vec<SetupWarning>,
    visit: &mut Visit,
) -> crate::Result<()> {
    if let Some(file) = set
        .attribute("file")
        .map(str::trim)
        .filter(|f| !f.is_empty())
    {
        let path = crate::io::resolve_data_path(base, file);
        let text = read_text(&path).map_err(|e| {
            r.error(
                set,
                format!("cannot read the {} file: {e}", set.tag_name().name()),
            )
        })?;
        let doc = parse_xml(&text, &path)?;
        let inner = Reader::new(&doc, &path);
        let root = doc.root_element();
        let element = if root.has_tag_name("OpenSimDocument") {
            root.children()
                .filter(Node::is_element)
                .find(|c| c.tag_name() == set.tag_name())
        } else {
            Some(root).filter(|c| c.tag_name() == set.tag_name())
        };
        let Some(element) = element else {
            return Err(inner.error(
                root,
                format!("no <{}> element in this file", set.tag_name().name()),
            ));
        };
        return members(&inner, element, warnings, visit);
    }
    members(r, set, warnings, visit)
}

fn members(
    r: &Reader,
    set: Node,
    warnings: &mut Vec<SetupWarning>,
    visit: &mut Visit,
) -> crate::Result<()> {
    for c in set.children().filter(Node::is_element) {
        match c.tag_name().name() {
            "objects" => {
                for o in c.children().filter(Node::is_element) {
                    visit(r, o, warnings)?;
                }
            }
            "groups" => {}
            _ => warnings.push(r.warning(c, "unknown set element, ignored")),
        }
    }
    Ok(())
}

fn measurement(
    r: &Reader,
    m: Node,
    warnings: &mut Vec<SetupWarning>,
) -> crate::Result<Measurement> {
    let mut out = Measurement {
        name: m.attribute("name").unwrap_or("").to_string(),
        apply: true,
        pairs: Vec::new(),
        bodies: Vec::new(),
        place: place(r, m),
    };
    for n in m.children().filter(Node::is_element) {
        match n.tag_name().name() {
            "apply" => out.apply = r.boolean(n)?,
            "MarkerPairSet" => members(r, n, warnings, &mut |r, o, w| {
                if !o.has_tag_name("MarkerPair") {
                    w.push(r.warning(o, "not a MarkerPair, ignored"));
                    return Ok(());
                }
                let mut markers = None;
                for c in o.children().filter(Node::is_element) {
                    if c.has_tag_name("markers") {
                        let names = Reader::words(c);
                        if names.len() != 2 {
                            return Err(r.error(
                                c,
                                format!("a marker pair needs 2 marker names, found {names:?}"),
                            ));
                        }
                        markers = Some([names[0].clone(), names[1].clone()]);
                    } else {
                        w.push(r.warning(c, "unknown MarkerPair setting, ignored"));
                    }
                }
                let markers =
                    markers.ok_or_else(|| r.error(o, "a MarkerPair without <markers>".into()))?;
                out.pairs.push(MarkerPair {
                    markers,
                    place: place(r, o),
                });
                Ok(())
            })?,
            "BodyScaleSet" => members(r, n, warnings, &mut |r, o, w| {
                if !o.has_tag_name("BodyScale") {
                    w.push(r.warning(o, "not a BodyScale, ignored"));
                    return Ok(());
                }
                let mut axes = [false; 3];
                for c in o.children().filter(Node::is_element) {
                    if c.has_tag_name("axes") {
                        for a in Reader::words(c) {
                            match a.as_str() {
                                "X" | "x" => axes[0] = true,
                                "Y" | "y" => axes[1] = true,
                                "Z" | "z" => axes[2] = true,
                                _ => {
                                    return Err(
                                        r.error(c, format!("`{a}` is not an axis (X, Y or Z)"))
                                    );
                                }
                            }
                        }
                    } else {
                        w.push(r.warning(c, "unknown BodyScale setting, ignored"));
                    }
                }
                out.bodies.push(BodyAxes {
                    body: o.attribute("name").unwrap_or("").trim().to_string(),
                    axes,
                    place: place(r, o),
                });
                Ok(())
            })?,
            _ => warnings.push(r.warning(n, "unknown Measurement setting, ignored")),
        }
    }
    Ok(out)
}

fn manual_scale(
    r: &Reader,
    s: Node,
    warnings: &mut Vec<SetupWarning>,
) -> crate::Result<ManualScale> {
    let mut out = ManualScale {
        body: String::new(),
        factors: Vec3::new(1.0, 1.0, 1.0),
        apply: true,
        place: place(r, s),
    };
    for n in s.children().filter(Node::is_element) {
        match n.tag_name().name() {
            "scales" => {
                let v = r.numbers(n, 3)?;
                out.factors = Vec3::new(v[0], v[1], v[2]);
            }
            "segment" => out.body = Reader::text(n).unwrap_or_default(),
            "apply" => out.apply = r.boolean(n)?,
            _ => warnings.push(r.warning(n, "unknown Scale setting, ignored")),
        }
    }
    if out.body.is_empty() {
        return Err(r.error(s, "a Scale without a <segment>".into()));
    }
    Ok(out)
}

fn marker_placer(
    r: &Reader,
    m: Node,
    base: &Path,
    warnings: &mut Vec<SetupWarning>,
) -> crate::Result<MarkerPlacer> {
    let mut out = MarkerPlacer {
        apply: true,
        tasks: Vec::new(),
        marker_file: None,
        coordinate_file: None,
        time_range: [-1.0, -1.0],
        output_model_file: None,
        output_marker_file: None,
        output_motion_file: None,
        max_marker_movement: None,
        place: place(r, m),
    };
    for n in m.children().filter(Node::is_element) {
        match n.tag_name().name() {
            "apply" => out.apply = r.boolean(n)?,
            "IKTaskSet" => with_set(r, n, base, warnings, &mut |r, o, w| {
                out.tasks.push(ik_task(r, o, w)?);
                Ok(())
            })?,
            "marker_file" => out.marker_file = r.path(n),
            "coordinate_file" => out.coordinate_file = r.path(n),
            "time_range" => out.time_range = time_range(r, n)?,
            "output_model_file" => out.output_model_file = r.path(n),
            "output_marker_file" => out.output_marker_file = r.path(n),
            "output_motion_file" => out.output_motion_file = r.path(n),
            "max_marker_movement" => {
                out.max_marker_movement = Some(r.number(n)?).filter(|d| *d >= 0.0)
            }
            _ => warnings.push(r.warning(n, "unknown MarkerPlacer setting, ignored")),
        }
    }
    Ok(out)
}

fn ik_task(r: &Reader, t: Node, warnings: &mut Vec<SetupWarning>) -> crate::Result<IkTask> {
    let name = t.attribute("name").unwrap_or("").trim().to_string();
    let tag = t.tag_name().name();
    if tag != "IKMarkerTask" && tag != "IKCoordinateTask" {
        return Err(r.error(
            t,
            format!("unknown task type <{tag}> (expected IKMarkerTask or IKCoordinateTask)"),
        ));
    }
    let (mut apply, mut weight) = (true, 0.0);
    let (mut value_type, mut value) = ("default_value".to_string(), 0.0);
    for n in t.children().filter(Node::is_element) {
        match n.tag_name().name() {
            "apply" => apply = r.boolean(n)?,
            "weight" => {
                weight = r.number(n)?;
                if weight < 0.0 {
                    return Err(r.error(n, format!("a weight of {weight} is negative")));
                }
            }
            "value_type" if tag == "IKCoordinateTask" => {
                value_type = Reader::text(n).unwrap_or_default()
            }
            "value" if tag == "IKCoordinateTask" => value = r.number(n)?,
            _ => warnings.push(r.warning(n, format!("unknown {tag} setting, ignored"))),
        }
    }
    let place = place(r, t);
    if tag == "IKMarkerTask" {
        return Ok(IkTask::Marker {
            name,
            apply,
            weight,
            place,
        });
    }
    let value = match value_type.as_str() {
        "default_value" => CoordinateValue::Default,
        "manual_value" => CoordinateValue::Manual(value),
        "from_file" => CoordinateValue::FromFile,
        other => {
            return Err(place.error(format!(
                "value_type `{other}` is not default_value, manual_value or from_file"
            )));
        }
    };
    Ok(IkTask::Coordinate {
        name,
        apply,
        weight,
        value,
        place,
    })
}

/// Reads the markers of an OpenSim `MarkerSet` file (OpenSim 3 `<body>` or OpenSim 4
/// `<socket_parent_frame>`), with warnings for elements not used.
pub fn read_marker_set(path: &Path) -> crate::Result<(Vec<MarkerDef>, Vec<SetupWarning>)> {
    let text = read_text(path)?;
    parse_marker_set(&text, path)
}

/// Parses a `MarkerSet` file's text; `path` names it in messages.
pub fn parse_marker_set(
    text: &str,
    path: &Path,
) -> crate::Result<(Vec<MarkerDef>, Vec<SetupWarning>)> {
    let doc = parse_xml(text, path)?;
    let r = Reader::new(&doc, path);
    let root = doc.root_element();
    let set = if root.has_tag_name("MarkerSet") {
        Some(root)
    } else {
        root.children()
            .filter(Node::is_element)
            .find(|c| c.has_tag_name("MarkerSet"))
    };
    let set = set.ok_or_else(|| r.error(root, "no <MarkerSet> element".into()))?;
    let mut markers: Vec<MarkerDef> = Vec::new();
    let mut warnings = Vec::new();
    members(&r, set, &mut warnings, &mut |r, o, w| {
        if !o.has_tag_name("Marker") {
            w.push(r.warning(o, "not a Marker, ignored"));
            return Ok(());
        }
        let name = o.attribute("name").unwrap_or("").trim().to_string();
        if name.is_empty() {
            return Err(r.error(o, "a Marker without a name".into()));
        }
        if let Some(first) = markers.iter().find(|m| m.name == name) {
            return Err(r.error(
                o,
                format!(
                    "marker \"{name}\" is defined twice (first at line {})",
                    first.place.line
                ),
            ));
        }
        let (mut parent, mut location, mut fixed) = (None, None, false);
        for c in o.children().filter(Node::is_element) {
            match c.tag_name().name() {
                "body" => parent = Reader::text(c).map(MarkerParent::Body),
                "socket_parent_frame" => parent = Reader::text(c).map(MarkerParent::Frame),
                "location" => {
                    let v = r.numbers(c, 3)?;
                    location = Some(Vec3::new(v[0], v[1], v[2]));
                }
                "fixed" => fixed = r.boolean(c)?,
                "VisibleObject" | "attached_geometry" | "appearance" | "Appearance" => {}
                _ => w.push(r.warning(c, "unknown Marker setting, ignored")),
            }
        }
        let parent = parent
            .ok_or_else(|| r.error(o, "a Marker without <body> or <socket_parent_frame>".into()))?;
        let location = location.ok_or_else(|| r.error(o, "a Marker without <location>".into()))?;
        if location.iter().any(|v| !v.is_finite()) {
            return Err(r.error(o, format!("location {location:?} is not finite")));
        }
        markers.push(MarkerDef {
            name,
            parent,
            location,
            fixed,
            place: place(r, o),
        });
        Ok(())
    })?;
    Ok((markers, warnings))
}
