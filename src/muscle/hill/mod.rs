//! Hill-type muscle force models, as OpenSim defines them:
//! - `Thelen2003Muscle` — Thelen (2003), J. Biomech. Eng. 125:70–77;
//! - `Millard2012EquilibriumMuscle` — Millard et al. (2013), J. Biomech. Eng. 135:021005,
//!   rigid or elastic tendon, with or without fiber damping;
//! - `DeGrooteFregly2016Muscle` — De Groote et al. (2016), Ann. Biomed. Eng. 44:2922–2936.
//!
//! A [`HillMuscle`] is built once from a model file's force element
//! ([`HillMuscle::from_force_element`]); its per-frame functions allocate nothing and return a
//! [`MuscleState`] with a [`MuscleStatus`] instead of panicking:
//! - [`HillMuscle::state_rigid_tendon`]: closed form with an inextensible tendon,
//!   F = (a f_L f_V + f_PE + β ṽ) F_max cos α;
//! - [`HillMuscle::state_at_fiber_length`]: the state OpenSim reports when the fiber length is
//!   known (e.g. from a states file): tendon force from the tendon curve, fiber velocity from
//!   the force balance;
//! - [`HillMuscle::state_equilibrium`]: the fiber length (and velocity) that balance fiber and
//!   tendon force for given a, ℓ_MT, ℓ̇_MT;
//! - [`HillMuscle::state`] and [`HillMuscle::isometric_force`]: the muscle's own tendon mode.
//!
//! Notation: l̃ = l / l_opt, ṽ = v / (v_max l_opt) with v_max in optimal fiber lengths per
//! second (lengthening positive), l̃ᵀ = lᵀ / l_s, forces normalised by F_max. Pennation keeps
//! the fiber's parallelogram height constant, h = l_opt sin α_opt ([`pennation`]).
//!
//! The definitions (curve shapes and constructions, defaults, clamping, minimum activation and
//! fiber length, the equilibrium equations) are OpenSim's. Deliberate differences:
//! - Solvers are tighter and cannot throw: OpenSim inverts Thelen's force–velocity relation
//!   by Newton to 1e-6 (here in closed form), stops equilibrium solves at 1e-8 F_max (here
//!   1e-12 F_max, bracketed), and throws where a status is returned here.
//! - Thelen with `ignore_tendon_compliance` is accepted (OpenSim refuses it).
//! - The curves are built once, for the tendon mode and damping the file declares (OpenSim's
//!   `extendFinalizeFromProperties` adjusts Millard's curves per mode); the rigid-tendon
//!   function of an undamped elastic Millard muscle therefore uses its classic-model curves.
//! - De Groote–Fregly with `fiber_damping` > 0: [`HillMuscle::state_at_fiber_length`] solves
//!   the damped force balance for the fiber velocity (OpenSim's explicit inversion leaves the
//!   damping out, so its fiber and tendon forces then disagree).
//! - The velocity sharing of the equilibrium initialisation, see [`VelocitySplit::Stiffness`].
//!
//! `Thelen2003Muscle` is the formulation of OpenSim 3.0 and later. Results written by OpenSim
//! 2.x (`Version="20302"` files, such as the Arm26 CMC tutorial outputs) come from the older
//! formulation that OpenSim now calls `Thelen2003Muscle_Deprecated` (damping 0.05, no
//! (0.25 + 0.75 a) velocity factor but v_max scaled from `Vmax0` to `Vmax` with activation,
//! tendon toe F_toe = 1/3 plus 0.001 (1 + ε), passive exp(k(l̃ − 1)/ε₀)/exp(k)), not modelled
//! here.

// Parameter checks are written `!(x > bound)` on purpose: NaN fails them.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bezier;
pub mod degroote;
mod equilibrium;
pub mod millard;
mod params;
pub mod pennation;
mod state;
#[cfg(test)]
mod tests;
pub mod thelen;

pub use bezier::{CurvePoint, SmoothSegmentedFunction};
pub use degroote::DeGrooteFregly2016Curves;
pub use equilibrium::{EquilibriumSettings, VelocitySplit};
pub use millard::Millard2012Curves;
pub use pennation::FixedWidthPennation;
pub use state::{MuscleState, MuscleStatus};
pub use thelen::Thelen2003Curves;

/// The OpenSim muscle classes modelled here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MuscleKind {
    Thelen2003,
    Millard2012Equilibrium,
    DeGrooteFregly2016,
}

impl MuscleKind {
    /// The OpenSim class name.
    pub fn opensim_class(&self) -> &'static str {
        match self {
            MuscleKind::Thelen2003 => "Thelen2003Muscle",
            MuscleKind::Millard2012Equilibrium => "Millard2012EquilibriumMuscle",
            MuscleKind::DeGrooteFregly2016 => "DeGrooteFregly2016Muscle",
        }
    }

    pub fn from_opensim_class(class: &str) -> Option<MuscleKind> {
        match class {
            "Thelen2003Muscle" => Some(MuscleKind::Thelen2003),
            "Millard2012EquilibriumMuscle" => Some(MuscleKind::Millard2012Equilibrium),
            "DeGrooteFregly2016Muscle" => Some(MuscleKind::DeGrooteFregly2016),
            _ => None,
        }
    }
}

/// The parameters common to the three models, as used (after OpenSim's adjustments).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HillParameters {
    /// F_max (N).
    pub max_isometric_force: f64,
    /// l_opt (m).
    pub optimal_fiber_length: f64,
    /// l_s (m).
    pub tendon_slack_length: f64,
    /// α_opt (rad).
    pub pennation_angle_at_optimal: f64,
    /// v_max in optimal fiber lengths per second.
    pub max_contraction_velocity: f64,
    /// τ_act (s).
    pub activation_time_constant: f64,
    /// τ_deact (s).
    pub deactivation_time_constant: f64,
    /// Activation is clamped to [minimum_activation, 1] by Thelen and Millard; 0 (and no
    /// clamping) for De Groote–Fregly.
    pub minimum_activation: f64,
    /// β: damping force β ṽ F_max along the fiber. Always 0 for Thelen; 0 for Millard when
    /// the file's value is below 0.001 (OpenSim then switches to the undamped model).
    pub fiber_damping: f64,
    /// The model's own tendon mode (Millard and De Groote–Fregly; OpenSim refuses it for
    /// Thelen, where it is kept but only selects the mode of [`HillMuscle::state`]).
    pub ignore_tendon_compliance: bool,
    pub ignore_activation_dynamics: bool,
    /// α_max (rad); π/2 for De Groote–Fregly, which has none.
    pub maximum_pennation_angle: f64,
    /// Shortest fiber length (m): Thelen h / sin α_max; Millard the larger of that and the
    /// active curve's lower end; 0 for De Groote–Fregly.
    pub minimum_fiber_length: f64,
    pub default_activation: f64,
    /// De Groote–Fregly's tanh smoothing of the activation/deactivation switch.
    pub activation_dynamics_smoothing: Option<f64>,
}

/// The curves of one muscle.
#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant)] // one per muscle, built once; no indirection per evaluation
pub enum HillCurves {
    Thelen2003(Thelen2003Curves),
    Millard2012(Millard2012Curves),
    DeGrooteFregly2016(DeGrooteFregly2016Curves),
}

impl HillCurves {
    /// Active force–length multiplier f_L(l̃).
    #[inline]
    pub fn active_force_length(&self, norm_fiber_length: f64) -> CurvePoint {
        match self {
            HillCurves::Thelen2003(c) => c.active_force_length(norm_fiber_length),
            HillCurves::Millard2012(c) => c.active_force_length(norm_fiber_length),
            HillCurves::DeGrooteFregly2016(c) => c.active_force_length(norm_fiber_length),
        }
    }

    /// Passive (elastic) fiber force multiplier f_PE(l̃).
    #[inline]
    pub fn passive_force_length(&self, norm_fiber_length: f64) -> CurvePoint {
        match self {
            HillCurves::Thelen2003(c) => c.passive_force_length(norm_fiber_length),
            HillCurves::Millard2012(c) => c.passive_force_length(norm_fiber_length),
            HillCurves::DeGrooteFregly2016(c) => c.passive_force_length(norm_fiber_length),
        }
    }

    /// Normalised tendon force f_T(l̃ᵀ).
    #[inline]
    pub fn tendon_force_length(&self, norm_tendon_length: f64) -> CurvePoint {
        match self {
            HillCurves::Thelen2003(c) => c.tendon_force_length(norm_tendon_length),
            HillCurves::Millard2012(c) => c.tendon_force_length(norm_tendon_length),
            HillCurves::DeGrooteFregly2016(c) => c.tendon_force_length(norm_tendon_length),
        }
    }

    /// Force–velocity multiplier f_V(ṽ) (Thelen's depends on activation too).
    #[inline]
    pub fn force_velocity(&self, activation: f64, norm_fiber_velocity: f64) -> CurvePoint {
        match self {
            HillCurves::Thelen2003(c) => c.force_velocity(activation, norm_fiber_velocity),
            HillCurves::Millard2012(c) => c.force_velocity(norm_fiber_velocity),
            HillCurves::DeGrooteFregly2016(c) => c.force_velocity(norm_fiber_velocity),
        }
    }

    /// ṽ from f_V as each OpenSim class inverts it: Thelen's Eq. 6–7 (`calcdlceN`), Millard's
    /// `ForceVelocityInverseCurve`, De Groote–Fregly's closed-form inverse.
    #[inline]
    pub fn norm_fiber_velocity(&self, activation: f64, fv: f64) -> f64 {
        match self {
            HillCurves::Thelen2003(c) => c.norm_fiber_velocity(activation, fv),
            HillCurves::Millard2012(c) => c.norm_fiber_velocity(fv),
            HillCurves::DeGrooteFregly2016(c) => c.norm_fiber_velocity(fv),
        }
    }
}

/// One muscle's force model: parameters, curves and pennation geometry.
#[derive(Clone, Debug)]
pub struct HillMuscle {
    name: String,
    kind: MuscleKind,
    params: HillParameters,
    curves: HillCurves,
    pennation: FixedWidthPennation,
}

impl HillMuscle {
    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn kind(&self) -> MuscleKind {
        self.kind
    }

    pub fn params(&self) -> &HillParameters {
        &self.params
    }

    pub fn curves(&self) -> &HillCurves {
        &self.curves
    }

    pub fn pennation(&self) -> &FixedWidthPennation {
        &self.pennation
    }

    /// v_max l_opt (m/s): the velocity that normalises fiber velocities.
    #[inline]
    pub fn max_fiber_velocity(&self) -> f64 {
        self.params.max_contraction_velocity * self.params.optimal_fiber_length
    }

    /// Activation as the model uses it: clamped to [minimum_activation, 1] by Thelen and
    /// Millard (`MuscleFirstOrderActivationDynamicModel::clampActivation`), unchanged by De
    /// Groote–Fregly.
    #[inline]
    pub fn clamp_activation(&self, activation: f64) -> f64 {
        match self.kind {
            MuscleKind::DeGrooteFregly2016 => activation,
            _ => activation.clamp(self.params.minimum_activation, 1.0),
        }
    }
}
