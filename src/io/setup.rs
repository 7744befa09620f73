//! OpenSim tool setup files (`.xml`): the settings of an `InverseDynamicsTool` and of an
//! `AnalyzeTool` running a `StaticOptimization` analysis — the properties musculo's inverse
//! dynamics and static optimization use.
//!
//! - File names (`model_file`, `coordinates_file`, `external_loads_file`, `force_set_files`,
//!   `results_directory`) are resolved relative to the setup file's directory, as OpenSim's
//!   tools do (they change to that directory before reading); a name written with Windows
//!   backslashes (`..\IK\walk.mot`) is read with them as separators when it does not exist
//!   as written ([`super::resolve_data_path`]). Empty values and `Unassigned` mean "not
//!   set".
//! - `lowpass_cutoff_frequency_for_coordinates` < 0 means no filtering (`None`); 0 is an error.
//! - Settings that musculo does not support but that would change OpenSim's results (a states
//!   or speeds file, controllers, analyses other than StaticOptimization, body forces at
//!   joints, OpenSim 2 load-kinematics settings, …) and unknown elements are returned as
//!   [`SetupWarning`]s, never printed. Display-only and integrator settings (which an Analyze
//!   run from coordinates does not use) are read silently.
//! - Malformed XML is [`Error::Xml`]; a value of the wrong form (a word where a number is
//!   expected, a time range of one number) is [`Error::Model`] naming the file, the line and
//!   the element (`InverseDynamicsTool "walk" > <time_range>`).

use super::resolve_data_path;
use crate::error::Error;
use roxmltree::{Document, Node};
use std::path::{Path, PathBuf};

/// A setting read but not applied, or not understood (the readers' common warning type).
pub type SetupWarning = super::FileWarning;

/// The settings of an OpenSim `InverseDynamicsTool`.
#[derive(Clone, Debug, PartialEq)]
pub struct InverseDynamicsSetup {
    /// The setup file read.
    pub source: PathBuf,
    /// The tool's `name` attribute.
    pub name: String,
    pub model_file: Option<PathBuf>,
    pub coordinates_file: Option<PathBuf>,
    pub external_loads_file: Option<PathBuf>,
    /// `lowpass_cutoff_frequency_for_coordinates` (Hz); None for a negative value or none.
    pub lowpass_cutoff_hz: Option<f64>,
    /// `time_range`; None when absent (OpenSim: (−∞, ∞)).
    pub time_range: Option<[f64; 2]>,
    /// `forces_to_exclude`: force names, group names, or the keywords All, Muscles,
    /// Actuators (case-insensitive).
    pub forces_to_exclude: Vec<String>,
    /// `output_gen_force_file` (a file name, written in `results_directory`).
    pub output_gen_force_file: Option<String>,
    pub results_directory: Option<PathBuf>,
    pub warnings: Vec<SetupWarning>,
}

/// The settings of an OpenSim `StaticOptimization` analysis, with OpenSim's defaults for
/// absent properties.
#[derive(Clone, Debug, PartialEq)]
pub struct StaticOptimizationSetup {
    pub name: String,
    /// `on` (true by default).
    pub on: bool,
    /// `start_time` / `end_time`; None when absent.
    pub start_time: Option<f64>,
    pub end_time: Option<f64>,
    /// `step_interval`: record every k-th row (1 by default).
    pub step_interval: usize,
    /// `in_degrees`: results in degrees (true by default; affects output only).
    pub in_degrees: bool,
    /// `use_model_force_set` (true by default).
    pub use_model_force_set: bool,
    /// `activation_exponent` (2 by default).
    pub activation_exponent: f64,
    /// `use_muscle_physiology` (true by default).
    pub use_muscle_physiology: bool,
    /// `optimizer_convergence_criterion` (1e-4 by default).
    pub optimizer_convergence_criterion: f64,
    /// `optimizer_max_iterations` (100 by default).
    pub optimizer_max_iterations: usize,
    /// Line of the element.
    pub line: u32,
}

impl Default for StaticOptimizationSetup {
    fn default() -> Self {
        StaticOptimizationSetup {
            name: "StaticOptimization".into(),
            on: true,
            start_time: None,
            end_time: None,
            step_interval: 1,
            in_degrees: true,
            use_model_force_set: true,
            activation_exponent: 2.0,
            use_muscle_physiology: true,
            optimizer_convergence_criterion: 1e-4,
            optimizer_max_iterations: 100,
            line: 0,
        }
    }
}

/// The settings of an OpenSim `AnalyzeTool`.
#[derive(Clone, Debug, PartialEq)]
pub struct AnalyzeSetup {
    pub source: PathBuf,
    pub name: String,
    pub model_file: Option<PathBuf>,
    pub coordinates_file: Option<PathBuf>,
    pub external_loads_file: Option<PathBuf>,
    pub lowpass_cutoff_hz: Option<f64>,
    pub initial_time: Option<f64>,
    pub final_time: Option<f64>,
    pub results_directory: Option<PathBuf>,
    /// `force_set_files`, resolved.
    pub force_set_files: Vec<PathBuf>,
    /// `replace_force_set` (false by default: the files' forces are appended).
    pub replace_force_set: bool,
    /// The StaticOptimization analysis of the AnalysisSet, if there is one.
    pub static_optimization: Option<StaticOptimizationSetup>,
    pub warnings: Vec<SetupWarning>,
}

/// A setup file of either supported tool.
#[derive(Clone, Debug, PartialEq)]
pub enum ToolSetup {
    InverseDynamics(InverseDynamicsSetup),
    Analyze(AnalyzeSetup),
}

/// Reads a setup file, whichever of the supported tools it configures.
pub fn read(path: &Path) -> crate::Result<ToolSetup> {
    let text = read_text(path)?;
    parse(&text, path)
}

/// Parses setup text; `path` names the file in messages and anchors relative paths.
pub fn parse(text: &str, path: &Path) -> crate::Result<ToolSetup> {
    let doc = parse_xml(text, path)?;
    let r = Reader::new(&doc, path);
    let tool = r.tool_element()?;
    match tool.tag_name().name() {
        "InverseDynamicsTool" => Ok(ToolSetup::InverseDynamics(r.inverse_dynamics(tool)?)),
        "AnalyzeTool" => Ok(ToolSetup::Analyze(r.analyze(tool)?)),
        other => Err(r.error(
            tool,
            format!(
                "unsupported tool `{other}`: musculo reads InverseDynamicsTool and AnalyzeTool \
                 setup files"
            ),
        )),
    }
}

impl InverseDynamicsSetup {
    /// Reads an `InverseDynamicsTool` setup file.
    pub fn read(path: &Path) -> crate::Result<InverseDynamicsSetup> {
        let text = read_text(path)?;
        Self::parse(&text, path)
    }

    /// Parses an `InverseDynamicsTool` setup; `path` names it and anchors relative paths.
    pub fn parse(text: &str, path: &Path) -> crate::Result<InverseDynamicsSetup> {
        let doc = parse_xml(text, path)?;
        let r = Reader::new(&doc, path);
        let tool = r.tool_element()?;
        if !tool.has_tag_name("InverseDynamicsTool") {
            return Err(r.error(
                tool,
                format!(
                    "expected an InverseDynamicsTool, found <{}>",
                    tool.tag_name().name()
                ),
            ));
        }
        r.inverse_dynamics(tool)
    }

    /// Where OpenSim writes the generalized forces: `results_directory/output_gen_force_file`.
    pub fn output_path(&self) -> Option<PathBuf> {
        let file = self.output_gen_force_file.as_ref()?;
        let dir = self
            .results_directory
            .clone()
            .unwrap_or_else(|| base_dir(&self.source).to_path_buf());
        Some(dir.join(file))
    }
}

impl AnalyzeSetup {
    /// Reads an `AnalyzeTool` setup file.
    pub fn read(path: &Path) -> crate::Result<AnalyzeSetup> {
        let text = read_text(path)?;
        Self::parse(&text, path)
    }

    /// Parses an `AnalyzeTool` setup; `path` names it and anchors relative paths.
    pub fn parse(text: &str, path: &Path) -> crate::Result<AnalyzeSetup> {
        let doc = parse_xml(text, path)?;
        let r = Reader::new(&doc, path);
        let tool = r.tool_element()?;
        if !tool.has_tag_name("AnalyzeTool") {
            return Err(r.error(
                tool,
                format!(
                    "expected an AnalyzeTool, found <{}>",
                    tool.tag_name().name()
                ),
            ));
        }
        r.analyze(tool)
    }
}

pub(crate) fn read_text(path: &Path) -> crate::Result<String> {
    crate::text::read_text(path)
}

pub(crate) fn parse_xml<'i>(text: &'i str, path: &Path) -> crate::Result<Document<'i>> {
    crate::xml::parse(text, &path.display().to_string())
}

pub(crate) fn base_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Elements read silently by both tools: display, bookkeeping, integrator settings.
const HARMLESS: &[&str] = &["defaults", "output_precision"];
const INTEGRATOR: &[&str] = &[
    "solve_for_equilibrium_for_auxiliary_states",
    "maximum_number_of_integrator_steps",
    "maximum_integrator_step_size",
    "minimum_integrator_step_size",
    "integrator_error_tolerance",
];

pub(crate) struct Reader<'a, 'i> {
    doc: &'a Document<'i>,
    path: &'a Path,
    file: String,
}

impl<'a, 'i> Reader<'a, 'i> {
    pub(crate) fn new(doc: &'a Document<'i>, path: &'a Path) -> Self {
        Reader {
            doc,
            path,
            file: path.display().to_string(),
        }
    }

    pub(crate) fn line(&self, n: Node) -> u32 {
        self.doc.text_pos_at(n.range().start).row
    }

    /// `AnalyzeTool "arm26" > AnalysisSet > StaticOptimization "so" > <step_interval>`.
    pub(crate) fn describe(&self, n: Node) -> String {
        let mut parts: Vec<String> = n
            .ancestors()
            .filter(|a| a.is_element())
            .take_while(|a| !a.has_tag_name("OpenSimDocument"))
            .filter(|a| !a.has_tag_name("objects"))
            .map(|a| match a.attribute("name") {
                Some(name) => format!("{} \"{name}\"", a.tag_name().name()),
                None if a == n => format!("<{}>", a.tag_name().name()),
                None => a.tag_name().name().to_string(),
            })
            .collect();
        parts.reverse();
        parts.join(" > ")
    }

    pub(crate) fn error(&self, n: Node, message: String) -> Error {
        Error::Model {
            file: self.file.clone(),
            line: self.line(n),
            element: self.describe(n),
            message,
        }
    }

    pub(crate) fn warning(&self, n: Node, message: impl Into<String>) -> SetupWarning {
        SetupWarning {
            file: self.file.clone(),
            line: self.line(n),
            element: self.describe(n),
            message: message.into(),
        }
    }

    pub(crate) fn tool_element(&self) -> crate::Result<Node<'a, 'i>> {
        let root = self.doc.root_element();
        if root.has_tag_name("OpenSimDocument") {
            root.first_element_child()
                .ok_or_else(|| self.error(root, "no tool element inside <OpenSimDocument>".into()))
        } else {
            Ok(root)
        }
    }

    /// Refuses `name` (an attribute or element of `n`) as part of an output file name when it
    /// would put the file outside the results folder (`AnalyzeTool name="../../x"`).
    pub(crate) fn plain_name(&self, n: Node, what: &str, name: &str) -> crate::Result<()> {
        match crate::io::output::plain_name_problem(name) {
            Some(problem) => Err(self.error(
                n,
                format!("{what} `{name}` {problem}; use a plain file name"),
            )),
            None => Ok(()),
        }
    }

    /// The trimmed text, None when empty or `Unassigned`.
    pub(crate) fn text(n: Node) -> Option<String> {
        let t = n.text().unwrap_or("").trim();
        (!t.is_empty() && t != "Unassigned").then(|| t.to_string())
    }

    /// A file named by the element, resolved against the setup's folder
    /// ([`resolve_data_path`]: Windows separators included).
    pub(crate) fn path(&self, n: Node) -> Option<PathBuf> {
        Self::text(n).map(|t| resolve_data_path(base_dir(self.path), &t))
    }

    pub(crate) fn number(&self, n: Node) -> crate::Result<f64> {
        let t = n.text().unwrap_or("").trim();
        parse_number(t).ok_or_else(|| self.error(n, format!("`{t}` is not a number")))
    }

    pub(crate) fn numbers(&self, n: Node, count: usize) -> crate::Result<Vec<f64>> {
        let t = n.text().unwrap_or("").trim();
        let v: Option<Vec<f64>> = t.split_whitespace().map(parse_number).collect();
        match v {
            Some(v) if v.len() == count => Ok(v),
            _ => Err(self.error(n, format!("expected {count} numbers, found `{t}`"))),
        }
    }

    pub(crate) fn count(&self, n: Node) -> crate::Result<usize> {
        let t = n.text().unwrap_or("").trim();
        t.parse::<usize>()
            .map_err(|_| self.error(n, format!("`{t}` is not a non-negative integer")))
    }

    pub(crate) fn boolean(&self, n: Node) -> crate::Result<bool> {
        let t = n.text().unwrap_or("").trim();
        match t.to_ascii_lowercase().as_str() {
            "true" => Ok(true),
            "false" => Ok(false),
            _ => Err(self.error(n, format!("`{t}` is not `true` or `false`"))),
        }
    }

    pub(crate) fn words(n: Node) -> Vec<String> {
        n.text()
            .unwrap_or("")
            .split_whitespace()
            .filter(|w| *w != "Unassigned")
            .map(str::to_string)
            .collect()
    }

    /// `lowpass_cutoff_frequency_for_coordinates`: negative → None; 0 → error.
    fn cutoff(&self, n: Node) -> crate::Result<Option<f64>> {
        let f = self.number(n)?;
        if f < 0.0 {
            Ok(None)
        } else if f == 0.0 || !f.is_finite() {
            Err(self.error(
                n,
                format!("a cutoff of {f} Hz cannot filter; use -1 for no filtering"),
            ))
        } else {
            Ok(Some(f))
        }
    }

    fn unknown(&self, n: Node, tool: &str) -> SetupWarning {
        let tag = n.tag_name().name();
        let message = if tag == "coordinates_in_degrees" {
            "an OpenSim 2 setting that OpenSim 4 does not read: the coordinate file's \
             `inDegrees` header decides"
                .to_string()
        } else {
            format!("unknown {tool} setting, ignored")
        };
        self.warning(n, message)
    }

    /// Settings both tools share with the same meaning; true when `n` was one of them.
    fn common(&self, n: Node, warnings: &mut Vec<SetupWarning>) -> crate::Result<bool> {
        let tag = n.tag_name().name();
        match tag {
            t if HARMLESS.contains(&t) => {}
            "input_directory" => {
                if Self::text(n).is_some() {
                    warnings.push(self.warning(
                        n,
                        "ignored, as OpenSim 4 ignores it: paths are relative to the setup \
                         file's directory",
                    ));
                }
            }
            "external_loads_model_kinematics_file" => {
                if Self::text(n).is_some() {
                    warnings.push(self.warning(
                        n,
                        "not supported: external load points are not re-expressed through \
                         separate load kinematics (OpenSim 2 setting)",
                    ));
                }
            }
            "lowpass_cutoff_frequency_for_load_kinematics" => {
                if self.number(n).is_ok_and(|f| f >= 0.0) {
                    warnings.push(self.warning(
                        n,
                        "not supported: load kinematics are not filtered separately \
                         (OpenSim 2 setting)",
                    ));
                }
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    fn inverse_dynamics(&self, tool: Node) -> crate::Result<InverseDynamicsSetup> {
        let mut s = InverseDynamicsSetup {
            source: self.path.to_path_buf(),
            name: tool.attribute("name").unwrap_or("").to_string(),
            model_file: None,
            coordinates_file: None,
            external_loads_file: None,
            lowpass_cutoff_hz: None,
            time_range: None,
            forces_to_exclude: Vec::new(),
            output_gen_force_file: None,
            results_directory: None,
            warnings: Vec::new(),
        };
        let mut joints_line = None;
        for n in tool.children().filter(Node::is_element) {
            match n.tag_name().name() {
                "model_file" => s.model_file = self.path(n),
                "coordinates_file" => s.coordinates_file = self.path(n),
                "external_loads_file" => s.external_loads_file = self.path(n),
                "results_directory" => s.results_directory = self.path(n),
                "output_gen_force_file" => {
                    s.output_gen_force_file = Self::text(n);
                    if let Some(name) = &s.output_gen_force_file {
                        self.plain_name(n, "the output file name", name)?;
                    }
                }
                "lowpass_cutoff_frequency_for_coordinates" => {
                    s.lowpass_cutoff_hz = self.cutoff(n)?
                }
                "time_range" => {
                    let v = self.numbers(n, 2)?;
                    if v[0].is_nan() || v[1].is_nan() || v[0] > v[1] {
                        return Err(self.error(n, format!("[{}, {}] is not a range", v[0], v[1])));
                    }
                    s.time_range = Some([v[0], v[1]]);
                }
                "forces_to_exclude" => s.forces_to_exclude = Self::words(n),
                "joints_to_report_body_forces" => {
                    if !Self::words(n).is_empty() {
                        joints_line = Some(n);
                    }
                }
                "output_body_forces_file" => {}
                _ => {
                    if !self.common(n, &mut s.warnings)? {
                        s.warnings.push(self.unknown(n, "InverseDynamicsTool"));
                    }
                }
            }
        }
        if let Some(n) = joints_line {
            s.warnings.push(self.warning(
                n,
                "not supported: equivalent body forces at joints are not computed",
            ));
        }
        Ok(s)
    }

    fn analyze(&self, tool: Node) -> crate::Result<AnalyzeSetup> {
        let mut s = AnalyzeSetup {
            source: self.path.to_path_buf(),
            name: tool.attribute("name").unwrap_or("").to_string(),
            model_file: None,
            coordinates_file: None,
            external_loads_file: None,
            lowpass_cutoff_hz: None,
            initial_time: None,
            final_time: None,
            results_directory: None,
            force_set_files: Vec::new(),
            replace_force_set: false,
            static_optimization: None,
            warnings: Vec::new(),
        };
        // The results are written as results_directory/<name>_<analysis>_….
        self.plain_name(tool, "the tool name", &s.name)?;
        for n in tool.children().filter(Node::is_element) {
            let tag = n.tag_name().name();
            match tag {
                "model_file" => s.model_file = self.path(n),
                "coordinates_file" => s.coordinates_file = self.path(n),
                "external_loads_file" => s.external_loads_file = self.path(n),
                "results_directory" => s.results_directory = self.path(n),
                "lowpass_cutoff_frequency_for_coordinates" => {
                    s.lowpass_cutoff_hz = self.cutoff(n)?
                }
                "initial_time" => s.initial_time = Some(self.number(n)?),
                "final_time" => s.final_time = Some(self.number(n)?),
                "replace_force_set" => s.replace_force_set = self.boolean(n)?,
                "force_set_files" => {
                    s.force_set_files = Self::words(n)
                        .into_iter()
                        .map(|w| resolve_data_path(base_dir(self.path), &w))
                        .collect()
                }
                "states_file" | "speeds_file" | "controls_file" => {
                    if Self::text(n).is_some() {
                        s.warnings.push(self.warning(
                            n,
                            format!(
                                "not supported: musculo derives everything from \
                                 coordinates_file; OpenSim would use this {}",
                                tag.trim_end_matches("_file")
                            ),
                        ));
                    }
                }
                "ControllerSet" => {
                    let has = n
                        .children()
                        .find(|c| c.has_tag_name("objects"))
                        .is_some_and(|o| o.children().any(|c| c.is_element()));
                    if has {
                        s.warnings
                            .push(self.warning(n, "not supported: controllers are not applied"));
                    }
                }
                "AnalysisSet" => {
                    let objects = n.children().find(|c| c.has_tag_name("objects"));
                    for a in objects
                        .iter()
                        .flat_map(|o| o.children())
                        .filter(Node::is_element)
                    {
                        if a.has_tag_name("StaticOptimization") {
                            if s.static_optimization.is_some() {
                                s.warnings.push(self.warning(
                                    a,
                                    "a second StaticOptimization analysis: only the first is \
                                     read",
                                ));
                                continue;
                            }
                            s.static_optimization =
                                Some(self.static_optimization(a, &mut s.warnings)?);
                        } else {
                            s.warnings.push(self.warning(
                                a,
                                format!(
                                    "not supported: the {} analysis is not run",
                                    a.tag_name().name()
                                ),
                            ));
                        }
                    }
                }
                t if INTEGRATOR.contains(&t) => {}
                _ => {
                    if !self.common(n, &mut s.warnings)? {
                        s.warnings.push(self.unknown(n, "AnalyzeTool"));
                    }
                }
            }
        }
        Ok(s)
    }

    fn static_optimization(
        &self,
        a: Node,
        warnings: &mut Vec<SetupWarning>,
    ) -> crate::Result<StaticOptimizationSetup> {
        let mut so = StaticOptimizationSetup {
            name: a
                .attribute("name")
                .unwrap_or("StaticOptimization")
                .to_string(),
            line: self.line(a),
            ..Default::default()
        };
        self.plain_name(a, "the analysis name", &so.name)?;
        for n in a.children().filter(Node::is_element) {
            match n.tag_name().name() {
                "on" => so.on = self.boolean(n)?,
                "start_time" => so.start_time = Some(self.number(n)?),
                "end_time" => so.end_time = Some(self.number(n)?),
                "step_interval" => {
                    so.step_interval = self.count(n)?;
                    if so.step_interval == 0 {
                        return Err(self.error(n, "the step interval must be at least 1".into()));
                    }
                }
                "in_degrees" => so.in_degrees = self.boolean(n)?,
                "use_model_force_set" => so.use_model_force_set = self.boolean(n)?,
                "activation_exponent" => {
                    so.activation_exponent = self.number(n)?;
                    if !(so.activation_exponent > 0.0 && so.activation_exponent.is_finite()) {
                        return Err(self.error(
                            n,
                            format!("{} is not a positive exponent", so.activation_exponent),
                        ));
                    }
                }
                "use_muscle_physiology" => so.use_muscle_physiology = self.boolean(n)?,
                "optimizer_convergence_criterion" => {
                    so.optimizer_convergence_criterion = self.number(n)?;
                    if so.optimizer_convergence_criterion.is_nan()
                        || so.optimizer_convergence_criterion <= 0.0
                    {
                        return Err(self.error(
                            n,
                            format!(
                                "{} is not a positive tolerance",
                                so.optimizer_convergence_criterion
                            ),
                        ));
                    }
                }
                "optimizer_max_iterations" => so.optimizer_max_iterations = self.count(n)?,
                _ => warnings.push(self.unknown(n, "StaticOptimization")),
            }
        }
        Ok(so)
    }
}

/// A number as OpenSim writes them, including `inf`, `-Inf`, `infinity`.
pub(crate) fn parse_number(t: &str) -> Option<f64> {
    t.parse::<f64>().ok().filter(|v| !v.is_nan())
}

#[cfg(test)]
mod tests {
    use super::*;

    const ID: &str = r#"<?xml version="1.0"?>
<OpenSimDocument Version="30000">
  <InverseDynamicsTool name="walk">
    <model_file>../subject01.osim</model_file>
    <results_directory>Results</results_directory>
    <time_range> 0 2.5</time_range>
    <forces_to_exclude> Muscles</forces_to_exclude>
    <external_loads_file>../ExperimentalData/grf.xml</external_loads_file>
    <coordinates_file>../IK/walk_IK.mot</coordinates_file>
    <lowpass_cutoff_frequency_for_coordinates>6</lowpass_cutoff_frequency_for_coordinates>
    <output_gen_force_file>walk_ID.sto</output_gen_force_file>
    <joints_to_report_body_forces> knee_r </joints_to_report_body_forces>
    <coordinates_in_degrees>true</coordinates_in_degrees>
  </InverseDynamicsTool>
</OpenSimDocument>"#;

    #[test]
    fn inverse_dynamics_settings_resolve_paths_against_the_setup_directory() {
        let s = InverseDynamicsSetup::parse(ID, Path::new("/data/ID/setup.xml")).unwrap();
        assert_eq!(s.name, "walk");
        assert_eq!(
            s.model_file,
            Some(PathBuf::from("/data/ID/../subject01.osim"))
        );
        assert_eq!(
            s.coordinates_file,
            Some(PathBuf::from("/data/ID/../IK/walk_IK.mot"))
        );
        assert_eq!(s.lowpass_cutoff_hz, Some(6.0));
        assert_eq!(s.time_range, Some([0.0, 2.5]));
        assert_eq!(s.forces_to_exclude, vec!["Muscles".to_string()]);
        assert_eq!(
            s.output_path(),
            Some(PathBuf::from("/data/ID/Results/walk_ID.sto"))
        );
        let w: Vec<String> = s.warnings.iter().map(|w| w.to_string()).collect();
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(
            w[0].contains("coordinates_in_degrees") && w[0].contains("setup.xml:13"),
            "{w:?}"
        );
        assert!(w[1].contains("joints_to_report_body_forces"), "{w:?}");
    }

    #[test]
    fn a_negative_cutoff_means_no_filtering_and_zero_is_an_error() {
        let t = ID.replace(">6<", ">-1<");
        let s = InverseDynamicsSetup::parse(&t, Path::new("s.xml")).unwrap();
        assert_eq!(s.lowpass_cutoff_hz, None);
        let e = InverseDynamicsSetup::parse(&ID.replace(">6<", ">0<"), Path::new("s.xml"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("s.xml:10") && e.contains("lowpass_cutoff"),
            "{e}"
        );
    }

    #[test]
    fn malformed_values_and_xml_are_errors_with_their_place() {
        let e = InverseDynamicsSetup::parse(&ID.replace(" 0 2.5", "0"), Path::new("s.xml"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("s.xml:6") && e.contains("InverseDynamicsTool \"walk\" > <time_range>"),
            "{e}"
        );
        let e = InverseDynamicsSetup::parse(&ID.replace("</model_file>", ""), Path::new("s.xml"))
            .unwrap_err();
        assert!(matches!(e, Error::Xml { .. }), "{e}");
        let e = AnalyzeSetup::parse(ID, Path::new("s.xml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("expected an AnalyzeTool"), "{e}");
    }

    #[test]
    fn static_optimization_settings_and_unsupported_analyze_settings() {
        let xml = r#"<OpenSimDocument Version="40000"><AnalyzeTool name="a">
            <model_file>m.osim</model_file>
            <replace_force_set>true</replace_force_set>
            <force_set_files> r1.xml  r2.xml </force_set_files>
            <initial_time>0.5</initial_time><final_time>2</final_time>
            <speeds_file>u.sto</speeds_file>
            <AnalysisSet name="Analyses"><objects>
              <StaticOptimization name="so"><step_interval>10</step_interval>
                <activation_exponent>3</activation_exponent>
                <use_muscle_physiology>false</use_muscle_physiology>
                <optimizer_max_iterations>50</optimizer_max_iterations></StaticOptimization>
              <MuscleAnalysis name="ma"/>
            </objects></AnalysisSet>
            <coordinates_file>q.sto</coordinates_file>
            <lowpass_cutoff_frequency_for_coordinates>-1</lowpass_cutoff_frequency_for_coordinates>
            <integrator_error_tolerance>1e-5</integrator_error_tolerance>
          </AnalyzeTool></OpenSimDocument>"#;
        let ToolSetup::Analyze(s) = parse(xml, Path::new("d/so.xml")).unwrap() else {
            panic!("not an AnalyzeTool")
        };
        assert!(s.replace_force_set);
        assert_eq!(
            s.force_set_files,
            vec![PathBuf::from("d/r1.xml"), PathBuf::from("d/r2.xml")]
        );
        assert_eq!((s.initial_time, s.final_time), (Some(0.5), Some(2.0)));
        let so = s.static_optimization.as_ref().unwrap();
        assert_eq!(so.step_interval, 10);
        assert_eq!(so.activation_exponent, 3.0);
        assert!(!so.use_muscle_physiology && so.use_model_force_set && so.on);
        assert_eq!(so.optimizer_max_iterations, 50);
        assert_eq!(so.optimizer_convergence_criterion, 1e-4);
        let w: Vec<String> = s.warnings.iter().map(|w| w.to_string()).collect();
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(w.iter().any(|m| m.contains("speeds_file")), "{w:?}");
        assert!(w.iter().any(|m| m.contains("MuscleAnalysis")), "{w:?}");
    }
}
