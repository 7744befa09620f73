//! The `Model` class: a model's description, its dynamics, muscles and inverse kinematics on
//! numpy arrays.

use crate::convert::{
    Input, MusculoError, Output, array, frames, frames_like, layout_blocks, per_frame, to_py,
};
use crate::reading::{LengthUnitArg, motion_from_array, read_clip};
use musculo::dynamics::{self, Data, RneaDerivatives};
use musculo::muscle::{MuscleData, MuscleSet, TendonMode, compute_muscles};
use musculo::spatial::Vec3;
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

/// A musculoskeletal model (immutable; shared by every call).
#[pyclass(frozen, module = "musculo")]
pub(crate) struct Model {
    pub(crate) inner: Arc<musculo::Model>,
    muscles: OnceLock<Result<Arc<MuscleSet>, String>>,
    /// The model's file text and its name in messages (for scaling, which edits the text).
    xml: Arc<(String, String)>,
}

impl Model {
    pub(crate) fn wrap(model: musculo::Model, xml: String, source: String) -> Model {
        Model {
            inner: Arc::new(model),
            muscles: OnceLock::new(),
            xml: Arc::new((xml, source)),
        }
    }

    pub(crate) fn muscle_set(&self) -> PyResult<Arc<MuscleSet>> {
        self.muscles
            .get_or_init(|| {
                MuscleSet::new(&self.inner)
                    .map(Arc::new)
                    .map_err(|e| e.to_string())
            })
            .clone()
            .map_err(MusculoError::new_err)
    }

    pub(crate) fn body(&self, name: &str) -> PyResult<usize> {
        self.inner.body_index(name).ok_or_else(|| {
            MusculoError::new_err(format!(
                "no body \"{name}\" in model \"{}\"",
                self.inner.name
            ))
        })
    }
}

#[pymethods]
impl Model {
    /// The built-in default full-body model (21 segments, 29 degrees of freedom, 324 muscles).
    #[staticmethod]
    fn default() -> Model {
        Model::wrap(
            musculo::Model::default_fullbody(),
            musculo::DEFAULT_MODEL_OSIM.to_string(),
            "musculo_fullbody.osim".to_string(),
        )
    }

    /// Reads an OpenSim 4.x model file (.osim).
    #[staticmethod]
    fn from_osim(py: Python<'_>, path: PathBuf) -> PyResult<Model> {
        py.detach(|| -> musculo::Result<Model> {
            let model = musculo::Model::from_osim_file(&path)?;
            let text = std::fs::read_to_string(&path).map_err(|e| musculo::Error::Io {
                path: path.clone(),
                source: e,
            })?;
            Ok(Model::wrap(model, text, path.display().to_string()))
        })
        .map_err(to_py)
    }

    /// Reads OpenSim 4.x model XML from a string (`source` names it in messages).
    #[staticmethod]
    #[pyo3(signature = (xml, source = "<string>"))]
    fn from_osim_string(py: Python<'_>, xml: &str, source: &str) -> PyResult<Model> {
        py.detach(|| musculo::Model::from_osim_str(xml, source))
            .map(|m| Model::wrap(m, xml.to_string(), source.to_string()))
            .map_err(to_py)
    }

    #[getter]
    fn name(&self) -> String {
        self.inner.name.clone()
    }

    /// Number of independent coordinates n (the length of q).
    #[getter]
    fn nq(&self) -> usize {
        self.inner.nq()
    }

    /// Number of full coordinates (movable transform axes).
    #[getter]
    fn n_full(&self) -> usize {
        self.inner.n_full()
    }

    /// Names of the independent coordinates, in q's order.
    #[getter]
    fn coordinate_names(&self) -> Vec<String> {
        self.inner.q_names().iter().map(|s| s.to_string()).collect()
    }

    #[getter]
    fn body_names(&self) -> Vec<String> {
        self.inner.bodies.iter().map(|b| b.name.clone()).collect()
    }

    /// Names of the muscles, in the order of muscle arrays.
    #[getter]
    fn muscle_names(&self) -> PyResult<Vec<String>> {
        Ok(self.muscle_set()?.names().map(str::to_string).collect())
    }

    #[getter]
    fn total_mass(&self) -> f64 {
        self.inner.total_mass()
    }

    /// The default coordinate values (n).
    fn default_q<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        array(py, &[], &[self.inner.nq()], self.inner.default_q())
    }

    /// The joint-space mass matrix M(q): (..., n) → (..., n, n).
    fn mass_matrix<'py>(
        &self,
        py: Python<'py>,
        q: Input<'py>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (m, n) = (&*self.inner, self.inner.nq());
        let (q, lead) = frames("q", &q, n)?;
        let t = q.len() / n.max(1);
        let out = py
            .detach(|| {
                per_frame(
                    t,
                    n * n,
                    || Data::new(m),
                    |data, i, row| {
                        let mm = dynamics::crba(m, data, &q[i * n..(i + 1) * n])?;
                        // row-major
                        for r in 0..n {
                            for c in 0..n {
                                row[r * n + c] = mm[(r, c)];
                            }
                        }
                        Ok(())
                    },
                )
            })
            .map_err(to_py)?;
        array(py, &lead, &[n, n], out)
    }

    /// The bias forces C(q, q̇) q̇ + G(q): (..., n) each → (..., n).
    fn bias<'py>(
        &self,
        py: Python<'py>,
        q: Input<'py>,
        qd: Input<'py>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (m, n) = (&*self.inner, self.inner.nq());
        let (q, lead) = frames("q", &q, n)?;
        let qd = frames_like("qd", &qd, n, &lead)?;
        let t = q.len() / n.max(1);
        let out = py
            .detach(|| {
                per_frame(
                    t,
                    n,
                    || Data::new(m),
                    |data, i, row| {
                        let r = i * n..(i + 1) * n;
                        row.copy_from_slice(
                            dynamics::nonlinear_effects(m, data, &q[r.clone()], &qd[r])?.as_slice(),
                        );
                        Ok(())
                    },
                )
            })
            .map_err(to_py)?;
        array(py, &lead, &[n], out)
    }

    /// Inverse dynamics τ = M q̈ + C q̇ + G: (..., n) each → (..., n).
    fn inverse_dynamics<'py>(
        &self,
        py: Python<'py>,
        q: Input<'py>,
        qd: Input<'py>,
        qdd: Input<'py>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (m, n) = (&*self.inner, self.inner.nq());
        let (q, lead) = frames("q", &q, n)?;
        let qd = frames_like("qd", &qd, n, &lead)?;
        let qdd = frames_like("qdd", &qdd, n, &lead)?;
        let t = q.len() / n.max(1);
        let out = py
            .detach(|| {
                per_frame(
                    t,
                    n,
                    || Data::new(m),
                    |data, i, row| {
                        let r = i * n..(i + 1) * n;
                        row.copy_from_slice(
                            dynamics::rnea(m, data, &q[r.clone()], &qd[r.clone()], &qdd[r])?
                                .as_slice(),
                        );
                        Ok(())
                    },
                )
            })
            .map_err(to_py)?;
        array(py, &lead, &[n], out)
    }

    /// ∂τ/∂q, ∂τ/∂q̇, ∂τ/∂q̈ of inverse dynamics: (..., n) each → three (..., n, n) arrays.
    fn inverse_dynamics_derivatives<'py>(
        &self,
        py: Python<'py>,
        q: Input<'py>,
        qd: Input<'py>,
        qdd: Input<'py>,
    ) -> PyResult<(Output<'py>, Output<'py>, Output<'py>)> {
        let (m, n) = (&*self.inner, self.inner.nq());
        let (q, lead) = frames("q", &q, n)?;
        let qd = frames_like("qd", &qd, n, &lead)?;
        let qdd = frames_like("qdd", &qdd, n, &lead)?;
        let t = q.len() / n.max(1);
        let nn = n * n;
        let out = py
            .detach(|| {
                per_frame(
                    t,
                    3 * nn,
                    || (Data::new(m), RneaDerivatives::new(m)),
                    |(data, der), i, row| {
                        let r = i * n..(i + 1) * n;
                        dynamics::rnea_derivatives(
                            m,
                            data,
                            &q[r.clone()],
                            &qd[r.clone()],
                            &qdd[r],
                            der,
                        )?;
                        for (k, mat) in [&der.dtau_dq, &der.dtau_dqd, &der.dtau_dqdd]
                            .iter()
                            .enumerate()
                        {
                            for a in 0..n {
                                for b in 0..n {
                                    row[k * nn + a * n + b] = mat[(a, b)];
                                }
                            }
                        }
                        Ok(())
                    },
                )
            })
            .map_err(to_py)?;
        let mut parts = [Vec::new(), Vec::new(), Vec::new()];
        for row in out.chunks(3 * nn.max(1)) {
            for (k, p) in parts.iter_mut().enumerate() {
                p.extend_from_slice(&row[k * nn..(k + 1) * nn]);
            }
        }
        let [a, b, c] = parts;
        Ok((
            array(py, &lead, &[n, n], a)?,
            array(py, &lead, &[n, n], b)?,
            array(py, &lead, &[n, n], c)?,
        ))
    }

    /// The contact Jacobian of body-fixed points `[(body name, [x, y, z] in the body), …]`:
    /// (..., n) → (..., 3P, n), rows 3i..3i+3 the velocity of point i in ground.
    fn contact_jacobian<'py>(
        &self,
        py: Python<'py>,
        q: Input<'py>,
        points: Vec<(String, [f64; 3])>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (m, n) = (&*self.inner, self.inner.nq());
        let pts: Vec<(usize, Vec3)> = points
            .iter()
            .map(|(b, p)| Ok((self.body(b)?, Vec3::new(p[0], p[1], p[2]))))
            .collect::<PyResult<_>>()?;
        let (q, lead) = frames("q", &q, n)?;
        let t = q.len() / n.max(1);
        let rows = 3 * pts.len();
        let out = py
            .detach(|| {
                per_frame(
                    t,
                    rows * n,
                    || (Data::new(m), nalgebra::DMatrix::zeros(rows, n)),
                    |(data, jc), i, row| {
                        dynamics::forward_kinematics(m, data, &q[i * n..(i + 1) * n])?;
                        dynamics::contact_jacobian(m, data, &pts, jc)?;
                        for a in 0..rows {
                            for b in 0..n {
                                row[a * n + b] = jc[(a, b)];
                            }
                        }
                        Ok(())
                    },
                )
            })
            .map_err(to_py)?;
        array(py, &lead, &[rows, n], out)
    }

    /// Musculotendon lengths and moment arms (r = −∂ℓ/∂q, so a tension F ≥ 0 gives the
    /// generalized force r F): (..., n) → ((..., m), (..., n, m)).
    fn muscle_paths<'py>(
        &self,
        py: Python<'py>,
        q: Input<'py>,
    ) -> PyResult<(Output<'py>, Output<'py>)> {
        let set = self.muscle_set()?;
        let (m, n, k) = (&*self.inner, self.inner.nq(), set.len());
        let (q, lead) = frames("q", &q, n)?;
        let t = q.len() / n.max(1);
        let zeros = vec![0.0; k];
        let out = py
            .detach(|| {
                per_frame(
                    t,
                    k + n * k,
                    || (Data::new(m), MuscleData::new(m, &set)),
                    |(data, md), i, row| {
                        dynamics::forward_kinematics(m, data, &q[i * n..(i + 1) * n])?;
                        compute_muscles(m, data, &set, &zeros, TendonMode::Rigid, false, md)?;
                        row[..k].copy_from_slice(&md.paths.length);
                        for a in 0..n {
                            for b in 0..k {
                                row[k + a * k + b] = md.paths.moment_arms[(a, b)];
                            }
                        }
                        Ok(())
                    },
                )
            })
            .map_err(to_py)?;
        let (mut lengths, mut arms) = (Vec::new(), Vec::new());
        for row in out.chunks((k + n * k).max(1)).take(t) {
            lengths.extend_from_slice(&row[..k]);
            arms.extend_from_slice(&row[k..]);
        }
        Ok((
            array(py, &lead, &[k], lengths)?,
            array(py, &lead, &[n, k], arms)?,
        ))
    }

    /// Inverse kinematics of a HumanML3D or KIT-ML clip (as for [`augment_clip`]) onto this
    /// model through the format's built-in skeleton map (the model needs the map's markers,
    /// as the default model has): per frame the weighted least-squares fit of the joint
    /// centres within the coordinate limits, warm-started from the previous frame. Returns a
    /// dict: `q` (T × n), `rmse` and `max_error` (T, m), `marker_error` (T × K, m) and
    /// `frames_at_limit`. The model is not scaled here (`augment_clip` scales it).
    #[pyo3(signature = (joints, fps = None, format = "humanml3d"))]
    fn inverse_kinematics<'py>(
        &self,
        py: Python<'py>,
        joints: Input<'py>,
        fps: Option<f64>,
        format: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        use musculo::motion::skeleton::SkeletonMap;
        use musculo::solve::ik;
        let clip = joints.as_array().to_owned();
        let m = &*self.inner;
        let solution = py
            .detach(|| -> musculo::Result<_> {
                let (motion, map_name) = motion_from_array(clip.view(), format, fps)?;
                let (targets, tasks) = SkeletonMap::builtin(map_name)?.apply(m, &motion)?;
                ik::solve_motion(m, &targets, &tasks, &ik::IkSettings::default(), &|_| {})
            })
            .map_err(to_py)?;
        ik_dict(py, solution)
    }

    /// The coordinates of a clip given in the per-joint layout (FlexMotion's; every array
    /// T × J × 3, J = the model's joints in order, as `augment_clip` writes them) at `fps`:
    /// q by a fit of the joint rotations and the root's centre, q̇ and q̈ from the joint rates
    /// (the root's translation rates by differences of its centre), τ on the angular
    /// coordinates from the joint moments (0 on the others). Returns a dict with `q`, `qd`,
    /// `qdd`, `tau` (T × n) and `rotation_error` (T: the largest rotation the fit leaves, rad).
    #[allow(clippy::too_many_arguments)]
    fn coordinates_from_layout<'py>(
        &self,
        py: Python<'py>,
        joint_pos: Input<'py>,
        joint_rot: Input<'py>,
        joint_vel: Input<'py>,
        joint_acc: Input<'py>,
        joint_torque: Input<'py>,
        fps: f64,
    ) -> PyResult<Bound<'py, PyDict>> {
        use musculo::augment::layout::JointLayout;
        use musculo::augment::layout_inverse::coordinates_from_layout;
        let m = &*self.inner;
        let (blocks, t) = layout_blocks(
            m.joints.len(),
            [joint_pos, joint_rot, joint_vel, joint_acc, joint_torque],
        )?;
        let out = py
            .detach(|| coordinates_from_layout(m, &JointLayout::new(m, 0), &blocks.clip(t, fps)))
            .map_err(to_py)?;
        let n = m.nq();
        let d = PyDict::new(py);
        d.set_item("q", array(py, &[t], &[n], out.q)?)?;
        d.set_item("qd", array(py, &[t], &[n], out.qd)?)?;
        d.set_item("qdd", array(py, &[t], &[n], out.qdd)?)?;
        d.set_item("tau", array(py, &[t], &[n], out.tau)?)?;
        d.set_item("rotation_error", array(py, &[t], &[], out.rotation_error)?)?;
        Ok(d)
    }

    /// The gradient of a loss with respect to a clip in the per-joint layout, from its
    /// gradient with respect to the coordinates `coordinates_from_layout` fits from it (same
    /// arguments, then `grad_q`, `grad_qd`, `grad_qdd`, `grad_tau`, each T × n): exact, through
    /// the fit by the implicit-function theorem, also where the layout's blocks disagree
    /// (a generated motion). Returns a dict with `grad_joint_pos`, `grad_joint_rot`,
    /// `grad_joint_vel`, `grad_joint_acc` and `grad_joint_torque` (T × J × 3; joint_pos is read
    /// only at the root joints, joint_torque only on the angular coordinates: zero elsewhere).
    #[allow(clippy::too_many_arguments)]
    fn coordinates_from_layout_vjp<'py>(
        &self,
        py: Python<'py>,
        joint_pos: Input<'py>,
        joint_rot: Input<'py>,
        joint_vel: Input<'py>,
        joint_acc: Input<'py>,
        joint_torque: Input<'py>,
        fps: f64,
        grad_q: Input<'py>,
        grad_qd: Input<'py>,
        grad_qdd: Input<'py>,
        grad_tau: Input<'py>,
    ) -> PyResult<Bound<'py, PyDict>> {
        use musculo::augment::layout::JointLayout;
        use musculo::augment::layout_inverse::coordinates_from_layout;
        use musculo::augment::layout_inverse_vjp::{
            CoordinateGradient, coordinates_from_layout_vjp,
        };
        let m = &*self.inner;
        let (n, nj) = (m.nq(), m.joints.len());
        let (blocks, t) = layout_blocks(
            nj,
            [joint_pos, joint_rot, joint_vel, joint_acc, joint_torque],
        )?;
        let mut bars = Vec::new();
        for (name, a) in [
            ("grad_q", &grad_q),
            ("grad_qd", &grad_qd),
            ("grad_qdd", &grad_qdd),
            ("grad_tau", &grad_tau),
        ] {
            let shape = a.as_array().shape().to_vec();
            if shape != [t, n] {
                return Err(MusculoError::new_err(format!(
                    "{name}: shape {shape:?}; expected {t} × {n} (the layout's frames × the \
                     model's coordinates)"
                )));
            }
            bars.push(a.as_array().iter().copied().collect::<Vec<f64>>());
        }
        let g = py
            .detach(|| {
                let layout = JointLayout::new(m, 0);
                let clip = blocks.clip(t, fps);
                let coords = coordinates_from_layout(m, &layout, &clip)?;
                coordinates_from_layout_vjp(
                    m,
                    &layout,
                    &clip,
                    &coords,
                    &CoordinateGradient {
                        q: &bars[0],
                        qd: &bars[1],
                        qdd: &bars[2],
                        tau: &bars[3],
                    },
                )
            })
            .map_err(to_py)?;
        let d = PyDict::new(py);
        for (name, v) in [
            ("grad_joint_pos", g.joint_pos),
            ("grad_joint_rot", g.joint_rot),
            ("grad_joint_vel", g.joint_vel),
            ("grad_joint_acc", g.joint_acc),
            ("grad_joint_torque", g.joint_torque),
        ] {
            d.set_item(name, array(py, &[t], &[nj, 3], v)?)?;
        }
        Ok(d)
    }

    /// Inverse kinematics of a motion file onto this model, as `musculo ik` runs it: the
    /// reader picked from the file (`format` = "humanml3d", "kit", "bvh", "c3d" or "trc"
    /// overrides), targets mapped by `map` (a built-in skeleton map's name or a map file;
    /// default the format's own map — HumanML3D, KIT-ML, CMU BVH — and for C3D/TRC markers
    /// matched to the model's markers by name), `length_unit` for BVH and KIT files ("m",
    /// "cm", "mm", "in" or metres per file unit). With `scale=True` the model is first scaled
    /// to the clip's bone lengths and its markers placed (`musculo ik --scale auto`; needs a
    /// skeleton map). Returns the dict of
    /// `inverse_kinematics` plus `time` (T, s), `marker_names` (the K targets of
    /// `marker_error`) and `model_xml` (the scaled model, None without `scale`).
    #[pyo3(signature = (path, format = None, map = None, length_unit = None, scale = false))]
    fn inverse_kinematics_file<'py>(
        &self,
        py: Python<'py>,
        path: PathBuf,
        format: Option<&str>,
        map: Option<&str>,
        length_unit: Option<LengthUnitArg>,
        scale: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        use musculo::solve::{ik, scale_from_clip};
        let base = &*self.inner;
        let xml = self.xml.clone();
        let (solution, time, names, scaled_xml) = py
            .detach(|| -> musculo::Result<_> {
                let (motion, _, map) = read_clip(&path, format, map, length_unit.as_ref())?;
                let scaled = if scale {
                    let map = map
                        .as_ref()
                        .ok_or_else(|| musculo::Error::InvalidArgument {
                            argument: "scale",
                            message: "scaling to the clip needs a skeleton map (give map=...)"
                                .into(),
                        })?;
                    let (text, source) = &*xml;
                    Some(scale_from_clip::scale_to_clip(
                        text, source, base, map, &motion,
                    )?)
                } else {
                    None
                };
                let m = scaled.as_ref().map_or(base, |s| &s.model);
                let (targets, tasks) = match &map {
                    Some(map) => map.apply(m, &motion)?,
                    None => {
                        let tasks = ik::tasks_by_name(m, &motion);
                        if tasks.markers.is_empty() {
                            return Err(musculo::Error::InvalidArgument {
                                argument: "map",
                                message: format!(
                                    "no marker of {} has a model marker of the same name; give \
                                     a skeleton map",
                                    motion.source
                                ),
                            });
                        }
                        (motion.clone(), tasks)
                    }
                };
                let names: Vec<String> = tasks
                    .markers
                    .iter()
                    .map(|t| m.markers[t.marker].name.clone())
                    .collect();
                let solution =
                    ik::solve_motion(m, &targets, &tasks, &ik::IkSettings::default(), &|_| {})?;
                let scaled_xml = scaled.map(|s| s.xml()).transpose()?;
                Ok((solution, targets.time.clone(), names, scaled_xml))
            })
            .map_err(to_py)?;
        let t = solution.n_frames();
        let d = ik_dict(py, solution)?;
        d.set_item("time", array(py, &[t], &[], time)?)?;
        d.set_item("marker_names", names)?;
        d.set_item("model_xml", scaled_xml)?;
        Ok(d)
    }

    /// Muscle (tendon) forces at activations a: (..., n), (..., n), (..., m) → (..., m), with
    /// each muscle's own tendon model, or rigid tendons with `rigid_tendon=True`.
    #[pyo3(signature = (q, qd, activation, rigid_tendon = false))]
    fn muscle_forces<'py>(
        &self,
        py: Python<'py>,
        q: Input<'py>,
        qd: Input<'py>,
        activation: Input<'py>,
        rigid_tendon: bool,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let set = self.muscle_set()?;
        let (m, n, k) = (&*self.inner, self.inner.nq(), set.len());
        let (q, lead) = frames("q", &q, n)?;
        let qd = frames_like("qd", &qd, n, &lead)?;
        let act = frames_like("activation", &activation, k, &lead)?;
        let t = q.len() / n.max(1);
        let mode = if rigid_tendon {
            TendonMode::Rigid
        } else {
            TendonMode::AsModel
        };
        let out = py
            .detach(|| {
                per_frame(
                    t,
                    k,
                    || (Data::new(m), MuscleData::new(m, &set)),
                    |(data, md), i, row| {
                        let r = i * n..(i + 1) * n;
                        dynamics::forward_kinematics_velocity(m, data, &q[r.clone()], &qd[r])?;
                        compute_muscles(m, data, &set, &act[i * k..(i + 1) * k], mode, false, md)?;
                        row.copy_from_slice(&md.force);
                        Ok(())
                    },
                )
            })
            .map_err(to_py)?;
        array(py, &lead, &[k], out)
    }
}

/// An IK solution as a dict: `q` (T × n), `rmse`, `max_error` (T), `marker_error` (T × K),
/// `frames_at_limit`.
fn ik_dict(
    py: Python<'_>,
    solution: musculo::solve::ik::IkSolution,
) -> PyResult<Bound<'_, PyDict>> {
    let (t, n) = (solution.n_frames(), solution.nq);
    let k = solution.marker_error.len() / t.max(1);
    let d = PyDict::new(py);
    d.set_item("frames_at_limit", solution.frames_at_limit())?;
    d.set_item("q", array(py, &[t], &[n], solution.q)?)?;
    d.set_item("rmse", array(py, &[t], &[], solution.rmse)?)?;
    d.set_item("max_error", array(py, &[t], &[], solution.max_error)?)?;
    d.set_item(
        "marker_error",
        array(py, &[t], &[k], solution.marker_error)?,
    )?;
    Ok(d)
}
