//! The muscle state at one instant, and the two closed-form evaluations: rigid tendon, and
//! elastic tendon at a known fiber length.

use super::{HillMuscle, MuscleKind};

/// How a muscle state was obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MuscleStatus {
    /// Closed form, or the equilibrium solve converged.
    Ok,
    /// The fiber is at its minimum length and cannot shorten further: OpenSim's clamped
    /// fiber state (zero fiber force, fiber velocity 0) or its "fiber at lower bound"
    /// equilibrium warning. The tendon force is what the tendon curve gives.
    FiberAtLowerBound,
    /// The force balance has no root in the admissible fiber lengths (e.g. a De
    /// Groote–Fregly muscle whose tendon force would leave OpenSim's range [0, 5] F_max).
    NoEquilibrium,
    /// The solver stopped at its iteration limit; the state holds the last iterate.
    MaxIterations,
    /// The fiber velocity is undetermined: a f_L = 0 and no fiber damping.
    Singular,
    /// A non-finite argument.
    InvalidInput,
}

/// Everything about a muscle at one instant. Lengths in m, velocities in m/s (lengthening
/// positive), forces in N; "normalised" as in the module notation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MuscleState {
    pub status: MuscleStatus,
    /// Solver iterations (0 for closed forms).
    pub iterations: u32,
    /// Activation as used (after the model's clamping).
    pub activation: f64,
    pub musculotendon_length: f64,
    pub musculotendon_speed: f64,
    pub fiber_length: f64,
    pub normalized_fiber_length: f64,
    pub fiber_velocity: f64,
    pub normalized_fiber_velocity: f64,
    pub pennation_angle: f64,
    pub cos_pennation_angle: f64,
    pub fiber_length_along_tendon: f64,
    pub fiber_velocity_along_tendon: f64,
    pub tendon_length: f64,
    /// Tendon strain + 1.
    pub normalized_tendon_length: f64,
    pub tendon_velocity: f64,
    /// f_L.
    pub active_force_length_multiplier: f64,
    /// f_PE.
    pub passive_force_multiplier: f64,
    /// f_V.
    pub force_velocity_multiplier: f64,
    /// Tendon force / F_max.
    pub normalized_tendon_force: f64,
    /// a f_L f_V F_max, along the fiber.
    pub active_fiber_force: f64,
    /// f_PE F_max, along the fiber.
    pub passive_fiber_force: f64,
    /// β ṽ F_max, along the fiber.
    pub damping_fiber_force: f64,
    /// Active + passive + damping, along the fiber.
    pub fiber_force: f64,
    pub fiber_force_along_tendon: f64,
    /// The force the musculotendon applies to the bones.
    pub tendon_force: f64,
    /// ∂(fiber force along tendon)/∂(fiber length along tendon) at constant fiber velocity
    /// (N/m).
    pub fiber_stiffness_along_tendon: f64,
    /// ∂(tendon force)/∂(tendon length) (N/m); infinite for a rigid tendon.
    pub tendon_stiffness: f64,
}

impl MuscleState {
    /// A state with every quantity NaN.
    pub fn invalid(status: MuscleStatus) -> Self {
        let n = f64::NAN;
        MuscleState {
            status,
            iterations: 0,
            activation: n,
            musculotendon_length: n,
            musculotendon_speed: n,
            fiber_length: n,
            normalized_fiber_length: n,
            fiber_velocity: n,
            normalized_fiber_velocity: n,
            pennation_angle: n,
            cos_pennation_angle: n,
            fiber_length_along_tendon: n,
            fiber_velocity_along_tendon: n,
            tendon_length: n,
            normalized_tendon_length: n,
            tendon_velocity: n,
            active_force_length_multiplier: n,
            passive_force_multiplier: n,
            force_velocity_multiplier: n,
            normalized_tendon_force: n,
            active_fiber_force: n,
            passive_fiber_force: n,
            damping_fiber_force: n,
            fiber_force: n,
            fiber_force_along_tendon: n,
            tendon_force: n,
            fiber_stiffness_along_tendon: n,
            tendon_stiffness: n,
        }
    }

    /// Fiber force along the tendon minus tendon force (N): zero at equilibrium.
    pub fn equilibrium_residual(&self) -> f64 {
        self.fiber_force_along_tendon - self.tendon_force
    }

    /// The fiber cannot shorten: no fiber force, no fiber velocity (OpenSim's clamped state).
    fn clamp_fiber(&mut self) {
        self.status = MuscleStatus::FiberAtLowerBound;
        self.fiber_velocity = 0.0;
        self.normalized_fiber_velocity = 0.0;
        self.fiber_velocity_along_tendon = 0.0;
        self.tendon_velocity = self.musculotendon_speed;
        self.force_velocity_multiplier = 1.0;
        self.active_fiber_force = 0.0;
        self.passive_fiber_force = 0.0;
        self.damping_fiber_force = 0.0;
        self.fiber_force = 0.0;
        self.fiber_force_along_tendon = 0.0;
        self.fiber_stiffness_along_tendon = 0.0;
    }
}

/// Tendon mode of one evaluation.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Tendon {
    /// Tendon force = fiber force along the tendon; tendon velocity 0.
    Rigid,
    /// Tendon force from the tendon curve.
    Elastic,
}

impl HillMuscle {
    /// The state at fiber length `lce` with normalised fiber velocity `v_norm`, evaluated
    /// without any clamping. `fv_override` replaces f_V(ṽ) when the multiplier comes from
    /// the force balance (OpenSim reports that value).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn evaluate(
        &self,
        activation: f64,
        l_mt: f64,
        v_mt: f64,
        lce: f64,
        v_norm: f64,
        fv_override: Option<f64>,
        tendon: Tendon,
    ) -> MuscleState {
        let p = &self.params;
        let f_max = p.max_isometric_force;
        let l_opt = p.optimal_fiber_length;
        let pen = self.pennation.at(lce);
        let l_at = lce * pen.cos;
        let l_t = l_mt - l_at;
        let l_n = lce / l_opt;
        let fal = self.curves.active_force_length(l_n);
        let fpe = self.curves.passive_force_length(l_n);
        let fv = match fv_override {
            Some(v) => v,
            None => self.curves.force_velocity(activation, v_norm).value,
        };
        let v_fiber = v_norm * self.max_fiber_velocity();
        // l_AT = √(l² − h²) ⇒ dl_AT/dt = v / cos α.
        let v_at = v_fiber / pen.cos;
        let active = activation * fal.value * fv;
        let damping = p.fiber_damping * v_norm;
        let fiber_norm = active + fpe.value + damping;
        // Fiber stiffness along the tendon at fixed velocity:
        // ∂F_AT/∂l_AT = (∂F/∂l cos α + F ∂cos α/∂l) / (∂l_AT/∂l), ∂l_AT/∂l = cos α + l ∂cos α/∂l.
        let dcos = self.pennation.dcos_dlength(lce, &pen);
        let dfiber = (activation * fal.slope * fv + fpe.slope) / l_opt;
        let k_fiber = f_max * (dfiber * pen.cos + fiber_norm * dcos) / (pen.cos + lce * dcos);
        let along_norm = fiber_norm * pen.cos;
        let (tendon_norm, k_tendon, v_tendon) = match tendon {
            Tendon::Rigid => (along_norm, f64::INFINITY, 0.0),
            Tendon::Elastic => {
                let ft = self.curves.tendon_force_length(l_t / p.tendon_slack_length);
                (
                    ft.value,
                    f_max * ft.slope / p.tendon_slack_length,
                    v_mt - v_at,
                )
            }
        };
        MuscleState {
            status: MuscleStatus::Ok,
            iterations: 0,
            activation,
            musculotendon_length: l_mt,
            musculotendon_speed: v_mt,
            fiber_length: lce,
            normalized_fiber_length: l_n,
            fiber_velocity: v_fiber,
            normalized_fiber_velocity: v_norm,
            pennation_angle: pen.angle,
            cos_pennation_angle: pen.cos,
            fiber_length_along_tendon: l_at,
            fiber_velocity_along_tendon: v_at,
            tendon_length: l_t,
            normalized_tendon_length: l_t / p.tendon_slack_length,
            tendon_velocity: v_tendon,
            active_force_length_multiplier: fal.value,
            passive_force_multiplier: fpe.value,
            force_velocity_multiplier: fv,
            normalized_tendon_force: tendon_norm,
            active_fiber_force: f_max * active,
            passive_fiber_force: f_max * fpe.value,
            damping_fiber_force: f_max * damping,
            fiber_force: f_max * fiber_norm,
            fiber_force_along_tendon: f_max * along_norm,
            tendon_force: f_max * tendon_norm,
            fiber_stiffness_along_tendon: k_fiber,
            tendon_stiffness: k_tendon,
        }
    }

    /// Rigid (inextensible) tendon, closed form: the fiber spans ℓ_MT − l_s,
    /// l = √(h² + (ℓ_MT − l_s)²), its velocity is ℓ̇_MT cos α, and
    /// F = (a f_L(l̃) f_V(ṽ) + f_PE(l̃) + β ṽ) F_max cos α.
    ///
    /// Per class, as OpenSim: Thelen (`calcInextensibleTendonActiveFiberForce` plus the
    /// passive force) and Millard (`ignore_tendon_compliance`) hold the fiber at its minimum
    /// length with zero force when ℓ_MT − l_s is shorter; Millard's fiber force is floored at
    /// 0 (the damping force saturates); De Groote–Fregly applies no clamping at all.
    pub fn state_rigid_tendon(&self, activation: f64, l_mt: f64, v_mt: f64) -> MuscleState {
        if !(activation.is_finite() && l_mt.is_finite() && v_mt.is_finite()) {
            return MuscleState::invalid(MuscleStatus::InvalidInput);
        }
        let p = &self.params;
        let a = self.clamp_activation(activation);
        let l_at = l_mt - p.tendon_slack_length;
        let v_max = self.max_fiber_velocity();
        match self.kind {
            MuscleKind::DeGrooteFregly2016 => {
                let lce = self.pennation.fiber_length(l_at);
                // cos α = l_AT / l, so the fiber velocity along the tendon is ℓ̇_MT.
                let cos = l_at / lce;
                let mut s =
                    self.evaluate(a, l_mt, v_mt, lce, v_mt * cos / v_max, None, Tendon::Rigid);
                // Keep OpenSim's signed cos α = l_AT / l (negative if ℓ_MT < l_s).
                if cos < 0.0 {
                    s.cos_pennation_angle = cos;
                    s.fiber_length_along_tendon = l_at;
                    s.fiber_force_along_tendon = s.fiber_force * cos;
                    s.tendon_force = s.fiber_force_along_tendon;
                    s.normalized_tendon_force = s.tendon_force / p.max_isometric_force;
                }
                s.fiber_velocity_along_tendon = v_mt;
                s
            }
            MuscleKind::Thelen2003 | MuscleKind::Millard2012Equilibrium => {
                let min = p.minimum_fiber_length;
                let min_at = min * self.pennation.at(min).cos;
                // MuscleFixedWidthPennationModel::calcFiberLength, then the class's clamp.
                let lce = if l_at >= min_at {
                    self.pennation.fiber_length(l_at).max(min)
                } else {
                    min
                };
                let cos = self.pennation.at(lce).cos;
                let tendon_slack =
                    l_mt - lce * cos < p.tendon_slack_length - super::millard::SIGNIFICANT_REAL;
                let v_norm = if tendon_slack {
                    0.0
                } else {
                    v_mt * cos / v_max
                };
                let mut s = self.evaluate(a, l_mt, v_mt, lce, v_norm, None, Tendon::Rigid);
                let clamped = match self.kind {
                    // Thelen produces active force only for a fiber longer than the minimum.
                    MuscleKind::Thelen2003 => lce <= min,
                    _ => (lce <= min && v_norm <= 0.0) || lce < min,
                };
                if clamped {
                    s.clamp_fiber();
                    s.tendon_force = 0.0;
                    s.normalized_tendon_force = 0.0;
                    return s;
                }
                if self.kind == MuscleKind::Millard2012Equilibrium && s.fiber_force < 0.0 {
                    // The damping force saturates so that the fiber only pulls.
                    s.damping_fiber_force = -s.active_fiber_force - s.passive_fiber_force;
                    s.fiber_force = 0.0;
                    s.fiber_force_along_tendon = 0.0;
                    s.tendon_force = 0.0;
                    s.normalized_tendon_force = 0.0;
                }
                s
            }
        }
    }

    /// Elastic tendon at a known fiber length (a state variable, e.g. from an OpenSim states
    /// file): the tendon spans ℓ_MT − l cos α, the tendon force is f_T(l̃ᵀ) F_max, and the
    /// fiber velocity is the one that balances the forces,
    /// a f_L f_V(ṽ) + f_PE + β ṽ = f_T / cos α, solved as each OpenSim class does:
    /// Thelen by its velocity relation, Millard by its inverse curve (undamped) or a Newton
    /// solve (damped), De Groote–Fregly by its closed-form inverse. ℓ̇_MT only sets the tendon
    /// velocity. The fiber length is clamped at the minimum fiber length (Thelen, Millard);
    /// a fiber at the minimum that would shorten is held (zero fiber force).
    pub fn state_at_fiber_length(
        &self,
        activation: f64,
        l_mt: f64,
        v_mt: f64,
        fiber_length: f64,
    ) -> MuscleState {
        let valid = activation.is_finite() && l_mt.is_finite() && v_mt.is_finite();
        if !valid || !fiber_length.is_finite() {
            return MuscleState::invalid(MuscleStatus::InvalidInput);
        }
        let p = &self.params;
        let a = self.clamp_activation(activation);
        let min = p.minimum_fiber_length;
        let lce = if self.kind == MuscleKind::DeGrooteFregly2016 {
            fiber_length
        } else {
            fiber_length.max(min)
        };
        let pen = self.pennation.at(lce);
        let l_n = lce / p.optimal_fiber_length;
        let l_tn = (l_mt - lce * pen.cos) / p.tendon_slack_length;
        let ft = self.curves.tendon_force_length(l_tn).value;
        let fal = self.curves.active_force_length(l_n).value;
        let fpe = self.curves.passive_force_length(l_n).value;
        // Required a f_L f_V + β ṽ.
        let needed = ft / pen.cos - fpe;
        let beta = p.fiber_damping;
        let (v_norm, fv, iterations, solved) = if beta > 0.0 {
            let (v, fv, it, ok) = self.damped_fiber_velocity(a, fal, needed);
            (v, Some(fv), it, ok)
        } else if a * fal > 0.0 {
            let fv = needed / (a * fal);
            (self.curves.norm_fiber_velocity(a, fv), Some(fv), 0, true)
        } else {
            let mut s = MuscleState::invalid(MuscleStatus::Singular);
            s.activation = a;
            s.fiber_length = lce;
            s.musculotendon_length = l_mt;
            s.musculotendon_speed = v_mt;
            s.tendon_force = ft * p.max_isometric_force;
            s.normalized_tendon_force = ft;
            return s;
        };
        let mut s = self.evaluate(a, l_mt, v_mt, lce, v_norm, fv, Tendon::Elastic);
        s.iterations = iterations;
        if !solved {
            s.status = MuscleStatus::MaxIterations;
        }
        let clamped = match self.kind {
            MuscleKind::DeGrooteFregly2016 => false,
            MuscleKind::Thelen2003 => fiber_length <= min && v_norm <= 0.0,
            MuscleKind::Millard2012Equilibrium => {
                (lce <= min && v_norm <= 0.0) || fiber_length < min
            }
        };
        if clamped {
            s.clamp_fiber();
        }
        s
    }

    /// Solves a f_L f_V(ṽ) + β ṽ = `needed` for ṽ (β > 0): the left side increases strictly
    /// with ṽ (f_V' ≥ 0), so a bracketed Newton iteration finds the one root.
    /// Returns (ṽ, f_V(ṽ), iterations, converged).
    fn damped_fiber_velocity(&self, a: f64, fal: f64, needed: f64) -> (f64, f64, u32, bool) {
        let beta = self.params.fiber_damping;
        let curves = &self.curves;
        let g = |v: f64| {
            let fv = curves.force_velocity(a, v);
            (
                a * fal * fv.value + beta * v - needed,
                a * fal * fv.slope + beta,
                fv.value,
            )
        };
        // Bracket: the residual is at least β-steep, so expanding by the residual over β
        // reaches the root.
        let (mut lo, mut hi) = (-1.0, 1.0);
        let (mut r_lo, mut r_hi) = (g(lo).0, g(hi).0);
        let mut expand = 0;
        while r_lo > 0.0 && expand < 60 {
            hi = lo;
            r_hi = r_lo;
            lo -= (r_lo / beta).max(1.0);
            r_lo = g(lo).0;
            expand += 1;
        }
        while r_hi < 0.0 && expand < 60 {
            lo = hi;
            r_lo = r_hi;
            hi += (-r_hi / beta).max(1.0);
            r_hi = g(hi).0;
            expand += 1;
        }
        if !(r_lo <= 0.0 && r_hi >= 0.0) {
            let v = 0.5 * (lo + hi);
            return (v, g(v).2, 0, false);
        }
        let tol = 1e-14 * (1.0 + needed.abs());
        let mut v = if r_hi - r_lo > 0.0 {
            lo - r_lo * (hi - lo) / (r_hi - r_lo)
        } else {
            0.5 * (lo + hi)
        };
        let mut step_before_last = hi - lo;
        let mut last_step = step_before_last;
        for it in 1..=100u32 {
            let (r, dr, fv) = g(v);
            if r.abs() <= tol || hi - lo <= 4.0 * f64::EPSILON * (1.0 + v.abs()) {
                return (v, fv, it, true);
            }
            if r < 0.0 {
                lo = v;
            } else {
                hi = v;
            }
            // Newton inside the bracket and shrinking fast enough, else bisection: across
            // the kink of f_V at ṽ = 0 (slopes 5 and 0.7 for OpenSim's default Millard
            // curve) plain Newton can jump from side to side without converging.
            let newton = v - r / dr;
            let step = if dr.is_finite()
                && dr != 0.0
                && newton > lo
                && newton < hi
                && (newton - v).abs() < 0.5 * step_before_last.abs()
            {
                newton - v
            } else {
                0.5 * (lo + hi) - v
            };
            step_before_last = last_step;
            last_step = step;
            v += step;
        }
        let (r, _, fv) = g(v);
        (v, fv, 100, r.abs() <= 1e-9)
    }
}
