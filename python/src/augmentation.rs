//! The augmentation chain of `musculo augment` on one clip: `augment_clip` (an array) and
//! `augment_file` (a motion file).

use crate::convert::{Input, MusculoError, json_to_py, to_py};
use crate::reading::{LengthUnitArg, motion_from_array, read_clip};
use ndarray::{ArrayD, IxDyn};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// Runs `musculo augment`'s chain on one clip given as an array — HumanML3D `new_joints`
/// (T × 22 × 3, m, y up) or `new_joint_vecs` (T × 263), or KIT-ML's (T × 21 × 3, T × 251) with
/// `format="kit"` — at `fps` frames per second (default the format's: 20, 12.5): the default
/// model scaled to the clip's bone lengths (with `scale_to_clip`), inverse
/// kinematics, inverse dynamics with contact forces from kinematics, static optimization and
/// excitations. Returns a dict of float32 arrays named as in the `.npz` files of `musculo
/// augment` (`q`, `qd`, `qdd`, `tau`, `contact_point_force`, `muscle_act`, `x`, …), with
/// `quality` (the manifest's per-clip figures), `model_xml` (the scaled model as OpenSim
/// XML, None when not scaled: `Model.from_osim_string(out["model_xml"])` is the model the
/// arrays belong to) and `model_identity` (the body the arrays belong to, as the `.npz`
/// member `model_identity` of `musculo augment` records it). `muscle_strength` multiplies every muscle's maximum isometric force
/// (`musculo augment --muscle-strength`; 1: the model as built).
#[pyfunction]
#[pyo3(signature = (joints, fps = None, format = "humanml3d", scale_to_clip = true, muscle_strength = 1.0))]
pub(crate) fn augment_clip<'py>(
    py: Python<'py>,
    joints: Input<'py>,
    fps: Option<f64>,
    format: &str,
    scale_to_clip: bool,
    muscle_strength: f64,
) -> PyResult<Bound<'py, PyDict>> {
    use musculo::augment::perturb::Variant;
    use musculo::motion::skeleton::SkeletonMap;
    let array = joints.as_array().to_owned();
    let output = py
        .detach(|| -> musculo::Result<_> {
            let (motion, map_name) = motion_from_array(array.view(), format, fps)?;
            let map = SkeletonMap::builtin(map_name)?;
            default_chain(scale_to_clip, muscle_strength)?.run(
                &motion,
                Some(&map),
                &Variant::identity(),
            )
        })
        .map_err(to_py)?;
    clip_output_dict(py, output)
}

/// [`augment_clip`] on a motion file, read and mapped as `musculo augment` reads it (see
/// `Model.inverse_kinematics_file` for `format`, `map`, `length_unit`); with
/// `force_plates=True` a C3D file's own force platforms are the ground reactions instead of
/// the estimate from kinematics; `muscle_strength` as for `augment_clip`. Returns the same
/// dict as `augment_clip`.
#[pyfunction]
#[pyo3(signature = (path, format = None, map = None, length_unit = None, scale_to_clip = true, force_plates = false, muscle_strength = 1.0))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn augment_file<'py>(
    py: Python<'py>,
    path: PathBuf,
    format: Option<&str>,
    map: Option<&str>,
    length_unit: Option<LengthUnitArg>,
    scale_to_clip: bool,
    force_plates: bool,
    muscle_strength: f64,
) -> PyResult<Bound<'py, PyDict>> {
    use musculo::augment::chain::MeasuredLoads;
    use musculo::motion::Format;
    let output = py
        .detach(|| -> musculo::Result<_> {
            let (motion, format, map) = read_clip(&path, format, map, length_unit.as_ref())?;
            let loads = match (force_plates, format) {
                (false, _) => None,
                (true, Format::C3d) => Some(MeasuredLoads::ForcePlates(path.clone())),
                (true, _) => {
                    return Err(musculo::Error::InvalidArgument {
                        argument: "force_plates",
                        message: format!(
                            "{} is not a C3D file: only C3D files carry force platforms",
                            path.display()
                        ),
                    });
                }
            };
            default_chain(scale_to_clip, muscle_strength)?.run_with_loads(
                &motion,
                map.as_ref(),
                &musculo::augment::perturb::Variant::identity(),
                loads.as_ref(),
            )
        })
        .map_err(to_py)?;
    clip_output_dict(py, output)
}

/// The augmentation chain on the built-in default model.
pub(crate) fn default_chain(
    scale_to_clip: bool,
    muscle_strength: f64,
) -> musculo::Result<musculo::augment::chain::Chain> {
    use musculo::augment::chain::{Chain, ChainOptions};
    Chain::new(
        musculo::DEFAULT_MODEL_OSIM.to_string(),
        "musculo_fullbody.osim".to_string(),
        ChainOptions {
            scale_to_clip,
            opensim_files: true,
            muscle_strength,
            ..ChainOptions::default()
        },
    )
}

/// The arrays, quality figures, scaled model and warnings of one augmented clip.
pub(crate) fn clip_output_dict(
    py: Python<'_>,
    output: musculo::augment::chain::ClipOutput,
) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    for a in output.arrays {
        let values = ArrayD::from_shape_vec(IxDyn(&a.shape), a.values)
            .map_err(|e| MusculoError::new_err(format!("internal shape error: {e}")))?;
        d.set_item(a.name, values.into_pyarray(py))?;
    }
    let quality = serde_json::to_value(&output.quality)
        .map_err(|e| MusculoError::new_err(format!("quality: {e}")))?;
    d.set_item("quality", json_to_py(py, &quality)?)?;
    d.set_item("model_xml", output.model_xml)?;
    let identity: serde_json::Value = serde_json::from_str(&output.identity.to_json())
        .map_err(|e| MusculoError::new_err(format!("model identity: {e}")))?;
    d.set_item("model_identity", json_to_py(py, &identity)?)?;
    d.set_item("warnings", output.warnings)?;
    Ok(d)
}
