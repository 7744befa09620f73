//! `musculo._musculo`, the extension module of the Python package: models, dynamics, muscles
//! and the Euler–Lagrange loss on numpy arrays. Thin by design: it converts arrays (any leading
//! batch shape; the last axis holds one frame), releases the GIL while the library works
//! (frames in parallel on rayon's threads), and raises `musculo.MusculoError` with the
//! library's message for bad input.
//!
//! By topic: `model` (the `Model` class), `losses` (the physics losses), `reading` (motion
//! files and clips as arrays), `augmentation` (the augmentation chain), `evaluation`
//! (plausibility metrics) and `convert` (the exception and the array conversions they share).

mod augmentation;
mod convert;
mod evaluation;
mod losses;
mod model;
mod reading;

use pyo3::prelude::*;

#[pymodule]
fn _musculo(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<model::Model>()?;
    m.add_class::<losses::EulerLagrangeLoss>()?;
    m.add_class::<losses::LayoutEulerLagrangeLoss>()?;
    m.add_class::<losses::MuscleLoss>()?;
    m.add_function(wrap_pyfunction!(augmentation::augment_clip, m)?)?;
    m.add_function(wrap_pyfunction!(augmentation::augment_file, m)?)?;
    m.add_function(wrap_pyfunction!(reading::read_motion, m)?)?;
    m.add_function(wrap_pyfunction!(evaluation::evaluate, m)?)?;
    m.add("MusculoError", m.py().get_type::<convert::MusculoError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
