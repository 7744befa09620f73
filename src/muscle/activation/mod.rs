//! First-order activation dynamics ȧ = f(u, a): muscle activation a following neural
//! excitation u, in OpenSim's forms; forward (a(t) from a sampled u(t)) and inverse (u(t)
//! from a sampled a(t)).
//!
//! # The forms
//!
//! With z(a) = 0.5 + 1.5 a, τ_act the activation and τ_deact the deactivation time constant:
//!
//! * **Thelen 2003**, as OpenSim's `MuscleFirstOrderActivationDynamicModel` implements it
//!   (the activation model of `Thelen2003Muscle` and `Millard2012EquilibriumMuscle`):
//!   activation is first clamped, ã = clamp(a, a_min, 1), then
//!   ȧ = (u − ã) / τ(u, ã), τ = τ_act · z(ã) if u > ã, else τ_deact / z(ã).
//!   The state a itself is not clamped and u is used as given (OpenSim removed both
//!   clampings from the derivative in 2016–17; they are kept out of the state by requiring
//!   u and the initial a to lie in [a_min, 1], which the exact solution then never leaves).
//! * **De Groote et al. 2016**, as OpenSim's `DeGrooteFregly2016Muscle` implements it: a
//!   tanh blend of the two rates instead of a switch,
//!   f = ½ tanh(b (u − a)),
//!   ȧ = [ (f + ½) / (τ_act z(a)) + (½ − f) z(a) / τ_deact ] (u − a),
//!   with b the `activation_dynamics_smoothing` (OpenSim's default 0.1 reproduces the paper;
//!   OpenSim recommends 10 for rates closer to the nominal time constants). Nothing is
//!   clamped; u and the initial a must lie in [0, 1].
//! * **Thelen 2003, OpenSim 2 form** (`Thelen2003Muscle_Deprecated`, OpenSim 2's
//!   `Thelen2003Muscle`): constant time constants, ȧ = (u − a)/τ_act if u ≥ a, else
//!   (u − a)/τ_deact, so a step response is an exponential. Reference results made with
//!   OpenSim 2 (such as the Arm26 CMC tutorial's) follow this form.
//!
//! # Forward: [`ActivationDynamics::integrate`]
//!
//! The sampled excitation is turned into a function of time by an explicit
//! [`Interpolation`]: linear, or held piecewise constant as OpenSim's `ControlLinear` does
//! with `use_steps` (the controls CMC writes). Each interval between consecutive excitation
//! samples (and requested output times) is integrated with the classical fourth-order
//! Runge–Kutta method on equal sub-steps no longer than min(τ_act, τ_deact) / 40. Steps never
//! straddle an excitation sample, so within a step u is smooth (linear or constant) and RK4
//! keeps its order; the only remaining non-smoothness, Thelen's switch at u = ã, is a kink
//! where ȧ = 0. The stiffness |∂ȧ/∂a| of these forms is at most about 8 / min(τ) (reached
//! near a = 0), so every step has |λ h| ≤ 0.2, well inside RK4's stability region, and the
//! error stays far below the tolerances OpenSim's integrators use. The number of steps is bounded before
//! integrating (an `Err` beyond [`MAX_STEPS`]).
//!
//! # Inverse: [`ActivationDynamics::excitation_from_activation`]
//!
//! ȧ is taken from the natural cubic spline through the activation samples: the derivative
//! of a C² interpolant, O(h³) or better away from the ends, where the natural end conditions
//! make the first and last few samples less accurate, and O(h) at a sample or two around
//! each point where ä jumps (a Thelen switch). At each sample ȧ = f(u, a) is then solved
//! for u — in closed form for the Thelen forms (f is increasing in u and each branch is
//! linear in u), by bisection for De Groote's blend on a bracket that provably holds the
//! root (ȧ is a rate between the two branch rates times u − a).
//! The solution is clamped to the admissible excitations ([a_min, 1] or [0, 1]) and every
//! clamped sample is reported with the excitation it would have needed.
//!
//! Bad input (non-finite values, time not strictly increasing, excitation or activation
//! outside the admissible range, invalid parameters) is an [`Error::InvalidArgument`]
//! naming the argument and the sample; nothing panics and nothing is clamped silently.

use crate::model::ForceElement;
use crate::{Error, Result};

/// The most RK4 steps one call to [`ActivationDynamics::integrate`] may take.
pub const MAX_STEPS: usize = 100_000_000;

/// RK4 sub-steps per shortest time constant.
const STEPS_PER_TIME_CONSTANT: f64 = 40.0;

/// First-order activation dynamics in one of OpenSim's forms (see the module documentation).
/// Time constants are in seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ActivationDynamics {
    /// OpenSim's `MuscleFirstOrderActivationDynamicModel` (Thelen 2003).
    Thelen2003 {
        activation_time_constant: f64,
        deactivation_time_constant: f64,
        minimum_activation: f64,
    },
    /// OpenSim's `Thelen2003Muscle_Deprecated` (OpenSim 2's `Thelen2003Muscle`): constant
    /// time constants.
    Thelen2003Deprecated {
        activation_time_constant: f64,
        deactivation_time_constant: f64,
    },
    /// OpenSim's `DeGrooteFregly2016Muscle` activation dynamics (De Groote et al. 2016).
    DeGroote2016 {
        activation_time_constant: f64,
        deactivation_time_constant: f64,
        /// `activation_dynamics_smoothing`, b in tanh(b (u − a)).
        smoothing: f64,
    },
}

/// How a sampled excitation u_k at times t_k is read between samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// u(t) linear between samples.
    Linear,
    /// u(t) = u_{k+1} on (t_k, t_{k+1}]: OpenSim's `ControlLinear` with `use_steps` (how CMC
    /// applies the controls it writes: the value at the end of each interval holds over it).
    HoldNext,
    /// u(t) = u_k on [t_k, t_{k+1}): zero-order hold of the latest sample.
    HoldPrevious,
}

/// A sample where the excitation solving ȧ = f(u, a) was outside the admissible range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClampedSample {
    /// Index into the activation samples.
    pub index: usize,
    pub time: f64,
    /// The excitation that would reproduce ȧ at this sample.
    pub required: f64,
    /// The bound used instead.
    pub applied: f64,
}

impl ClampedSample {
    /// How far the required excitation was beyond the bound (signed, `required − applied`).
    pub fn amount(&self) -> f64 {
        self.required - self.applied
    }
}

/// The result of [`ActivationDynamics::excitation_from_activation`].
#[derive(Clone, Debug, PartialEq)]
pub struct ExcitationEstimate {
    /// Excitation at each activation sample, within the admissible range.
    pub excitation: Vec<f64>,
    /// ȧ at each sample, from the spline.
    pub activation_rate: Vec<f64>,
    /// The samples where the excitation had to be clamped, in time order.
    pub clamped: Vec<ClampedSample>,
}

/// z(a) = 0.5 + 1.5 a, the activation-dependent factor of both forms.
fn z(a: f64) -> f64 {
    0.5 + 1.5 * a
}

impl ActivationDynamics {
    /// Thelen 2003 with `Thelen2003Muscle`'s defaults: τ_act 0.015 s, τ_deact 0.050 s,
    /// a_min 0.01.
    pub const THELEN2003_DEFAULT: Self = Self::Thelen2003 {
        activation_time_constant: 0.015,
        deactivation_time_constant: 0.050,
        minimum_activation: 0.01,
    };

    /// The first-order model with `Millard2012EquilibriumMuscle`'s defaults (and those of
    /// `MuscleFirstOrderActivationDynamicModel`): τ_act 0.010 s, τ_deact 0.040 s, a_min 0.01.
    pub const MILLARD2012_DEFAULT: Self = Self::Thelen2003 {
        activation_time_constant: 0.010,
        deactivation_time_constant: 0.040,
        minimum_activation: 0.01,
    };

    /// The OpenSim 2 form with `Thelen2003Muscle_Deprecated`'s defaults: τ_act 0.010 s,
    /// τ_deact 0.040 s.
    pub const THELEN2003_DEPRECATED_DEFAULT: Self = Self::Thelen2003Deprecated {
        activation_time_constant: 0.010,
        deactivation_time_constant: 0.040,
    };

    /// De Groote 2016 with `DeGrooteFregly2016Muscle`'s defaults: τ_act 0.015 s,
    /// τ_deact 0.060 s, smoothing 0.1.
    pub const DE_GROOTE2016_DEFAULT: Self = Self::DeGroote2016 {
        activation_time_constant: 0.015,
        deactivation_time_constant: 0.060,
        smoothing: 0.1,
    };

    /// The activation dynamics of a muscle of the model, from its properties
    /// (`activation_time_constant`, `deactivation_time_constant`, and `minimum_activation`
    /// or `activation_dynamics_smoothing`), the class's defaults filling absent ones.
    /// Supported: `Thelen2003Muscle`, `Millard2012EquilibriumMuscle`,
    /// `DeGrooteFregly2016Muscle`. `file` names the model file in errors. A property that is
    /// present but not a number, an invalid value, another class, or
    /// `ignore_activation_dynamics` set to true is an [`Error::Model`].
    pub fn from_muscle(force: &ForceElement, file: &str) -> Result<Self> {
        let err = |line: u32, message: String| Error::Model {
            file: file.to_string(),
            line,
            element: format!("{} \"{}\"", force.kind, force.name),
            message,
        };
        let property = |tag: &str, default: f64| -> Result<f64> {
            match force.raw.child(tag) {
                None => Ok(default),
                Some(child) => force
                    .raw
                    .number(tag)
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| {
                        err(
                            child.line,
                            format!("<{tag}> `{}` is not a number", child.text.trim()),
                        )
                    }),
            }
        };
        if let Some(flag) = force.raw.child("ignore_activation_dynamics")
            && flag.text.trim() == "true"
        {
            return Err(err(
                flag.line,
                "ignore_activation_dynamics is true: activation equals excitation".into(),
            ));
        }
        let defaults = match force.kind.as_str() {
            "Thelen2003Muscle" => Self::THELEN2003_DEFAULT,
            "Millard2012EquilibriumMuscle" => Self::MILLARD2012_DEFAULT,
            "Thelen2003Muscle_Deprecated" => Self::THELEN2003_DEPRECATED_DEFAULT,
            "DeGrooteFregly2016Muscle" => Self::DE_GROOTE2016_DEFAULT,
            other => {
                return Err(err(
                    force.line,
                    format!("no activation dynamics known for class {other}"),
                ));
            }
        };
        let dynamics = match defaults {
            Self::Thelen2003 {
                activation_time_constant,
                deactivation_time_constant,
                minimum_activation,
            } => Self::Thelen2003 {
                activation_time_constant: property(
                    "activation_time_constant",
                    activation_time_constant,
                )?,
                deactivation_time_constant: property(
                    "deactivation_time_constant",
                    deactivation_time_constant,
                )?,
                minimum_activation: property("minimum_activation", minimum_activation)?,
            },
            Self::Thelen2003Deprecated {
                activation_time_constant,
                deactivation_time_constant,
            } => Self::Thelen2003Deprecated {
                activation_time_constant: property(
                    "activation_time_constant",
                    activation_time_constant,
                )?,
                deactivation_time_constant: property(
                    "deactivation_time_constant",
                    deactivation_time_constant,
                )?,
            },
            Self::DeGroote2016 {
                activation_time_constant,
                deactivation_time_constant,
                smoothing,
            } => Self::DeGroote2016 {
                activation_time_constant: property(
                    "activation_time_constant",
                    activation_time_constant,
                )?,
                deactivation_time_constant: property(
                    "deactivation_time_constant",
                    deactivation_time_constant,
                )?,
                smoothing: property("activation_dynamics_smoothing", smoothing)?,
            },
        };
        dynamics
            .validate()
            .map_err(|e| err(force.line, e.to_string()))?;
        // Thelen2003Muscle is stricter than its activation model (a singularity at a = 0).
        if let Self::Thelen2003 {
            minimum_activation, ..
        } = dynamics
            && force.kind == "Thelen2003Muscle"
            && minimum_activation < 0.01
        {
            return Err(err(
                force.line,
                format!("minimum_activation {minimum_activation} is below Thelen2003Muscle's 0.01"),
            ));
        }
        Ok(dynamics)
    }

    /// Checks the parameters: time constants finite and positive, a_min in [0, 1),
    /// smoothing finite and positive (OpenSim's rules).
    pub fn validate(&self) -> Result<()> {
        let (tau_act, tau_deact) = self.time_constants();
        for (name, tau) in [
            ("activation_time_constant", tau_act),
            ("deactivation_time_constant", tau_deact),
        ] {
            if !(tau.is_finite() && tau > 0.0) {
                return Err(Error::invalid(
                    name,
                    format!("{tau} must be finite and positive"),
                ));
            }
        }
        match *self {
            Self::Thelen2003 {
                minimum_activation: a_min,
                ..
            } if !(0.0..1.0).contains(&a_min) => Err(Error::invalid(
                "minimum_activation",
                format!("{a_min} must lie in [0, 1)"),
            )),
            Self::DeGroote2016 { smoothing: b, .. } if !(b.is_finite() && b > 0.0) => Err(
                Error::invalid("smoothing", format!("{b} must be finite and positive")),
            ),
            _ => Ok(()),
        }
    }

    /// (τ_act, τ_deact) in seconds.
    pub fn time_constants(&self) -> (f64, f64) {
        match *self {
            Self::Thelen2003 {
                activation_time_constant,
                deactivation_time_constant,
                ..
            }
            | Self::Thelen2003Deprecated {
                activation_time_constant,
                deactivation_time_constant,
            }
            | Self::DeGroote2016 {
                activation_time_constant,
                deactivation_time_constant,
                ..
            } => (activation_time_constant, deactivation_time_constant),
        }
    }

    /// The admissible excitations and activations: [a_min, 1] for Thelen, [0, 1] for
    /// De Groote.
    pub fn range(&self) -> (f64, f64) {
        match *self {
            Self::Thelen2003 {
                minimum_activation, ..
            } => (minimum_activation, 1.0),
            Self::Thelen2003Deprecated { .. } | Self::DeGroote2016 { .. } => (0.0, 1.0),
        }
    }

    /// ȧ = f(u, a) (1/s). Parameters are not checked here (see [`Self::validate`]).
    pub fn derivative(&self, excitation: f64, activation: f64) -> f64 {
        let u = excitation;
        match *self {
            Self::Thelen2003 {
                activation_time_constant: tau_act,
                deactivation_time_constant: tau_deact,
                minimum_activation: a_min,
            } => {
                // ã = clamp(a, a_min, 1); τ = τ_act z(ã) if u > ã else τ_deact / z(ã)
                let a = activation.clamp(a_min, 1.0);
                let tau = if u > a {
                    tau_act * z(a)
                } else {
                    tau_deact / z(a)
                };
                // ȧ = (u − ã) / τ
                (u - a) / tau
            }
            Self::Thelen2003Deprecated {
                activation_time_constant: tau_act,
                deactivation_time_constant: tau_deact,
            } => {
                // ȧ = (u − a)/τ_act if u ≥ a, else (u − a)/τ_deact
                let a = activation;
                (u - a) / if u >= a { tau_act } else { tau_deact }
            }
            Self::DeGroote2016 {
                activation_time_constant: tau_act,
                deactivation_time_constant: tau_deact,
                smoothing: b,
            } => {
                let a = activation;
                // f = ½ tanh(b (u − a))
                let f = 0.5 * (b * (u - a)).tanh();
                // ȧ = [(f + ½)/(τ_act z) + (½ − f) z/τ_deact] (u − a)
                let rate = (f + 0.5) / (tau_act * z(a)) + (0.5 - f) * z(a) / tau_deact;
                rate * (u - a)
            }
        }
    }

    /// The excitation u with f(u, a) = `rate`, unclamped. f is increasing in u through
    /// f(ã, a) = 0 for Thelen, so the root is unique; for De Groote it lies in
    /// a + rate/[k_max, k_min] (k the blended rate constant, between the two branch
    /// constants), where bisection finds it.
    pub fn excitation_for_rate(&self, activation: f64, rate: f64) -> f64 {
        match *self {
            Self::Thelen2003 {
                activation_time_constant: tau_act,
                deactivation_time_constant: tau_deact,
                minimum_activation: a_min,
            } => {
                let a = activation.clamp(a_min, 1.0);
                // u = ã + ȧ τ, with the branch ȧ's sign selects
                if rate > 0.0 {
                    a + rate * tau_act * z(a)
                } else {
                    a + rate * tau_deact / z(a)
                }
            }
            Self::Thelen2003Deprecated {
                activation_time_constant: tau_act,
                deactivation_time_constant: tau_deact,
            } => {
                // u = a + ȧ τ
                activation + rate * if rate > 0.0 { tau_act } else { tau_deact }
            }
            Self::DeGroote2016 {
                activation_time_constant: tau_act,
                deactivation_time_constant: tau_deact,
                ..
            } => {
                let a = activation;
                if rate == 0.0 {
                    return a;
                }
                let k_act = 1.0 / (tau_act * z(a));
                let k_deact = z(a) / tau_deact;
                let (k_min, k_max) = (k_act.min(k_deact), k_act.max(k_deact));
                let (mut lo, mut hi) = if rate > 0.0 {
                    (a + rate / k_max, a + rate / k_min)
                } else {
                    (a + rate / k_min, a + rate / k_max)
                };
                for _ in 0..200 {
                    let mid = 0.5 * (lo + hi);
                    if mid <= lo || mid >= hi {
                        break;
                    }
                    if self.derivative(mid, a) < rate {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                0.5 * (lo + hi)
            }
        }
    }

    /// Integrates ȧ = f(u(t), a) from a(`time[0]`) = `initial_activation` over the sampled
    /// excitation (`time`, `excitation`, read as `interpolation` says) and returns a at each
    /// of `output_times` (non-decreasing, within [`time[0]`, last time]). See the module
    /// documentation for the method.
    pub fn integrate(
        &self,
        time: &[f64],
        excitation: &[f64],
        interpolation: Interpolation,
        initial_activation: f64,
        output_times: &[f64],
    ) -> Result<Vec<f64>> {
        self.validate()?;
        check_samples(time, excitation, "excitation", 2)?;
        let (lo, hi) = self.range();
        check_range(excitation, "excitation", lo, hi)?;
        check_range(&[initial_activation], "initial_activation", lo, hi)?;
        let (t_first, t_last) = (time[0], time[time.len() - 1]);
        for (i, &t) in output_times.iter().enumerate() {
            if !(t >= t_first && t <= t_last) {
                return Err(Error::invalid(
                    "output_times",
                    format!(
                        "output_times[{i}] = {t} is outside the excitation's [{t_first}, {t_last}]"
                    ),
                ));
            }
            if i > 0 && t < output_times[i - 1] {
                return Err(Error::invalid(
                    "output_times",
                    format!("output_times[{i}] = {t} is earlier than the one before"),
                ));
            }
        }
        let (tau_act, tau_deact) = self.time_constants();
        let h_max = tau_act.min(tau_deact) / STEPS_PER_TIME_CONSTANT;
        let steps_needed =
            (t_last - t_first) / h_max + time.len() as f64 + output_times.len() as f64;
        if steps_needed > MAX_STEPS as f64 {
            return Err(Error::invalid(
                "time",
                format!(
                    "{} s at steps of {h_max} s would take about {steps_needed:.3e} steps, more \
                     than {MAX_STEPS}",
                    t_last - t_first
                ),
            ));
        }

        let mut out = Vec::with_capacity(output_times.len());
        let mut next_out = output_times.iter().peekable();
        while next_out.next_if(|&&t| t == t_first).is_some() {
            out.push(initial_activation);
        }
        let mut a = initial_activation;
        for k in 0..time.len() - 1 {
            if next_out.peek().is_none() {
                break; // nothing more to report
            }
            let (t0, t1) = (time[k], time[k + 1]);
            let (u0, u1) = (excitation[k], excitation[k + 1]);
            // u(t) on this interval, as `interpolation` reads it.
            let u = |t: f64| match interpolation {
                Interpolation::Linear => u0 + (u1 - u0) * ((t - t0) / (t1 - t0)),
                Interpolation::HoldNext => u1,
                Interpolation::HoldPrevious => u0,
            };
            let mut t = t0;
            loop {
                let target = match next_out.peek() {
                    Some(&&t_out) if t_out <= t1 => t_out,
                    _ => t1,
                };
                a = self.rk4(&u, t, target, h_max, a);
                t = target;
                if next_out.next_if(|&&t_out| t_out <= t1).is_some() {
                    out.push(a);
                    while next_out.next_if(|&&t_out| t_out == t).is_some() {
                        out.push(a);
                    }
                } else {
                    break;
                }
            }
        }
        Ok(out)
    }

    /// a(t_end) from a(t_start) = a by RK4 on equal steps of at most `h_max`.
    fn rk4(&self, u: &impl Fn(f64) -> f64, t_start: f64, t_end: f64, h_max: f64, a: f64) -> f64 {
        let span = t_end - t_start;
        if span <= 0.0 {
            return a;
        }
        let n = (span / h_max).ceil().max(1.0) as usize;
        let h = span / n as f64;
        let f = |t: f64, a: f64| self.derivative(u(t), a);
        let mut a = a;
        for i in 0..n {
            let t = t_start + i as f64 * h;
            // k1 = f(t, a), k2 = f(t + h/2, a + h k1/2), k3 = f(t + h/2, a + h k2/2),
            // k4 = f(t + h, a + h k3); a ← a + h (k1 + 2 k2 + 2 k3 + k4)/6
            let k1 = f(t, a);
            let k2 = f(t + 0.5 * h, a + 0.5 * h * k1);
            let k3 = f(t + 0.5 * h, a + 0.5 * h * k2);
            let k4 = f(t + h, a + h * k3);
            a += h * (k1 + 2.0 * k2 + 2.0 * k3 + k4) / 6.0;
        }
        a
    }

    /// The excitation that produces the sampled activation (see the module documentation):
    /// ȧ from the natural cubic spline through (`time`, `activation`), u solving
    /// ȧ = f(u, a) at each sample, clamped to [`Self::range`] with each clamped sample
    /// reported. Needs at least two samples; activations must lie in the range.
    pub fn excitation_from_activation(
        &self,
        time: &[f64],
        activation: &[f64],
    ) -> Result<ExcitationEstimate> {
        self.validate()?;
        check_samples(time, activation, "activation", 2)?;
        let (lo, hi) = self.range();
        check_range(activation, "activation", lo, hi)?;
        let slopes = natural_cubic_slopes(time, activation);
        let mut estimate = ExcitationEstimate {
            excitation: Vec::with_capacity(time.len()),
            activation_rate: Vec::with_capacity(time.len()),
            clamped: Vec::new(),
        };
        for (index, (&t, &a)) in time.iter().zip(activation).enumerate() {
            let rate = slopes[index];
            let required = self.excitation_for_rate(a, rate);
            let applied = required.clamp(lo, hi);
            if applied != required {
                estimate.clamped.push(ClampedSample {
                    index,
                    time: t,
                    required,
                    applied,
                });
            }
            estimate.activation_rate.push(rate);
            estimate.excitation.push(applied);
        }
        Ok(estimate)
    }
}

/// The slopes s′(tᵢ) at the knots of the natural cubic spline s through (tᵢ, yᵢ) (s″ = 0 at
/// both ends): the second derivatives Mᵢ solve the tridiagonal system
///   hᵢ₋₁ Mᵢ₋₁ + 2(hᵢ₋₁ + hᵢ) Mᵢ + hᵢ Mᵢ₊₁ = 6 (dᵢ − dᵢ₋₁),  M₀ = Mₙ₋₁ = 0,
/// with hᵢ = tᵢ₊₁ − tᵢ and dᵢ = (yᵢ₊₁ − yᵢ)/hᵢ (solved by the Thomas algorithm, the system being
/// diagonally dominant), and then s′(tᵢ) = dᵢ − hᵢ(2Mᵢ + Mᵢ₊₁)/6, s′(tₙ₋₁) = dₙ₋₂ +
/// hₙ₋₂(Mₙ₋₂ + 2Mₙ₋₁)/6. O(n), the same spline as `NaturalSpline::interpolating(2, …)`.
/// Needs n ≥ 2 samples with increasing times (checked by the caller).
pub fn natural_cubic_slopes(t: &[f64], y: &[f64]) -> Vec<f64> {
    let n = t.len();
    let h: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let d: Vec<f64> = (0..n - 1).map(|i| (y[i + 1] - y[i]) / h[i]).collect();
    let mut m = vec![0.0; n];
    if n > 2 {
        // interior unknowns M₁ … Mₙ₋₂: forward elimination, then back substitution
        let k = n - 2;
        let mut diag = vec![0.0; k];
        let mut rhs = vec![0.0; k];
        for j in 0..k {
            let i = j + 1;
            diag[j] = 2.0 * (h[i - 1] + h[i]);
            rhs[j] = 6.0 * (d[i] - d[i - 1]);
            if j > 0 {
                let w = h[i - 1] / diag[j - 1];
                diag[j] -= w * h[i - 1];
                rhs[j] -= w * rhs[j - 1];
            }
        }
        for j in (0..k).rev() {
            let upper = if j + 1 < k { h[j + 1] * m[j + 2] } else { 0.0 };
            m[j + 1] = (rhs[j] - upper) / diag[j];
        }
    }
    let mut slopes: Vec<f64> = (0..n - 1)
        .map(|i| d[i] - h[i] * (2.0 * m[i] + m[i + 1]) / 6.0)
        .collect();
    slopes.push(d[n - 2] + h[n - 2] * (m[n - 2] + 2.0 * m[n - 1]) / 6.0);
    slopes
}

/// At least `min` samples, equal lengths, finite values, strictly increasing time.
fn check_samples(time: &[f64], values: &[f64], name: &'static str, min: usize) -> Result<()> {
    if time.len() != values.len() {
        return Err(Error::invalid(
            name,
            format!("has {} samples but time has {}", values.len(), time.len()),
        ));
    }
    if time.len() < min {
        return Err(Error::invalid(
            "time",
            format!("needs at least {min} samples, got {}", time.len()),
        ));
    }
    for (i, (&t, &v)) in time.iter().zip(values).enumerate() {
        if !t.is_finite() {
            return Err(Error::invalid(
                "time",
                format!("time[{i}] = {t} is not finite"),
            ));
        }
        if !v.is_finite() {
            return Err(Error::invalid(name, format!("sample {i} (t = {t}) is {v}")));
        }
        if i > 0 && t <= time[i - 1] {
            return Err(Error::invalid(
                "time",
                format!(
                    "time[{i}] = {t} does not exceed time[{}] = {}; time must increase strictly",
                    i - 1,
                    time[i - 1]
                ),
            ));
        }
    }
    Ok(())
}

/// Every value within [lo, hi].
fn check_range(values: &[f64], name: &'static str, lo: f64, hi: f64) -> Result<()> {
    match values.iter().position(|v| !(lo..=hi).contains(v)) {
        None => Ok(()),
        Some(i) => Err(Error::invalid(
            name,
            format!(
                "sample {i} is {}, outside the admissible [{lo}, {hi}] of these dynamics",
                values[i]
            ),
        )),
    }
}

#[cfg(test)]
mod tests;
