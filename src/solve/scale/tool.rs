//! OpenSim's `ScaleTool::run` from a setup file: GenericModelMaker (load the generic model,
//! merge the marker set, name the model after the tool), ModelScaler (factors, scaled
//! model, scale-set file), MarkerPlacer (see [`super::place`]). The library writes no file:
//! the result lists each output the setup asks for, with its path and text.

pub use super::measure::read_trial;
use super::measure::{MeasuredFactor, scale_set};
use super::{ScaleOptions, ScaleSet, ScaledModel, markers, scale_osim};
use crate::error::Error;
use crate::io::scale_setup::{ScaleSetup, ScalingStep, read_marker_set};
use crate::io::setup::SetupWarning;
use crate::model::{LoadOptions, Model};
use std::path::{Path, PathBuf};

/// Choices the setup file does not make.
#[derive(Clone, Debug, Default)]
pub struct ToolOptions {
    /// The generic model to scale instead of GenericModelMaker's `model_file`.
    pub model_file: Option<PathBuf>,
    /// Skip MarkerPlacer even when the setup applies it.
    pub skip_placement: bool,
    /// Options for reading the models.
    pub load: LoadOptions,
}

/// What an output file is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputKind {
    /// ModelScaler `output_model_file`.
    ScaledModel,
    /// ModelScaler `output_scale_file`.
    ScaleSet,
    /// MarkerPlacer `output_model_file`.
    PlacedModel,
    /// MarkerPlacer `output_marker_file`.
    MarkerSet,
    /// MarkerPlacer `output_motion_file`.
    StaticPose,
}

/// A file the setup asks for: where (resolved against the setup's folder) and its text.
#[derive(Clone, Debug)]
pub struct Output {
    pub kind: OutputKind,
    pub path: PathBuf,
    pub text: String,
}

/// Everything a Scale tool run produced.
#[derive(Clone, Debug)]
pub struct ScaleToolResult {
    /// The tool's name (the scaled model's name).
    pub name: String,
    /// The generic model read.
    pub generic_file: PathBuf,
    /// The generic model after GenericModelMaker (marker set merged), parsed.
    pub generic: Model,
    /// The factors applied (None when ModelScaler is absent or off).
    pub scale_set: Option<ScaleSet>,
    /// Each applied measurement's factor and pair distances.
    pub measurements: Vec<MeasuredFactor>,
    /// The model after ModelScaler (the generic model when it did not run).
    pub scaled: ScaledModel,
    /// MarkerPlacer's result, when it ran.
    pub placement: Option<super::place::Placement>,
    /// The files to write, in the order OpenSim writes them.
    pub outputs: Vec<Output>,
    pub warnings: Vec<SetupWarning>,
}

impl ScaleToolResult {
    /// The final model: after marker placement when it ran, else after scaling.
    pub fn final_model(&self) -> (&str, &Model) {
        match &self.placement {
            Some(p) => (&p.xml, &p.model),
            None => (&self.scaled.xml, &self.scaled.model),
        }
    }
}

fn read(path: &Path) -> crate::Result<String> {
    crate::text::read_text(path)
}

/// Runs the Scale tool a setup describes.
pub fn run(setup: &ScaleSetup, options: &ToolOptions) -> crate::Result<ScaleToolResult> {
    let mut warnings = setup.warnings.clone();
    let setup_file = setup.source.display().to_string();
    let gmm = setup.generic_model_maker.as_ref();
    let generic_file = match (&options.model_file, gmm.and_then(|g| g.model_file.clone())) {
        (Some(m), _) => m.clone(),
        (None, Some(m)) => m,
        (None, None) => {
            return Err(match gmm {
                Some(g) => g
                    .place
                    .error("no model_file: the generic model is not named"),
                None => Error::Model {
                    file: setup_file,
                    line: 1,
                    element: format!("ScaleTool \"{}\"", setup.name),
                    message: "no GenericModelMaker: the generic model is not named".into(),
                },
            });
        }
    };
    let source = generic_file.display().to_string();
    let mut xml = read(&generic_file)?;
    let mut model = Model::from_osim_str_with(&xml, &source, &options.load)?;
    if let Some(file) = gmm.and_then(|g| g.marker_set_file.as_ref()) {
        let (defs, w) = read_marker_set(file)?;
        warnings.extend(w);
        xml = markers::merge_marker_set(&xml, &source, &model, &defs)?;
        model = Model::from_osim_str_with(&xml, &source, &options.load)?;
    }
    if !setup.name.is_empty() {
        xml = markers::rename_model(&xml, &source, &setup.name)?;
        model = Model::from_osim_str_with(&xml, &source, &options.load)?;
    }
    let generic = model.clone();
    let mut outputs = Vec::new();
    let mut scale_result = None;
    let mut measurements = Vec::new();
    let scaled = match setup.model_scaler.as_ref().filter(|s| s.apply) {
        Some(scaler) => {
            let needs_trial = scaler.scaling_order.contains(&ScalingStep::Measurements)
                && scaler.measurements.iter().any(|m| m.apply);
            let trial = match (&scaler.marker_file, needs_trial) {
                (Some(f), true) => {
                    let (trial, read) = read_trial(f)?;
                    warnings.extend(read);
                    Some(trial)
                }
                _ => None,
            };
            let (set, measured, w) = scale_set(&model, scaler, trial.as_ref())?;
            warnings.extend(w);
            let scale_options = ScaleOptions {
                preserve_mass_distribution: scaler.preserve_mass_distribution,
                subject_mass: setup.mass,
                load: options.load.clone(),
                ..ScaleOptions::default()
            };
            let scaled = scale_osim(&xml, &source, &model, &set, &scale_options)?;
            if let Some(p) = &scaler.output_model_file {
                outputs.push(Output {
                    kind: OutputKind::ScaledModel,
                    path: p.clone(),
                    text: scaled.xml.clone(),
                });
            }
            if let Some(p) = &scaler.output_scale_file {
                outputs.push(Output {
                    kind: OutputKind::ScaleSet,
                    path: p.clone(),
                    text: markers::scale_set_file(&set, &xml, &source)?,
                });
            }
            measurements = measured;
            scale_result = Some(set);
            scaled
        }
        None => ScaledModel {
            total_mass: model.total_mass(),
            xml: xml.clone(),
            model: model.clone(),
            length_ratios: Vec::new(),
        },
    };
    let mut placement = None;
    if let Some(placer) = setup.marker_placer.as_ref().filter(|p| p.apply)
        && !options.skip_placement
    {
        let p = super::place::place_markers(&scaled.xml, &source, placer, &options.load)?;
        warnings.extend(p.warnings.iter().cloned());
        for (kind, path, text) in [
            (
                OutputKind::PlacedModel,
                &placer.output_model_file,
                Some(&p.xml),
            ),
            (OutputKind::MarkerSet, &placer.output_marker_file, None),
            (
                OutputKind::StaticPose,
                &placer.output_motion_file,
                Some(&p.static_pose),
            ),
        ] {
            let Some(path) = path else { continue };
            let text = match text {
                Some(t) => t.clone(),
                None => markers::marker_set_file(&p.xml, &source)?,
            };
            outputs.push(Output {
                kind,
                path: path.clone(),
                text,
            });
        }
        placement = Some(p);
    }
    Ok(ScaleToolResult {
        name: setup.name.clone(),
        generic_file,
        generic,
        scale_set: scale_result,
        measurements,
        scaled,
        placement,
        outputs,
        warnings,
    })
}
