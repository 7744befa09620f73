//! Millard 2012 curves: OpenSim's `ActiveForceLengthCurve`, `ForceVelocityCurve`,
//! `ForceVelocityInverseCurve`, `FiberForceLengthCurve` and `TendonForceLengthCurve`, each a
//! [`SmoothSegmentedFunction`] built from the curve's parameters exactly as
//! `SmoothSegmentedFunctionFactory` places the Bézier corners.
//!
//! Millard M, Uchida T, Seth A, Delp SL (2013), "Flexing computational muscle: modeling and
//! simulation of musculotendon dynamics", J. Biomech. Eng. 135(2):021005.

use super::bezier::{CurvePoint, SmoothSegmentedFunction, corner_control_points, scale_curviness};

/// √ε, OpenSim's `SimTK::SqrtEps`.
const SQRT_EPS: f64 = 1.490_116_119_384_765_6e-8;
/// ε^(7/8), OpenSim's `SimTK::SignificantReal`.
pub(crate) const SIGNIFICANT_REAL: f64 = 1.776_356_839_400_250_5e-14;

/// `ActiveForceLengthCurve` parameters (OpenSim defaults).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ActiveForceLengthParams {
    /// Normalised fiber length where active force vanishes on the ascending limb
    /// (`min_norm_active_fiber_length`, default 0.47 − 0.0259).
    pub min_norm_active_fiber_length: f64,
    /// Start of the shallow ascending plateau (`transition_norm_fiber_length`, default 0.73).
    pub transition_norm_fiber_length: f64,
    /// Normalised fiber length where active force vanishes on the descending limb
    /// (`max_norm_active_fiber_length`, default 1.8123).
    pub max_norm_active_fiber_length: f64,
    /// Slope of the shallow ascending plateau (`shallow_ascending_slope`, default 0.8616).
    pub shallow_ascending_slope: f64,
    /// Value of the curve outside its active range (`minimum_value`, default 0.1).
    pub minimum_value: f64,
}

impl Default for ActiveForceLengthParams {
    fn default() -> Self {
        ActiveForceLengthParams {
            min_norm_active_fiber_length: 0.47 - 0.0259,
            transition_norm_fiber_length: 0.73,
            max_norm_active_fiber_length: 1.8123,
            shallow_ascending_slope: 0.8616,
            minimum_value: 0.1,
        }
    }
}

/// `ForceVelocityCurve` parameters (OpenSim defaults); the `ForceVelocityInverseCurve` is
/// built from the same numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceVelocityParams {
    pub concentric_slope_at_vmax: f64,
    pub concentric_slope_near_vmax: f64,
    pub isometric_slope: f64,
    pub eccentric_slope_at_vmax: f64,
    pub eccentric_slope_near_vmax: f64,
    pub max_eccentric_velocity_force_multiplier: f64,
    pub concentric_curviness: f64,
    pub eccentric_curviness: f64,
}

impl Default for ForceVelocityParams {
    fn default() -> Self {
        ForceVelocityParams {
            concentric_slope_at_vmax: 0.0,
            concentric_slope_near_vmax: 0.25,
            isometric_slope: 5.0,
            eccentric_slope_at_vmax: 0.0,
            eccentric_slope_near_vmax: 0.15,
            max_eccentric_velocity_force_multiplier: 1.4,
            concentric_curviness: 0.6,
            eccentric_curviness: 0.9,
        }
    }
}

/// `FiberForceLengthCurve` parameters as used (the optional ones resolved).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FiberForceLengthParams {
    /// Fiber strain where passive force starts (`strain_at_zero_force`, default 0).
    pub strain_at_zero_force: f64,
    /// Fiber strain at one normalised passive force (`strain_at_one_norm_force`, default 0.7).
    pub strain_at_one_norm_force: f64,
    /// Stiffness near zero force (`stiffness_at_low_force`; default 0.2 when the three
    /// optional properties are absent).
    pub stiffness_at_low_force: f64,
    /// Stiffness at one normalised force (`stiffness_at_one_norm_force`; default
    /// 2 / (strain_at_one_norm_force − strain_at_zero_force)).
    pub stiffness_at_one_norm_force: f64,
    /// `curviness` (default 0.75).
    pub curviness: f64,
}

impl FiberForceLengthParams {
    /// OpenSim's fitted defaults for the optional properties.
    pub fn with_default_shape(strain_at_zero_force: f64, strain_at_one_norm_force: f64) -> Self {
        FiberForceLengthParams {
            strain_at_zero_force,
            strain_at_one_norm_force,
            stiffness_at_low_force: 0.2,
            stiffness_at_one_norm_force: 2.0 / (strain_at_one_norm_force - strain_at_zero_force),
            curviness: 0.75,
        }
    }
}

impl Default for FiberForceLengthParams {
    fn default() -> Self {
        Self::with_default_shape(0.0, 0.7)
    }
}

/// `TendonForceLengthCurve` parameters as used (the optional ones resolved).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TendonForceLengthParams {
    /// Tendon strain at one normalised force (`strain_at_one_norm_force`, default 0.049).
    pub strain_at_one_norm_force: f64,
    /// Stiffness of the linear region (`stiffness_at_one_norm_force`; default 1.375 / ε₀).
    pub stiffness_at_one_norm_force: f64,
    /// Normalised force where the toe region ends (`norm_force_at_toe_end`; default 2/3).
    pub norm_force_at_toe_end: f64,
    /// `curviness` (default 0.5).
    pub curviness: f64,
}

impl TendonForceLengthParams {
    /// OpenSim's defaults for the optional properties.
    pub fn with_default_shape(strain_at_one_norm_force: f64) -> Self {
        TendonForceLengthParams {
            strain_at_one_norm_force,
            stiffness_at_one_norm_force: 1.375 / strain_at_one_norm_force,
            norm_force_at_toe_end: 2.0 / 3.0,
            curviness: 0.5,
        }
    }
}

impl Default for TendonForceLengthParams {
    fn default() -> Self {
        Self::with_default_shape(0.049)
    }
}

fn in_unit(name: &str, v: f64) -> Result<(), String> {
    if (0.0..=1.0).contains(&v) {
        Ok(())
    } else {
        Err(format!("{name} must be in [0, 1], found {v}"))
    }
}

/// Active force–length curve from 5 corners (`createFiberActiveForceLengthCurve`):
/// zero-slope ends at (x0, y_low) and (x3, y_low), the peak (x2 = 1, 1) with zero slope, a
/// shallow plateau of slope `dydx` ending half a shoulder (0.05 x2) before the peak, a steep
/// ascending limb through its midpoint, and a descending limb through (midpoint, 0.5). The
/// curve parameter `curviness` is 1 in OpenSim's `ActiveForceLengthCurve`.
pub fn active_force_length_curve(
    p: &ActiveForceLengthParams,
) -> Result<SmoothSegmentedFunction, String> {
    let x0 = p.min_norm_active_fiber_length;
    let x1 = p.transition_norm_fiber_length;
    let x2 = 1.0;
    let x3 = p.max_norm_active_fiber_length;
    let ylow = p.minimum_value;
    let dydx = p.shallow_ascending_slope;
    if !(x0 >= 0.0 && x1 > x0 + SQRT_EPS && x2 > x1 + SQRT_EPS && x3 > x2 + SQRT_EPS) {
        return Err(format!(
            "ActiveForceLengthCurve: need 0 ≤ min_norm_active_fiber_length < \
             transition_norm_fiber_length < 1 < max_norm_active_fiber_length, found {x0}, {x1}, \
             1, {x3}"
        ));
    }
    if !(ylow >= 0.0) {
        return Err(format!(
            "ActiveForceLengthCurve: minimum_value must be ≥ 0, found {ylow}"
        ));
    }
    let dydx_max = (1.0 - ylow) / (x2 - x1);
    if !(dydx >= 0.0 && dydx < dydx_max) {
        return Err(format!(
            "ActiveForceLengthCurve: shallow_ascending_slope must be in [0, {dydx_max}), found \
             {dydx}"
        ));
    }
    let c = scale_curviness(1.0);
    // Shoulder: the plateau ends 5% of x2 before the peak.
    let x_delta = 0.05 * x2;
    let xs = x2 - x_delta;
    // Ascending limb, from zero at x0 up to the plateau line at x1.
    let y1 = 1.0 - dydx * (xs - x1);
    let dydx01 = 1.25 * y1 / (x1 - x0);
    let x01 = x0 + 0.5 * (x1 - x0);
    let y01 = 0.5 * y1;
    // Middle of the shallow plateau.
    let x1s = x1 + 0.5 * (xs - x1);
    let y1s = y1 + 0.5 * (1.0 - y1);
    // Descending limb: through its midpoint at 0.5 with the chord slope between the shoulders.
    let x23 = (x2 + x_delta) + 0.5 * (x3 - (x2 + x_delta));
    let y23 = 0.5;
    let dydx23 = -1.0 / ((x3 - x_delta) - (x2 + x_delta));
    let corners = [
        (x0, ylow, 0.0, x01, y01, dydx01),
        (x01, y01, dydx01, x1s, y1s, dydx),
        (x1s, y1s, dydx, x2, 1.0, 0.0),
        (x2, 1.0, 0.0, x23, y23, dydx23),
        (x23, y23, dydx23, x3, ylow, 0.0),
    ];
    let mut px = [[0.0; 6]; 5];
    let mut py = [[0.0; 6]; 5];
    for (i, k) in corners.iter().enumerate() {
        (px[i], py[i]) = corner_control_points(k.0, k.1, k.2, k.3, k.4, k.5, c)
            .map_err(|e| format!("ActiveForceLengthCurve: {e}"))?;
    }
    Ok(SmoothSegmentedFunction::new(
        &px, &py, x0, x3, ylow, ylow, 0.0, 0.0,
    ))
}

/// x and y control points of four corners.
type FourCorners = ([[f64; 6]; 4], [[f64; 6]; 4]);

/// Control points of the force–velocity curve (`createFiberForceVelocityCurve`): corners
/// between (−1, 0) slope `at_vmax`, (−0.9, y_nearC) slope `near_vmax`, (0, 1) slope
/// `isometric_slope`, (0.9, y_nearE), (1, f_max,E), where the "near" points lie on the mean of
/// the two end slopes: y_near = y_end + ½(k_near + k_end)(x_near − x_end).
fn force_velocity_control_points(p: &ForceVelocityParams) -> Result<FourCorners, String> {
    let fmax_e = p.max_eccentric_velocity_force_multiplier;
    let c_c = scale_curviness(p.concentric_curviness);
    let c_e = scale_curviness(p.eccentric_curviness);
    let (xc, yc, x_near_c) = (-1.0, 0.0, -0.9);
    let y_near_c = yc
        + 0.5 * p.concentric_slope_near_vmax * (x_near_c - xc)
        + 0.5 * p.concentric_slope_at_vmax * (x_near_c - xc);
    let (xe, ye, x_near_e) = (1.0, fmax_e, 0.9);
    let y_near_e = ye
        + 0.5 * p.eccentric_slope_near_vmax * (x_near_e - xe)
        + 0.5 * p.eccentric_slope_at_vmax * (x_near_e - xe);
    let corners = [
        (
            xc,
            yc,
            p.concentric_slope_at_vmax,
            x_near_c,
            y_near_c,
            p.concentric_slope_near_vmax,
            c_c,
        ),
        (
            x_near_c,
            y_near_c,
            p.concentric_slope_near_vmax,
            0.0,
            1.0,
            p.isometric_slope,
            c_c,
        ),
        (
            0.0,
            1.0,
            p.isometric_slope,
            x_near_e,
            y_near_e,
            p.eccentric_slope_near_vmax,
            c_e,
        ),
        (
            x_near_e,
            y_near_e,
            p.eccentric_slope_near_vmax,
            xe,
            ye,
            p.eccentric_slope_at_vmax,
            c_e,
        ),
    ];
    let mut px = [[0.0; 6]; 4];
    let mut py = [[0.0; 6]; 4];
    for (i, k) in corners.iter().enumerate() {
        (px[i], py[i]) = corner_control_points(k.0, k.1, k.2, k.3, k.4, k.5, k.6)?;
    }
    Ok((px, py))
}

/// Force–velocity curve f_V(ṽ), ṽ ∈ [−1, 1] in units of v_max, linear outside.
pub fn force_velocity_curve(p: &ForceVelocityParams) -> Result<SmoothSegmentedFunction, String> {
    let fmax_e = p.max_eccentric_velocity_force_multiplier;
    let err = |m: String| Err(format!("ForceVelocityCurve: {m}"));
    if !(fmax_e > 1.0) {
        return err(format!(
            "max_eccentric_velocity_force_multiplier must be > 1, found {fmax_e}"
        ));
    }
    if !(p.concentric_slope_at_vmax >= 0.0 && p.concentric_slope_at_vmax < 1.0) {
        return err(format!(
            "concentric_slope_at_vmax must be in [0, 1), found {}",
            p.concentric_slope_at_vmax
        ));
    }
    if !(p.concentric_slope_near_vmax > p.concentric_slope_at_vmax
        && p.concentric_slope_near_vmax <= 1.0)
    {
        return err(format!(
            "concentric_slope_near_vmax must be in (concentric_slope_at_vmax, 1], found {}",
            p.concentric_slope_near_vmax
        ));
    }
    if !(p.isometric_slope > 1.0) {
        return err(format!(
            "isometric_slope must be > 1, found {}",
            p.isometric_slope
        ));
    }
    if !(p.eccentric_slope_at_vmax >= 0.0 && p.eccentric_slope_at_vmax < fmax_e - 1.0) {
        return err(format!(
            "eccentric_slope_at_vmax must be in [0, {}), found {}",
            fmax_e - 1.0,
            p.eccentric_slope_at_vmax
        ));
    }
    if !(p.eccentric_slope_near_vmax >= p.eccentric_slope_at_vmax
        && p.eccentric_slope_near_vmax < fmax_e - 1.0)
    {
        return err(format!(
            "eccentric_slope_near_vmax must be in [eccentric_slope_at_vmax, {}), found {}",
            fmax_e - 1.0,
            p.eccentric_slope_near_vmax
        ));
    }
    in_unit(
        "ForceVelocityCurve: concentric_curviness",
        p.concentric_curviness,
    )?;
    in_unit(
        "ForceVelocityCurve: eccentric_curviness",
        p.eccentric_curviness,
    )?;
    let (px, py) =
        force_velocity_control_points(p).map_err(|e| format!("ForceVelocityCurve: {e}"))?;
    Ok(SmoothSegmentedFunction::new(
        &px,
        &py,
        -1.0,
        1.0,
        0.0,
        fmax_e,
        p.concentric_slope_at_vmax,
        p.eccentric_slope_at_vmax,
    ))
}

/// Inverse force–velocity curve ṽ(f_V) (`createFiberForceVelocityInverseCurve`): the same
/// control points with x and y exchanged, linear outside [0, f_max,E] with the reciprocal end
/// slopes, which must therefore be positive.
pub fn force_velocity_inverse_curve(
    p: &ForceVelocityParams,
) -> Result<SmoothSegmentedFunction, String> {
    let fmax_e = p.max_eccentric_velocity_force_multiplier;
    let err = |m: String| Err(format!("ForceVelocityInverseCurve: {m}"));
    if !(fmax_e > 1.0) {
        return err(format!(
            "max_eccentric_velocity_force_multiplier must be > 1, found {fmax_e}"
        ));
    }
    if !(p.concentric_slope_at_vmax > SIGNIFICANT_REAL && p.concentric_slope_at_vmax < 1.0) {
        return err(format!(
            "concentric_slope_at_vmax must be in (0, 1), found {}",
            p.concentric_slope_at_vmax
        ));
    }
    if !(p.concentric_slope_near_vmax > p.concentric_slope_at_vmax
        && p.concentric_slope_near_vmax < 1.0)
    {
        return err(format!(
            "concentric_slope_near_vmax must be in (concentric_slope_at_vmax, 1), found {}",
            p.concentric_slope_near_vmax
        ));
    }
    if !(p.isometric_slope > 1.0) {
        return err(format!(
            "isometric_slope must be > 1, found {}",
            p.isometric_slope
        ));
    }
    if !(p.eccentric_slope_at_vmax > SIGNIFICANT_REAL && p.eccentric_slope_at_vmax < fmax_e - 1.0) {
        return err(format!(
            "eccentric_slope_at_vmax must be in (0, {}), found {}",
            fmax_e - 1.0,
            p.eccentric_slope_at_vmax
        ));
    }
    if !(p.eccentric_slope_near_vmax >= p.eccentric_slope_at_vmax
        && p.eccentric_slope_near_vmax < fmax_e - 1.0)
    {
        return err(format!(
            "eccentric_slope_near_vmax must be in [eccentric_slope_at_vmax, {}), found {}",
            fmax_e - 1.0,
            p.eccentric_slope_near_vmax
        ));
    }
    in_unit(
        "ForceVelocityInverseCurve: concentric_curviness",
        p.concentric_curviness,
    )?;
    in_unit(
        "ForceVelocityInverseCurve: eccentric_curviness",
        p.eccentric_curviness,
    )?;
    let (px, py) =
        force_velocity_control_points(p).map_err(|e| format!("ForceVelocityInverseCurve: {e}"))?;
    Ok(SmoothSegmentedFunction::new(
        &py,
        &px,
        0.0,
        fmax_e,
        -1.0,
        1.0,
        1.0 / p.concentric_slope_at_vmax,
        1.0 / p.eccentric_slope_at_vmax,
    ))
}

/// Passive fiber force–length curve (`createFiberForceLengthCurve`): two corners from
/// (1 + ε_zero, 0) with zero slope, through a low-force point of slope k_low, to
/// (1 + ε_iso, 1) with slope k_iso; linear with slope k_iso beyond.
pub fn fiber_force_length_curve(
    p: &FiberForceLengthParams,
) -> Result<SmoothSegmentedFunction, String> {
    let (e_zero, e_iso) = (p.strain_at_zero_force, p.strain_at_one_norm_force);
    let (k_low, k_iso) = (p.stiffness_at_low_force, p.stiffness_at_one_norm_force);
    let err = |m: String| Err(format!("FiberForceLengthCurve: {m}"));
    if !(e_iso > e_zero) {
        return err(format!(
            "strain_at_one_norm_force ({e_iso}) must exceed strain_at_zero_force ({e_zero})"
        ));
    }
    let k_min = 1.0 / (e_iso - e_zero);
    if !(k_iso > k_min) {
        return err(format!(
            "stiffness_at_one_norm_force must be > {k_min}, found {k_iso}"
        ));
    }
    if !(k_low > 0.0 && k_low < k_min) {
        return err(format!(
            "stiffness_at_low_force must be in (0, {k_min}), found {k_low}"
        ));
    }
    in_unit("FiberForceLengthCurve: curviness", p.curviness)?;
    let c = scale_curviness(p.curviness);
    let x_zero = 1.0 + e_zero;
    let x_iso = 1.0 + e_iso;
    let delta_x = (0.1 / k_iso).min(0.1 * (x_iso - x_zero));
    let x_low = x_zero + delta_x;
    let x_foot = x_zero + 0.5 * (x_low - x_zero);
    let y_low = k_low * (x_low - x_foot);
    let (px0, py0) = corner_control_points(x_zero, 0.0, 0.0, x_low, y_low, k_low, c)
        .map_err(|e| format!("FiberForceLengthCurve: {e}"))?;
    let (px1, py1) = corner_control_points(x_low, y_low, k_low, x_iso, 1.0, k_iso, c)
        .map_err(|e| format!("FiberForceLengthCurve: {e}"))?;
    Ok(SmoothSegmentedFunction::new(
        &[px0, px1],
        &[py0, py1],
        x_zero,
        x_iso,
        0.0,
        1.0,
        0.0,
        k_iso,
    ))
}

/// Tendon force–length curve (`createTendonForceLengthCurve`): the linear region of slope
/// k_iso through (1 + ε_iso, 1) starts at the toe end (x_toe, F_toe); the toe is two corners
/// from (1, 0) through a control point on the line from the foot (1 + (x_toe − 1)/10, 0)
/// to the point of the linear region at F_toe/2.
pub fn tendon_force_length_curve(
    p: &TendonForceLengthParams,
) -> Result<SmoothSegmentedFunction, String> {
    let e_iso = p.strain_at_one_norm_force;
    let k_iso = p.stiffness_at_one_norm_force;
    let f_toe = p.norm_force_at_toe_end;
    let err = |m: String| Err(format!("TendonForceLengthCurve: {m}"));
    if !(e_iso > 0.0) {
        return err(format!(
            "strain_at_one_norm_force must be > 0, found {e_iso}"
        ));
    }
    if !(f_toe > 0.0 && f_toe < 1.0) {
        return err(format!(
            "norm_force_at_toe_end must be in (0, 1), found {f_toe}"
        ));
    }
    if !(k_iso > 1.0 / e_iso) {
        return err(format!(
            "stiffness_at_one_norm_force must be > 1/strain_at_one_norm_force = {}, found {k_iso}",
            1.0 / e_iso
        ));
    }
    in_unit("TendonForceLengthCurve: curviness", p.curviness)?;
    let c = scale_curviness(p.curviness);
    let x_iso = 1.0 + e_iso;
    let x_toe = (f_toe - 1.0) / k_iso + x_iso;
    let x_foot = 1.0 + (x_toe - 1.0) / 10.0;
    let y_toe_mid = 0.5 * f_toe;
    let x_toe_mid = (y_toe_mid - 1.0) / k_iso + x_iso;
    let dydx_toe_mid = y_toe_mid / (x_toe_mid - x_foot);
    let x_toe_ctrl = x_foot + 0.5 * (x_toe_mid - x_foot);
    let y_toe_ctrl = dydx_toe_mid * (x_toe_ctrl - x_foot);
    let (px0, py0) = corner_control_points(1.0, 0.0, 0.0, x_toe_ctrl, y_toe_ctrl, dydx_toe_mid, c)
        .map_err(|e| format!("TendonForceLengthCurve: {e}"))?;
    let (px1, py1) =
        corner_control_points(x_toe_ctrl, y_toe_ctrl, dydx_toe_mid, x_toe, f_toe, k_iso, c)
            .map_err(|e| format!("TendonForceLengthCurve: {e}"))?;
    Ok(SmoothSegmentedFunction::new(
        &[px0, px1],
        &[py0, py1],
        1.0,
        x_toe,
        0.0,
        f_toe,
        0.0,
        k_iso,
    ))
}

/// The five curves of a `Millard2012EquilibriumMuscle`, with the parameters actually used
/// (after OpenSim's mode-dependent adjustments, see [`Millard2012Curves::build`]).
#[derive(Clone, Debug)]
pub struct Millard2012Curves {
    pub active_force_length_params: ActiveForceLengthParams,
    pub force_velocity_params: ForceVelocityParams,
    pub fiber_force_length_params: FiberForceLengthParams,
    pub tendon_force_length_params: TendonForceLengthParams,
    pub active_force_length: SmoothSegmentedFunction,
    pub force_velocity: SmoothSegmentedFunction,
    /// The inverse curve, built with end slopes half the "near v_max" slopes so that it is
    /// invertible; used by the undamped elastic-tendon model to get velocity from force.
    pub force_velocity_inverse: SmoothSegmentedFunction,
    pub fiber_force_length: SmoothSegmentedFunction,
    pub tendon_force_length: SmoothSegmentedFunction,
}

impl Millard2012Curves {
    /// Builds the curves the way `Millard2012EquilibriumMuscle::extendFinalizeFromProperties`
    /// does. `classic_hill` is true for an elastic tendon without fiber damping (the
    /// "classic" model of Millard et al. Eq. 6), which needs an active-force floor of at
    /// least 0.1 and force–velocity end slopes of at least half the near-v_max slopes; in
    /// every other configuration (damped, or rigid tendon) the floor and the end slopes are
    /// set to 0 when they are positive.
    pub fn build(
        mut active: ActiveForceLengthParams,
        mut fv: ForceVelocityParams,
        passive: FiberForceLengthParams,
        tendon: TendonForceLengthParams,
        classic_hill: bool,
    ) -> Result<Self, String> {
        if fv.concentric_slope_near_vmax < SQRT_EPS {
            return Err(format!(
                "ForceVelocityCurve: concentric_slope_near_vmax must be at least 1.49e-8, found {}",
                fv.concentric_slope_near_vmax
            ));
        }
        if fv.eccentric_slope_near_vmax < SQRT_EPS {
            return Err(format!(
                "ForceVelocityCurve: eccentric_slope_near_vmax must be at least 1.49e-8, found {}",
                fv.eccentric_slope_near_vmax
            ));
        }
        if classic_hill {
            active.minimum_value = active.minimum_value.max(0.1);
            fv.concentric_slope_at_vmax = fv
                .concentric_slope_at_vmax
                .max(0.5 * fv.concentric_slope_near_vmax);
            fv.eccentric_slope_at_vmax = fv
                .eccentric_slope_at_vmax
                .max(0.5 * fv.eccentric_slope_near_vmax);
        } else {
            active.minimum_value = active.minimum_value.min(0.0);
            fv.concentric_slope_at_vmax = fv.concentric_slope_at_vmax.min(0.0);
            fv.eccentric_slope_at_vmax = fv.eccentric_slope_at_vmax.min(0.0);
        }
        let fv_inverse_params = ForceVelocityParams {
            concentric_slope_at_vmax: 0.5 * fv.concentric_slope_near_vmax,
            eccentric_slope_at_vmax: 0.5 * fv.eccentric_slope_near_vmax,
            ..fv
        };
        Ok(Millard2012Curves {
            active_force_length: active_force_length_curve(&active)?,
            force_velocity: force_velocity_curve(&fv)?,
            force_velocity_inverse: force_velocity_inverse_curve(&fv_inverse_params)?,
            fiber_force_length: fiber_force_length_curve(&passive)?,
            tendon_force_length: tendon_force_length_curve(&tendon)?,
            active_force_length_params: active,
            force_velocity_params: fv,
            fiber_force_length_params: passive,
            tendon_force_length_params: tendon,
        })
    }

    /// The default curves of a damped (or rigid-tendon) Millard muscle.
    pub fn default_damped() -> Self {
        Self::build(
            ActiveForceLengthParams::default(),
            ForceVelocityParams::default(),
            FiberForceLengthParams::default(),
            TendonForceLengthParams::default(),
            false,
        )
        .expect("OpenSim's default Millard curves are valid")
    }

    pub fn active_force_length(&self, norm_fiber_length: f64) -> CurvePoint {
        self.active_force_length.eval(norm_fiber_length)
    }

    pub fn passive_force_length(&self, norm_fiber_length: f64) -> CurvePoint {
        self.fiber_force_length.eval(norm_fiber_length)
    }

    pub fn tendon_force_length(&self, norm_tendon_length: f64) -> CurvePoint {
        self.tendon_force_length.eval(norm_tendon_length)
    }

    pub fn force_velocity(&self, norm_fiber_velocity: f64) -> CurvePoint {
        self.force_velocity.eval(norm_fiber_velocity)
    }

    /// ṽ from f_V by the inverse curve.
    pub fn norm_fiber_velocity(&self, fv: f64) -> f64 {
        self.force_velocity_inverse.value(fv)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fd(f: &SmoothSegmentedFunction, x: f64) -> f64 {
        let h = 1e-7;
        (f.value(x + h) - f.value(x - h)) / (2.0 * h)
    }

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    /// Value and slope continuous everywhere and slope equal to finite differences.
    fn assert_c1(f: &SmoothSegmentedFunction, from: f64, to: f64, name: &str) {
        let n = 2000;
        for i in 0..=n {
            let x = from + (to - from) * i as f64 / n as f64;
            let p = f.eval(x);
            let slope_fd = fd(f, x);
            assert!(
                close(p.slope, slope_fd, 2e-6 * (1.0 + slope_fd.abs())),
                "{name}: slope {} vs finite difference {} at {x}",
                p.slope,
                slope_fd
            );
            // Curvature against the difference of slopes.
            let h = 1e-6;
            let curv_fd = (f.eval(x + h).slope - f.eval(x - h).slope) / (2.0 * h);
            let scale = 1.0 + curv_fd.abs();
            // Joints between sections may have a curvature jump; skip the immediate vicinity.
            if (f.eval(x + h).curvature - f.eval(x - h).curvature).abs() < 1e-3 * scale {
                assert!(
                    close(p.curvature, curv_fd, 1e-4 * scale),
                    "{name}: curvature {} vs {} at {x}",
                    p.curvature,
                    curv_fd
                );
            }
        }
    }

    #[test]
    fn millard_active_force_length_passes_through_its_defining_points() {
        for (p, classic) in [
            (ActiveForceLengthParams::default(), true),
            (ActiveForceLengthParams::default(), false),
            (
                ActiveForceLengthParams {
                    min_norm_active_fiber_length: 0.25,
                    transition_norm_fiber_length: 0.77,
                    max_norm_active_fiber_length: 1.9,
                    shallow_ascending_slope: 0.75,
                    minimum_value: 0.0,
                },
                false,
            ),
        ] {
            let c = Millard2012Curves::build(
                p,
                ForceVelocityParams::default(),
                FiberForceLengthParams::default(),
                TendonForceLengthParams::default(),
                classic,
            )
            .unwrap();
            let used = c.active_force_length_params;
            let f = &c.active_force_length;
            let ylow = if classic { 0.1 } else { 0.0 };
            assert_eq!(used.minimum_value, ylow);
            // Peak (1, 1) with zero slope.
            assert!(close(f.value(1.0), 1.0, 1e-14) && close(f.eval(1.0).slope, 0.0, 1e-12));
            // The floor value at and beyond both ends.
            for x in [
                p.min_norm_active_fiber_length,
                p.max_norm_active_fiber_length,
            ] {
                assert!(close(f.value(x), ylow, 1e-14));
            }
            assert_eq!(f.value(0.1), ylow);
            assert_eq!(f.value(2.5), ylow);
            // The shallow plateau: slope `shallow_ascending_slope` at its midpoint, which lies
            // on the line of that slope through (0.95, 1).
            let xs = 0.95;
            let x_mid =
                p.transition_norm_fiber_length + 0.5 * (xs - p.transition_norm_fiber_length);
            let y_line = 1.0 - p.shallow_ascending_slope * (xs - x_mid);
            let y1 = 1.0 - p.shallow_ascending_slope * (xs - p.transition_norm_fiber_length);
            let y_mid = y1 + 0.5 * (1.0 - y1);
            assert!(close(f.eval(x_mid).slope, p.shallow_ascending_slope, 1e-12));
            assert!(close(f.value(x_mid), y_mid, 1e-13));
            assert!(y_line > y_mid - 1e-12); // the plateau point lies below the shoulder line
            // Descending limb passes 0.5 halfway between the shoulder (1.05) and x3.
            let x23 = 1.05 + 0.5 * (p.max_norm_active_fiber_length - 1.05);
            assert!(close(f.value(x23), 0.5, 1e-13));
            assert_c1(f, 0.0, 2.2, "active force–length");
        }
    }

    #[test]
    fn millard_force_velocity_has_its_parameter_slopes() {
        let p = ForceVelocityParams::default();
        for classic in [false, true] {
            let c = Millard2012Curves::build(
                ActiveForceLengthParams::default(),
                p,
                FiberForceLengthParams::default(),
                TendonForceLengthParams::default(),
                classic,
            )
            .unwrap();
            let f = &c.force_velocity;
            let used = c.force_velocity_params;
            let con_at = if classic { 0.125 } else { 0.0 };
            let ecc_at = if classic { 0.075 } else { 0.0 };
            assert_eq!(used.concentric_slope_at_vmax, con_at);
            assert_eq!(used.eccentric_slope_at_vmax, ecc_at);
            assert!(close(f.value(0.0), 1.0, 1e-14));
            assert!(close(f.eval(0.0).slope, p.isometric_slope, 1e-11));
            assert!(close(f.value(-1.0), 0.0, 1e-14));
            assert!(close(f.eval(-1.0).slope, con_at, 1e-11));
            assert!(close(f.value(1.0), 1.4, 1e-14));
            assert!(close(f.eval(1.0).slope, ecc_at, 1e-11));
            // Near v_max: slope `near_vmax` at ±0.9, on the mean-slope line.
            let y_near_c = 0.5 * (p.concentric_slope_near_vmax + con_at) * 0.1;
            assert!(close(f.value(-0.9), y_near_c, 1e-14));
            assert!(close(
                f.eval(-0.9).slope,
                p.concentric_slope_near_vmax,
                1e-11
            ));
            let y_near_e = 1.4 - 0.5 * (p.eccentric_slope_near_vmax + ecc_at) * 0.1;
            assert!(close(f.value(0.9), y_near_e, 1e-14));
            assert!(close(f.eval(0.9).slope, p.eccentric_slope_near_vmax, 1e-11));
            // Linear continuation.
            assert!(close(f.value(-1.5), -0.5 * con_at, 1e-14));
            assert!(close(f.value(1.5), 1.4 + 0.5 * ecc_at, 1e-14));
            assert_c1(f, -1.2, 1.2, "force–velocity");
            // In the classic model the forward curve's end slopes are those of the inverse
            // curve, which is then its exact inverse; in the damped model (end slopes 0) the
            // inverse is only OpenSim's starting guess, close to the forward curve's inverse.
            let tol = if classic { 1e-12 } else { 0.03 };
            for i in 0..=100 {
                let v = -0.9 + 1.8 * i as f64 / 100.0;
                let back = c.norm_fiber_velocity(f.value(v));
                assert!(close(back, v, tol), "v {v} back {back}");
            }
            assert!(close(c.norm_fiber_velocity(1.0), 0.0, 1e-14));
            assert_c1(
                &c.force_velocity_inverse,
                -0.2,
                1.6,
                "inverse force–velocity",
            );
        }
    }

    #[test]
    fn millard_passive_and_tendon_curves_reach_one_at_their_strains() {
        let c = Millard2012Curves::default_damped();
        let fpe = &c.fiber_force_length;
        assert_eq!(fpe.value(1.0), 0.0);
        assert_eq!(fpe.value(0.5), 0.0);
        assert!(close(fpe.value(1.7), 1.0, 1e-14));
        assert!(close(fpe.eval(1.7).slope, 2.0 / 0.7, 1e-10));
        assert!(close(fpe.value(1.8), 1.0 + 0.1 * 2.0 / 0.7, 1e-13));
        assert_c1(fpe, 0.9, 1.9, "fiber force–length");

        let ft = &c.tendon_force_length;
        let e0 = 0.049;
        let k = 1.375 / e0;
        assert_eq!(ft.value(1.0), 0.0);
        assert_eq!(ft.value(0.98), 0.0);
        assert!(close(ft.value(1.0 + e0), 1.0, 1e-13));
        assert!(close(ft.eval(1.0 + e0).slope, k, 1e-9));
        // The toe ends at 2/3 of the normalised force on the linear region.
        let x_toe = (2.0 / 3.0 - 1.0) / k + 1.0 + e0;
        assert!(close(ft.value(x_toe), 2.0 / 3.0, 1e-14));
        assert!(close(ft.eval(x_toe).slope, k, 1e-9));
        assert_c1(ft, 0.99, 1.0 + 1.5 * e0, "tendon force–length");

        // Explicit optional parameters are used as given.
        let t = TendonForceLengthParams {
            strain_at_one_norm_force: 0.04,
            stiffness_at_one_norm_force: 40.0,
            norm_force_at_toe_end: 0.5,
            curviness: 0.3,
        };
        let f = tendon_force_length_curve(&t).unwrap();
        assert!(close(f.value(1.04), 1.0, 1e-13) && close(f.eval(1.04).slope, 40.0, 1e-9));
    }

    #[test]
    fn millard_invalid_curve_parameters_are_errors() {
        let bad_fv = ForceVelocityParams {
            max_eccentric_velocity_force_multiplier: 0.9,
            ..Default::default()
        };
        assert!(
            force_velocity_curve(&bad_fv)
                .unwrap_err()
                .contains("max_eccentric")
        );
        let bad_fl = ActiveForceLengthParams {
            transition_norm_fiber_length: 0.3,
            ..Default::default()
        };
        assert!(active_force_length_curve(&bad_fl).is_err());
        let bad_tendon = TendonForceLengthParams {
            stiffness_at_one_norm_force: 10.0,
            ..Default::default()
        };
        assert!(
            tendon_force_length_curve(&bad_tendon)
                .unwrap_err()
                .contains("stiffness")
        );
        let bad_passive = FiberForceLengthParams {
            strain_at_one_norm_force: -0.1,
            ..Default::default()
        };
        assert!(fiber_force_length_curve(&bad_passive).is_err());
    }
}
