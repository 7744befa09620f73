//! De Groote–Fregly (2016) curves as OpenSim's `DeGrooteFregly2016Muscle` defines them.
//!
//! De Groote F, Kinney AL, Rao AV, Fregly BJ (2016), "Evaluation of direct collocation
//! optimal control problem formulations for solving the muscle redundancy problem",
//! Ann. Biomed. Eng. 44(10):2922–2936, Supplementary Material. OpenSim refits two constants
//! so that the curves pass exactly through (1, 1) (active force–length) and (−1, 0), (0, 1)
//! (force–velocity), and parameterises the tendon by its strain at one normalised force
//! instead of k_T; these are the values used here.

use super::bezier::CurvePoint;

/// One Gaussian-like term of the active force–length curve: (b1, b2, b3, b4).
type Gaussian = (f64, f64, f64, f64);

/// Active force–length terms, b_1i exp(−½ (l̃ − b_2i)² / (b_3i + b_4i l̃)²) (paper's Table S1,
/// OpenSim's refitted digits).
pub const ACTIVE_TERMS: [Gaussian; 3] = [
    (
        0.8150671134243542,
        1.055033428970575,
        0.162384573599574,
        0.063303448465465,
    ),
    (
        0.433004984392647,
        0.716775413397760,
        -0.029947116970696,
        0.200356847296188,
    ),
    (0.1, 1.0, 0.353553390593274, 0.0),
];
/// Passive exponential shape, k_PE.
pub const K_PE: f64 = 4.0;
/// Tendon curve constants: f_T = c1 exp(k_T (l̃ᵀ − c2)) − c3.
pub const C1: f64 = 0.2;
pub const C2: f64 = 1.0;
pub const C3: f64 = 0.2;
/// Force–velocity constants: f_V = d1 ln(d2 ṽ + d3 + √((d2 ṽ + d3)² + 1)) + d4.
pub const D1: f64 = -0.3211346127989808;
pub const D2: f64 = -8.149;
pub const D3: f64 = -0.374;
pub const D4: f64 = 0.8825327733249912;
/// Normalised fiber length at which the passive curve is zero (OpenSim's lower bound).
pub const MIN_NORM_FIBER_LENGTH: f64 = 0.2;

/// Parameters of the De Groote–Fregly 2016 curves (OpenSim property names and defaults).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeGrooteFregly2016Curves {
    /// Widens the active curve: it is evaluated at (l̃ − 1)/scale + 1
    /// (`active_force_width_scale`, default 1, must be ≥ 1).
    pub active_force_width_scale: f64,
    /// Fiber strain at one normalised passive force, e₀
    /// (`passive_fiber_strain_at_one_norm_force`, default 0.6).
    pub passive_fiber_strain_at_one_norm_force: f64,
    /// Tendon strain at one normalised force (`tendon_strain_at_one_norm_force`, default
    /// 0.049); sets k_T = ln((1 + c3)/c1) / (1 + strain − c2).
    pub tendon_strain_at_one_norm_force: f64,
    /// Makes the passive fiber force zero (`ignore_passive_fiber_force`, default false).
    pub ignore_passive_fiber_force: bool,
}

impl Default for DeGrooteFregly2016Curves {
    fn default() -> Self {
        DeGrooteFregly2016Curves {
            active_force_width_scale: 1.0,
            passive_fiber_strain_at_one_norm_force: 0.6,
            tendon_strain_at_one_norm_force: 0.049,
            ignore_passive_fiber_force: false,
        }
    }
}

/// g(x) = b1 exp(−½ z²), z = (x − b2)/(b3 + b4 x), with first and second derivatives:
/// z' = (b3 + b4 b2)/w², z'' = −2 b4 z'/w, g' = −g z z', g'' = −g' z z' − g (z'² + z z'').
fn gaussian_like((b1, b2, b3, b4): Gaussian, x: f64) -> CurvePoint {
    let w = b3 + b4 * x;
    let z = (x - b2) / w;
    let dz = (b3 + b4 * b2) / (w * w);
    let ddz = -2.0 * b4 * dz / w;
    let g = b1 * (-0.5 * z * z).exp();
    let dg = -g * z * dz;
    let ddg = -dg * z * dz - g * (dz * dz + z * ddz);
    CurvePoint::new(g, dg, ddg)
}

impl DeGrooteFregly2016Curves {
    /// Checks OpenSim's bounds.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.active_force_width_scale >= 1.0 && self.active_force_width_scale.is_finite()) {
            return Err(format!(
                "<active_force_width_scale> must be at least 1, found {}",
                self.active_force_width_scale
            ));
        }
        for (name, v) in [
            (
                "passive_fiber_strain_at_one_norm_force",
                self.passive_fiber_strain_at_one_norm_force,
            ),
            (
                "tendon_strain_at_one_norm_force",
                self.tendon_strain_at_one_norm_force,
            ),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                return Err(format!("<{name}> must be positive, found {v}"));
            }
        }
        Ok(())
    }

    /// Tendon stiffness k_T = ln((1 + c3)/c1) / (1 + ε₀ − c2), so that f_T(1 + ε₀) = 1.
    pub fn tendon_stiffness_parameter(&self) -> f64 {
        // ln((1 + c3)/c1) = ln 6.
        const LN_6: f64 = 1.791_759_469_228_055;
        LN_6 / (1.0 + self.tendon_strain_at_one_norm_force - C2)
    }

    /// Active force–length: sum of three Gaussian-like terms at x = (l̃ − 1)/scale + 1.
    pub fn active_force_length(&self, norm_fiber_length: f64) -> CurvePoint {
        let scale = self.active_force_width_scale;
        let x = (norm_fiber_length - 1.0) / scale + 1.0;
        let mut sum = CurvePoint::new(0.0, 0.0, 0.0);
        for term in ACTIVE_TERMS {
            let g = gaussian_like(term, x);
            sum.value += g.value;
            sum.slope += g.slope;
            sum.curvature += g.curvature;
        }
        sum.slope /= scale;
        sum.curvature /= scale * scale;
        sum
    }

    /// Passive force–length, shifted to vanish at l̃ = 0.2:
    /// f_PE = (exp(k_PE (l̃ − 1)/e₀) − o) / (exp(k_PE) − o), o = exp(k_PE (0.2 − 1)/e₀).
    /// Negative below l̃ = 0.2, as in OpenSim.
    pub fn passive_force_length(&self, norm_fiber_length: f64) -> CurvePoint {
        if self.ignore_passive_fiber_force {
            return CurvePoint::new(0.0, 0.0, 0.0);
        }
        let e0 = self.passive_fiber_strain_at_one_norm_force;
        let offset = (K_PE * (MIN_NORM_FIBER_LENGTH - 1.0) / e0).exp();
        let denom = K_PE.exp() - offset;
        let e = (K_PE * (norm_fiber_length - 1.0) / e0).exp();
        let r = K_PE / e0;
        CurvePoint::new((e - offset) / denom, r * e / denom, r * r * e / denom)
    }

    /// Tendon force–length: f_T = c1 exp(k_T (l̃ᵀ − c2)) − c3 (negative when slack, down to
    /// −c3, as in OpenSim).
    pub fn tendon_force_length(&self, norm_tendon_length: f64) -> CurvePoint {
        let k = self.tendon_stiffness_parameter();
        let e = C1 * (k * (norm_tendon_length - C2)).exp();
        CurvePoint::new(e - C3, k * e, k * k * e)
    }

    /// Normalised tendon length at normalised tendon force f: ln((f + c3)/c1)/k_T + c2.
    pub fn tendon_length_at_force(&self, norm_tendon_force: f64) -> f64 {
        ((norm_tendon_force + C3) / C1).ln() / self.tendon_stiffness_parameter() + C2
    }

    /// Force–velocity: f_V = d1 asinh(d2 ṽ + d3) + d4, slope d1 d2 / √((d2 ṽ + d3)² + 1).
    pub fn force_velocity(&self, norm_fiber_velocity: f64) -> CurvePoint {
        let t = D2 * norm_fiber_velocity + D3;
        let root = (t * t + 1.0).sqrt();
        // d/dṽ [d1 d2 / root] = −d1 d2² t / root³.
        CurvePoint::new(
            D1 * t.asinh() + D4,
            D1 * D2 / root,
            -D1 * D2 * D2 * t / (root * root * root),
        )
    }

    /// Inverse force–velocity: ṽ = (sinh((f_V − d4)/d1) − d3)/d2.
    pub fn norm_fiber_velocity(&self, fv: f64) -> f64 {
        (((fv - D4) / D1).sinh() - D3) / D2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degroote_curves_pass_through_their_defining_points() {
        let c = DeGrooteFregly2016Curves::default();
        // OpenSim's refit: f_L(1) = 1 to the digits of its constants.
        assert!((c.active_force_length(1.0).value - 1.0).abs() < 1e-9);
        // f_V(−1) = 0 and f_V(0) = 1.
        assert!(c.force_velocity(-1.0).value.abs() < 1e-14);
        assert!((c.force_velocity(0.0).value - 1.0).abs() < 1e-14);
        // Passive: zero at 0.2, one at 1 + e₀.
        assert!(c.passive_force_length(0.2).value.abs() < 1e-15);
        assert!((c.passive_force_length(1.6).value - 1.0).abs() < 1e-14);
        // Tendon: zero at slack, one at 1 + strain, and the inverse matches.
        assert!(c.tendon_force_length(1.0).value.abs() < 1e-15);
        assert!((c.tendon_force_length(1.049).value - 1.0).abs() < 1e-14);
        for f in [0.0, 0.3, 1.0, 4.0] {
            assert!((c.tendon_force_length(c.tendon_length_at_force(f)).value - f).abs() < 1e-13);
        }
        for v in [-1.0, -0.4, 0.0, 0.5, 1.0] {
            assert!((c.norm_fiber_velocity(c.force_velocity(v).value) - v).abs() < 1e-13);
        }
    }

    #[test]
    fn degroote_curves_match_the_paper_parameters() {
        // De Groote et al. (2016) Supplementary Material: k_T = 35, d = (−0.318, −8.149,
        // −0.374, 0.886), b rounded to 3 decimals, k_PE = 4, e₀ = 0.6.
        let kt35 = DeGrooteFregly2016Curves {
            tendon_strain_at_one_norm_force: 6.0f64.ln() / 35.0,
            ..Default::default()
        };
        assert!((kt35.tendon_stiffness_parameter() - 35.0).abs() < 1e-12);
        // The paper's tendon curve, 0.2 exp(35 (l̃ − 0.995)) − 0.25, reaches one normalised
        // force at strain 0.995 + ln(6.25)/35 − 1 ≈ 0.0474. OpenSim's form (c2 = 1,
        // c3 = 0.2) with that strain stays within 0.02 of it up to one normalised force.
        let paper_ft = |l: f64| 0.2 * (35.0 * (l - 0.995)).exp() - 0.25;
        let paper_strain = 0.995 + 6.25f64.ln() / 35.0 - 1.0;
        assert!((paper_strain - 0.0474).abs() < 5e-5);
        let matched = DeGrooteFregly2016Curves {
            tendon_strain_at_one_norm_force: paper_strain,
            ..Default::default()
        };
        for i in 0..=50 {
            let l = 1.0 + paper_strain * i as f64 / 50.0;
            assert!(
                (matched.tendon_force_length(l).value - paper_ft(l)).abs() < 0.02,
                "l {l}"
            );
        }
        #[allow(clippy::approx_constant)] // the paper's d1 = −0.318, not −1/π
        let paper_fv = |v: f64| {
            let t = -8.149 * v - 0.374;
            -0.318 * (t + (t * t + 1.0).sqrt()).ln() + 0.886
        };
        let c = DeGrooteFregly2016Curves::default();
        for i in 0..=40 {
            let v = -1.0 + 2.0 * i as f64 / 40.0;
            assert!((c.force_velocity(v).value - paper_fv(v)).abs() < 0.015);
        }
        let b_paper = [
            (0.815, 1.055, 0.162, 0.063),
            (0.433, 0.717, -0.030, 0.200),
            (0.100, 1.000, 0.354, 0.000),
        ];
        for i in 0..=60 {
            let l = 0.4 + 1.2 * i as f64 / 60.0;
            let paper: f64 = b_paper.iter().map(|&b| gaussian_like(b, l).value).sum();
            assert!(
                (c.active_force_length(l).value - paper).abs() < 5e-3,
                "l {l}"
            );
        }
        // Passive curve with the paper's form: (exp(k_PE (l̃ − 1)/e₀) − 1)/(exp(k_PE) − 1),
        // which OpenSim shifts to vanish at l̃ = 0.2: the two differ by less than
        // 1/(exp(k_PE) − 1) and agree at one normalised force.
        for i in 0..=40 {
            let l = 0.2 + 1.4 * i as f64 / 40.0;
            let paper = ((4.0 * (l - 1.0) / 0.6).exp() - 1.0) / (4.0f64.exp() - 1.0);
            assert!((c.passive_force_length(l).value - paper).abs() < 1.0 / (4.0f64.exp() - 1.0));
        }
    }

    #[test]
    fn degroote_curve_slopes_match_finite_differences() {
        let c = DeGrooteFregly2016Curves {
            active_force_width_scale: 1.3,
            ..Default::default()
        };
        let h = 1e-6;
        type Curve = Box<dyn Fn(f64) -> CurvePoint>;
        let curves: [(&str, Curve, f64, f64); 4] = [
            (
                "active",
                Box::new(move |x| c.active_force_length(x)),
                0.3,
                1.9,
            ),
            (
                "passive",
                Box::new(move |x| c.passive_force_length(x)),
                0.3,
                1.9,
            ),
            (
                "tendon",
                Box::new(move |x| c.tendon_force_length(x)),
                0.95,
                1.1,
            ),
            ("fv", Box::new(move |x| c.force_velocity(x)), -1.5, 1.5),
        ];
        for (name, f, a, b) in curves.iter() {
            for i in 0..=200 {
                let x = a + (b - a) * i as f64 / 200.0;
                let p = f(x);
                let slope = (f(x + h).value - f(x - h).value) / (2.0 * h);
                let curv = (f(x + h).slope - f(x - h).slope) / (2.0 * h);
                assert!(
                    (p.slope - slope).abs() < 1e-6 * (1.0 + slope.abs()),
                    "{name} {x}"
                );
                assert!(
                    (p.curvature - curv).abs() < 1e-5 * (1.0 + curv.abs()),
                    "{name} {x}"
                );
            }
        }
    }
}
