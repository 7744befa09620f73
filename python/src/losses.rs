//! The physics losses with their gradients: `EulerLagrangeLoss`, `LayoutEulerLagrangeLoss` and
//! `MuscleLoss`.

use crate::convert::{
    Input, MusculoError, array, frames, frames_like, point_frames, set_coordinate_gradients, to_py,
};
use crate::model::Model;
use musculo::loss::{
    EulerLagrange, EulerLagrangeBatch, EulerLagrangeOutput, LossContact, MuscleBatch,
    MuscleLoss as MuscleLossCore, MuscleLossOutput,
};
use musculo::solve::contact::ContactSet;
use musculo::spatial::Vec3;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::Arc;

/// The Euler–Lagrange loss L = Σ_t Σ_j w_j r_tj², r = M q̈ + C q̇ + G − τ − Σ_i J_iᵀ λ_i, with
/// its gradients.
#[pyclass(frozen, module = "musculo")]
pub(crate) struct EulerLagrangeLoss {
    model: Arc<musculo::Model>,
    loss: EulerLagrange,
}

#[pymethods]
impl EulerLagrangeLoss {
    /// `contacts`: None (no contact forces, the default), "model" (the model's contact
    /// spheres, each loaded at its lowest point on the floor), or a list of `(body name,
    /// [x, y, z] in the body, [gx, gy, gz] offset fixed in ground)`. `weights`: one w_j ≥ 0 per
    /// coordinate (default all 1).
    #[new]
    #[pyo3(signature = (model, contacts = None, weights = None))]
    fn new(
        model: &Model,
        contacts: Option<&Bound<'_, PyAny>>,
        weights: Option<Vec<f64>>,
    ) -> PyResult<EulerLagrangeLoss> {
        let mut loss = match contacts {
            None => EulerLagrange::new(),
            Some(c) if c.extract::<String>().is_ok() => {
                let word: String = c.extract()?;
                if word != "model" {
                    return Err(MusculoError::new_err(format!(
                        "contacts: \"{word}\" — give \"model\", None or a list of (body, location, offset)"
                    )));
                }
                EulerLagrange::new()
                    .with_contact_set(&ContactSet::from_model(&model.inner).map_err(to_py)?)
            }
            Some(c) => {
                let list: Vec<(String, [f64; 3], [f64; 3])> = c.extract()?;
                EulerLagrange {
                    contacts: list
                        .iter()
                        .enumerate()
                        .map(|(i, (b, c, g))| {
                            Ok(LossContact {
                                name: format!("{b}#{i}"),
                                body: model.body(b)?,
                                location_in_body: Vec3::new(c[0], c[1], c[2]),
                                offset_in_ground: Vec3::new(g[0], g[1], g[2]),
                            })
                        })
                        .collect::<PyResult<_>>()?,
                    weights: vec![],
                }
            }
        };
        loss.weights = weights.unwrap_or_default();
        loss.validate(&model.inner).map_err(to_py)?;
        Ok(EulerLagrangeLoss {
            model: model.inner.clone(),
            loss,
        })
    }

    /// Names of the contact points, in the order of λ's second-to-last axis.
    #[getter]
    fn contact_names(&self) -> Vec<String> {
        self.loss.contacts.iter().map(|c| c.name.clone()).collect()
    }

    /// L and its parts for q, q̇, q̈, τ (..., n) and λ (..., P, 3): a dict with `loss` (float),
    /// `per_frame` (...), `residual` (..., n) and, with `gradients`, `grad_q`, `grad_qd`,
    /// `grad_qdd`, `grad_tau` (..., n) and `grad_lambda` (..., P, 3).
    #[pyo3(signature = (q, qd, qdd, tau, lam = None, gradients = true))]
    #[allow(clippy::too_many_arguments)]
    fn __call__<'py>(
        &self,
        py: Python<'py>,
        q: Input<'py>,
        qd: Input<'py>,
        qdd: Input<'py>,
        tau: Input<'py>,
        lam: Option<Input<'py>>,
        gradients: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (m, n, p) = (&*self.model, self.model.nq(), self.loss.contacts.len());
        let (q, lead) = frames("q", &q, n)?;
        let qd = frames_like("qd", &qd, n, &lead)?;
        let qdd = frames_like("qdd", &qdd, n, &lead)?;
        let tau = frames_like("tau", &tau, n, &lead)?;
        let t = q.len() / n.max(1);
        let lambda = match (&lam, p) {
            (None, 0) => vec![],
            (None, _) => {
                return Err(MusculoError::new_err(format!(
                    "lam: this loss has {p} contact points; give λ of shape (..., {p}, 3)"
                )));
            }
            (Some(l), _) => point_frames("lam", l, p, &lead)?,
        };
        let mut out = EulerLagrangeOutput::default();
        py.detach(|| {
            let batch = EulerLagrangeBatch {
                frames: t,
                q: &q,
                qd: &qd,
                qdd: &qdd,
                tau: &tau,
                lambda: &lambda,
            };
            self.loss.evaluate(m, &batch, gradients, &mut out)
        })
        .map_err(to_py)?;
        let d = PyDict::new(py);
        d.set_item("loss", out.loss)?;
        d.set_item("per_frame", array(py, &lead, &[], out.per_frame)?)?;
        d.set_item("residual", array(py, &lead, &[n], out.residual)?)?;
        if gradients {
            let grads = [out.grad_q, out.grad_qd, out.grad_qdd, out.grad_tau];
            set_coordinate_gradients(py, &d, &lead, n, grads)?;
            d.set_item("grad_lambda", array(py, &lead, &[p, 3], out.grad_lambda)?)?;
        }
        Ok(d)
    }
}

/// L_euler of motions in the per-joint layout (`loss::layout`): the layout's contact forces
/// (one per joint, T × J × 3) act at the joint centres, with a free couple on each body that
/// touches the ground, the couple that best explains the motion; r = M q̈ + C q̇ + G − τ −
/// Σ_j J_jᵀ λ_j − Σ_b J_ω,bᵀ μ_b at the best μ, L = Σ_t Σ_j w_j r_tj², with its gradients.
#[pyclass(frozen, module = "musculo")]
pub(crate) struct LayoutEulerLagrangeLoss {
    model: Arc<musculo::Model>,
    loss: musculo::loss::LayoutEulerLagrange,
}

#[pymethods]
impl LayoutEulerLagrangeLoss {
    /// `couples`: "model" (the bodies of the model's contact spheres, the default), None (no
    /// couples) or a list of body names. `weights`: one w_j ≥ 0 per coordinate (default 1).
    #[new]
    #[pyo3(signature = (model, couples = Some("model".to_string()), weights = None))]
    fn new(
        model: &Model,
        couples: Option<String>,
        weights: Option<Vec<f64>>,
    ) -> PyResult<LayoutEulerLagrangeLoss> {
        let bodies = LayoutEulerLagrangeLoss::bodies(model, couples.as_deref(), None)?;
        Self::build(model, bodies, weights)
    }

    /// The same with the couples on the bodies named in `bodies`.
    #[staticmethod]
    #[pyo3(signature = (model, bodies, weights = None))]
    fn on_bodies(
        model: &Model,
        bodies: Vec<String>,
        weights: Option<Vec<f64>>,
    ) -> PyResult<LayoutEulerLagrangeLoss> {
        let bodies = LayoutEulerLagrangeLoss::bodies(model, None, Some(&bodies))?;
        Self::build(model, bodies, weights)
    }

    /// Names of the bodies that carry a couple, in the order of `couple`'s second-to-last
    /// axis.
    #[getter]
    fn couple_bodies(&self) -> Vec<String> {
        self.loss
            .couple_bodies()
            .iter()
            .map(|&b| self.model.bodies[b].name.clone())
            .collect()
    }

    /// L for q, q̇, q̈, τ (..., T, n; e.g. from `Model.coordinates_from_layout`) and the
    /// layout's `contact_force` (..., T, J, 3): a dict with `loss`, `per_frame`, `residual`
    /// (at the best couples), `couple` (..., T, B, 3) and, with `gradients`, `grad_q`,
    /// `grad_qd`, `grad_qdd`, `grad_tau` (..., n) and `grad_contact_force` (..., J, 3).
    #[pyo3(signature = (q, qd, qdd, tau, contact_force, gradients = true))]
    #[allow(clippy::too_many_arguments)]
    fn __call__<'py>(
        &self,
        py: Python<'py>,
        q: Input<'py>,
        qd: Input<'py>,
        qdd: Input<'py>,
        tau: Input<'py>,
        contact_force: Input<'py>,
        gradients: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        use musculo::loss::{LayoutEulerLagrangeBatch, LayoutEulerLagrangeOutput};
        let m = &*self.model;
        let (n, nj, nb) = (m.nq(), m.joints.len(), self.loss.couple_bodies().len());
        let (q, lead) = frames("q", &q, n)?;
        let qd = frames_like("qd", &qd, n, &lead)?;
        let qdd = frames_like("qdd", &qdd, n, &lead)?;
        let tau = frames_like("tau", &tau, n, &lead)?;
        let t = q.len() / n.max(1);
        let lambda = point_frames("contact_force", &contact_force, nj, &lead)?;
        let mut out = LayoutEulerLagrangeOutput::default();
        py.detach(|| {
            let batch = LayoutEulerLagrangeBatch {
                frames: t,
                q: &q,
                qd: &qd,
                qdd: &qdd,
                tau: &tau,
                contact_force: &lambda,
            };
            self.loss.evaluate(m, &batch, gradients, &mut out)
        })
        .map_err(to_py)?;
        let d = PyDict::new(py);
        d.set_item("loss", out.loss)?;
        d.set_item("per_frame", array(py, &lead, &[], out.per_frame)?)?;
        d.set_item("residual", array(py, &lead, &[n], out.residual)?)?;
        d.set_item("couple", array(py, &lead, &[nb, 3], out.couple)?)?;
        if gradients {
            let grads = [out.grad_q, out.grad_qd, out.grad_qdd, out.grad_tau];
            set_coordinate_gradients(py, &d, &lead, n, grads)?;
            d.set_item(
                "grad_contact_force",
                array(py, &lead, &[nj, 3], out.grad_contact_force)?,
            )?;
        }
        Ok(d)
    }
}

impl LayoutEulerLagrangeLoss {
    /// The couple bodies: by keyword ("model" or none) or by name.
    fn bodies(model: &Model, word: Option<&str>, names: Option<&[String]>) -> PyResult<Vec<usize>> {
        if let Some(names) = names {
            return names.iter().map(|b| model.body(b)).collect();
        }
        match word {
            None => Ok(vec![]),
            Some("model") => Ok(ContactSet::from_model(&model.inner)
                .map_err(to_py)?
                .points
                .iter()
                .map(|p| p.body)
                .collect()),
            Some(w) => Err(MusculoError::new_err(format!(
                "couples: \"{w}\" — give \"model\", None, or use LayoutEulerLagrangeLoss.on_bodies"
            ))),
        }
    }

    fn build(
        model: &Model,
        bodies: Vec<usize>,
        weights: Option<Vec<f64>>,
    ) -> PyResult<LayoutEulerLagrangeLoss> {
        let loss = musculo::loss::LayoutEulerLagrange::new(
            &model.inner,
            &bodies,
            weights.unwrap_or_default(),
        )
        .map_err(to_py)?;
        Ok(LayoutEulerLagrangeLoss {
            model: model.inner.clone(),
            loss,
        })
    }
}

/// The muscle loss L = Σ_t [Σ_j w_j (q̈ − M⁻¹ R F_max a)_tj² + β‖a‖² + γ Σ_k (max(0, a_k − 1)² +
/// max(0, −a_k)²)], R the moment arms (R_jk = −∂ℓ_k/∂q_j: a tension F ≥ 0 gives the
/// generalized force R_jk F), with its exact gradients.
#[pyclass(frozen, module = "musculo")]
pub(crate) struct MuscleLoss {
    model: Arc<musculo::Model>,
    loss: MuscleLossCore,
}

#[pymethods]
impl MuscleLoss {
    /// `weights`: one w_j ≥ 0 per coordinate (default all 1); `beta` = β ≥ 0 (default 0);
    /// `bound_weight` = γ ≥ 0 (default 1).
    #[new]
    #[pyo3(signature = (model, weights = None, beta = 0.0, bound_weight = 1.0))]
    fn new(
        model: &Model,
        weights: Option<Vec<f64>>,
        beta: f64,
        bound_weight: f64,
    ) -> PyResult<MuscleLoss> {
        let mut loss = MuscleLossCore::new(&model.inner).map_err(to_py)?;
        loss.weights = weights.unwrap_or_default();
        loss.beta = beta;
        loss.bound_weight = bound_weight;
        loss.validate(&model.inner).map_err(to_py)?;
        Ok(MuscleLoss {
            model: model.inner.clone(),
            loss,
        })
    }

    /// Names of the muscles, in the order of a's last axis.
    #[getter]
    fn muscle_names(&self) -> Vec<String> {
        self.loss
            .paths
            .paths
            .iter()
            .map(|p| p.name.clone())
            .collect()
    }

    /// F_max of each muscle (N).
    #[getter]
    fn max_isometric_force(&self) -> Vec<f64> {
        self.loss.max_isometric_force.clone()
    }

    /// L and its parts for q, q̈ (..., n) and a (..., m): a dict with `loss` (float),
    /// `per_frame` (...), `residual` (..., n: q̈ − M⁻¹RFa) and, with `gradients`, `grad_q`,
    /// `grad_qdd` (..., n) and `grad_a` (..., m).
    #[pyo3(signature = (q, qdd, a, gradients = true))]
    fn __call__<'py>(
        &self,
        py: Python<'py>,
        q: Input<'py>,
        qdd: Input<'py>,
        a: Input<'py>,
        gradients: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (model, n, m) = (&*self.model, self.model.nq(), self.loss.muscles());
        let (q, lead) = frames("q", &q, n)?;
        let qdd = frames_like("qdd", &qdd, n, &lead)?;
        let a = frames_like("a", &a, m, &lead)?;
        let t = q.len() / n.max(1);
        let mut out = MuscleLossOutput::default();
        py.detach(|| {
            let batch = MuscleBatch {
                frames: t,
                q: &q,
                qdd: &qdd,
                a: &a,
            };
            self.loss.evaluate(model, &batch, gradients, &mut out)
        })
        .map_err(to_py)?;
        let d = PyDict::new(py);
        d.set_item("loss", out.loss)?;
        d.set_item("per_frame", array(py, &lead, &[], out.per_frame)?)?;
        d.set_item("residual", array(py, &lead, &[n], out.residual)?)?;
        if gradients {
            d.set_item("grad_q", array(py, &lead, &[n], out.grad_q)?)?;
            d.set_item("grad_qdd", array(py, &lead, &[n], out.grad_qdd)?)?;
            d.set_item("grad_a", array(py, &lead, &[m], out.grad_a)?)?;
        }
        Ok(d)
    }
}
