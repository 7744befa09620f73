//! OpenSim `InverseKinematicsTool` setup files, read as OpenSim 4 reads them.
//!
//! Read: `model_file`, `marker_file`, `coordinate_file`, `time_range`, `output_motion_file`,
//! `results_directory`, `accuracy`, `constraint_weight`, `report_errors`,
//! `report_marker_locations`, and the `IKTaskSet` (inline, or from a file named by its
//! `file` attribute) with `IKMarkerTask` (apply, weight) and `IKCoordinateTask` (apply,
//! weight, value_type `default_value` | `manual_value` | `from_file`, value). Paths are
//! relative to the setup file's folder. Anything else is a warning naming its line.

use super::setup::{Reader, SetupWarning, base_dir, parse_xml, read_text};
use roxmltree::Node;
use std::path::{Path, PathBuf};

/// Where an IKCoordinateTask's target value comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum CoordinateValue {
    /// The coordinate's default value in the model.
    Default,
    /// A fixed value, as written in the file (see [`CoordinateTaskSetup::value`]).
    Manual(f64),
    /// The coordinate's column of `coordinate_file`.
    FromFile,
}

/// One IKMarkerTask.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerTaskSetup {
    pub name: String,
    pub apply: bool,
    pub weight: f64,
    pub line: u32,
}

/// One IKCoordinateTask.
#[derive(Clone, Debug, PartialEq)]
pub struct CoordinateTaskSetup {
    pub name: String,
    pub apply: bool,
    pub weight: f64,
    /// Manual values are as written in the file; the IK tool takes them in the coordinate's
    /// own units (radians or metres).
    pub value: CoordinateValue,
    pub line: u32,
}

/// An InverseKinematicsTool setup.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IkSetup {
    pub source: PathBuf,
    pub name: String,
    pub model_file: Option<PathBuf>,
    pub marker_file: Option<PathBuf>,
    pub coordinate_file: Option<PathBuf>,
    pub time_range: Option<[f64; 2]>,
    pub output_motion_file: Option<PathBuf>,
    pub results_directory: Option<PathBuf>,
    /// OpenSim's assembler accuracy (default 1e-5).
    pub accuracy: f64,
    /// Weight of constraint errors (`Inf`: constraints enforced; musculo always enforces
    /// them exactly, by the coordinate reduction).
    pub constraint_weight: f64,
    pub report_errors: bool,
    pub report_marker_locations: bool,
    pub marker_tasks: Vec<MarkerTaskSetup>,
    pub coordinate_tasks: Vec<CoordinateTaskSetup>,
    pub warnings: Vec<SetupWarning>,
}

impl IkSetup {
    /// Reads an `InverseKinematicsTool` setup file.
    pub fn read(path: &Path) -> crate::Result<IkSetup> {
        let text = read_text(path)?;
        Self::parse(&text, path)
    }

    /// Parses setup text; `path` names it in messages and anchors relative paths.
    pub fn parse(text: &str, path: &Path) -> crate::Result<IkSetup> {
        let doc = parse_xml(text, path)?;
        let r = Reader::new(&doc, path);
        let tool = r.tool_element()?;
        if !tool.has_tag_name("InverseKinematicsTool") {
            return Err(r.error(
                tool,
                format!(
                    "expected an InverseKinematicsTool, found <{}>",
                    tool.tag_name().name()
                ),
            ));
        }
        let mut s = IkSetup {
            source: path.to_path_buf(),
            name: tool.attribute("name").unwrap_or("").to_string(),
            accuracy: 1e-5,
            constraint_weight: f64::INFINITY,
            report_errors: true,
            ..IkSetup::default()
        };
        for n in tool.children().filter(Node::is_element) {
            match n.tag_name().name() {
                "model_file" => s.model_file = r.path(n),
                "marker_file" => s.marker_file = r.path(n),
                "coordinate_file" => s.coordinate_file = r.path(n),
                "output_motion_file" => s.output_motion_file = r.path(n),
                "results_directory" => s.results_directory = r.path(n),
                "time_range" => {
                    let v = r.numbers(n, 2)?;
                    if !(v[0] <= v[1]) {
                        return Err(r.error(n, format!("start {} is after end {}", v[0], v[1])));
                    }
                    s.time_range = Some([v[0], v[1]]);
                }
                "accuracy" => {
                    s.accuracy = r.number(n)?;
                    if !(s.accuracy > 0.0) {
                        return Err(r.error(n, format!("{} must be positive", s.accuracy)));
                    }
                }
                "constraint_weight" => {
                    let t = n.text().unwrap_or("").trim();
                    s.constraint_weight = if t.eq_ignore_ascii_case("inf") {
                        f64::INFINITY
                    } else {
                        r.number(n)?
                    };
                }
                "report_errors" => s.report_errors = r.boolean(n)?,
                "report_marker_locations" => s.report_marker_locations = r.boolean(n)?,
                "IKTaskSet" => read_task_set(&r, n, path, &mut s)?,
                "input_directory" => {
                    if Reader::text(n).is_some() {
                        s.warnings.push(r.warning(
                            n,
                            "ignored, as OpenSim 4 ignores it: paths are relative to the setup \
                             file's directory",
                        ));
                    }
                }
                "defaults" | "output_precision" => {}
                _ => s
                    .warnings
                    .push(r.warning(n, "unknown InverseKinematicsTool setting, ignored")),
            }
        }
        Ok(s)
    }

    /// Where OpenSim writes the motion: the output file, relative to `results_directory`
    /// when that is given (OpenSim 4 writes `output_motion_file` as given, relative to the
    /// setup's folder).
    pub fn output_path(&self) -> Option<PathBuf> {
        self.output_motion_file.clone()
    }
}

fn read_task_set(r: &Reader, set: Node, path: &Path, s: &mut IkSetup) -> crate::Result<()> {
    if let Some(file) = set.attribute("file").filter(|f| !f.trim().is_empty()) {
        // <IKTaskSet file="tasks.xml"/>: the tasks live in another file.
        let other = super::resolve_data_path(base_dir(path), file);
        let text = read_text(&other)?;
        let doc = parse_xml(&text, &other)?;
        let r2 = Reader::new(&doc, &other);
        let root = doc.root_element();
        let inner = if root.has_tag_name("IKTaskSet") {
            root
        } else {
            root.descendants()
                .find(|d| d.has_tag_name("IKTaskSet"))
                .ok_or_else(|| r2.error(root, "no <IKTaskSet> in this file".into()))?
        };
        return read_tasks(&r2, inner, s);
    }
    read_tasks(r, set, s)
}

fn read_tasks(r: &Reader, set: Node, s: &mut IkSetup) -> crate::Result<()> {
    let objects = set.children().filter(|c| c.has_tag_name("objects"));
    for task in objects.flat_map(|o| o.children().filter(Node::is_element)) {
        let kind = task.tag_name().name();
        let name = task.attribute("name").unwrap_or("").trim().to_string();
        if kind != "IKMarkerTask" && kind != "IKCoordinateTask" {
            s.warnings
                .push(r.warning(task, format!("unknown task type <{kind}>, ignored")));
            continue;
        }
        if name.is_empty() {
            return Err(r.error(
                task,
                "a task needs a name (the marker or coordinate)".into(),
            ));
        }
        let (mut apply, mut weight, mut value_type, mut value) = (true, 0.0, None, None);
        for c in task.children().filter(Node::is_element) {
            match c.tag_name().name() {
                "apply" => apply = r.boolean(c)?,
                "weight" => {
                    weight = r.number(c)?;
                    if !(weight >= 0.0 && weight.is_finite()) {
                        return Err(r.error(c, format!("weight {weight} must be ≥ 0 and finite")));
                    }
                }
                "value_type" if kind == "IKCoordinateTask" => {
                    value_type = Some((c, n_text(c)));
                }
                "value" if kind == "IKCoordinateTask" => value = Some(r.number(c)?),
                _ => s
                    .warnings
                    .push(r.warning(c, "unknown task setting, ignored")),
            }
        }
        let line = r.line(task);
        if kind == "IKMarkerTask" {
            s.marker_tasks.push(MarkerTaskSetup {
                name,
                apply,
                weight,
                line,
            });
        } else {
            let value = match value_type {
                None => CoordinateValue::Default,
                Some((_, t)) if t == "default_value" => CoordinateValue::Default,
                Some((_, t)) if t == "manual_value" => {
                    CoordinateValue::Manual(value.unwrap_or(0.0))
                }
                Some((_, t)) if t == "from_file" => CoordinateValue::FromFile,
                Some((node, t)) => {
                    return Err(r.error(
                        node,
                        format!("`{t}`: expected default_value, manual_value or from_file"),
                    ));
                }
            };
            s.coordinate_tasks.push(CoordinateTaskSetup {
                name,
                apply,
                weight,
                value,
                line,
            });
        }
    }
    Ok(())
}

fn n_text(n: Node) -> String {
    n.text().unwrap_or("").trim().to_string()
}
