//! The Euler–Lagrange residual of a tensor file: an `.npz` written by `musculo augment` (or a
//! generated motion in the same format) read back and checked frame by frame.
//!
//! Arrays used (float32 or float64, T frames): `q`, `qd`, `qdd`, `tau` (T × n, the model's
//! independent coordinates in `Model::q_names` order) and, when the file has contacts,
//! `contact_point_force` (T × P × 3, ground axes, N) at the model's contact spheres, each
//! loaded at its lowest point. `musculo augment` writes τ = τ_ID − J_cᵀλ (the floating-base rows
//! carrying whatever the contacts leave unexplained), so its files have r ≈ 0 up to the
//! float32 rounding of the stored arrays.
//!
//! A file holding only the per-joint layout (`joint_pos` … `joint_torque`, `time`, optionally
//! `contact_force`; a generated motion) has its coordinates fitted first
//! ([`crate::augment::layout_inverse`]) and the residual of [`super::layout`]: the contact
//! forces at the joint centres with the best couple on each foot. On a layout written by
//! `musculo augment` that residual is what the layout cannot carry: the generalized forces
//! on the root's translations (τ there is not in the layout) and the differences between the
//! root's translation rates by differences and augment's.
//!
//! With `muscle_act` (T × m, the model's muscles in `Model::forces` order) the file also gets the
//! muscle loss of [`super::MuscleLoss`] (unit weights, β = 0, γ = 1): e = q̈ − M⁻¹ R F_max a per
//! frame. It is not zero for an augmented clip — its activations balance the torques with
//! force–length–velocity, passive forces, gravity and reserves, which FlexMotion's term leaves
//! out — but it is what a trainer adding that term will see.

use super::{
    EulerLagrange, EulerLagrangeBatch, EulerLagrangeOutput, LayoutEulerLagrange,
    LayoutEulerLagrangeBatch, LayoutEulerLagrangeOutput, MuscleBatch, MuscleLoss, MuscleLossOutput,
};
use crate::model::Model;
use crate::motion::npy::read_npz_as_f64;
use crate::solve::kinematics::MAX_COORDINATE_MAGNITUDE;
use crate::text::short_number;
use std::path::Path;

/// The largest magnitude of any value of a tensor file. For `q` it is the coordinates' bound
/// ([`MAX_COORDINATE_MAGNITUDE`]: rad or m, where adjacent doubles no longer resolve a pose);
/// no rate, acceleration, force, activation or time of a body comes near 10¹⁵ either (rad/s,
/// N, N·m, s), so one bound serves every array. A file scaled by 10³⁰ is read as a pose
/// 10³⁰ m above the floor otherwise, and `evaluate` prints a Float of 10³² mm.
pub const MAX_TENSOR_MAGNITUDE: f64 = MAX_COORDINATE_MAGNITUDE;

/// The frames of a tensor file, widened to f64.
#[derive(Clone, Debug)]
pub struct TensorFrames {
    pub frames: usize,
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    pub qdd: Vec<f64>,
    pub tau: Vec<f64>,
    /// T × P × 3, empty without contacts.
    pub lambda: Vec<f64>,
    /// P, the contact points of `lambda`.
    pub contacts: usize,
    /// T × m activations (`muscle_act`), empty when the file has none.
    pub muscle_act: Vec<f64>,
    /// m, the muscles of `muscle_act` (0 without).
    pub muscles: usize,
    /// T × m muscle tensions (`muscle_force`, N), empty when the file has none.
    pub muscle_force: Vec<f64>,
    /// The frames' times (`time`, s), empty when the file has none.
    pub time: Vec<f64>,
    /// T × n generalized forces of measured external loads (`external`, written by
    /// `augment --external-loads/--force-plates`: Q = Σ Jᵀ w), empty when the file has none.
    /// They enter the residual beside τ: r = M q̈ + C q̇ + G − τ − Q − J_cᵀλ.
    pub external: Vec<f64>,
    /// T × G × 3 ground reaction force per contact group (`grf`, N: the estimate's sums, or
    /// the measured loads), empty when the file has none.
    pub grf: Vec<f64>,
    /// G, the contact groups of `grf` (0 without).
    pub groups: usize,
    /// Set when the file holds only the per-joint layout (no `q`): the coordinates were
    /// fitted from it ([`crate::augment::layout_inverse`]) and this is the largest rotation
    /// error the fit left (rad). Its L_euler is that of [`super::layout`]: the layout's
    /// `contact_force` at the joint centres with the best couple on each body of the model's
    /// contact set.
    pub layout_error: Option<f64>,
    /// The layout's `contact_force` (T × J × 3, ground axes, N) of a layout-only file that
    /// has one; empty otherwise.
    pub contact_force: Vec<f64>,
}

impl TensorFrames {
    /// Reads `path` for `model` (n = `model.nq()` values per frame in every coordinate array).
    pub fn read(path: &Path, model: &Model) -> crate::Result<TensorFrames> {
        let arrays = read_npz_as_f64(path)?;
        Self::from_arrays(&arrays, model, &path.display().to_string())
    }

    /// The frames of named arrays (as a tensor file holds them; `source` names them in
    /// errors) for `model`.
    pub fn from_arrays(
        arrays: &[(String, ndarray::ArrayD<f64>)],
        model: &Model,
        source: &str,
    ) -> crate::Result<TensorFrames> {
        let n = model.nq();
        let file = NamedArrays { arrays, source };
        let layout_only = file.find("q").is_none() && file.find("joint_rot").is_some();
        let FileCoordinates {
            q,
            qd,
            qdd,
            tau,
            frames,
            layout_error,
        } = file.coordinates(model, layout_only)?;
        // Every reader (loss, evaluate, report) gets its frames here: a file without any
        // has no residual to speak of, and a sum over no frames would read as a perfect 0.
        if frames == 0 {
            return Err(file.bad(
                "has 0 frames (`q`, `qd`, `qdd` and `tau` have no rows): nothing to evaluate"
                    .to_string(),
            ));
        }
        let optional = |name: &str, dims: &[Option<usize>]| file.optional(name, dims, frames);
        let (lambda, contacts) = optional("contact_point_force", &[None, Some(3)])?;
        let contact_force = if layout_only {
            optional("contact_force", &[Some(model.joints.len()), Some(3)])?.0
        } else {
            Vec::new()
        };
        let (muscle_act, muscles) = optional("muscle_act", &[None])?;
        let (external, _) = optional("external", &[Some(n)])?;
        let (grf, groups) = optional("grf", &[None, Some(3)])?;
        let (muscle_force, _) = optional("muscle_force", &[None])?;
        let (time, _) = optional("time", &[])?;
        file.check_magnitudes(
            frames,
            layout_only,
            &[
                ("q", &q),
                ("qd", &qd),
                ("qdd", &qdd),
                ("tau", &tau),
                ("contact_point_force", &lambda),
                ("muscle_act", &muscle_act),
                ("muscle_force", &muscle_force),
                ("time", &time),
                ("external", &external),
                ("grf", &grf),
                ("contact_force", &contact_force),
            ],
        )?;
        Ok(TensorFrames {
            frames,
            q,
            qd,
            qdd,
            tau,
            lambda,
            contacts,
            muscle_act,
            muscles,
            muscle_force,
            time,
            external,
            grf,
            groups,
            layout_error,
            contact_force,
        })
    }

    /// The frame rate from `time` (Hz): (T − 1) / (t_last − t_first); an error without
    /// `time`, with fewer than 2 frames or with times that do not increase.
    pub fn rate_hz(&self) -> crate::Result<f64> {
        let t = &self.time;
        if t.len() < 2 || !(t[t.len() - 1] > t[0]) {
            return Err(crate::Error::invalid(
                "time",
                format!(
                    "{} sample(s){}; a rate needs ≥ 2 increasing times",
                    t.len(),
                    if t.is_empty() {
                        " (the file has no `time`)"
                    } else {
                        ""
                    }
                ),
            ));
        }
        Ok((t.len() - 1) as f64 / (t[t.len() - 1] - t[0]))
    }

    /// The frames as a loss batch.
    pub fn batch(&self) -> EulerLagrangeBatch<'_> {
        EulerLagrangeBatch {
            frames: self.frames,
            q: &self.q,
            qd: &self.qd,
            qdd: &self.qdd,
            tau: &self.tau,
            lambda: &self.lambda,
        }
    }
}

/// A tensor file's named arrays, and its name for errors.
struct NamedArrays<'a> {
    arrays: &'a [(String, ndarray::ArrayD<f64>)],
    source: &'a str,
}

/// The coordinate arrays of a tensor file (T × n each, frame-major), read or fitted.
struct FileCoordinates {
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    tau: Vec<f64>,
    frames: usize,
    /// A layout-only file's largest rotation error left by the fit (rad).
    layout_error: Option<f64>,
}

impl NamedArrays<'_> {
    /// The array named `name`, if the file has one.
    fn find(&self, name: &str) -> Option<&ndarray::ArrayD<f64>> {
        self.arrays.iter().find(|(k, _)| k == name).map(|(_, a)| a)
    }

    /// An error about the file.
    fn bad(&self, msg: String) -> crate::Error {
        crate::Error::invalid("tensor file", format!("{}: {msg}", self.source))
    }

    /// q, qd, qdd and tau: read (each T × n, with the frame count of `q`), or for a
    /// layout-only file fitted from its layout arrays
    /// ([`crate::augment::layout_inverse::coordinates_from_layout`]).
    fn coordinates(&self, model: &Model, layout_only: bool) -> crate::Result<FileCoordinates> {
        let n = model.nq();
        let bad = |msg: String| self.bad(msg);
        let mut frames: Option<usize> = None;
        let mut coordinate_array = |name: &str| -> crate::Result<Vec<f64>> {
            let a = self
                .find(name)
                .ok_or_else(|| bad(format!("has no array `{name}`")))?;
            if a.ndim() != 2 || a.shape()[1] != n {
                return Err(bad(format!(
                    "`{name}` has shape {:?}; the model \"{}\" needs T × {n}",
                    a.shape(),
                    model.name
                )));
            }
            let t = a.shape()[0];
            // `q` is read first and sets the frame count the others must have
            let first = *frames.get_or_insert(t);
            if first != t {
                return Err(bad(format!("`{name}` has {t} frames, `q` has {first}")));
            }
            Ok(a.iter().copied().collect())
        };
        let mut layout_error = None;
        let (q, qd, qdd, tau) = if layout_only {
            let c = from_layout(model, self.arrays, &bad)?;
            frames = Some(c.rotation_error.len());
            layout_error = Some(c.rotation_error.iter().fold(0.0f64, |m, v| m.max(*v)));
            (c.q, c.qd, c.qdd, c.tau)
        } else {
            (
                coordinate_array("q")?,
                coordinate_array("qd")?,
                coordinate_array("qdd")?,
                coordinate_array("tau")?,
            )
        };
        Ok(FileCoordinates {
            q,
            qd,
            qdd,
            tau,
            frames: frames.unwrap_or(0),
            layout_error,
        })
    }

    /// An optional array of shape `frames` × dims (None: any size), and its second
    /// dimension; empty (and 0) when the file has none.
    fn optional(
        &self,
        name: &str,
        dims: &[Option<usize>],
        frames: usize,
    ) -> crate::Result<(Vec<f64>, usize)> {
        let Some(a) = self.find(name) else {
            return Ok((Vec::new(), 0));
        };
        let shape = a.shape();
        let fits = shape.len() == dims.len() + 1
            && shape[0] == frames
            && dims
                .iter()
                .zip(&shape[1..])
                .all(|(d, s)| d.is_none_or(|d| d == *s));
        if !fits {
            let expected: Vec<String> = std::iter::once(frames.to_string())
                .chain(dims.iter().map(|d| d.map_or("*".into(), |d| d.to_string())))
                .collect();
            return Err(self.bad(format!(
                "`{name}` has shape {shape:?}; expected {}",
                expected.join(" × ")
            )));
        }
        Ok((
            a.iter().copied().collect(),
            shape.get(1).copied().unwrap_or(0),
        ))
    }

    /// Every value of the `named` arrays (frame-major, `frames` rows) within
    /// ±[`MAX_TENSOR_MAGNITUDE`]: beyond it (or not finite) a value is a scaling or unit
    /// error, not a motion, and the metrics of such a file would be finite nonsense.
    fn check_magnitudes(
        &self,
        frames: usize,
        layout_only: bool,
        named: &[(&str, &Vec<f64>)],
    ) -> crate::Result<()> {
        // (a layout-only file's q … tau are fitted from its layout arrays, which are named)
        let coordinates = if layout_only { "fitted " } else { "" };
        for &(name, values) in named {
            if let Some((i, v)) = values
                .iter()
                .enumerate()
                .find(|(_, v)| !(v.abs() <= MAX_TENSOR_MAGNITUDE))
            {
                // the arrays are frame-major: T rows of `width` values
                let width = values.len() / frames;
                let what = if matches!(name, "q" | "qd" | "qdd" | "tau") {
                    coordinates
                } else {
                    ""
                };
                let beyond = if v.is_finite() {
                    format!(
                        ", beyond ±{MAX_TENSOR_MAGNITUDE:e}, which no motion reaches: a \
                         scaling or unit error"
                    )
                } else {
                    String::new()
                };
                return Err(self.bad(format!(
                    "{what}`{name}` is {} at frame {} (value {} of the frame's {width}){beyond}",
                    short_number(*v),
                    i / width,
                    i % width
                )));
            }
        }
        Ok(())
    }
}

/// Per-frame and per-coordinate figures of a residual.
#[derive(Clone, Debug)]
pub struct ResidualSummary {
    pub frames: usize,
    /// L_euler over all frames (unit weights).
    pub loss: f64,
    /// ‖r_t‖ per frame, and ‖r_t‖ / ‖τ_ID,t‖.
    pub frame_norm: Vec<f64>,
    pub frame_relative: Vec<f64>,
    /// RMS and maximum |r_tj| over frames, per coordinate.
    pub coordinate_rms: Vec<f64>,
    pub coordinate_max: Vec<f64>,
}

/// The residual of `frames` against `model` and its contact spheres (none when the file has
/// no contact forces); errors when the file's contact points do not match the model's. A
/// layout-only file gets the residual of [`super::layout`] (its `contact_force` at the joint
/// centres, a free couple on each body of the model's contact set, none if the model has no
/// contact set; no contact forces without `contact_force`).
pub fn residual_of(model: &Model, frames: &TensorFrames) -> crate::Result<ResidualSummary> {
    let mut out = EulerLagrangeOutput::default();
    if frames.layout_error.is_some() {
        let bodies: Vec<usize> = crate::augment::chain::contact_set(model)
            .map(|set| set.points.iter().map(|p| p.body).collect())
            .unwrap_or_default();
        let loss = LayoutEulerLagrange::new(model, &bodies, Vec::new())?;
        let zero;
        let contact_force = if frames.contact_force.is_empty() {
            zero = vec![0.0; frames.frames * model.joints.len() * 3];
            &zero
        } else {
            &frames.contact_force
        };
        let mut layout_out = LayoutEulerLagrangeOutput::default();
        let batch = LayoutEulerLagrangeBatch {
            frames: frames.frames,
            q: &frames.q,
            qd: &frames.qd,
            qdd: &frames.qdd,
            tau: &frames.tau,
            contact_force,
        };
        loss.evaluate(model, &batch, false, &mut layout_out)?;
        out.loss = layout_out.loss;
        out.residual = layout_out.residual;
        out.tau_id_norm = layout_out.tau_id_norm;
        return Ok(summary(model, frames, &out));
    }
    let loss = if frames.contacts == 0 {
        EulerLagrange::new()
    } else {
        let set = crate::augment::chain::contact_set(model)?;
        if set.points.len() != frames.contacts {
            return Err(crate::Error::invalid(
                "tensor file",
                format!(
                    "`contact_point_force` has {} points; the model \"{}\" has {} contact spheres",
                    frames.contacts,
                    model.name,
                    set.points.len()
                ),
            ));
        }
        EulerLagrange::new().with_contact_set(&set)
    };
    if frames.external.is_empty() {
        loss.evaluate(model, &frames.batch(), false, &mut out)?;
    } else {
        // measured loads act beside τ: the residual sees τ + Q
        let tau: Vec<f64> = frames
            .tau
            .iter()
            .zip(&frames.external)
            .map(|(t, q)| t + q)
            .collect();
        let batch = EulerLagrangeBatch {
            tau: &tau,
            ..frames.batch()
        };
        loss.evaluate(model, &batch, false, &mut out)?;
    }
    Ok(summary(model, frames, &out))
}

/// The per-frame and per-coordinate figures of a loss's residuals.
fn summary(model: &Model, frames: &TensorFrames, out: &EulerLagrangeOutput) -> ResidualSummary {
    let n = model.nq();
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let mut s = ResidualSummary {
        frames: frames.frames,
        loss: out.loss,
        frame_norm: Vec::with_capacity(frames.frames),
        frame_relative: Vec::with_capacity(frames.frames),
        coordinate_rms: vec![0.0; n],
        coordinate_max: vec![0.0; n],
    };
    for t in 0..frames.frames {
        let r = &out.residual[t * n..(t + 1) * n];
        let rn = norm(r);
        s.frame_norm.push(rn);
        s.frame_relative
            .push(rn / out.tau_id_norm[t].max(f64::MIN_POSITIVE));
        for (j, v) in r.iter().enumerate() {
            s.coordinate_rms[j] += v * v;
            s.coordinate_max[j] = s.coordinate_max[j].max(v.abs());
        }
    }
    for v in &mut s.coordinate_rms {
        *v = (*v / frames.frames.max(1) as f64).sqrt();
    }
    s
}

/// The muscle loss of a tensor file's frames (see the module documentation).
#[derive(Clone, Debug)]
pub struct MuscleSummary {
    /// L_muscle over all frames.
    pub loss: f64,
    /// L_t and |q̈ − M⁻¹RFa| per frame.
    pub per_frame: Vec<f64>,
    pub residual_norm: Vec<f64>,
    /// Activations outside [0, 1] (entries over all frames).
    pub out_of_bounds: usize,
}

/// The muscle loss of `frames` against `model`, or `None` when the file has no `muscle_act`;
/// an error when its width is not the model's muscle count.
pub fn muscle_residual_of(
    model: &Model,
    frames: &TensorFrames,
) -> crate::Result<Option<MuscleSummary>> {
    if frames.muscles == 0 && frames.muscle_act.is_empty() {
        return Ok(None);
    }
    let loss = MuscleLoss::new(model)?;
    if loss.muscles() != frames.muscles {
        return Err(crate::Error::invalid(
            "tensor file",
            format!(
                "`muscle_act` has {} muscles; the model \"{}\" has {}",
                frames.muscles,
                model.name,
                loss.muscles()
            ),
        ));
    }
    let batch = MuscleBatch {
        frames: frames.frames,
        q: &frames.q,
        qdd: &frames.qdd,
        a: &frames.muscle_act,
    };
    let mut out = MuscleLossOutput::default();
    loss.evaluate(model, &batch, false, &mut out)?;
    let n = model.nq();
    Ok(Some(MuscleSummary {
        loss: out.loss,
        residual_norm: out
            .residual
            .chunks(n.max(1))
            .map(|r| r.iter().map(|v| v * v).sum::<f64>().sqrt())
            .collect(),
        per_frame: out.per_frame,
        out_of_bounds: frames
            .muscle_act
            .iter()
            .filter(|a| !(0.0..=1.0).contains(*a))
            .count(),
    }))
}

/// The coordinates of a file that holds only the per-joint layout: `joint_pos`, `joint_rot`,
/// `joint_vel`, `joint_acc`, `joint_torque` (T × J × 3) and `time` (T, s) for the rate.
fn from_layout(
    model: &Model,
    arrays: &[(String, ndarray::ArrayD<f64>)],
    bad: &dyn Fn(String) -> crate::Error,
) -> crate::Result<crate::augment::layout_inverse::LayoutCoordinates> {
    use crate::augment::layout::JointLayout;
    use crate::augment::layout_inverse::{LayoutClip, coordinates_from_layout};
    let nj = model.joints.len();
    let get = |name: &str| -> crate::Result<Vec<f64>> {
        let a = arrays
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, a)| a)
            .ok_or_else(|| {
                bad(format!(
                    "has `joint_rot` but no `{name}` (the per-joint layout needs it)"
                ))
            })?;
        if a.ndim() != 3 || a.shape()[1] != nj || a.shape()[2] != 3 {
            return Err(bad(format!(
                "`{name}` has shape {:?}; the model \"{}\" needs T × {nj} × 3",
                a.shape(),
                model.name
            )));
        }
        Ok(a.iter().copied().collect())
    };
    let time: Vec<f64> = arrays
        .iter()
        .find(|(k, _)| k == "time")
        .map(|(_, a)| a.iter().copied().collect())
        .ok_or_else(|| bad("has the per-joint layout but no `time` (its rate is needed)".into()))?;
    let frames = time.len();
    if frames < 2 || !(time[frames - 1] > time[0]) {
        return Err(bad(format!(
            "`time` has {frames} samples; the layout needs ≥ 2, increasing"
        )));
    }
    let rate_hz = (frames - 1) as f64 / (time[frames - 1] - time[0]);
    let (pos, rot, vel, acc, torque) = (
        get("joint_pos")?,
        get("joint_rot")?,
        get("joint_vel")?,
        get("joint_acc")?,
        get("joint_torque")?,
    );
    if pos.len() != frames * nj * 3 {
        return Err(bad(format!(
            "`joint_pos` has {} frames, `time` {frames}",
            pos.len() / (3 * nj)
        )));
    }
    let layout = JointLayout::new(model, 0);
    coordinates_from_layout(
        model,
        &layout,
        &LayoutClip {
            frames,
            rate_hz,
            joint_pos: &pos,
            joint_rot: &rot,
            joint_vel: &vel,
            joint_acc: &acc,
            joint_torque: &torque,
        },
    )
}
