//! Joint capacity: the maximum isometric moment the muscles can give about a coordinate, in
//! each direction,
//!
//!   C±_j(q) = Σ_k max(0, ±r_jk(q)) F_iso,k(ℓ_k(q)),
//!
//! r the moment arms (r_jk = −∂ℓ_k/∂q_j) and F_iso,k the tendon force of muscle k at full
//! activation and zero speed (force–length and tendon included, as `musculo check` computes the
//! maximum isometric moments). [`capacity_at`] evaluates it at the pose of a `Data`;
//! [`CapacityCurves`] tabulates it once per model as joint strength curves, C±_j as a function
//! of q_j alone with every other coordinate at its default value (the torque–angle curves of
//! dynamometry), so that a metric over many frames costs one table lookup per coordinate.

use crate::dynamics::{self, Data};
use crate::model::Model;
use crate::muscle::MuscleSet;
use crate::muscle::path::{PathData, compute_paths};

/// Samples of each curve over its coordinate's range.
const CURVE_SAMPLES: usize = 41;

/// F_iso,k at the path lengths of `paths` into `f_iso` (0 where the muscle model gives no
/// finite positive force).
pub fn isometric_forces(muscles: &MuscleSet, paths: &PathData, f_iso: &mut [f64]) {
    for ((f, muscle), &l) in f_iso.iter_mut().zip(&muscles.muscles).zip(&paths.length) {
        let v = muscle.isometric_force(l);
        *f = if v.is_finite() { v.max(0.0) } else { 0.0 };
    }
}

/// (C+_j, C−_j) from the moment arms of `paths` and the forces `f_iso`.
pub fn capacity_at(paths: &PathData, f_iso: &[f64], j: usize) -> (f64, f64) {
    let (mut up, mut down) = (0.0, 0.0);
    for (k, f) in f_iso.iter().enumerate() {
        let arm = paths.moment_arms[(j, k)];
        if arm > 0.0 {
            up += arm * f;
        } else {
            down -= arm * f;
        }
    }
    (up, down)
}

/// One coordinate's strength curves on a uniform grid.
#[derive(Clone, Debug)]
struct Curve {
    lo: f64,
    step: f64,
    up: Vec<f64>,
    down: Vec<f64>,
}

/// The joint strength curves of a model (see the module documentation).
#[derive(Clone, Debug)]
pub struct CapacityCurves {
    /// Per independent coordinate; None where it is skipped or no muscle crosses it.
    curves: Vec<Option<Curve>>,
}

impl CapacityCurves {
    /// Curves for the independent coordinates of `model` but those in `skip` (the floating
    /// base), each sampled at 41 points over its range.
    pub fn new(model: &Model, skip: &[usize]) -> crate::Result<CapacityCurves> {
        let n = model.nq();
        let muscles = MuscleSet::new(model)?;
        let mut data = Data::new(model);
        let mut paths = PathData::new(model, &muscles.paths);
        let mut f_iso = vec![0.0; muscles.muscles.len()];
        let default = model.default_q();
        let mut curves = Vec::with_capacity(n);
        for (j, &c) in model.reduction.independent.iter().enumerate() {
            if skip.contains(&j) || muscles.muscles.is_empty() {
                curves.push(None);
                continue;
            }
            let [a, b] = model.coordinates[c].range;
            let (lo, hi) = (a.min(b), a.max(b));
            if !(hi > lo && (hi - lo).is_finite()) {
                curves.push(None);
                continue;
            }
            let step = (hi - lo) / (CURVE_SAMPLES - 1) as f64;
            let mut q = default.clone();
            let (mut up, mut down) = (Vec::new(), Vec::new());
            for i in 0..CURVE_SAMPLES {
                q[j] = lo + step * i as f64;
                dynamics::forward_kinematics(model, &mut data, &q)?;
                compute_paths(model, &data, &muscles.paths, &mut paths)?;
                isometric_forces(&muscles, &paths, &mut f_iso);
                let (u, d) = capacity_at(&paths, &f_iso, j);
                up.push(u);
                down.push(d);
            }
            let crossed = up.iter().chain(&down).any(|v| *v > 0.0);
            curves.push(crossed.then_some(Curve { lo, step, up, down }));
        }
        Ok(CapacityCurves { curves })
    }

    /// (C+_j, C−_j) at q_j (linear between samples, the end values outside the range); None
    /// for a coordinate without a curve.
    pub fn at(&self, j: usize, q: f64) -> Option<(f64, f64)> {
        let c = self.curves.get(j)?.as_ref()?;
        let last = c.up.len() - 1;
        let x = ((q - c.lo) / c.step).clamp(0.0, last as f64);
        let i = (x.floor() as usize).min(last - 1);
        let w = x - i as f64;
        let lerp = |v: &[f64]| v[i] + w * (v[i + 1] - v[i]);
        Some((lerp(&c.up), lerp(&c.down)))
    }
}
