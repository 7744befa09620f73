//! `musculo._musculo`, the extension module of the Python package: models, dynamics, muscles
//! and the Euler–Lagrange loss on numpy arrays. Thin by design: it converts arrays (any leading
//! batch shape; the last axis holds one frame), releases the GIL while the library works
//! (frames in parallel on rayon's threads), and raises `musculo.MusculoError` with the
//! library's message for bad input.

use musculo::dynamics::{self, Data, RneaDerivatives};
use musculo::loss::{
    EulerLagrange, EulerLagrangeBatch, EulerLagrangeOutput, LossContact, MuscleBatch,
    MuscleLoss as MuscleLossCore, MuscleLossOutput,
};
use musculo::muscle::{MuscleData, MuscleSet, TendonMode, compute_muscles};
use musculo::solve::contact::ContactSet;
use musculo::spatial::Vec3;
use ndarray::{ArrayD, IxDyn};
use numpy::{AllowTypeChange, IntoPyArray, PyArrayDyn, PyArrayLikeDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

pyo3::create_exception!(
    _musculo,
    MusculoError,
    PyValueError,
    "An error reported by musculo: bad input (shape, non-finite value, unknown name) or a bad model file."
);

fn to_py(e: musculo::Error) -> PyErr {
    MusculoError::new_err(e.to_string())
}

type Input<'py> = PyArrayLikeDyn<'py, f64, AllowTypeChange>;
type Output<'py> = Bound<'py, PyArrayDyn<f64>>;

/// The frames of an array whose last axis holds `width` values: (values in C order, leading
/// shape).
fn frames(name: &str, a: &Input, width: usize) -> PyResult<(Vec<f64>, Vec<usize>)> {
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
fn frames_like(name: &str, a: &Input, width: usize, lead: &[usize]) -> PyResult<Vec<f64>> {
    let (v, l) = frames(name, a, width)?;
    if l != lead {
        return Err(MusculoError::new_err(format!(
            "{name}: leading shape {l:?} differs from q's {lead:?}"
        )));
    }
    Ok(v)
}

fn array<'py>(
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
fn point_frames(name: &str, a: &Input, points: usize, lead: &[usize]) -> PyResult<Vec<f64>> {
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
fn set_coordinate_gradients(
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
struct LayoutBlocks([Vec<f64>; 5]);

impl LayoutBlocks {
    fn clip(&self, frames: usize, fps: f64) -> musculo::augment::layout_inverse::LayoutClip<'_> {
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
fn layout_blocks(nj: usize, arrays: [Input; 5]) -> PyResult<(LayoutBlocks, usize)> {
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
fn per_frame<W, I, F>(frames: usize, width: usize, init: I, f: F) -> musculo::Result<Vec<f64>>
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

/// A musculoskeletal model (immutable; shared by every call).
#[pyclass(frozen, module = "musculo")]
struct Model {
    inner: Arc<musculo::Model>,
    muscles: OnceLock<Result<Arc<MuscleSet>, String>>,
    /// The model's file text and its name in messages (for scaling, which edits the text).
    xml: Arc<(String, String)>,
}

impl Model {
    fn wrap(model: musculo::Model, xml: String, source: String) -> Model {
        Model {
            inner: Arc::new(model),
            muscles: OnceLock::new(),
            xml: Arc::new((xml, source)),
        }
    }

    fn muscle_set(&self) -> PyResult<Arc<MuscleSet>> {
        self.muscles
            .get_or_init(|| {
                MuscleSet::new(&self.inner)
                    .map(Arc::new)
                    .map_err(|e| e.to_string())
            })
            .clone()
            .map_err(MusculoError::new_err)
    }

    fn body(&self, name: &str) -> PyResult<usize> {
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
        length_unit: Option<&str>,
        scale: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        use musculo::solve::{ik, scale_from_clip};
        let base = &*self.inner;
        let xml = self.xml.clone();
        let (solution, time, names, scaled_xml) = py
            .detach(|| -> musculo::Result<_> {
                let (motion, _, map) = read_clip(&path, format, map, length_unit)?;
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

/// The Euler–Lagrange loss L = Σ_t Σ_j w_j r_tj², r = M q̈ + C q̇ + G − τ − Σ_i J_iᵀ λ_i, with
/// its gradients.
#[pyclass(frozen, module = "musculo")]
struct EulerLagrangeLoss {
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
struct LayoutEulerLagrangeLoss {
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
struct MuscleLoss {
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

/// A JSON value as the Python object json.loads would give.
fn json_to_py<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
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

/// A HumanML3D or KIT-ML clip from an array (joints T × J × 3 or features T × F) at `fps`
/// (default: the format's rate), with the name of its built-in skeleton map.
fn motion_from_array(
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
fn augment_clip<'py>(
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

/// `length_unit`: a unit name or metres per file unit.
fn length_unit_of(text: Option<&str>) -> musculo::Result<Option<musculo::motion::LengthUnit>> {
    text.map(|u| {
        musculo::motion::LengthUnit::parse(u).ok_or_else(|| musculo::Error::InvalidArgument {
            argument: "length_unit",
            message: format!("`{u}`: use m, cm, mm, in or a number"),
        })
    })
    .transpose()
}

/// `map`: a JSON file (a `.json` name or an existing path) or a built-in map's name.
fn skeleton_map_of(
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
fn read_clip(
    path: &std::path::Path,
    format: Option<&str>,
    map: Option<&str>,
    length_unit: Option<&str>,
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
fn read_motion<'py>(
    py: Python<'py>,
    path: PathBuf,
    format: Option<&str>,
    length_unit: Option<&str>,
) -> PyResult<Bound<'py, PyDict>> {
    let (motion, _, _) = py
        .detach(|| read_clip(&path, format, None, length_unit))
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

/// [`augment_clip`] on a motion file, read and mapped as `musculo augment` reads it (see
/// `Model.inverse_kinematics_file` for `format`, `map`, `length_unit`); with
/// `force_plates=True` a C3D file's own force platforms are the ground reactions instead of
/// the estimate from kinematics; `muscle_strength` as for `augment_clip`. Returns the same
/// dict as `augment_clip`.
#[pyfunction]
#[pyo3(signature = (path, format = None, map = None, length_unit = None, scale_to_clip = true, force_plates = false, muscle_strength = 1.0))]
#[allow(clippy::too_many_arguments)]
fn augment_file<'py>(
    py: Python<'py>,
    path: PathBuf,
    format: Option<&str>,
    map: Option<&str>,
    length_unit: Option<&str>,
    scale_to_clip: bool,
    force_plates: bool,
    muscle_strength: f64,
) -> PyResult<Bound<'py, PyDict>> {
    use musculo::augment::chain::MeasuredLoads;
    use musculo::motion::Format;
    let output = py
        .detach(|| -> musculo::Result<_> {
            let (motion, format, map) = read_clip(&path, format, map, length_unit)?;
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
fn evaluate<'py>(
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
    length_unit: Option<&str>,
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
            let length_unit = length_unit_of(length_unit)?;
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

/// The augmentation chain on the built-in default model.
fn default_chain(
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
fn clip_output_dict(
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

#[pymodule]
fn _musculo(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Model>()?;
    m.add_class::<EulerLagrangeLoss>()?;
    m.add_class::<LayoutEulerLagrangeLoss>()?;
    m.add_class::<MuscleLoss>()?;
    m.add_function(wrap_pyfunction!(augment_clip, m)?)?;
    m.add_function(wrap_pyfunction!(augment_file, m)?)?;
    m.add_function(wrap_pyfunction!(read_motion, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add("MusculoError", m.py().get_type::<MusculoError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
