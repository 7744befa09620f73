//! Reading motions: files (`read_motion`, and the options the other functions share: `format`,
//! `map`, `length_unit`) and clips given as arrays.

use crate::convert::{array, to_py};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// A HumanML3D or KIT-ML clip from an array (joints T × J × 3 or features T × F) at `fps`
/// (default: the format's rate), with the name of its built-in skeleton map.
pub(crate) fn motion_from_array(
    array: ndarray::ArrayViewD<'_, f64>,
    format: &str,
    fps: Option<f64>,
) -> musculo::Result<(musculo::motion::Motion, &'static str)> {
    use musculo::motion::{humanml3d, kit};
    match format {
        "humanml3d" => {
            let mut o = humanml3d::Options::default();
            o.rate_hz = fps.unwrap_or(o.rate_hz);
            Ok((humanml3d::from_array(array, "<array>", &o)?, "humanml3d"))
        }
        "kit" => {
            let mut o = kit::Options::default();
            o.rate_hz = fps.unwrap_or(o.rate_hz);
            Ok((kit::from_array(array, "<array>", &o)?, "kit"))
        }
        other => Err(musculo::Error::InvalidArgument {
            argument: "format",
            message: format!("\"{other}\": give \"humanml3d\" or \"kit\""),
        }),
    }
}

/// `length_unit` as Python gives it: a unit name ("m", "cm", "mm", "in") or metres per file
/// unit, as a string ("0.056444") or a number (0.056444). A bool is caught before the number
/// (Python's bool is an int, so `True` would otherwise read as 1 m per unit) and refused.
#[derive(Clone, Debug, FromPyObject)]
pub(crate) enum LengthUnitArg {
    Name(String),
    Flag(bool),
    Metres(f64),
}

/// `length_unit`: a unit name or metres per file unit.
pub(crate) fn length_unit_of(
    unit: Option<&LengthUnitArg>,
) -> musculo::Result<Option<musculo::motion::LengthUnit>> {
    unit.map(|u| {
        // A number goes through the same parser as its text (Rust's shortest round-trip
        // form: the same value), so that both forms accept the same range.
        let text = match u {
            LengthUnitArg::Name(name) => name.clone(),
            LengthUnitArg::Flag(flag) => {
                return Err(musculo::Error::InvalidArgument {
                    argument: "length_unit",
                    message: format!(
                        "{}: a bool is not a length unit; use m, cm, mm, in or a number",
                        if *flag { "True" } else { "False" }
                    ),
                });
            }
            LengthUnitArg::Metres(metres) => metres.to_string(),
        };
        musculo::motion::LengthUnit::parse(&text).ok_or_else(|| musculo::Error::InvalidArgument {
            argument: "length_unit",
            message: format!("`{text}`: use m, cm, mm, in or a number"),
        })
    })
    .transpose()
}

/// `map`: a JSON file (a `.json` name or an existing path) or a built-in map's name.
pub(crate) fn skeleton_map_of(
    name: Option<&str>,
) -> musculo::Result<Option<musculo::motion::skeleton::SkeletonMap>> {
    use musculo::motion::skeleton::SkeletonMap;
    match name {
        Some(n) if n.ends_with(".json") || std::path::Path::new(n).exists() => {
            Ok(Some(SkeletonMap::read(std::path::Path::new(n))?))
        }
        Some(n) => Ok(Some(SkeletonMap::builtin(n)?)),
        None => Ok(None),
    }
}

/// A motion file read as `musculo ik` and `musculo augment` read it: the motion, its format
/// and the skeleton map that applies (`map` given, else the format's built-in one; None for
/// markers matched by name).
pub(crate) fn read_clip(
    path: &std::path::Path,
    format: Option<&str>,
    map: Option<&str>,
    length_unit: Option<&LengthUnitArg>,
) -> musculo::Result<(
    musculo::motion::Motion,
    musculo::motion::Format,
    Option<musculo::motion::skeleton::SkeletonMap>,
)> {
    use musculo::motion::skeleton::SkeletonMap;
    use musculo::motion::{Format, ReadOptions};
    let format = match format {
        Some(f) => Format::parse(f)?,
        None => Format::detect(path)?,
    };
    let length_unit = length_unit_of(length_unit)?;
    let motion = musculo::motion::read(path, Some(format), &ReadOptions { length_unit })?;
    let map = match skeleton_map_of(map)? {
        Some(m) => Some(m),
        None => format.default_map().map(SkeletonMap::builtin).transpose()?,
    };
    Ok((motion, format, map))
}

/// Reads a motion file (HumanML3D/KIT-ML `.npy`, BVH, C3D, TRC; `format` overrides the
/// detection from the file, `length_unit` applies to BVH and KIT files) as musculo's readers
/// return it: a dict with `names` (K target names: joints or markers), `targets` (T × K × 3,
/// m, in the file's axes — C3D rotated into OpenSim's y-up frame — NaN where a marker is
/// missing), `time` (T, s), `rate_hz` and `source`.
#[pyfunction]
#[pyo3(signature = (path, format = None, length_unit = None))]
pub(crate) fn read_motion<'py>(
    py: Python<'py>,
    path: PathBuf,
    format: Option<&str>,
    length_unit: Option<LengthUnitArg>,
) -> PyResult<Bound<'py, PyDict>> {
    let (motion, _, _) = py
        .detach(|| read_clip(&path, format, None, length_unit.as_ref()))
        .map_err(to_py)?;
    let (t, k) = (motion.n_frames(), motion.names.len());
    let flat: Vec<f64> = motion
        .positions
        .iter()
        .flat_map(|p| [p.x, p.y, p.z])
        .collect();
    let d = PyDict::new(py);
    d.set_item("names", motion.names)?;
    d.set_item("targets", array(py, &[t], &[k, 3], flat)?)?;
    d.set_item("time", array(py, &[t], &[], motion.time)?)?;
    d.set_item("rate_hz", motion.rate_hz)?;
    d.set_item("source", motion.source)?;
    Ok(d)
}
