//! Errors and conversions between numpy arrays and the library's frame-major buffers: the
//! `MusculoError` exception, frames of arrays with any leading batch shape, the per-joint layout's
//! blocks, per-frame parallel runs and JSON values.

use ndarray::{ArrayD, IxDyn};
use numpy::{AllowTypeChange, IntoPyArray, PyArrayDyn, PyArrayLikeDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

pyo3::create_exception!(
    _musculo,
    MusculoError,
    PyValueError,
    "An error reported by musculo: bad input (shape, non-finite value, unknown name) or a bad model file."
);

pub(crate) fn to_py(e: musculo::Error) -> PyErr {
    MusculoError::new_err(e.to_string())
}

pub(crate) type Input<'py> = PyArrayLikeDyn<'py, f64, AllowTypeChange>;
pub(crate) type Output<'py> = Bound<'py, PyArrayDyn<f64>>;

/// The frames of an array whose last axis holds `width` values: (values in C order, leading
/// shape).
pub(crate) fn frames(name: &str, a: &Input, width: usize) -> PyResult<(Vec<f64>, Vec<usize>)> {
    let shape = a.as_array().shape().to_vec();
    if shape.last() != Some(&width) {
        return Err(MusculoError::new_err(format!(
            "{name}: shape {shape:?}; its last axis must have {width} values"
        )));
    }
    Ok((
        a.as_array().iter().copied().collect(),
        shape[..shape.len() - 1].to_vec(),
    ))
}

/// Frames of a second array that must have the leading shape `lead`.
pub(crate) fn frames_like(
    name: &str,
    a: &Input,
    width: usize,
    lead: &[usize],
) -> PyResult<Vec<f64>> {
    let (v, l) = frames(name, a, width)?;
    if l != lead {
        return Err(MusculoError::new_err(format!(
            "{name}: leading shape {l:?} differs from q's {lead:?}"
        )));
    }
    Ok(v)
}

pub(crate) fn array<'py>(
    py: Python<'py>,
    lead: &[usize],
    tail: &[usize],
    values: Vec<f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let shape: Vec<usize> = lead.iter().chain(tail).copied().collect();
    let a = ArrayD::from_shape_vec(IxDyn(&shape), values)
        .map_err(|e| MusculoError::new_err(format!("internal shape error: {e}")))?;
    Ok(a.into_pyarray(py))
}

/// The values of an array of shape (lead..., `points`, 3), in C order.
pub(crate) fn point_frames(
    name: &str,
    a: &Input,
    points: usize,
    lead: &[usize],
) -> PyResult<Vec<f64>> {
    let (v, lead_a) = frames(name, a, 3)?;
    let expected: Vec<usize> = lead.iter().copied().chain([points]).collect();
    if lead_a != expected {
        return Err(MusculoError::new_err(format!(
            "{name}: shape {:?}; expected {:?}",
            a.as_array().shape(),
            expected.iter().chain(&[3]).collect::<Vec<_>>()
        )));
    }
    Ok(v)
}

/// Sets `grad_q`, `grad_qd`, `grad_qdd`, `grad_tau` (lead..., n) in `d`.
pub(crate) fn set_coordinate_gradients(
    py: Python<'_>,
    d: &Bound<'_, PyDict>,
    lead: &[usize],
    n: usize,
    grads: [Vec<f64>; 4],
) -> PyResult<()> {
    for (name, g) in ["grad_q", "grad_qd", "grad_qdd", "grad_tau"]
        .into_iter()
        .zip(grads)
    {
        d.set_item(name, array(py, lead, &[n], g)?)?;
    }
    Ok(())
}

/// The five T × J × 3 blocks of a clip in the per-joint layout (joint_pos, joint_rot,
/// joint_vel, joint_acc, joint_torque), in C order.
pub(crate) struct LayoutBlocks([Vec<f64>; 5]);

impl LayoutBlocks {
    pub(crate) fn clip(
        &self,
        frames: usize,
        fps: f64,
    ) -> musculo::augment::layout_inverse::LayoutClip<'_> {
        musculo::augment::layout_inverse::LayoutClip {
            frames,
            rate_hz: fps,
            joint_pos: &self.0[0],
            joint_rot: &self.0[1],
            joint_vel: &self.0[2],
            joint_acc: &self.0[3],
            joint_torque: &self.0[4],
        }
    }
}

/// Reads the layout blocks, each T × `nj` × 3 with the same T; returns them and T.
pub(crate) fn layout_blocks(nj: usize, arrays: [Input; 5]) -> PyResult<(LayoutBlocks, usize)> {
    let names = [
        "joint_pos",
        "joint_rot",
        "joint_vel",
        "joint_acc",
        "joint_torque",
    ];
    let mut frames = None;
    let mut out: [Vec<f64>; 5] = Default::default();
    for ((name, a), v) in names.iter().zip(&arrays).zip(&mut out) {
        let shape = a.as_array().shape().to_vec();
        if shape.len() != 3 || shape[1] != nj || shape[2] != 3 {
            return Err(MusculoError::new_err(format!(
                "{name}: shape {shape:?}; expected T × {nj} × 3 (the model's joints)"
            )));
        }
        let t = *frames.get_or_insert(shape[0]);
        if shape[0] != t {
            return Err(MusculoError::new_err(format!(
                "{name}: {} frames; joint_pos has {t}",
                shape[0]
            )));
        }
        *v = a.as_array().iter().copied().collect();
    }
    Ok((LayoutBlocks(out), frames.unwrap_or(0)))
}

/// Runs `f(workspace, frame, row)` for every frame in parallel (one workspace per worker),
/// each writing its `width` values of the result.
pub(crate) fn per_frame<W, I, F>(
    frames: usize,
    width: usize,
    init: I,
    f: F,
) -> musculo::Result<Vec<f64>>
where
    I: Fn() -> W + Sync + Send,
    F: Fn(&mut W, usize, &mut [f64]) -> musculo::Result<()> + Sync + Send,
{
    let mut out = vec![0.0; frames * width];
    let at = |i: usize, e: musculo::Error| musculo::Error::InvalidArgument {
        argument: "frames",
        message: format!("frame {i}: {e}"),
    };
    if width == 0 {
        let mut w = init();
        for i in 0..frames {
            f(&mut w, i, &mut []).map_err(|e| at(i, e))?;
        }
        return Ok(out);
    }
    out.par_chunks_mut(width)
        .enumerate()
        .try_for_each_init(init, |w, (i, row)| f(w, i, row).map_err(|e| at(i, e)))?;
    Ok(out)
}

/// A JSON value as the Python object json.loads would give.
pub(crate) fn json_to_py<'py>(
    py: Python<'py>,
    v: &serde_json::Value,
) -> PyResult<Bound<'py, PyAny>> {
    use pyo3::IntoPyObjectExt;
    use serde_json::Value;
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_bound_py_any(py)?,
        Value::Number(n) => match n.as_i64() {
            Some(i) => i.into_bound_py_any(py)?,
            None => n.as_f64().unwrap_or(f64::NAN).into_bound_py_any(py)?,
        },
        Value::String(s) => s.into_bound_py_any(py)?,
        Value::Array(a) => a
            .iter()
            .map(|x| json_to_py(py, x))
            .collect::<PyResult<Vec<_>>>()?
            .into_bound_py_any(py)?,
        Value::Object(o) => {
            let d = PyDict::new(py);
            for (k, x) in o {
                d.set_item(k, json_to_py(py, x)?)?;
            }
            d.into_any()
        }
    })
}
