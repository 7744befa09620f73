//! Reading a muscle's OpenSim properties from its `ForceElement`, with OpenSim's defaults
//! for absent elements and OpenSim's bounds checks.

use super::degroote::DeGrooteFregly2016Curves;
use super::millard::{
    ActiveForceLengthParams, FiberForceLengthParams, ForceVelocityParams, Millard2012Curves,
    TendonForceLengthParams,
};
use super::pennation::FixedWidthPennation;
use super::thelen::Thelen2003Curves;
use super::{HillCurves, HillMuscle, HillParameters, MuscleKind};
use crate::model::{ForceElement, RawElement};
use std::f64::consts::FRAC_PI_2;

/// Fiber damping below which OpenSim's Millard muscle switches to the undamped model.
const MIN_NONZERO_DAMPING: f64 = 0.001;

/// Typed access to one element's children.
#[derive(Clone, Copy)]
struct Props<'a> {
    el: &'a RawElement,
}

impl<'a> Props<'a> {
    /// A number child, or `default` when absent (or empty).
    fn number(&self, tag: &str, default: f64) -> Result<f64, String> {
        Ok(self.optional(tag)?.unwrap_or(default))
    }

    /// A number child if present.
    fn optional(&self, tag: &str) -> Result<Option<f64>, String> {
        match self.el.child(tag) {
            None => Ok(None),
            Some(c) if c.text.trim().is_empty() => Ok(None),
            Some(c) => match c.text.trim().parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(Some(v)),
                _ => Err(format!(
                    "<{tag}> (line {}) is not a finite number: `{}`",
                    c.line,
                    c.text.trim()
                )),
            },
        }
    }

    fn boolean(&self, tag: &str, default: bool) -> Result<bool, String> {
        match self.el.child(tag) {
            None => Ok(default),
            Some(c) => match c.text.trim() {
                "" => Ok(default),
                "true" | "1" => Ok(true),
                "false" | "0" => Ok(false),
                other => Err(format!(
                    "<{tag}> (line {}) must be true or false, found `{other}`",
                    c.line
                )),
            },
        }
    }

    fn text(&self, tag: &str) -> Option<&'a str> {
        self.el.child(tag).map(|c| c.text.trim())
    }

    /// An object-valued property; OpenSim 3 files wrap it in an element of the same tag.
    fn object(&self, tag: &str) -> Option<Props<'a>> {
        let c = self.el.child(tag)?;
        Some(Props {
            el: c.child(tag).unwrap_or(c),
        })
    }
}

fn positive(name: &str, v: f64) -> Result<f64, String> {
    if v > 0.0 {
        Ok(v)
    } else {
        Err(format!("<{name}> must be positive, found {v}"))
    }
}

impl HillMuscle {
    /// Builds the force model of an OpenSim muscle (`Thelen2003Muscle`,
    /// `Millard2012EquilibriumMuscle` or `DeGrooteFregly2016Muscle`) from the model reader's
    /// force element, reading OpenSim's property names and using OpenSim's defaults for absent
    /// ones. Invalid values are errors naming the muscle and the property.
    pub fn from_force_element(element: &ForceElement) -> Result<HillMuscle, String> {
        let kind = MuscleKind::from_opensim_class(&element.kind).ok_or_else(|| {
            format!(
                "force element `{}` (line {}) is a `{}`, not a Hill-type muscle musculo models \
                 (Thelen2003Muscle, Millard2012EquilibriumMuscle, DeGrooteFregly2016Muscle)",
                element.name, element.line, element.kind
            )
        })?;
        read(kind, &element.name, &element.raw).map_err(|e| {
            format!(
                "muscle `{}` ({}, line {}): {e}",
                element.name,
                kind.opensim_class(),
                element.line
            )
        })
    }
}

/// Reads a muscle of class `kind`: the Muscle base class's properties, its pennation model,
/// then the class's curves and the class-specific parameters (minimum activation, fiber
/// damping, minimum fiber length, activation smoothing).
fn read(kind: MuscleKind, name: &str, raw: &RawElement) -> Result<HillMuscle, String> {
    let p = Props { el: raw };
    let mut params = read_base_parameters(kind, &p)?;
    let pennation = FixedWidthPennation::new(
        params.optimal_fiber_length,
        params.pennation_angle_at_optimal,
        params.maximum_pennation_angle,
    );
    let pennation_minimum = pennation.minimum_fiber_length(params.optimal_fiber_length);
    let curves = match kind {
        MuscleKind::Thelen2003 => read_thelen(&p, &mut params, pennation_minimum)?,
        MuscleKind::Millard2012Equilibrium => read_millard(&p, &mut params, pennation_minimum)?,
        MuscleKind::DeGrooteFregly2016 => read_degroote(&p, &mut params)?,
    };
    Ok(HillMuscle {
        name: name.to_string(),
        kind,
        params,
        curves,
        pennation,
    })
}

/// The Muscle base class's properties with the class's defaults (time constants, default
/// activation) and the maximum pennation angle; the class-specific fields are left at zero
/// (minimum activation, fiber damping, minimum fiber length) or None.
fn read_base_parameters(kind: MuscleKind, p: &Props) -> Result<HillParameters, String> {
    let max_isometric_force = p.number("max_isometric_force", 1000.0)?;
    if !(max_isometric_force >= 0.0) {
        return Err(format!(
            "<max_isometric_force> must be non-negative, found {max_isometric_force}"
        ));
    }
    let optimal_fiber_length = positive(
        "optimal_fiber_length",
        p.number("optimal_fiber_length", 0.1)?,
    )?;
    let tendon_slack_length =
        positive("tendon_slack_length", p.number("tendon_slack_length", 0.2)?)?;
    let pennation_angle_at_optimal = p.number("pennation_angle_at_optimal", 0.0)?;
    if !(0.0..FRAC_PI_2 - super::millard::SIGNIFICANT_REAL).contains(&pennation_angle_at_optimal) {
        return Err(format!(
            "<pennation_angle_at_optimal> must be in [0, π/2), found {pennation_angle_at_optimal}"
        ));
    }
    let max_contraction_velocity = positive(
        "max_contraction_velocity",
        p.number("max_contraction_velocity", 10.0)?,
    )?;
    let ignore_tendon_compliance = p.boolean("ignore_tendon_compliance", false)?;
    let ignore_activation_dynamics = p.boolean("ignore_activation_dynamics", false)?;

    // Per-class defaults: (τ_act, τ_deact, default activation).
    let (tau_a, tau_d, default_activation) = match kind {
        MuscleKind::Thelen2003 => (0.015, 0.050, 0.05),
        MuscleKind::Millard2012Equilibrium => (0.010, 0.040, 0.05),
        MuscleKind::DeGrooteFregly2016 => (0.015, 0.060, 0.5),
    };
    let activation_time_constant = p.number("activation_time_constant", tau_a)?;
    let deactivation_time_constant = p.number("deactivation_time_constant", tau_d)?;
    for (tag, v) in [
        ("activation_time_constant", activation_time_constant),
        ("deactivation_time_constant", deactivation_time_constant),
    ] {
        positive(tag, v)?;
    }
    let default_activation = p.number("default_activation", default_activation)?;

    let maximum_pennation_angle = match kind {
        MuscleKind::DeGrooteFregly2016 => FRAC_PI_2,
        _ => {
            let a = p.number("maximum_pennation_angle", 0.1f64.acos())?;
            if !(0.0..=FRAC_PI_2).contains(&a) {
                return Err(format!(
                    "<maximum_pennation_angle> must be in [0, π/2], found {a}"
                ));
            }
            a
        }
    };
    Ok(HillParameters {
        max_isometric_force,
        optimal_fiber_length,
        tendon_slack_length,
        pennation_angle_at_optimal,
        max_contraction_velocity,
        activation_time_constant,
        deactivation_time_constant,
        minimum_activation: 0.0,
        fiber_damping: 0.0,
        ignore_tendon_compliance,
        ignore_activation_dynamics,
        maximum_pennation_angle,
        minimum_fiber_length: 0.0,
        default_activation,
        activation_dynamics_smoothing: None,
    })
}

/// Thelen2003Muscle: its curve parameters, minimum activation in [0.01, 1), and the
/// pennation model's minimum fiber length.
fn read_thelen(
    p: &Props,
    params: &mut HillParameters,
    pennation_minimum: f64,
) -> Result<HillCurves, String> {
    let d = Thelen2003Curves::default();
    let c = Thelen2003Curves {
        fmax_tendon_strain: p.number("FmaxTendonStrain", d.fmax_tendon_strain)?,
        fmax_muscle_strain: p.number("FmaxMuscleStrain", d.fmax_muscle_strain)?,
        kshape_active: p.number("KshapeActive", d.kshape_active)?,
        kshape_passive: p.number("KshapePassive", d.kshape_passive)?,
        af: p.number("Af", d.af)?,
        flen: p.number("Flen", d.flen)?,
        fv_linear_extrap_threshold: p
            .number("fv_linear_extrap_threshold", d.fv_linear_extrap_threshold)?,
    };
    c.validate()?;
    let min_act = p.number("minimum_activation", 0.01)?;
    if !(0.01..1.0).contains(&min_act) {
        return Err(format!(
            "<minimum_activation> must be in [0.01, 1) for Thelen2003Muscle, found {min_act}"
        ));
    }
    params.minimum_activation = min_act;
    params.minimum_fiber_length = pennation_minimum;
    Ok(HillCurves::Thelen2003(c))
}

/// Millard2012EquilibriumMuscle: fiber damping (below MIN_NONZERO_DAMPING the undamped
/// model), minimum activation (at least 0.01 for the classic elastic, undamped model), its
/// curves, and the minimum fiber length max(ε, l_min,active, l_min,pennation).
fn read_millard(
    p: &Props,
    params: &mut HillParameters,
    pennation_minimum: f64,
) -> Result<HillCurves, String> {
    let damping = p.number("fiber_damping", 0.1)?;
    if damping < 0.0 {
        return Err(format!(
            "<fiber_damping> must be non-negative, found {damping}"
        ));
    }
    let damped = damping >= MIN_NONZERO_DAMPING;
    params.fiber_damping = if damped { damping } else { 0.0 };
    let classic = !params.ignore_tendon_compliance && !damped;
    let mut min_act = p.number("minimum_activation", 0.01)?;
    if classic {
        if !(min_act >= 0.01) {
            return Err(format!(
                "<minimum_activation> must be at least 0.01 for an elastic tendon without \
                 fiber damping, found {min_act}"
            ));
        }
    } else if min_act < 0.0 {
        return Err(format!(
            "<minimum_activation> must be non-negative, found {min_act}"
        ));
    } else {
        min_act = min_act.min(1.0);
    }
    if min_act >= 1.0 {
        return Err(format!(
            "<minimum_activation> must be below 1, found {min_act}"
        ));
    }
    params.minimum_activation = min_act;
    let curves = read_millard_curves(p, classic)?;
    let active_min = curves
        .active_force_length_params
        .min_norm_active_fiber_length
        * params.optimal_fiber_length;
    params.minimum_fiber_length =
        super::millard::SIGNIFICANT_REAL.max(active_min.max(pennation_minimum));
    Ok(HillCurves::Millard2012(curves))
}

/// DeGrooteFregly2016Muscle: its curve parameters, fiber damping, activation smoothing, a
/// positive default activation and the tendon compliance mode (read, not used).
fn read_degroote(p: &Props, params: &mut HillParameters) -> Result<HillCurves, String> {
    let d = DeGrooteFregly2016Curves::default();
    let c = DeGrooteFregly2016Curves {
        active_force_width_scale: p
            .number("active_force_width_scale", d.active_force_width_scale)?,
        passive_fiber_strain_at_one_norm_force: p.number(
            "passive_fiber_strain_at_one_norm_force",
            d.passive_fiber_strain_at_one_norm_force,
        )?,
        tendon_strain_at_one_norm_force: p.number(
            "tendon_strain_at_one_norm_force",
            d.tendon_strain_at_one_norm_force,
        )?,
        ignore_passive_fiber_force: p.boolean("ignore_passive_fiber_force", false)?,
    };
    c.validate()?;
    let damping = p.number("fiber_damping", 0.0)?;
    if damping < 0.0 {
        return Err(format!(
            "<fiber_damping> must be non-negative, found {damping}"
        ));
    }
    params.fiber_damping = damping;
    let smoothing = positive(
        "activation_dynamics_smoothing",
        p.number("activation_dynamics_smoothing", 0.1)?,
    )?;
    params.activation_dynamics_smoothing = Some(smoothing);
    let default_activation = params.default_activation;
    if !(default_activation > 0.0) {
        return Err(format!(
            "<default_activation> must be positive, found {default_activation}"
        ));
    }
    if let Some(mode) = p.text("tendon_compliance_dynamics_mode")
        && !mode.is_empty()
        && mode != "explicit"
        && mode != "implicit"
    {
        return Err(format!(
            "<tendon_compliance_dynamics_mode> must be `explicit` or `implicit`, found `{mode}`"
        ));
    }
    Ok(HillCurves::DeGrooteFregly2016(c))
}

fn read_millard_curves(p: &Props, classic_hill: bool) -> Result<Millard2012Curves, String> {
    let empty = RawElement::default();
    let none = Props { el: &empty };

    let fl = p.object("ActiveForceLengthCurve").unwrap_or(none);
    let d = ActiveForceLengthParams::default();
    let active = ActiveForceLengthParams {
        min_norm_active_fiber_length: fl.number(
            "min_norm_active_fiber_length",
            d.min_norm_active_fiber_length,
        )?,
        transition_norm_fiber_length: fl.number(
            "transition_norm_fiber_length",
            d.transition_norm_fiber_length,
        )?,
        max_norm_active_fiber_length: fl.number(
            "max_norm_active_fiber_length",
            d.max_norm_active_fiber_length,
        )?,
        shallow_ascending_slope: fl.number("shallow_ascending_slope", d.shallow_ascending_slope)?,
        minimum_value: fl.number("minimum_value", d.minimum_value)?,
    };

    let v = p.object("ForceVelocityCurve").unwrap_or(none);
    let d = ForceVelocityParams::default();
    let fv = ForceVelocityParams {
        concentric_slope_at_vmax: v
            .number("concentric_slope_at_vmax", d.concentric_slope_at_vmax)?,
        concentric_slope_near_vmax: v
            .number("concentric_slope_near_vmax", d.concentric_slope_near_vmax)?,
        isometric_slope: v.number("isometric_slope", d.isometric_slope)?,
        eccentric_slope_at_vmax: v.number("eccentric_slope_at_vmax", d.eccentric_slope_at_vmax)?,
        eccentric_slope_near_vmax: v
            .number("eccentric_slope_near_vmax", d.eccentric_slope_near_vmax)?,
        max_eccentric_velocity_force_multiplier: v.number(
            "max_eccentric_velocity_force_multiplier",
            d.max_eccentric_velocity_force_multiplier,
        )?,
        concentric_curviness: v.number("concentric_curviness", d.concentric_curviness)?,
        eccentric_curviness: v.number("eccentric_curviness", d.eccentric_curviness)?,
    };

    let f = p.object("FiberForceLengthCurve").unwrap_or(none);
    let e_zero = f.number("strain_at_zero_force", 0.0)?;
    let e_iso = f.number("strain_at_one_norm_force", 0.7)?;
    let optional = [
        f.optional("stiffness_at_low_force")?,
        f.optional("stiffness_at_one_norm_force")?,
        f.optional("curviness")?,
    ];
    let passive = match optional {
        [Some(k_low), Some(k_iso), Some(curviness)] => FiberForceLengthParams {
            strain_at_zero_force: e_zero,
            strain_at_one_norm_force: e_iso,
            stiffness_at_low_force: k_low,
            stiffness_at_one_norm_force: k_iso,
            curviness,
        },
        [None, None, None] => FiberForceLengthParams::with_default_shape(e_zero, e_iso),
        _ => {
            return Err("FiberForceLengthCurve: stiffness_at_low_force, \
                        stiffness_at_one_norm_force and curviness must be all set or all absent"
                .to_string());
        }
    };

    let t = p.object("TendonForceLengthCurve").unwrap_or(none);
    let e0 = t.number("strain_at_one_norm_force", 0.049)?;
    let optional = [
        t.optional("stiffness_at_one_norm_force")?,
        t.optional("norm_force_at_toe_end")?,
        t.optional("curviness")?,
    ];
    let tendon = match optional {
        [Some(k), Some(f_toe), Some(curviness)] => TendonForceLengthParams {
            strain_at_one_norm_force: e0,
            stiffness_at_one_norm_force: k,
            norm_force_at_toe_end: f_toe,
            curviness,
        },
        [None, None, None] => {
            if !(e0 > 0.0) {
                return Err(format!(
                    "TendonForceLengthCurve: strain_at_one_norm_force must be positive, found {e0}"
                ));
            }
            TendonForceLengthParams::with_default_shape(e0)
        }
        _ => {
            return Err("TendonForceLengthCurve: stiffness_at_one_norm_force, \
                        norm_force_at_toe_end and curviness must be all set or all absent"
                .to_string());
        }
    };

    Millard2012Curves::build(active, fv, passive, tendon, classic_hill)
}
