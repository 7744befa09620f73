//! The per-clip chain of `musculo augment`:
//!
//!   motion → (scaling to the clip) → inverse kinematics → low-pass filter and quintic-spline
//!   derivatives → inverse dynamics → contact forces from the floating-base rows → static
//!   optimization (muscles + reserves) → excitations by inverse activation dynamics →
//!   muscle forces, fibre lengths and velocities, and the per-joint layout.
//!
//! Per frame, with τ_ID = M q̈ + C q̇ + G from inverse dynamics and λ the contact forces:
//!   τ = τ_ID − J_cᵀ λ
//! are the generalized forces the actuators carry; on the floating-base rows τ is what no
//! contact could explain (the residual, carried by residual actuators), on the joints it is
//! shared by the muscles and one reserve actuator per coordinate (optimal force
//! [`ChainOptions::reserve_optimal_force`], so a reserve costs as much per N·m as a muscle
//! of that maximum force would). The emitted arrays satisfy M q̈ + C q̇ + G = τ + J_cᵀ λ
//! exactly (up to float32 rounding): the identity holds by construction of τ; what the
//! chain estimates is how τ and λ split.
//!
//! The per-frame loop allocates nothing: every workspace is built once per clip.

use super::layout::{JointFrame, JointLayout, LayoutWorkspace};
use super::perturb::Variant;
use super::verdict;
pub use super::verdict::{ClipQuality, IK_ERROR_WARNED};
use crate::dynamics::{self, Data};
use crate::error::Error;
use crate::io::Table;
use crate::model::{ActuatorKind, ForceElement, Model, ScalarActuator};
use crate::motion::Motion;
use crate::motion::skeleton::SkeletonMap;
use crate::muscle::activation::ActivationDynamics;
use crate::solve::contact::{
    self, ContactFrame, ContactOptions, ContactSet, ContactStates, ContactWorkspace, GroupWrench,
};
use crate::solve::external_loads::ExternalLoadSet;
use crate::solve::filter::HIGHEST_CUTOFF_FRACTION;
use crate::solve::ik::robust as ik_robust;
use crate::solve::ik::{self, IkSettings};
use crate::solve::kinematics::{CoordinateTrajectory, Differentiation, KinematicsOptions};
use crate::solve::orientation_filter::{EulerJoint, OrientationTrajectory};
use crate::solve::scale_from_clip;
use crate::solve::static_optimization::{
    SoFrame, SoStatus, SoWorkspace, StaticOptimization, StaticOptimizationOptions,
};
use crate::spatial::Vec3;
use crate::text::short_number;

/// Excitation samples clamped by more than this (in excitation units) are counted in
/// [`ClipQuality::clamped_excitations`]: an activation resting on its lower bound asks for
/// excitations a hair below it at almost every sample, which says nothing.
pub const CLAMP_REPORTED: f64 = 0.01;

/// Options of the chain.
#[derive(Clone, Debug)]
pub struct ChainOptions {
    /// Low-pass cutoff of the coordinates (Hz) before differentiation; None: none.
    /// Default 6 Hz (OpenSim's usual choice for gait).
    pub lowpass_hz: Option<f64>,
    /// Scale the model's segments to each clip's bone lengths (needs a skeleton map with
    /// segments). Default true.
    pub scale_to_clip: bool,
    pub ik: IkSettings,
    pub contact: ContactOptions,
    /// Optimal force of the reserve actuator on every joint coordinate (N·m or N): a reserve
    /// control x costs x² in static optimization, like a muscle's activation. Default 1.
    pub reserve_optimal_force: f64,
    /// Also produce OpenSim files per clip (see [`ClipOutput::tables`]). Default false.
    pub opensim_files: bool,
    /// Static optimization's options (OpenSim's defaults: exponent 2, force–length–velocity).
    pub static_optimization: StaticOptimizationOptions,
    /// Every muscle's maximum isometric force × this factor, applied to the model's text when
    /// the chain is made ([`crate::solve::scale::strength`]), so that the model hash, the
    /// scaling to each clip and the OpenSim files all see the strengthened model. Default 1
    /// (the model as given).
    pub muscle_strength: f64,
    /// Run static optimization and activation dynamics. Default true. Without them (what
    /// `musculo evaluate` needs of a motion file: kinematics, torques, contacts) the muscle
    /// arrays (`muscle_act`, `muscle_force`, fibre states, `excitation`) are left out of the
    /// output and the quality figures of static optimization are zero.
    pub muscles: bool,
    /// Keep a held pose at either end that the motion jumps from or to (a calibration T-pose:
    /// [`crate::motion::calibration`]); false (the default) leaves it out with a warning.
    pub keep_calibration_frames: bool,
}

impl Default for ChainOptions {
    fn default() -> Self {
        ChainOptions {
            lowpass_hz: Some(6.0),
            scale_to_clip: true,
            // a marker that disagrees with the others (a wrong label in a marker file matched
            // by name) is down-weighted and named in the clip's warnings
            ik: IkSettings {
                robust: Some(ik_robust::RobustMarkers::default()),
                ..IkSettings::default()
            },
            contact: ContactOptions::default(),
            reserve_optimal_force: 1.0,
            opensim_files: false,
            static_optimization: StaticOptimizationOptions::default(),
            muscle_strength: 1.0,
            muscles: true,
            keep_calibration_frames: false,
        }
    }
}

/// Measured ground reactions, used instead of the contact estimate.
#[derive(Clone, Debug, PartialEq)]
pub enum MeasuredLoads {
    /// An OpenSim ExternalLoads file (and the data file it names).
    ExternalLoads(std::path::PathBuf),
    /// The force platforms of the clip's own C3D file: each plate's force, centre of pressure
    /// and free moment (below 20 N of normal load a plate counts as unloaded) applied to the
    /// calcaneus nearest its centre of pressure over the frames it is loaded.
    ForcePlates(std::path::PathBuf),
}

/// Normal load (N) below which a force plate counts as unloaded.
pub const PLATE_THRESHOLD: f64 = 20.0;

/// One named float32 array of a clip's output.
#[derive(Clone, Debug)]
pub struct Array {
    pub name: &'static str,
    pub shape: Vec<usize>,
    pub values: Vec<f32>,
}

/// Everything the chain computed for one clip.
#[derive(Clone, Debug)]
pub struct ClipOutput {
    pub arrays: Vec<Array>,
    pub quality: ClipQuality,
    /// With [`ChainOptions::opensim_files`]: OpenSim tables as (file suffix, table) —
    /// `_ik.mot` (every coordinate, rotational ones in degrees, as OpenSim's IK writes them),
    /// `_tau.sto` (generalized forces, OpenSim ID's `_moment`/`_force` labels),
    /// `_activation.sto` (muscle activations) and `_grf.mot` (per contact group: force,
    /// centre of pressure and free moment, in ExternalLoads' column naming).
    pub tables: Vec<(&'static str, Table)>,
    /// With [`ChainOptions::opensim_files`], the clip's model as OpenSim XML: scaled to the
    /// clip, and with a variant's mass scaling and carried load in its bodies' mass
    /// properties; None for an unscaled model that the variant leaves as it is.
    pub model_xml: Option<String>,
    /// Which body the clip belongs to (written into its `.npz`; see [`super::identity`]).
    pub identity: super::identity::ModelIdentity,
    pub warnings: Vec<String>,
}

/// The part of the chain shared by all clips: the base model's text, the options, and the
/// models scaled for clips so far (clips of one skeleton share one:
/// [`scale_from_clip::scale_to_clip_shared`]).
#[derive(Clone, Debug)]
pub struct Chain {
    pub xml: String,
    pub source: String,
    pub model: Model,
    pub options: ChainOptions,
    /// The model file the clips' bodies are made from (their identities' base).
    pub base: super::identity::BaseModel,
    scaled: scale_from_clip::ScaledModels,
    /// The activation dynamics of the base model's forces, by force index (None for a force
    /// that is not a muscle, or whose properties are an error): the same in every clip's
    /// model, which scaling and variants change in lengths and masses only.
    activation: Vec<Option<ActivationDynamics>>,
}

impl Chain {
    /// A chain on the built-in default full-body model.
    pub fn default_model(options: ChainOptions) -> crate::Result<Chain> {
        Chain::new(
            crate::DEFAULT_MODEL_OSIM.to_string(),
            "models/musculo_fullbody.osim".into(),
            options,
        )
    }

    /// A chain on the model in `xml` (named `source` in messages).
    pub fn new(xml: String, source: String, options: ChainOptions) -> crate::Result<Chain> {
        if !(options.reserve_optimal_force > 0.0 && options.reserve_optimal_force.is_finite()) {
            return Err(Error::invalid(
                "reserve_optimal_force",
                format!("must be positive, got {}", options.reserve_optimal_force),
            ));
        }
        let file_text = (options.muscle_strength != 1.0).then(|| xml.clone());
        let xml = if options.muscle_strength == 1.0 {
            xml
        } else {
            crate::solve::scale::strength::scale_muscle_strength(
                &xml,
                &source,
                options.muscle_strength,
            )
            .map_err(|e| match e {
                Error::InvalidArgument { message, .. } => {
                    Error::invalid("muscle_strength", message)
                }
                other => other,
            })?
            .0
        };
        let model = Model::from_osim_str(&xml, &source)?;
        contact_set(&model)?;
        // the verdicts are per body weight: refused before any clip, not NaN in every record
        if let Some(why) = model.weightless() {
            return Err(Error::invalid(
                "model",
                format!("{source}: {why}: the contact forces and verdicts are per body weight"),
            ));
        }
        let base = super::identity::BaseModel::new(
            &model.name,
            &source,
            file_text.as_deref().unwrap_or(&xml),
            options.muscle_strength,
            &xml,
        );
        let activation = (model.forces.iter())
            .map(|f| ActivationDynamics::from_muscle(f, f.file_or(&model.source)).ok())
            .collect();
        Ok(Chain {
            xml,
            source,
            model,
            options,
            base,
            scaled: scale_from_clip::ScaledModels::new(),
            activation,
        })
    }

    /// The model the chain uses for `motion` (as the variant sees it: see
    /// [`Variant::apply_to_motion`]): the base model scaled to the clip's bone lengths (the
    /// segment factors rounded to [`scale_from_clip::SHARED_FACTOR_GRID`]) when a map with
    /// segments is given, with one reserve actuator per coordinate, perturbed by
    /// `variant` (mass, load). Deterministic: a clip's `.npz` can be checked against it.
    pub fn clip_model(
        &self,
        motion: &Motion,
        map: Option<&SkeletonMap>,
        variant: &Variant,
    ) -> crate::Result<Model> {
        Ok(self.clip_model_and_xml(motion, map, variant)?.0)
    }

    /// [`Chain::clip_model`], when it was scaled with `opensim_files` the scaled model's XML,
    /// and the clip's model identity.
    fn clip_model_and_xml(
        &self,
        motion: &Motion,
        map: Option<&SkeletonMap>,
        variant: &Variant,
    ) -> crate::Result<(Model, Option<String>, super::identity::ModelIdentity)> {
        let mut scale = None;
        let (mut model, xml) = match map {
            Some(map) if self.options.scale_to_clip && !map.segments.is_empty() => {
                let s = scale_from_clip::scale_to_clip_shared(
                    &self.xml,
                    &self.source,
                    &self.model,
                    map,
                    motion,
                    &self.scaled,
                )?;
                let xml = if self.options.opensim_files {
                    Some(s.xml()?)
                } else {
                    None
                };
                scale = Some((s.scales, super::identity::fnv1a_hex(&s.scaled_xml)));
                (s.model, xml)
            }
            _ => (self.model.clone(), None),
        };
        add_reserves(&mut model, self.options.reserve_optimal_force);
        variant.apply_to_model(&mut model)?;
        let identity = super::identity::ModelIdentity::new(
            &self.base,
            scale.as_ref().map(|(set, hash)| (set, hash.clone())),
            variant,
        );
        Ok((model, xml, identity))
    }

    /// Runs the chain on one clip (`motion` as read, `map` from its skeleton to the model's
    /// markers, None for marker sets matched by name) with perturbation `variant`.
    pub fn run(
        &self,
        motion: &Motion,
        map: Option<&SkeletonMap>,
        variant: &Variant,
    ) -> crate::Result<ClipOutput> {
        self.run_with_loads(motion, map, variant, None)
    }

    /// [`Chain::run`] with measured ground reactions (an OpenSim ExternalLoads file resolved
    /// against the clip's model, or a C3D file's force plates) used instead of the contact
    /// estimate. They enter as Q = Σ Jᵀ w (array `external`), so the arrays satisfy
    /// M q̈ + C q̇ + G = τ + Q; `grf`, `cop` and `free_moment` then report the measured
    /// forces per contact group (a force belongs to the group of the body it is applied to).
    /// The loads fix the body's dynamics, so only the identity variant is accepted.
    pub fn run_with_loads(
        &self,
        motion: &Motion,
        map: Option<&SkeletonMap>,
        variant: &Variant,
        external_loads: Option<&MeasuredLoads>,
    ) -> crate::Result<ClipOutput> {
        if external_loads.is_some() && *variant != Variant::identity() {
            return Err(Error::invalid(
                "variant",
                "measured loads belong to the recorded body and speed: perturbed variants \
                 need the contact estimate (no --external-loads)",
            ));
        }
        let mut warnings = Vec::new();
        let motion = variant.apply_to_motion(motion)?;
        let (model, scaled_xml, mut identity) = self.clip_model_and_xml(&motion, map, variant)?;
        let source = motion.source.as_str();
        let (targets, tasks) = self.ik_targets(&model, &motion, map, &mut warnings)?;
        let solution = self.inverse_kinematics(&model, source, &targets, &tasks, &mut warnings)?;
        let kinematics =
            self.filtered_kinematics(&model, source, &targets, &solution, &mut warnings)?;
        let loads = measured_loads(&model, source, external_loads, &kinematics, targets.rate_hz)?;
        let solvers = self.clip_solvers(&model, &kinematics, targets.rate_hz, loads.as_ref())?;
        low_body_warnings(
            &model,
            source,
            &solvers.set,
            self.options.contact.max_point_offset,
            &kinematics.q,
            &mut warnings,
        )?;
        let per_frame = self.dynamics_per_frame(&PerFrameInputs {
            model: &model,
            source,
            kinematics: &kinematics,
            solvers: &solvers,
            loads: loads.as_ref(),
        })?;
        let clip = ClipComputed {
            model,
            rate_hz: targets.rate_hz,
            tasks,
            solution,
            kinematics,
            measured: loads.is_some(),
            solvers,
            per_frame,
        };
        let (excitation, clamped) = self.excitations(&clip)?;
        let mut quality = self.clip_quality(&clip, clamped);
        quality_warnings(&clip, &quality, source, &mut warnings);
        let (tables, model_xml) = self.opensim_outputs(&clip, variant, scaled_xml)?;
        let arrays = self.output_arrays(clip, excitation);
        check_finite(&arrays)?;
        quality.verdict = Some(verdict::judge(&quality));
        identity.osim_hash = model_xml.as_deref().map(super::identity::fnv1a_hex);
        Ok(ClipOutput {
            arrays,
            quality,
            tables,
            model_xml,
            identity,
            warnings,
        })
    }

    /// The IK targets and tasks of the clip: the skeleton map applied (or the model's markers
    /// matched by name), trimmed to the frames with data, and without a calibration pose at
    /// either end unless [`ChainOptions::keep_calibration_frames`].
    fn ik_targets(
        &self,
        model: &Model,
        motion: &Motion,
        map: Option<&SkeletonMap>,
        warnings: &mut Vec<String>,
    ) -> crate::Result<(Motion, ik::IkTasks)> {
        let (targets, tasks) = match map {
            Some(map) => map.apply(model, motion)?,
            None => {
                let tasks = ik::tasks_by_name(model, motion);
                if tasks.markers.is_empty() {
                    return Err(no_common_markers(model, motion));
                }
                (motion.clone(), tasks)
            }
        };
        let mut targets = trim_to_data(&targets, warnings)?;
        if !self.options.keep_calibration_frames {
            let (kept, warning) = crate::motion::calibration::trim(&targets, motion)?;
            targets = kept;
            warnings.extend(warning);
        }
        Ok((targets, tasks))
    }

    /// Inverse kinematics of the clip (disagreeing markers down-weighted and named in the
    /// warnings); a clip of fewer than 4 frames is refused.
    fn inverse_kinematics(
        &self,
        model: &Model,
        source: &str,
        targets: &Motion,
        tasks: &ik::IkTasks,
        warnings: &mut Vec<String>,
    ) -> crate::Result<ik::IkSolution> {
        let solution = ik::solve_motion(model, targets, tasks, &self.options.ik, &|_| {})?;
        warnings.extend(ik_robust::warnings(model, tasks, &solution, source));
        let frames = solution.n_frames();
        if frames < 4 {
            return Err(Error::invalid(
                "motion",
                format!("{source}: {frames} frames; the chain needs at least 4"),
            ));
        }
        Ok(solution)
    }

    /// Filtering and differentiation: IK's coordinates low-passed and differentiated twice
    /// by quintic splines, sampled at the clip's times and rounded to float32.
    fn filtered_kinematics(
        &self,
        model: &Model,
        source: &str,
        targets: &Motion,
        solution: &ik::IkSolution,
        warnings: &mut Vec<String>,
    ) -> crate::Result<ClipKinematics> {
        let frames = solution.n_frames();
        let n = model.nq();
        let names: Vec<String> = model.q_names().iter().map(|s| s.to_string()).collect();
        let times = sample_times(targets, frames);
        let lowpass_hz = self.lowpass_cutoff(source, targets.rate_hz, &times, warnings);
        let table = Table::new("ik", names, times.clone(), solution.q.clone())?;
        let trajectory = CoordinateTrajectory::from_table(
            model,
            &Table {
                in_degrees: Some(false),
                ..table
            },
            source,
            &KinematicsOptions {
                lowpass_hz,
                differentiation: Differentiation::SecondDerivative,
            },
        )?;
        // Three-axis rotations are filtered and differentiated as orientations, which stay
        // smooth where their angles swing through gimbal lock (`solve::orientation_filter`).
        let orientations = OrientationTrajectory::fit(
            EulerJoint::of_model(model),
            &times,
            &solution.q,
            n,
            lowpass_hz,
        )
        .map_err(|m| Error::invalid("motion", format!("{source}: joint orientations: {m}")))?;
        let mut q = solution.q.clone();
        let mut qd = vec![0.0; frames * n];
        let mut qdd = vec![0.0; frames * n];
        let mut raw = vec![0.0; n];
        for f in 0..frames {
            let r = f * n..(f + 1) * n;
            let (a, b, c) = (&mut q[r.clone()], &mut qd[r.clone()], &mut qdd[r]);
            // the frame's own coordinates start the orientations' decomposition
            raw.copy_from_slice(a);
            trajectory.eval_finite(times[f], a, b, c)?;
            for joint in orientations.joints() {
                for &k in &joint.q {
                    a[k] = raw[k];
                }
            }
            orientations.eval(times[f], a, b, c);
        }
        // The dynamics are computed for the kinematics as emitted (float32), so that
        // M q̈ + C q̇ + G = τ + J_cᵀλ holds for the arrays in the file, not only for values
        // a reader never sees.
        for v in q.iter_mut().chain(qd.iter_mut()).chain(qdd.iter_mut()) {
            *v = *v as f32 as f64;
        }
        Ok(ClipKinematics {
            times,
            q,
            qd,
            qdd,
            frames,
            n,
        })
    }

    /// The low-pass cutoff for a clip sampled at `times`: [`ChainOptions::lowpass_hz`], or,
    /// above [`HIGHEST_CUTOFF_FRACTION`] of the clip's rate, that fraction (with a warning).
    fn lowpass_cutoff(
        &self,
        source: &str,
        rate_hz: f64,
        times: &[f64],
        warnings: &mut Vec<String>,
    ) -> Option<f64> {
        let frames = times.len();
        // One cutoff serves a dataset of several rates (HumanML3D's 20 fps against mocap's
        // 120): above 0.4 of a clip's rate, where the filter would ring
        // (`solve::filter::HIGHEST_CUTOFF_FRACTION`), the clip is filtered at that fraction,
        // and its warnings say so.
        self.options.lowpass_hz.map(|fc| {
            let rate = (frames - 1) as f64 / (times[frames - 1] - times[0]);
            let highest = HIGHEST_CUTOFF_FRACTION * rate;
            if fc > highest {
                // rounded down to 1 mHz (after a nudge of 1e-10 against the round-off of
                // the rate, within the filter's own margin of 1e-9), so its check passes
                let lowered = (highest * (1.0 + 1e-10) * 1e3).floor() / 1e3;
                warnings.push(format!(
                    "{}: the low-pass cutoff {} Hz is above {HIGHEST_CUTOFF_FRACTION} of the \
                     clip's sampling rate ({} Hz), where the filter rings: its coordinates \
                     were filtered at {} Hz",
                    source,
                    short_number(fc),
                    short_number(rate_hz),
                    short_number(lowered)
                ));
                lowered
            } else {
                fc
            }
        })
    }

    /// What stays fixed over the clip's frames: the contact set on the detected floor, the
    /// contact states, static optimization, the joint layout, and the contact group of each
    /// measured load.
    fn clip_solvers(
        &self,
        model: &Model,
        kinematics: &ClipKinematics,
        rate_hz: f64,
        loads: Option<&ExternalLoadSet>,
    ) -> crate::Result<ClipSolvers> {
        let set = contact_set(model)?;
        let ClipKinematics { q, qd, qdd, .. } = kinematics;
        let states = contact::detect(model, &set, &self.options.contact, q, qd, qdd, rate_hz)?;
        let set = set.with_floor(states.floor);
        let so = StaticOptimization::new(model, self.options.static_optimization.clone())?;
        let layout = JointLayout::new(model, so.muscles.muscles.len());
        let load_group = loads
            .map(|l| load_groups(model, &set, l))
            .unwrap_or_default();
        Ok(ClipSolvers {
            set,
            states,
            so,
            layout,
            load_group,
        })
    }

    /// Contacts, inverse dynamics, static optimization and the joint layout, frame by frame,
    /// in workspaces built once for the clip.
    fn dynamics_per_frame(&self, inputs: &PerFrameInputs) -> crate::Result<FrameArrays> {
        let (model, solvers) = (inputs.model, inputs.solvers);
        let mut per_frame = FrameArrays::new(
            model,
            &solvers.so,
            &solvers.set,
            &solvers.layout,
            inputs.kinematics.frames,
        );
        let mut ws = FrameWorkspaces::new(model, solvers);
        for f in 0..inputs.kinematics.frames {
            self.dynamics_at_frame(inputs, f, &mut ws, &mut per_frame)?;
        }
        Ok(per_frame)
    }

    /// One frame: τ_ID by inverse dynamics, the contact forces (estimated or measured) taken
    /// off it, static optimization of what remains, the joint layout, and the frame's record.
    fn dynamics_at_frame(
        &self,
        inputs: &PerFrameInputs,
        f: usize,
        ws: &mut FrameWorkspaces,
        per_frame: &mut FrameArrays,
    ) -> crate::Result<()> {
        let (model, solvers, k) = (inputs.model, inputs.solvers, inputs.kinematics);
        let r = f * k.n..(f + 1) * k.n;
        // τ_ID = M q̈ + C q̇ + G
        let tau_id = dynamics::rnea(
            model,
            &mut ws.data,
            &k.q[r.clone()],
            &k.qd[r.clone()],
            &k.qdd[r.clone()],
        )?;
        ws.tau.copy_from_slice(tau_id.as_slice());
        let demand = vertical_support_demand(model, &ws.data);
        ws.external.fill(0.0);
        ws.body_contact.fill(Vec3::zeros());
        match inputs.loads {
            None => self.estimated_contact(model, solvers, f, ws)?,
            Some(loads) => measured_contact(model, solvers, loads, k.times[f], ws)?,
        }
        per_frame.record_support(demand, vertical(model, ws.body_contact.iter().sum()));
        if self.options.muscles {
            (solvers.so)
                .solve_frame(model, &ws.data, &ws.tau, &mut ws.so, &mut ws.so_frame)
                .map_err(|e| at_frame(inputs.source, f, e))?;
        }
        // body accelerations without gravity, for the joint accelerations
        dynamics::forward_kinematics_acceleration(
            model,
            &mut ws.data,
            &k.q[r.clone()],
            &k.qd[r.clone()],
            &k.qdd[r],
        )?;
        solvers.layout.frame(
            model,
            &ws.data,
            &ws.tau,
            &ws.body_contact,
            &mut ws.layout,
            &mut ws.joint_frame,
        )?;
        per_frame
            .external
            .extend(ws.external.iter().map(|&v| v as f32));
        per_frame.record(
            &solvers.so,
            &ws.so,
            &ws.so_frame,
            &ws.contact_frame,
            &ws.groups,
            &solvers.layout,
            &ws.joint_frame,
            &ws.tau,
        );
        Ok(())
    }

    /// The contact estimate at frame `f`: the floating-base rows of τ_ID distributed over the
    /// points in contact, τ = τ_ID − J_cᵀ λ, and the per-group and per-body reactions.
    fn estimated_contact(
        &self,
        model: &Model,
        solvers: &ClipSolvers,
        f: usize,
        ws: &mut FrameWorkspaces,
    ) -> crate::Result<()> {
        let set = &solvers.set;
        let p = set.points.len();
        ws.contact.distribute(
            model,
            &ws.data,
            set,
            &self.options.contact,
            &solvers.states.factor[f * p..(f + 1) * p],
            &ws.tau,
            &mut ws.contact_frame,
        )?;
        // τ = τ_ID − J_cᵀ λ
        for (t, g) in ws.tau.iter_mut().zip(&ws.contact_frame.generalized) {
            *t -= g;
        }
        contact::ground_reaction(set, &ws.contact_frame, &mut ws.groups)?;
        for (point, force) in set.points.iter().zip(&ws.contact_frame.forces) {
            ws.body_contact[point.body] += force;
        }
        Ok(())
    }

    /// Excitations by inverse activation dynamics from static optimization's activations
    /// (frames × muscles, empty without muscles), and the samples clamped by more than
    /// [`CLAMP_REPORTED`].
    fn excitations(&self, clip: &ClipComputed) -> crate::Result<(Vec<f32>, usize)> {
        let (model, so) = (&clip.model, &clip.solvers.so);
        let (frames, times) = (clip.kinematics.frames, &clip.kinematics.times);
        let mut clamped = 0;
        let m = so.muscles.muscles.len();
        let mut excitation = vec![0.0f32; frames * m];
        let mut series = vec![0.0; frames];
        let muscles = if self.options.muscles {
            so.muscles.muscles.as_slice()
        } else {
            &[]
        };
        for (k, muscle) in muscles.iter().enumerate() {
            let index = so.muscles.paths.paths[k].force;
            let force = &model.forces[index];
            // The base model's, read once per chain: the clip's model is the base model
            // scaled (its file re-read: the same forces in the same order), with reserves
            // appended and a variant's mass and load, so force `index` is the same muscle.
            let dynamics = match self.activation.get(index) {
                Some(Some(d)) => *d,
                _ => ActivationDynamics::from_muscle(force, force.file_or(&model.source))?,
            };
            let (lo, hi) = dynamics.range();
            for f in 0..frames {
                series[f] = clip.per_frame.activation[f * m + k].clamp(lo, hi);
            }
            let estimate = dynamics
                .excitation_from_activation(times, &series)
                .map_err(|e| Error::invalid("activation", format!("{}: {e}", muscle.name())))?;
            clamped += estimate
                .clamped
                .iter()
                .filter(|c| c.amount().abs() > CLAMP_REPORTED)
                .count();
            for f in 0..frames {
                excitation[f * m + k] = estimate.excitation[f] as f32;
            }
        }
        Ok((excitation, clamped))
    }

    /// The clip's quality figures (without its verdict); those of static optimization zero
    /// without muscles.
    fn clip_quality(&self, clip: &ClipComputed, clamped: usize) -> ClipQuality {
        let model = &clip.model;
        let mut quality = clip.per_frame.quality(
            model,
            &clip.solution,
            clip.kinematics.frames,
            clip.rate_hz,
            clamped,
            self.options.reserve_optimal_force,
        );
        if !clip.measured {
            quality.treadmill = clip.solvers.states.treadmill;
            quality.belt_velocity = clip.solvers.states.floor_velocity.into();
        }
        quality.ik_markers = (clip.tasks.markers.iter())
            .map(|t| model.markers[t.marker].name.clone())
            .collect();
        quality.ik_rmse_by_marker =
            rmse_by_column(&clip.solution.marker_error, clip.tasks.markers.len());
        if !self.options.muscles {
            quality.so_unsolved_frames = 0;
            quality.reserve_share = 0.0;
            quality.reserve_by_coordinate.clear();
            quality.reserve_peak_share = 0.0;
            quality.reserve_peak_coordinate.clear();
            quality.muscle_samples = 0;
            quality.muscle_samples_at_full_activation = 0;
            quality.full_activation_share = 0.0;
        }
        quality
    }

    /// With [`ChainOptions::opensim_files`]: the OpenSim tables of the clip, and its model's
    /// XML (the scaled model's, with a variant's mass properties written in).
    fn opensim_outputs(
        &self,
        clip: &ClipComputed,
        variant: &Variant,
        scaled_xml: Option<String>,
    ) -> crate::Result<(Vec<(&'static str, Table)>, Option<String>)> {
        if !self.options.opensim_files {
            return Ok((Vec::new(), None));
        }
        let model = &clip.model;
        let plain = variant.mass_scale == 1.0 && variant.load_kg == 0.0;
        let xml = if plain {
            scaled_xml
        } else {
            // the variant's body: the clip's (scaled) model text with its mass properties
            let base = scaled_xml.as_deref().unwrap_or(&self.xml);
            Some(crate::solve::scale::inertial::set_inertial_properties(
                base,
                &self.source,
                model,
            )?)
        };
        let tables = opensim_tables(
            model,
            &clip.solvers.so,
            &clip.solvers.set,
            &clip.kinematics.times,
            &clip.kinematics.q,
            &clip.per_frame,
        )?;
        Ok((tables, xml))
    }

    /// The clip's arrays: the per-frame records, kinematics, excitations, times and IK's
    /// marker errors (the muscle arrays left out without muscles).
    fn output_arrays(&self, clip: ClipComputed, excitation: Vec<f32>) -> Vec<Array> {
        let ClipKinematics {
            times,
            q,
            qd,
            qdd,
            frames,
            n,
        } = clip.kinematics;
        let m = clip.solvers.so.muscles.muscles.len();
        let mut arrays =
            (clip.per_frame).into_arrays(&clip.solvers.layout, &q, &qd, &qdd, frames, n);
        arrays.push(Array {
            name: "excitation",
            shape: vec![frames, m],
            values: excitation,
        });
        arrays.push(Array {
            name: "time",
            shape: vec![frames],
            values: times.iter().map(|&t| t as f32).collect(),
        });
        // per frame and IK marker: ‖model marker − target‖ of the IK solution (before the
        // low-pass filter), NaN where the input had no target
        arrays.push(Array {
            name: "ik_marker_error",
            shape: vec![frames, clip.tasks.markers.len()],
            values: clip
                .solution
                .marker_error
                .iter()
                .map(|&e| e as f32)
                .collect(),
        });
        if !self.options.muscles {
            // nothing computed there (and `x` would carry its zeros)
            arrays.retain(|a| {
                !matches!(
                    a.name,
                    "x" | "muscle_act"
                        | "muscle_force"
                        | "muscle_length"
                        | "fiber_length"
                        | "fiber_velocity"
                        | "excitation"
                )
            });
        }
        arrays
    }
}

/// The clip's coordinates after filtering, and their first and second derivatives, frame by
/// frame (frames × nq, float32 values held as f64), at the clip's sample times.
struct ClipKinematics {
    times: Vec<f64>,
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    frames: usize,
    /// Coordinates per frame (nq).
    n: usize,
}

/// What stays fixed over a clip's frames ([`Chain::clip_solvers`]).
struct ClipSolvers {
    /// The contact set, on the floor the contact detection found.
    set: ContactSet,
    states: ContactStates,
    so: StaticOptimization,
    layout: JointLayout,
    /// The contact group of each measured load (empty without measured loads).
    load_group: Vec<Option<usize>>,
}

/// The inputs of the per-frame loop ([`Chain::dynamics_per_frame`]).
struct PerFrameInputs<'a> {
    model: &'a Model,
    /// The clip's name in messages.
    source: &'a str,
    kinematics: &'a ClipKinematics,
    solvers: &'a ClipSolvers,
    /// Measured loads used instead of the contact estimate.
    loads: Option<&'a ExternalLoadSet>,
}

/// The workspaces of the per-frame loop, built once per clip (the loop allocates nothing).
struct FrameWorkspaces {
    data: Data,
    contact: ContactWorkspace,
    contact_frame: ContactFrame,
    groups: Vec<GroupWrench>,
    so: SoWorkspace,
    so_frame: SoFrame,
    layout: LayoutWorkspace,
    joint_frame: JointFrame,
    /// τ of the frame: τ_ID less the contact (or measured) forces.
    tau: Vec<f64>,
    /// Q = Σ Jᵀ w of the measured loads (zero without them).
    external: Vec<f64>,
    /// The contact force on each body (ground frame).
    body_contact: Vec<Vec3>,
}

impl FrameWorkspaces {
    fn new(model: &Model, solvers: &ClipSolvers) -> FrameWorkspaces {
        let n = model.nq();
        FrameWorkspaces {
            data: Data::new(model),
            contact: ContactWorkspace::new(model, &solvers.set),
            contact_frame: ContactFrame::new(model, &solvers.set),
            groups: vec![GroupWrench::default(); solvers.set.groups().len()],
            so: SoWorkspace::new(model, &solvers.so),
            so_frame: SoFrame::new(&solvers.so, model),
            layout: solvers.layout.workspace(model),
            joint_frame: JointFrame::new(&solvers.layout),
            tau: vec![0.0; n],
            external: vec![0.0; n],
            body_contact: vec![Vec3::zeros(); model.bodies.len()],
        }
    }
}

/// Everything computed for a clip before its outputs are assembled.
struct ClipComputed {
    model: Model,
    /// The targets' sampling rate (Hz).
    rate_hz: f64,
    tasks: ik::IkTasks,
    solution: ik::IkSolution,
    kinematics: ClipKinematics,
    /// Whether measured loads stood in for the contact estimate.
    measured: bool,
    solvers: ClipSolvers,
    per_frame: FrameArrays,
}

/// The sample times of the clip's `frames` frames. Files store times rounded (OpenSim's
/// subject01_walk1.trc at 60 Hz writes 0.017, 0.033): times within 5 % of a sample interval
/// of the uniform grid at the motion's rate are put on it, so the filter accepts them.
fn sample_times(targets: &Motion, frames: usize) -> Vec<f64> {
    let dt = 1.0 / targets.rate_hz;
    let grid: Vec<f64> = (0..frames)
        .map(|f| targets.time[0] + f as f64 * dt)
        .collect();
    let on_grid = grid
        .iter()
        .zip(&targets.time)
        .all(|(g, t)| (g - t).abs() <= 0.05 * dt);
    if on_grid { grid } else { targets.time.clone() }
}

/// The measured loads of the clip, if given: an ExternalLoads file (which must cover the
/// clip) or the force plates of a C3D file.
fn measured_loads(
    model: &Model,
    source: &str,
    external_loads: Option<&MeasuredLoads>,
    kinematics: &ClipKinematics,
    rate_hz: f64,
) -> crate::Result<Option<ExternalLoadSet>> {
    let (times, frames) = (&kinematics.times, kinematics.frames);
    match external_loads {
        None => Ok(None),
        Some(MeasuredLoads::ExternalLoads(p)) => {
            let set = ExternalLoadSet::read(model, p)?;
            // Beyond its data a load is extrapolated (linearly, as OpenSim's splines are):
            // `id` computes such rows with a warning, as OpenSim does; here the loads stand
            // in for the contact estimate, and a clip beyond them would get invented
            // reactions (HumanML3D's 8.45 s against gait2392's 2.5 s of plates: −17 kN).
            let [l0, l1] = set.time_span;
            let slack = 0.5 * (1.0 / rate_hz);
            if times[0] < l0 - slack || times[frames - 1] > l1 + slack {
                return Err(Error::invalid(
                    "--external-loads",
                    format!(
                        "{}: the measured loads span {} s to {} s, but {} runs from {} s \
                         to {} s: the loads must cover the clip",
                        set.data_source,
                        short_number(l0),
                        short_number(l1),
                        source,
                        short_number(times[0]),
                        short_number(times[frames - 1])
                    ),
                ));
            }
            Ok(Some(set))
        }
        Some(MeasuredLoads::ForcePlates(p)) => {
            Ok(Some(plate_loads(model, p, times, &kinematics.q)?))
        }
    }
}

/// The measured loads at time `t` in place of the contact estimate: τ = τ_ID − Q with
/// Q = Σ Jᵀ w, and the per-group and per-body reactions they make.
fn measured_contact(
    model: &Model,
    solvers: &ClipSolvers,
    loads: &ExternalLoadSet,
    t: f64,
    ws: &mut FrameWorkspaces,
) -> crate::Result<()> {
    // τ = τ_ID − Q, Q = Σ Jᵀ w of the measured forces
    loads.add_generalized_forces(model, &ws.data, t, &mut ws.external)?;
    for (v, e) in ws.tau.iter_mut().zip(&ws.external) {
        *v -= e;
    }
    ws.contact_frame.forces.fill(Vec3::zeros());
    ws.contact_frame.points.fill(Vec3::zeros());
    measured_reaction(
        &solvers.set,
        loads,
        &solvers.load_group,
        &ws.data,
        t,
        &mut ws.groups,
        &mut ws.body_contact,
    );
    Ok(())
}

/// A warning per body without contact points that comes as low as a foot at rest
/// (`max_point_offset` of the floor; see [`contact::low_bodies`]): the floor may carry it
/// there, which the contacts — the feet — cannot show.
fn low_body_warnings(
    model: &Model,
    source: &str,
    set: &ContactSet,
    max_point_offset: f64,
    q: &[f64],
    warnings: &mut Vec<String>,
) -> crate::Result<()> {
    for low in contact::low_bodies(model, set, max_point_offset, q)? {
        warnings.push(format!(
            "{}: {} comes within {} m of the floor in {} frame(s) ({}–{}, lowest {:.3} m): the \
             floor may carry it there (kneeling, a hand put down, sitting), but the contacts \
             are the feet's, so its load goes through them and those frames' joint moments \
             and muscle forces are not the body's",
            source,
            model.bodies[low.body].name,
            max_point_offset,
            low.frames,
            low.first,
            low.last,
            low.lowest
        ));
    }
    Ok(())
}

/// The clip's warnings from its quality: frames static optimization left unbalanced, and an
/// IK that could not follow the clip (its worst marker error that was not down-weighted).
fn quality_warnings(
    clip: &ClipComputed,
    quality: &ClipQuality,
    source: &str,
    warnings: &mut Vec<String>,
) {
    if quality.so_unsolved_frames > 0 {
        warnings.push(format!(
            "{}: static optimization left {} frame(s) unbalanced",
            source, quality.so_unsolved_frames
        ));
    }
    if quality.ik_error_max > IK_ERROR_WARNED {
        let (model, tasks, solution) = (&clip.model, &clip.tasks, &clip.solution);
        let nm = tasks.markers.len();
        let down_weighted = |k: usize| solution.disagreeing.iter().any(|d| d.task == k % nm);
        let worst = (solution.marker_error.iter().enumerate())
            .filter(|&(k, e)| e.is_finite() && !down_weighted(k))
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map(|(k, _)| k);
        if let Some(k) = worst {
            warnings.push(format!(
                "{}: IK could not follow the clip: its worst error is {:.0} mm (frame {}, \
                 {}; median RMSE {:.0} mm), and {} frame(s) ended with a coordinate at its \
                 bound (check the skeleton map, its axes and the length unit)",
                source,
                quality.ik_error_max * 1e3,
                k / nm,
                model.markers[tasks.markers[k % nm].marker].name,
                quality.ik_rmse_median * 1e3,
                quality.ik_frames_at_bound
            ));
        }
    }
}

/// The unit vector up: against gravity (+y for a model without gravity).
fn up(model: &Model) -> Vec3 {
    let g = model.gravity;
    if g.norm() > 0.0 {
        -g / g.norm()
    } else {
        Vec3::y()
    }
}

/// The vertical component (along [`up`]) of `force`; 0 for a model without gravity.
fn vertical(model: &Model, force: Vec3) -> f64 {
    if model.gravity.norm() > 0.0 {
        up(model).dot(&force)
    } else {
        0.0
    }
}

/// The vertical external force the motion needs at the frame of the last inverse dynamics
/// (`data` after [`dynamics::rnea`]): D = up·Σ_i m_i (a_i − g), the linear part of the spatial
/// force each joint attached to ground transmits (RNEA's backward pass accumulates every
/// body's I a + v ×* I v, with gravity entering as ground's upward acceleration, into the
/// root of its subtree). Bodies welded to ground carry nothing the contacts must supply.
fn vertical_support_demand(model: &Model, data: &Data) -> f64 {
    let needed: Vec3 = (model.joints.iter())
        .filter(|j| j.parent_body == 0 && !j.coordinates.is_empty())
        .map(|j| data.body_force[j.child_body].lin)
        .sum();
    vertical(model, needed)
}

/// Per column of a row-major frames × `columns` array: the RMS over the column's finite
/// values, √(Σ e² / n); none where the column has none.
fn rmse_by_column(values: &[f64], columns: usize) -> Vec<Option<f64>> {
    let mut sum = vec![0.0; columns];
    let mut count = vec![0usize; columns];
    for row in values.chunks_exact(columns.max(1)) {
        for (k, &e) in row.iter().enumerate().filter(|(_, e)| e.is_finite()) {
            sum[k] += e * e;
            count[k] += 1;
        }
    }
    (sum.iter().zip(&count))
        .map(|(s, &n)| (n > 0).then(|| (s / n as f64).sqrt()))
        .collect()
}

/// Every emitted value finite (NaN only in `ik_marker_error`, where a target was missing):
/// a value beyond float32's range (a model of 10³⁰⁰ kg, a muscle strength of 10³⁰⁰, a
/// sampling rate of 1 GHz) fails the clip, naming the array, rather than writing infinities.
fn check_finite(arrays: &[Array]) -> crate::Result<()> {
    for a in arrays {
        let nan_allowed = a.name == "ik_marker_error";
        if let Some(k) =
            (a.values.iter()).position(|v| v.is_infinite() || (!nan_allowed && v.is_nan()))
        {
            let per_frame = a.shape.iter().skip(1).product::<usize>().max(1);
            return Err(Error::invalid(
                "motion",
                format!(
                    "array `{}` holds {} at frame {} (column {}): beyond float32's range — \
                     the model or the motion is far out of scale (body mass, muscle strength, \
                     sampling rate)",
                    a.name,
                    a.values[k],
                    k / per_frame,
                    k % per_frame
                ),
            ));
        }
    }
    Ok(())
}

/// The contact points of `model`: its ContactSpheres, or, for a model without any that has
/// gait2392's foot bodies (calcn_r/l, toes_r/l), the points of `data/contacts/gait2392_feet.json`
/// scaled to its feet.
pub fn contact_set(model: &Model) -> crate::Result<ContactSet> {
    match ContactSet::from_model(model) {
        Ok(set) => Ok(set),
        Err(e) => {
            let feet = ["calcn_r", "calcn_l", "toes_r", "toes_l"];
            let spheres = model
                .contact_geometry
                .iter()
                .any(|g| matches!(g.shape, crate::model::ContactShape::Sphere { .. }));
            if !spheres && feet.iter().all(|b| model.body_index(b).is_some()) {
                let points = contact::points_from_json(
                    model,
                    contact::GAIT2392_FEET_JSON,
                    "data/contacts/gait2392_feet.json",
                    None,
                )?;
                ContactSet::from_points(model, points)
            } else if !spheres {
                // the library's hint (`ContactSet::from_points`) is no way out on the
                // command line
                Err(Error::invalid(
                    "model",
                    format!(
                        "model \"{}\" ({}) has no ContactSphere for the ground contacts and \
                         not gait2392's foot bodies (calcn_r/l, toes_r/l) to put them on: add \
                         ContactSpheres to its ContactGeometrySet, as the default model has \
                         on its feet",
                        model.name, model.source
                    ),
                ))
            } else {
                Err(e)
            }
        }
    }
}

/// `motion` without its leading and trailing frames in which fewer than half of the targets
/// are present (a capture volume's ends, where only a few markers are seen); a warning says
/// how many were dropped. Gaps inside are left to IK (targets missing in a frame are left out
/// there).
fn trim_to_data(motion: &Motion, warnings: &mut Vec<String>) -> crate::Result<Motion> {
    let n = motion.names.len();
    let enough = |f: usize| {
        let present = motion.frame(f).iter().filter(|p| p.x.is_finite()).count();
        2 * present >= n
    };
    let frames = motion.n_frames();
    let Some(first) = (0..frames).find(|&f| enough(f)) else {
        return Err(Error::Motion {
            file: motion.source.clone(),
            location: "every frame".into(),
            message: format!("fewer than half of the {n} targets are present in any frame"),
        });
    };
    let last = (0..frames).rev().find(|&f| enough(f)).unwrap_or(first);
    if first == 0 && last + 1 == frames {
        return Ok(motion.clone());
    }
    warnings.push(format!(
        "{}: frames {first}–{last} of {frames} kept (fewer than half of the targets outside)",
        motion.source
    ));
    motion.time_window(motion.time[first], motion.time[last])
}

/// The force plates of the C3D file `path` as measured loads on `model`: each plate's force,
/// centre of pressure and free moment (ground frame, OpenSim axes) applied to `calcn_r` or
/// `calcn_l`, whichever lies nearer the plate's centre of pressure on average over the frames
/// the plate is loaded (poses from `q` at `times`, the C3D's marker clock). A plate never
/// loaded is left out.
fn plate_loads(
    model: &Model,
    path: &std::path::Path,
    times: &[f64],
    q: &[f64],
) -> crate::Result<ExternalLoadSet> {
    use crate::io::external_loads::{ExternalForce, ExternalLoads};
    let c3d = crate::motion::c3d::C3d::read(path)?;
    let table = c3d.ground_reactions(PLATE_THRESHOLD)?;
    let feet = ["calcn_r", "calcn_l"].map(|b| model.body_index(b));
    let [Some(right), Some(left)] = feet else {
        return Err(Error::invalid(
            "force plates",
            format!(
                "{}: assigning plates to feet needs bodies calcn_r and calcn_l, which model {} \
                 lacks",
                path.display(),
                model.name
            ),
        ));
    };
    let n = model.nq();
    let mut data = Data::new(model);
    let columns = table.labels.len();
    let mut forces = Vec::new();
    for plate in 1..=c3d.plates.len() {
        let col = |name: &str| {
            table
                .labels
                .iter()
                .position(|l| *l == format!("plate{plate}_{name}"))
        };
        let (Some(fy), Some(px)) = (col("force_vy"), col("force_px")) else {
            continue;
        };
        // mean distance of the COP to each calcaneus over the loaded samples (nearest pose)
        let (mut d_right, mut d_left, mut count) = (0.0, 0.0, 0usize);
        for (row, &t) in table.time.iter().enumerate() {
            let v = &table.values[row * columns..(row + 1) * columns];
            if v[fy] == 0.0 {
                continue;
            }
            let f = times.partition_point(|&x| x < t).min(times.len() - 1);
            if (times[f] - t).abs() > 0.5 * (times[1] - times[0]).abs().max(1e-9) {
                continue;
            }
            crate::dynamics::forward_kinematics(model, &mut data, &q[f * n..(f + 1) * n])?;
            let cop = Vec3::new(v[px], v[px + 1], v[px + 2]);
            d_right += (data.body_pose(right).1 - cop).norm();
            d_left += (data.body_pose(left).1 - cop).norm();
            count += 1;
        }
        if count == 0 {
            continue;
        }
        let body = if d_right <= d_left {
            "calcn_r"
        } else {
            "calcn_l"
        };
        forces.push(ExternalForce {
            name: format!("plate{plate}"),
            applied_to_body: body.into(),
            force_expressed_in_body: "ground".into(),
            point_expressed_in_body: "ground".into(),
            force_identifier: Some(format!("plate{plate}_force_v")),
            point_identifier: Some(format!("plate{plate}_force_p")),
            torque_identifier: Some(format!("plate{plate}_torque_")),
            line: 0,
        });
    }
    let source = path.display().to_string();
    let loads = ExternalLoads {
        source: source.clone(),
        datafile: None,
        forces,
        prescribed: Vec::new(),
    };
    ExternalLoadSet::new(model, &loads, &table, &source)
}

/// The contact group of each force of `loads` (by the body it is applied to).
fn load_groups(model: &Model, set: &ContactSet, loads: &ExternalLoadSet) -> Vec<Option<usize>> {
    loads
        .forces
        .iter()
        .map(|f| {
            let name = contact::group_for_body(&model.bodies[f.applied_to_body].name);
            set.groups().iter().position(|g| *g == name)
        })
        .collect()
}

/// Measured ground reactions per contact group (forces on a body of the group summed; the
/// centre of pressure as the normal-force-weighted mean of the forces' points, projected on
/// the floor; the free moment as the torques' component along the floor normal), and the
/// force on each body.
#[allow(clippy::too_many_arguments)]
fn measured_reaction(
    set: &ContactSet,
    loads: &ExternalLoadSet,
    load_group: &[Option<usize>],
    data: &Data,
    t: f64,
    groups: &mut [GroupWrench],
    body_contact: &mut [Vec3],
) {
    let n = set.floor_normal;
    for i in 0..loads.forces.len() {
        let w = loads.wrench(data, i, t);
        body_contact[w.body] += w.force_in_ground;
    }
    for (k, g) in groups.iter_mut().enumerate() {
        *g = GroupWrench::default();
        let (mut total, mut weighted) = (0.0, Vec3::zeros());
        for i in 0..loads.forces.len() {
            if load_group[i] != Some(k) {
                continue;
            }
            let w = loads.wrench(data, i, t);
            let normal = w.force_in_ground.dot(&n).max(0.0);
            g.force += w.force_in_ground;
            g.free_moment += w.torque_in_ground.dot(&n);
            total += normal;
            weighted += w.point_in_ground * normal;
        }
        if total > 1e-6 {
            let c = weighted / total;
            g.cop = c - n * (n.dot(&c) - set.floor_height);
            g.loaded = true;
        }
    }
}

/// The file suffixes of the OpenSim tables, in the order [`ClipOutput::tables`] gives them:
/// coordinates, generalized forces, activations, ground reactions.
pub const OPENSIM_SUFFIXES: [&str; 4] = ["_ik.mot", "_tau.sto", "_activation.sto", "_grf.mot"];

/// The OpenSim tables of [`ClipOutput::tables`].
fn opensim_tables(
    model: &Model,
    so: &StaticOptimization,
    set: &ContactSet,
    time: &[f64],
    q: &[f64],
    frames: &FrameArrays,
) -> crate::Result<Vec<(&'static str, Table)>> {
    use crate::model::MotionType;
    use crate::solve::inverse_dynamics::generalized_force_labels;
    let n = model.nq();
    let mut data = Data::new(model);
    let mut values = Vec::with_capacity(time.len() * model.coordinates.len());
    for f in 0..time.len() {
        dynamics::forward_kinematics(model, &mut data, &q[f * n..(f + 1) * n])?;
        for (c, v) in model.coordinates.iter().zip(data.coordinate_values(model)) {
            values.push(if c.motion_type == MotionType::Rotational {
                v.to_degrees()
            } else {
                *v
            });
        }
    }
    let labels = model.coordinates.iter().map(|c| c.name.clone()).collect();
    let mut ik = Table::new("Coordinates", labels, time.to_vec(), values)?;
    ik.in_degrees = Some(true);
    let labels = generalized_force_labels(model);
    let mut tau = Table::new(
        "Inverse Dynamics",
        labels,
        time.to_vec(),
        frames.tau.clone(),
    )?;
    tau.in_degrees = Some(false);
    let labels = so
        .muscles
        .muscles
        .iter()
        .map(|m| m.name().to_string())
        .collect();
    let mut act = Table::new(
        "Static Optimization",
        labels,
        time.to_vec(),
        frames.activation.clone(),
    )?;
    act.in_degrees = Some(false);
    let mut labels = Vec::new();
    for g in set.groups() {
        for suffix in [
            "ground_force_vx",
            "ground_force_vy",
            "ground_force_vz",
            "ground_force_px",
            "ground_force_py",
            "ground_force_pz",
            "ground_torque_y",
        ] {
            labels.push(format!("{g}_{suffix}"));
        }
    }
    let ng = set.groups().len();
    let mut values = Vec::with_capacity(time.len() * labels.len());
    for f in 0..time.len() {
        for g in 0..ng {
            let k = (f * ng + g) * 3;
            values.extend(frames.grf[k..k + 3].iter().map(|&v| v as f64));
            values.extend(frames.cop[k..k + 3].iter().map(|&v| v as f64));
            values.push(frames.free_moment[f * ng + g] as f64);
        }
    }
    let mut grf = Table::new("GRF", labels, time.to_vec(), values)?;
    grf.in_degrees = Some(false);
    let [ik_suffix, tau_suffix, act_suffix, grf_suffix] = OPENSIM_SUFFIXES;
    Ok(vec![
        (ik_suffix, ik),
        (tau_suffix, tau),
        (act_suffix, act),
        (grf_suffix, grf),
    ])
}

/// A CoordinateActuator named `reserve_<coordinate>` on every independent coordinate (the
/// residual actuators of the floating base and the joints' reserves), controls unbounded,
/// as OpenSim's reserve force-set files define them.
fn add_reserves(model: &mut Model, optimal_force: f64) {
    let independent = model.reduction.independent.clone();
    for c in independent {
        let name = model.coordinates[c].name.clone();
        model.forces.push(ForceElement {
            name: format!("reserve_{name}"),
            kind: "CoordinateActuator".into(),
            path: None,
            applies_force: true,
            actuator: Some(ScalarActuator {
                min_control: f64::NEG_INFINITY,
                max_control: f64::INFINITY,
                optimal_force,
                kind: ActuatorKind::Coordinate { coordinate: c },
            }),
            raw: Default::default(),
            line: 0,
            file: String::new(),
        });
    }
}

/// The error for marker data matched by name to a model that has none of its markers.
fn no_common_markers(model: &Model, motion: &Motion) -> Error {
    // the first four names, and "…" when there are more
    fn some<'a>(names: impl Iterator<Item = &'a str>) -> String {
        let names: Vec<&str> = names.collect();
        let shown = names[..names.len().min(4)].join(", ");
        if names.len() > 4 {
            format!("{shown}, …")
        } else {
            shown
        }
    }
    Error::invalid(
        "markers",
        format!(
            "{}: none of its {} markers ({}) is a marker of the model `{}` ({} markers: {}); \
             give the model they were placed on (--model) or a skeleton map (--map)",
            motion.source,
            motion.names.len(),
            some(motion.names.iter().map(String::as_str)),
            model.name,
            model.markers.len(),
            some(model.markers.iter().map(|m| m.name.as_str())),
        ),
    )
}

fn at_frame(source: &str, frame: usize, e: Error) -> Error {
    match e {
        Error::InvalidArgument { argument, message } => Error::InvalidArgument {
            argument,
            message: format!("{source}, frame {frame}: {message}"),
        },
        other => other,
    }
}

/// The per-frame outputs of a clip, filled frame by frame (allocated once).
struct FrameArrays {
    x: Vec<f32>,
    /// Generalized forces of measured loads (zero without them).
    external: Vec<f32>,
    tau: Vec<f64>,
    activation: Vec<f64>,
    muscle_force: Vec<f32>,
    fiber_length: Vec<f32>,
    fiber_velocity: Vec<f32>,
    muscle_length: Vec<f32>,
    grf: Vec<f32>,
    cop: Vec<f32>,
    free_moment: Vec<f32>,
    contact_point_force: Vec<f32>,
    contact_point_pos: Vec<f32>,
    contact_state: Vec<f32>,
    residual: Vec<f64>,
    reserve_abs: f64,
    joint_abs: f64,
    /// Σ|reserve| per reserve column (same order as `reserve_columns`).
    reserve_by_column: Vec<f64>,
    /// max_t |reserve| and max_t |τ| per reserve column.
    reserve_peak_by_column: Vec<f64>,
    joint_peak_by_column: Vec<f64>,
    /// Upper activation bound of each muscle (`muscle_columns` order), and the muscle
    /// samples that reached it.
    muscle_upper: Vec<f64>,
    at_full_activation: usize,
    /// Σ_t D_t⁺ and Σ_t min(G_t⁺, D_t⁺) of [`ClipQuality::contact_consistency`].
    support_demand: f64,
    support_carried: f64,
    unsolved: usize,
    in_contact: usize,
    muscle_columns: Vec<usize>,
    reserve_columns: Vec<(usize, usize)>,
    floating: Vec<usize>,
    /// Whether each floating-base row is a rotation ([`ContactSet::floating_base_rotational`]).
    floating_rotational: Vec<bool>,
    groups: usize,
}

impl FrameArrays {
    fn new(
        model: &Model,
        so: &StaticOptimization,
        set: &ContactSet,
        layout: &JointLayout,
        frames: usize,
    ) -> FrameArrays {
        let m = so.muscles.muscles.len();
        let p = set.points.len();
        let g = set.groups().len();
        let muscle_columns = (0..m)
            .map(|k| {
                so.actuators
                    .iter()
                    .position(|a| a.muscle == Some(k))
                    .expect("every muscle is an actuator")
            })
            .collect();
        let muscle_upper = (0..m)
            .map(|k| {
                let column = so.actuators.iter().position(|a| a.muscle == Some(k));
                column.map_or(1.0, |c| so.actuators[c].max_control)
            })
            .collect();
        let floating = set.floating_base.clone();
        let names = model.q_names();
        let reserve_columns = so
            .actuators
            .iter()
            .enumerate()
            .filter_map(|(k, a)| {
                let name = a.name.strip_prefix("reserve_")?;
                let j = names.iter().position(|n| *n == name)?;
                (!floating.contains(&j)).then_some((k, j))
            })
            .collect();
        FrameArrays {
            x: Vec::with_capacity(frames * layout.width()),
            external: Vec::with_capacity(frames * model.nq()),
            tau: Vec::with_capacity(frames * model.nq()),
            activation: Vec::with_capacity(frames * m),
            muscle_force: Vec::with_capacity(frames * m),
            fiber_length: Vec::with_capacity(frames * m),
            fiber_velocity: Vec::with_capacity(frames * m),
            muscle_length: Vec::with_capacity(frames * m),
            grf: Vec::with_capacity(frames * g * 3),
            cop: Vec::with_capacity(frames * g * 3),
            free_moment: Vec::with_capacity(frames * g),
            contact_point_force: Vec::with_capacity(frames * p * 3),
            contact_point_pos: Vec::with_capacity(frames * p * 3),
            contact_state: Vec::with_capacity(frames * p),
            residual: Vec::with_capacity(frames * 6),
            reserve_abs: 0.0,
            joint_abs: 0.0,
            reserve_by_column: Vec::new(),
            reserve_peak_by_column: Vec::new(),
            joint_peak_by_column: Vec::new(),
            muscle_upper,
            at_full_activation: 0,
            support_demand: 0.0,
            support_carried: 0.0,
            unsolved: 0,
            in_contact: 0,
            muscle_columns,
            reserve_columns,
            floating,
            floating_rotational: set.floating_base_rotational.clone(),
            groups: g,
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn record(
        &mut self,
        so: &StaticOptimization,
        so_ws: &SoWorkspace,
        so_frame: &SoFrame,
        contact: &ContactFrame,
        groups: &[GroupWrench],
        layout: &JointLayout,
        joint: &JointFrame,
        tau: &[f64],
    ) {
        let start = self.activation.len();
        for &k in &self.muscle_columns {
            self.activation.push(so_frame.controls[k]);
        }
        let acts = &self.activation[start..];
        // on the bound to round-off: the QP projects onto it
        self.at_full_activation += (acts.iter().zip(&self.muscle_upper))
            .filter(|(a, hi)| **a >= **hi - 1e-9 * hi.abs().max(1.0))
            .count();
        layout.flatten(joint, acts, &mut self.x);
        for (i, &k) in self.muscle_columns.iter().enumerate() {
            let (fiber_length, fiber_velocity) = so.fiber_kinematics(so_ws, i);
            self.muscle_force.push(so_frame.forces[k] as f32);
            self.fiber_length.push(fiber_length as f32);
            self.fiber_velocity.push(fiber_velocity as f32);
            self.muscle_length.push(so_ws.paths.length[i] as f32);
        }
        self.tau.extend_from_slice(tau);
        for &(k, j) in &self.reserve_columns {
            self.reserve_abs += so_frame.forces[k].abs();
            self.joint_abs += tau[j].abs();
        }
        self.reserve_by_column
            .resize(self.reserve_columns.len(), 0.0);
        self.reserve_peak_by_column
            .resize(self.reserve_columns.len(), 0.0);
        self.joint_peak_by_column
            .resize(self.reserve_columns.len(), 0.0);
        for (i, &(k, j)) in self.reserve_columns.iter().enumerate() {
            let reserve = so_frame.forces[k].abs();
            self.reserve_by_column[i] += reserve;
            self.reserve_peak_by_column[i] = self.reserve_peak_by_column[i].max(reserve);
            self.joint_peak_by_column[i] = self.joint_peak_by_column[i].max(tau[j].abs());
        }
        if so_frame.status != SoStatus::Solved {
            self.unsolved += 1;
        }
        for g in groups {
            self.grf
                .extend([g.force.x as f32, g.force.y as f32, g.force.z as f32]);
            self.cop
                .extend([g.cop.x as f32, g.cop.y as f32, g.cop.z as f32]);
            self.free_moment.push(g.free_moment as f32);
        }
        let mut any = false;
        for (f, p) in contact.forces.iter().zip(&contact.points) {
            self.contact_point_force
                .extend([f.x as f32, f.y as f32, f.z as f32]);
            self.contact_point_pos
                .extend([p.x as f32, p.y as f32, p.z as f32]);
            self.contact_state
                .push(if f.norm() > 0.0 { 1.0 } else { 0.0 });
            any |= f.norm() > 0.0;
        }
        if any {
            self.in_contact += 1;
        }
        for &j in &self.floating {
            self.residual.push(tau[j]);
        }
    }

    /// One frame's vertical support demand D and the vertical contact force G
    /// ([`ClipQuality::contact_consistency`]).
    fn record_support(&mut self, demand: f64, carried: f64) {
        let d = demand.max(0.0);
        self.support_demand += d;
        self.support_carried += carried.max(0.0).min(d);
    }

    fn quality(
        &self,
        model: &Model,
        ik: &ik::IkSolution,
        frames: usize,
        rate_hz: f64,
        clamped: usize,
        reserve_optimal_force: f64,
    ) -> ClipQuality {
        let mass: f64 = model.bodies.iter().map(|b| b.mass).sum();
        let weight = mass * model.gravity.norm();
        let nf = self.floating.len().max(1);
        // peak over rows and frames; RMS over frames per row, the largest row
        let (mut force, mut moment) = (0.0f64, 0.0f64);
        let (mut force_rms, mut moment_rms) = (0.0f64, 0.0f64);
        for i in 0..self.floating.len() {
            let (mut peak, mut sum_sq) = (0.0f64, 0.0);
            for f in 0..frames {
                let v = self.residual[f * nf + i];
                peak = peak.max(v.abs());
                sum_sq += v * v;
            }
            let rms = (sum_sq / frames.max(1) as f64).sqrt();
            // (the contact set's classification, from the root joint's axes: a model file's
            // coordinates may leave their motion type to the joint, as gait2392's pelvis_t* do)
            if !self.floating_rotational[i] {
                force = force.max(peak);
                force_rms = force_rms.max(rms);
            } else {
                moment = moment.max(peak);
                moment_rms = moment_rms.max(rms);
            }
        }
        // the coordinate whose peak reserve is the largest share of its peak joint moment
        let names = model.q_names();
        let (reserve_peak_share, reserve_peak_coordinate) = (self.reserve_columns.iter())
            .zip(
                self.reserve_peak_by_column
                    .iter()
                    .zip(&self.joint_peak_by_column),
            )
            .filter(|(_, (r, t))| **r > 0.0 && **t >= reserve_optimal_force)
            .map(|(&(_, j), (r, t))| (r / t.max(1e-300), names[j].to_string()))
            .max_by(|a, b| a.0.total_cmp(&b.0).then_with(|| b.1.cmp(&a.1)))
            .unwrap_or((0.0, String::new()));
        let muscle_samples = frames * self.muscle_upper.len();
        let mut rmse: Vec<f64> = ik.rmse.iter().copied().filter(|v| v.is_finite()).collect();
        rmse.sort_by(f64::total_cmp);
        ClipQuality {
            frames,
            rate_hz,
            ik_rmse_median: rmse.get(rmse.len() / 2).copied().unwrap_or(f64::NAN),
            ik_error_max: ik
                .max_error
                .iter()
                .copied()
                .filter(|v| v.is_finite())
                .fold(0.0, f64::max),
            ik_frames_at_bound: ik.frames_at_limit(),
            ik_frames_at_bound_share: ik.frames_at_limit() as f64 / frames.max(1) as f64,
            ik_markers: Vec::new(),
            ik_rmse_by_marker: Vec::new(),
            residual_force_max_bw: force / weight,
            residual_force_rms_bw: force_rms / weight,
            residual_moment_max: moment,
            residual_moment_max_bwm: moment / weight,
            residual_moment_rms_bwm: moment_rms / weight,
            reserve_share: if self.joint_abs > 0.0 {
                self.reserve_abs / self.joint_abs
            } else {
                0.0
            },
            reserve_peak_share,
            reserve_peak_coordinate,
            reserve_by_coordinate: {
                let mut v: Vec<(String, f64)> = self
                    .reserve_columns
                    .iter()
                    .zip(&self.reserve_by_column)
                    .filter(|(_, r)| **r > 0.0)
                    .map(|(&(_, j), r)| (names[j].to_string(), r / self.joint_abs.max(1e-300)))
                    .collect();
                v.sort_by(|a, b| b.1.total_cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
                v.truncate(5);
                v
            },
            so_unsolved_frames: self.unsolved,
            muscle_samples,
            muscle_samples_at_full_activation: self.at_full_activation,
            full_activation_share: self.at_full_activation as f64 / muscle_samples.max(1) as f64,
            clamped_excitations: clamped,
            contact_fraction: self.in_contact as f64 / frames as f64,
            contact_consistency: (self.support_demand > 0.0)
                .then(|| self.support_carried / self.support_demand),
            body_mass: mass,
            treadmill: false,
            belt_velocity: [0.0; 3],
            body_weight: weight,
            verdict: None,
        }
    }

    fn into_arrays(
        self,
        layout: &JointLayout,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        frames: usize,
        n: usize,
    ) -> Vec<Array> {
        let f32s = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
        let width = layout.width();
        let mut arrays = Vec::new();
        // the per-joint blocks, cut out of x
        for r in layout.ranges() {
            let mut values = Vec::with_capacity(frames * (r.end - r.start));
            for f in 0..frames {
                values.extend_from_slice(&self.x[f * width + r.start..f * width + r.end]);
            }
            let mut shape = vec![frames];
            shape.extend(&r.shape);
            arrays.push(Array {
                name: block_name(&r.name),
                shape,
                values,
            });
        }
        let (m, g, nf) = (layout.n_muscles, self.groups, self.floating.len());
        let p = self.contact_state.len() / frames.max(1);
        let mut push = |name: &'static str, shape: &[usize], values: Vec<f32>| {
            let mut full = vec![frames];
            full.extend_from_slice(shape);
            arrays.push(Array {
                name,
                shape: full,
                values,
            });
        };
        push("x", &[width], self.x);
        for (name, v) in [("q", q), ("qd", qd), ("qdd", qdd), ("tau", &self.tau[..])] {
            push(name, &[n], f32s(v));
        }
        push("external", &[n], self.external);
        push("grf", &[g, 3], self.grf);
        push("cop", &[g, 3], self.cop);
        push("free_moment", &[g], self.free_moment);
        push("contact_point_force", &[p, 3], self.contact_point_force);
        push("contact_point_pos", &[p, 3], self.contact_point_pos);
        push("contact_state", &[p], self.contact_state);
        push("muscle_force", &[m], self.muscle_force);
        push("muscle_length", &[m], self.muscle_length);
        push("fiber_length", &[m], self.fiber_length);
        push("fiber_velocity", &[m], self.fiber_velocity);
        push("residual", &[nf], f32s(&self.residual));
        arrays
    }
}

fn block_name(name: &str) -> &'static str {
    super::layout::BLOCKS
        .iter()
        .find(|b| **b == name)
        .copied()
        .unwrap_or("unknown")
}
