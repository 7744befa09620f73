//! Physical-plausibility metrics of tensor and motion files (`musculo evaluate`).

use crate::convert::{MusculoError, to_py};
use crate::reading::{LengthUnitArg, length_unit_of, skeleton_map_of};
use pyo3::prelude::*;
use std::path::PathBuf;

/// Physical-plausibility metrics (`musculo evaluate`) of tensor files (`.npz` in musculo's
/// format, e.g. written from `augment_clip`'s arrays or by a generator) and motion files,
/// or folders of them: a dict with `clips` (one dict of metrics per clip), `failed`
/// ([clip, reason] pairs) and `summary` (FlexMotion's columns). `floor` is a height in metres
/// or "clip"; `floor_velocity` the floor's velocity (x, y, z) in m/s (a treadmill's belt) or
/// "clip" (each clip's own), a floor at rest by default; `model`, `reference` and `control` are paths as for the command; see the
/// documentation of `musculo::evaluate` for every metric's definition and unit.
#[pyfunction]
#[pyo3(signature = (inputs, model = None, reference = None, control = None, floor = None, floor_velocity = None, muscles_per_frame = false, format = None, map = None, length_unit = None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn evaluate<'py>(
    py: Python<'py>,
    inputs: Vec<PathBuf>,
    model: Option<PathBuf>,
    reference: Option<PathBuf>,
    control: Option<PathBuf>,
    floor: Option<Bound<'py, PyAny>>,
    floor_velocity: Option<Bound<'py, PyAny>>,
    muscles_per_frame: bool,
    format: Option<&str>,
    map: Option<&str>,
    length_unit: Option<LengthUnitArg>,
) -> PyResult<Bound<'py, PyAny>> {
    use musculo::evaluate::{EvaluateOptions, SetOptions, collect, evaluate_set};
    use musculo::motion::{Format, ReadOptions};
    let floor_height = match floor {
        None => Some(0.0),
        Some(f) if f.extract::<String>().is_ok_and(|s| s == "clip") => None,
        Some(f) => Some(
            f.extract::<f64>()
                .map_err(|_| MusculoError::new_err("floor: give a height in metres or \"clip\""))?,
        ),
    };
    let floor_velocity = match floor_velocity {
        None => Some(musculo::spatial::Vec3::zeros()),
        Some(v) if v.extract::<String>().is_ok_and(|s| s == "clip") => None,
        Some(v) => {
            let c: [f64; 3] = v.extract().map_err(|_| {
                MusculoError::new_err("floor_velocity: give (x, y, z) in m/s or \"clip\"")
            })?;
            Some(musculo::spatial::Vec3::new(c[0], c[1], c[2]))
        }
    };
    let text = py
        .detach(|| -> musculo::Result<String> {
            let format = format.map(Format::parse).transpose()?;
            let length_unit = length_unit_of(length_unit.as_ref())?;
            let map = skeleton_map_of(map)?;
            let clips = collect(&inputs, format)?;
            let options = SetOptions {
                model,
                reference,
                control,
                metrics: EvaluateOptions {
                    floor_height,
                    floor_velocity,
                    muscles_per_frame,
                    ..EvaluateOptions::default()
                },
                read: ReadOptions { length_unit },
                map,
            };
            let report = evaluate_set(&clips, &options, &|_, _| {})?;
            serde_json::to_string(&report).map_err(|e| musculo::Error::InvalidArgument {
                argument: "report",
                message: e.to_string(),
            })
        })
        .map_err(to_py)?;
    py.import("json")?.call_method1("loads", (text,))
}
