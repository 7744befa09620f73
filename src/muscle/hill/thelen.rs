//! Thelen (2003) curves as OpenSim's `Thelen2003Muscle` defines them.
//!
//! Thelen DG (2003), "Adjustment of muscle mechanics model parameters to simulate dynamic
//! contractions in older adults", J. Biomech. Eng. 125(1):70–77. OpenSim's version differs
//! from the paper in two documented ways, both kept here: the tendon curve's toe constants are
//! the exact values that make it C1 (the paper rounds ε_toe = 0.609 ε₀, k_lin = 1.712/ε₀),
//! and the force–velocity relation (Thelen's Eq. 6–7, which gives velocity from force) is
//! extrapolated linearly outside [0, fv_linear_extrap_threshold·Flen].

use super::bezier::CurvePoint;

/// Parameters of the Thelen 2003 curves (OpenSim property names; defaults are OpenSim's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thelen2003Curves {
    /// Tendon strain at one normalised force, ε₀ᵀ (`FmaxTendonStrain`, default 0.04).
    pub fmax_tendon_strain: f64,
    /// Passive fiber strain at one normalised force, ε₀ᴹ (`FmaxMuscleStrain`, default 0.6).
    pub fmax_muscle_strain: f64,
    /// Width γ of the active Gaussian (`KshapeActive`, default 0.45).
    pub kshape_active: f64,
    /// Exponential shape k_PE of the passive curve (`KshapePassive`, default 5).
    pub kshape_passive: f64,
    /// Force–velocity shape factor A_f (`Af`, default 0.25).
    pub af: f64,
    /// Maximum eccentric force multiplier F̄ᴹ_len (`Flen`, default 1.4).
    pub flen: f64,
    /// Fraction of Flen beyond which the force–velocity relation is linear
    /// (`fv_linear_extrap_threshold`, default 0.95).
    pub fv_linear_extrap_threshold: f64,
}

impl Default for Thelen2003Curves {
    fn default() -> Self {
        Thelen2003Curves {
            fmax_tendon_strain: 0.04,
            fmax_muscle_strain: 0.6,
            kshape_active: 0.45,
            kshape_passive: 5.0,
            af: 0.25,
            flen: 1.4,
            fv_linear_extrap_threshold: 0.95,
        }
    }
}

/// Exponential toe shape of the tendon curve, k_toe (Thelen 2003 Eq. 5).
const K_TOE: f64 = 3.0;
/// Normalised tendon force at the end of the toe region, F_toe.
const F_TOE: f64 = 0.33;

impl Thelen2003Curves {
    /// Checks OpenSim's bounds (`Thelen2003Muscle::extendFinalizeFromProperties`).
    pub fn validate(&self) -> Result<(), String> {
        let positive = [
            ("FmaxTendonStrain", self.fmax_tendon_strain),
            ("FmaxMuscleStrain", self.fmax_muscle_strain),
            ("KshapeActive", self.kshape_active),
            ("KshapePassive", self.kshape_passive),
            ("Af", self.af),
        ];
        for (name, v) in positive {
            if !(v > 0.0 && v.is_finite()) {
                return Err(format!("<{name}> must be positive, found {v}"));
            }
        }
        if !(self.flen > 1.0 && self.flen.is_finite()) {
            return Err(format!(
                "<Flen> must be greater than 1, found {}",
                self.flen
            ));
        }
        if !(self.fv_linear_extrap_threshold > 1.0 / self.flen
            && self.fv_linear_extrap_threshold.is_finite())
        {
            return Err(format!(
                "<fv_linear_extrap_threshold> must be greater than 1/Flen = {}, found {}",
                1.0 / self.flen,
                self.fv_linear_extrap_threshold
            ));
        }
        Ok(())
    }

    /// Active force–length: f_L(l̃) = exp(−(l̃ − 1)² / γ).
    pub fn active_force_length(&self, norm_fiber_length: f64) -> CurvePoint {
        let g = self.kshape_active;
        let d = norm_fiber_length - 1.0;
        let f = (-d * d / g).exp();
        // f' = −2d/γ · f;  f'' = (4d²/γ² − 2/γ) · f.
        CurvePoint::new(f, -2.0 * d / g * f, (4.0 * d * d / (g * g) - 2.0 / g) * f)
    }

    /// Passive force–length: f_PE(l̃) = (exp(k_PE (l̃ − 1)/ε₀ᴹ) − 1) / (exp(k_PE) − 1) for
    /// l̃ > 1, else 0.
    pub fn passive_force_length(&self, norm_fiber_length: f64) -> CurvePoint {
        if norm_fiber_length <= 1.0 {
            return CurvePoint::new(0.0, 0.0, 0.0);
        }
        let k = self.kshape_passive;
        let e0 = self.fmax_muscle_strain;
        let denom = k.exp() - 1.0;
        let e = (k * (norm_fiber_length - 1.0) / e0).exp();
        let r = k / e0;
        CurvePoint::new((e - 1.0) / denom, r * e / denom, r * r * e / denom)
    }

    /// Strain at the end of the toe region, ε_toe = 99 ε₀ e³ / (166 e³ − 67), the value that
    /// makes the tendon curve C1 (OpenSim; the paper's 0.609 ε₀ is this rounded).
    pub fn toe_strain(&self) -> f64 {
        let e3 = K_TOE.exp();
        99.0 * self.fmax_tendon_strain * e3 / (166.0 * e3 - 67.0)
    }

    /// Slope of the linear tendon region, k_lin = 0.67 / (ε₀ − ε_toe).
    pub fn linear_tendon_stiffness(&self) -> f64 {
        (1.0 - F_TOE) / (self.fmax_tendon_strain - self.toe_strain())
    }

    /// Tendon force–length (Thelen 2003 Eq. 5), ε = l̃ᵀ − 1:
    /// f_T = F_toe/(e^k_toe − 1)·(exp(k_toe ε/ε_toe) − 1) for 0 < ε ≤ ε_toe,
    /// k_lin (ε − ε_toe) + F_toe beyond, 0 when slack.
    pub fn tendon_force_length(&self, norm_tendon_length: f64) -> CurvePoint {
        let strain = norm_tendon_length - 1.0;
        let e_toe = self.toe_strain();
        if strain > e_toe {
            let k_lin = self.linear_tendon_stiffness();
            CurvePoint::new(k_lin * (strain - e_toe) + F_TOE, k_lin, 0.0)
        } else if strain > 0.0 {
            let c = F_TOE / (K_TOE.exp() - 1.0);
            let r = K_TOE / e_toe;
            let e = (r * strain).exp();
            CurvePoint::new(c * (e - 1.0), c * r * e, c * r * r * e)
        } else {
            CurvePoint::new(0.0, 0.0, 0.0)
        }
    }

    /// The tendon curve of OpenSim 2.x's Thelen muscle (today's `Thelen2003Muscle_Deprecated`),
    /// which produced results written by OpenSim 2 (e.g. the Arm26 CMC tutorial outputs): the
    /// paper's rounded constants (toe strain 0.609 ε₀, stiffness 1.712/ε₀, toe force 0.333333,
    /// which make the curve slightly discontinuous in slope) plus a small stiffness so the
    /// tendon never goes fully slack: f_T2(ε) = f_toe-or-linear(ε) + 0.001 (1 + ε).
    pub fn tendon_force_length_opensim2(&self, norm_tendon_length: f64) -> f64 {
        const TOE_FORCE_OPENSIM2: f64 = 0.333333;
        let strain = norm_tendon_length - 1.0;
        let e_toe = 0.609 * self.fmax_tendon_strain;
        let f = if strain > e_toe {
            1.712 / self.fmax_tendon_strain * (strain - e_toe) + TOE_FORCE_OPENSIM2
        } else if strain > 0.0 {
            TOE_FORCE_OPENSIM2 * ((K_TOE * strain / e_toe).exp() - 1.0) / (K_TOE.exp() - 1.0)
        } else {
            0.0
        };
        f + 0.001 * (1.0 + strain)
    }

    /// Shape constant of the eccentric branch, c = (Flen − 1) / (2 + 2/A_f).
    fn eccentric_shape(&self) -> f64 {
        (self.flen - 1.0) / (2.0 + 2.0 / self.af)
    }

    /// Normalised fiber velocity ṽ = v / (v_max l_opt) at which the force–velocity multiplier
    /// is `fv`, at activation `a` (Thelen 2003 Eq. 6–7 divided through by a·f_L, as OpenSim's
    /// `calcdlceN`), with s = 0.25 + 0.75 a:
    /// - concentric (0 < f_V ≤ 1): ṽ = s (f_V − 1) / (1 + f_V/A_f);
    /// - eccentric (1 < f_V < θ Flen): ṽ = s (f_V − 1) / ((Flen − f_V)/c);
    /// - outside: the tangent line at f_V = 0 or at f_V = θ Flen.
    pub fn norm_fiber_velocity(&self, activation: f64, fv: f64) -> f64 {
        let s = 0.25 + 0.75 * activation;
        let fv_ecc = self.fv_linear_extrap_threshold * self.flen;
        if fv > 0.0 && fv < fv_ecc {
            if fv <= 1.0 {
                s * (fv - 1.0) / (1.0 + fv / self.af)
            } else {
                let c = self.eccentric_shape();
                s * c * (fv - 1.0) / (self.flen - fv)
            }
        } else if fv <= 0.0 {
            // Tangent at f_V = 0: ṽ = −s + s (1 + 1/A_f) f_V.
            -s + s * (1.0 + 1.0 / self.af) * fv
        } else {
            let (v0, slope) = self.eccentric_extrapolation(s);
            v0 + slope * (fv - fv_ecc)
        }
    }

    /// (ṽ, dṽ/df_V) at f_V = θ Flen, where the eccentric branch turns linear.
    fn eccentric_extrapolation(&self, s: f64) -> (f64, f64) {
        let fv0 = self.fv_linear_extrap_threshold * self.flen;
        let c = self.eccentric_shape();
        let v0 = s * c * (fv0 - 1.0) / (self.flen - fv0);
        // dṽ/df_V = s c (Flen − 1) / (Flen − f_V)².
        let slope = s * c * (self.flen - 1.0) / (self.flen - fv0).powi(2);
        (v0, slope)
    }

    /// Force–velocity multiplier f_V(ṽ; a): the inverse of [`Self::norm_fiber_velocity`],
    /// in closed form, floored at 0 as OpenSim's `calcfvInv` does (so f_V = 0 for
    /// ṽ ≤ −(0.25 + 0.75 a)). Slope is df_V/dṽ; curvature is not provided (0).
    /// - −s < ṽ ≤ 0: f_V = (s + ṽ) / (s − ṽ/A_f);
    /// - 0 < ṽ < ṽ_θ: f_V = (Flen ṽ + s c) / (s c + ṽ).
    pub fn force_velocity(&self, activation: f64, norm_fiber_velocity: f64) -> CurvePoint {
        let v = norm_fiber_velocity;
        let s = 0.25 + 0.75 * activation;
        if v <= -s {
            return CurvePoint::new(0.0, 0.0, 0.0);
        }
        if v <= 0.0 {
            let d = s - v / self.af;
            return CurvePoint::new((s + v) / d, s * (1.0 + 1.0 / self.af) / (d * d), 0.0);
        }
        let (v0, slope) = self.eccentric_extrapolation(s);
        if v < v0 {
            let c = self.eccentric_shape();
            let d = s * c + v;
            CurvePoint::new(
                (self.flen * v + s * c) / d,
                s * c * (self.flen - 1.0) / (d * d),
                0.0,
            )
        } else {
            let fv0 = self.fv_linear_extrap_threshold * self.flen;
            CurvePoint::new(fv0 + (v - v0) / slope, 1.0 / slope, 0.0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fd_slope(f: impl Fn(f64) -> f64, x: f64) -> f64 {
        let h = 1e-6;
        (f(x + h) - f(x - h)) / (2.0 * h)
    }

    #[test]
    fn thelen_active_force_length_is_one_at_optimal_length() {
        let c = Thelen2003Curves::default();
        assert_eq!(c.active_force_length(1.0).value, 1.0);
        assert_eq!(c.active_force_length(1.0).slope, 0.0);
        // Gaussian width: f_L(1 ± √γ) = e⁻¹.
        let w = c.kshape_active.sqrt();
        assert!((c.active_force_length(1.0 + w).value - (-1.0f64).exp()).abs() < 1e-15);
    }

    #[test]
    fn thelen_passive_force_is_one_at_fmax_muscle_strain() {
        for c in [
            Thelen2003Curves::default(),
            Thelen2003Curves {
                fmax_muscle_strain: 0.6,
                kshape_passive: 4.0,
                ..Default::default()
            },
        ] {
            let p = c.passive_force_length(1.0 + c.fmax_muscle_strain);
            assert!((p.value - 1.0).abs() < 1e-14, "{}", p.value);
            assert_eq!(c.passive_force_length(1.0).value, 0.0);
            assert_eq!(c.passive_force_length(0.7).value, 0.0);
        }
    }

    #[test]
    fn thelen_tendon_force_is_one_at_fmax_tendon_strain_and_c1_at_toe() {
        for e0 in [0.033, 0.04, 0.1] {
            let c = Thelen2003Curves {
                fmax_tendon_strain: e0,
                ..Default::default()
            };
            assert!((c.tendon_force_length(1.0 + e0).value - 1.0).abs() < 1e-14);
            assert_eq!(c.tendon_force_length(1.0).value, 0.0);
            // The paper's rounded constants: ε_toe ≈ 0.609 ε₀, k_lin ≈ 1.712 / ε₀.
            assert!((c.toe_strain() / e0 - 0.609).abs() < 5e-4);
            assert!((c.linear_tendon_stiffness() * e0 - 1.712).abs() < 2e-3);
            // Value and slope continuous at the toe: F_toe and k_lin from both sides.
            let et = c.toe_strain();
            let below = c.tendon_force_length(1.0 + et * (1.0 - 1e-12));
            let above = c.tendon_force_length(1.0 + et * (1.0 + 1e-12));
            assert!((below.value - 0.33).abs() < 1e-9 && (above.value - 0.33).abs() < 1e-9);
            assert!((below.slope - above.slope).abs() < 1e-6 * above.slope);
        }
    }

    #[test]
    fn thelen_force_velocity_passes_through_zero_and_one() {
        for c in [
            Thelen2003Curves::default(),
            Thelen2003Curves {
                af: 0.3,
                flen: 1.8,
                ..Default::default()
            },
        ] {
            // Full activation: f_V(−v_max) = 0, f_V(0) = 1, f_V → Flen eccentrically.
            assert!(c.force_velocity(1.0, -1.0).value.abs() < 1e-15);
            assert_eq!(c.force_velocity(1.0, 0.0).value, 1.0);
            assert_eq!(c.force_velocity(1.0, -2.0).value, 0.0);
            // Eccentric: above 1, approaching Flen, then continued linearly.
            let fv_ecc = c.force_velocity(1.0, 0.05).value;
            assert!(fv_ecc > 1.0 && fv_ecc < c.fv_linear_extrap_threshold * c.flen);
            // At lower activation the maximum shortening speed is (0.25 + 0.75 a) v_max.
            let a = 0.2;
            assert!(c.force_velocity(a, -(0.25 + 0.75 * a)).value.abs() < 1e-15);
            // Hill's hyperbola at a = 1: f_V(−0.5) = (1 − 0.5)/(1 + 0.5/A_f).
            let expected = 0.5 / (1.0 + 0.5 / c.af);
            assert!((c.force_velocity(1.0, -0.5).value - expected).abs() < 1e-15);
        }
    }

    #[test]
    fn thelen_force_velocity_inverts_opensim_velocity_relation() {
        let c = Thelen2003Curves {
            af: 0.3,
            flen: 1.8,
            ..Default::default()
        };
        for a in [0.01, 0.3, 1.0] {
            for i in 0..200 {
                let fv = 0.005 + i as f64 * 0.01; // 0.005 … 1.995 spans every branch
                let v = c.norm_fiber_velocity(a, fv);
                let back = c.force_velocity(a, v);
                assert!(
                    (back.value - fv).abs() < 1e-12,
                    "a {a} fv {fv} v {v} back {}",
                    back.value
                );
                let slope = fd_slope(|x| c.force_velocity(a, x).value, v);
                if (fv - 1.0).abs() > 1e-3 && (fv - 0.95 * 1.8).abs() > 1e-3 {
                    assert!((slope - back.slope).abs() < 1e-5 * (1.0 + slope.abs()));
                }
            }
        }
    }

    #[test]
    fn thelen_curve_slopes_match_finite_differences() {
        let c = Thelen2003Curves::default();
        for i in 0..100 {
            let x = 0.4 + i as f64 * 0.0123;
            let fl = c.active_force_length(x);
            assert!((fl.slope - fd_slope(|t| c.active_force_length(t).value, x)).abs() < 1e-8);
            assert!((fl.curvature - fd_slope(|t| c.active_force_length(t).slope, x)).abs() < 1e-7);
            if (x - 1.0).abs() > 1e-5 {
                let fp = c.passive_force_length(x);
                let fd = fd_slope(|t| c.passive_force_length(t).value, x);
                assert!((fp.slope - fd).abs() < 1e-7 * (1.0 + fd.abs()));
            }
            let t = 0.99 + i as f64 * 0.0007;
            if (t - 1.0).abs() > 1e-5 {
                let ft = c.tendon_force_length(t);
                let fd = fd_slope(|u| c.tendon_force_length(u).value, t);
                assert!((ft.slope - fd).abs() < 1e-6 * (1.0 + fd.abs()), "t {t}");
            }
        }
    }
}
