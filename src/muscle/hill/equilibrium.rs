//! Elastic-tendon equilibrium: the fiber length at which the fiber force along the tendon
//! equals the tendon force, for given activation, ℓ_MT and ℓ̇_MT.
//!
//! With the fiber velocity fixed, the residual
//!   r(l) = (a f_L(l̃) f_V(ṽ) + f_PE(l̃) + β ṽ) cos α(l) − f_T((ℓ_MT − l cos α)/l_s)
//! (normalised by F_max) is negative at the shortest admissible fiber (longest tendon) and
//! non-negative where the tendon goes slack, so a bracketed Newton iteration (Newton steps
//! kept inside the bracket, bisection otherwise) finds a root in bounded iterations.
//!
//! The fiber velocity follows one of three rules ([`VelocitySplit`]). OpenSim's Thelen and
//! Millard initialisations share ℓ̇_MT between fiber and tendon in inverse proportion to
//! their stiffnesses (springs in series); since the fiber stiffness depends on f_V and so on
//! the velocity, the split and the length are iterated to a common fixed point, and the
//! returned state satisfies the force balance for the returned velocity.

use super::state::{MuscleState, MuscleStatus, Tendon};
use super::{CurvePoint, HillMuscle, MuscleKind};

/// How ℓ̇_MT is shared between fiber and tendon in [`HillMuscle::state_equilibrium`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VelocitySplit {
    /// Fiber velocity 0, the tendon takes all of ℓ̇_MT (OpenSim Millard's default
    /// `computeInitialFiberEquilibrium`, which solves at zero velocity).
    Static,
    /// Tendon velocity 0: the fiber takes all of ℓ̇_MT, ṽ = ℓ̇_MT cos α / v_max (OpenSim De
    /// Groote–Fregly's `computeInitialFiberEquilibrium`, ∂f_T/∂t = 0).
    RigidTendonVelocity,
    /// ℓ̇_T = K_M / (K_M + K_T) ℓ̇_MT with K_M the fiber stiffness along the tendon and K_T
    /// the tendon stiffness (OpenSim Thelen's `initMuscleState`, Millard's
    /// `computeFiberEquilibrium(s, true)`); a slack tendon takes all of ℓ̇_MT, as in OpenSim.
    /// OpenSim lags this split by one Newton step; here the velocity and the length are
    /// solved together. Deviations that give the rule a fixed point: the ratio is clamped to
    /// [−1, 1] (a negative fiber stiffness on the descending limb gives OpenSim's small
    /// negative ratios, kept, but as K_M → −K_T it would send the fiber velocity to infinity);
    /// a tendon balanced at exactly zero force counts as taut; and when both stiffnesses
    /// vanish, the fiber takes all of ℓ̇_MT.
    Stiffness,
}

impl VelocitySplit {
    /// The rule of each OpenSim class's equilibrium initialisation.
    pub fn opensim_default(kind: MuscleKind) -> VelocitySplit {
        match kind {
            MuscleKind::Thelen2003 | MuscleKind::Millard2012Equilibrium => VelocitySplit::Stiffness,
            MuscleKind::DeGrooteFregly2016 => VelocitySplit::RigidTendonVelocity,
        }
    }
}

/// Settings of the equilibrium solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EquilibriumSettings {
    /// Force-balance tolerance as a fraction of F_max (default 1e-12).
    pub tolerance: f64,
    /// Iterations of each fiber-length solve (default 100).
    pub max_iterations: u32,
    /// Iterations of the velocity fixed point for [`VelocitySplit::Stiffness`] (default 100).
    pub max_velocity_iterations: u32,
    /// None: the OpenSim class's own rule ([`VelocitySplit::opensim_default`]).
    pub velocity_split: Option<VelocitySplit>,
}

impl Default for EquilibriumSettings {
    fn default() -> Self {
        EquilibriumSettings {
            tolerance: 1e-12,
            max_iterations: 100,
            max_velocity_iterations: 100,
            velocity_split: None,
        }
    }
}

/// The fiber velocity during one fiber-length solve.
#[derive(Clone, Copy)]
enum FiberVelocity {
    /// ṽ fixed.
    Fixed(f64),
    /// ṽ = ℓ̇_MT cos α(l) / v_max.
    AlongPath(f64),
    /// ṽ fixed, with f_V(ṽ) (value, slope) evaluated once for the whole solve.
    FixedWithMultiplier(f64, f64, f64),
}

/// How a fiber-length solve at a given velocity rule ended.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum InnerKind {
    Root,
    LowerBound,
    NoRoot,
    MaxIterations,
}

#[derive(Clone, Copy, Debug)]
struct Inner {
    lce: f64,
    kind: InnerKind,
    iterations: u32,
}

/// Outcome of one fiber-length solve.
struct Solve {
    lce: f64,
    iterations: u32,
    status: MuscleStatus,
}

impl HillMuscle {
    /// Residual r(l) and dr/dl (normalised by F_max, per metre) at fiber length `lce`, with
    /// the ṽ used.
    fn residual(&self, a: f64, l_mt: f64, lce: f64, velocity: FiberVelocity) -> (f64, f64, f64) {
        let p = &self.params;
        let pen = self.pennation.sin_cos(lce);
        let dcos = self.pennation.dcos_dlength(lce, &pen);
        let l_n = lce / p.optimal_fiber_length;
        let fal = self.curves.active_force_length(l_n);
        let fpe = self.curves.passive_force_length(l_n);
        let (v, dv, fv) = match velocity {
            FiberVelocity::Fixed(v) => (v, 0.0, self.curves.force_velocity(a, v)),
            FiberVelocity::FixedWithMultiplier(v, fv, dfv) => {
                (v, 0.0, CurvePoint::new(fv, dfv, 0.0))
            }
            FiberVelocity::AlongPath(v_mt) => {
                let k = v_mt / self.max_fiber_velocity();
                let v = k * pen.cos;
                (v, k * dcos, self.curves.force_velocity(a, v))
            }
        };
        let beta = p.fiber_damping;
        let fiber = a * fal.value * fv.value + fpe.value + beta * v;
        let dfiber = (a * fal.slope * fv.value + fpe.slope) / p.optimal_fiber_length
            + (a * fal.value * fv.slope + beta) * dv;
        // l_T = ℓ_MT − l cos α ⇒ dl_T/dl = −(cos α + l ∂cos α/∂l).
        let dlat = pen.cos + lce * dcos;
        let ft = self
            .curves
            .tendon_force_length((l_mt - lce * pen.cos) / p.tendon_slack_length);
        let r = fiber * pen.cos - ft.value;
        let dr = dfiber * pen.cos + fiber * dcos + ft.slope * dlat / p.tendon_slack_length;
        (r, dr, v)
    }

    /// Bracketed Newton on [lo, hi] with r(lo) < 0 < r(hi) (the caller checks the signs).
    #[allow(clippy::too_many_arguments)]
    fn solve_fiber_length(
        &self,
        a: f64,
        l_mt: f64,
        velocity: FiberVelocity,
        mut lo: f64,
        mut hi: f64,
        guess: f64,
        settings: &EquilibriumSettings,
    ) -> Solve {
        let tol = settings.tolerance;
        let mut x = if guess > lo && guess < hi {
            guess
        } else {
            0.5 * (lo + hi)
        };
        let mut step_before_last = hi - lo;
        let mut last_step = step_before_last;
        for it in 1..=settings.max_iterations {
            let (r, dr, _) = self.residual(a, l_mt, x, velocity);
            if r.abs() <= tol {
                return Solve {
                    lce: x,
                    iterations: it,
                    status: MuscleStatus::Ok,
                };
            }
            if r < 0.0 {
                lo = x;
            } else {
                hi = x;
            }
            if hi - lo <= 2.0 * f64::EPSILON * x.abs() {
                // The bracket is as narrow as f64 allows: this is the root to machine
                // precision (|r| is then the residual's rounding error).
                return Solve {
                    lce: x,
                    iterations: it,
                    status: MuscleStatus::Ok,
                };
            }
            let newton = x - r / dr;
            // Newton inside the bracket and shrinking fast enough, else bisection.
            let step = if dr.is_finite()
                && dr != 0.0
                && newton > lo
                && newton < hi
                && (x - newton).abs() < 0.5 * step_before_last.abs()
            {
                x - newton
            } else {
                x - 0.5 * (lo + hi)
            };
            step_before_last = last_step;
            last_step = step;
            x -= step;
        }
        Solve {
            lce: x,
            iterations: settings.max_iterations,
            status: MuscleStatus::MaxIterations,
        }
    }

    /// The normalised fiber velocity from OpenSim's stiffness-sharing rule at fiber length
    /// `lce`, with f_V evaluated at the current estimate `v`.
    pub(super) fn stiffness_split_velocity(
        &self,
        a: f64,
        l_mt: f64,
        v_mt: f64,
        lce: f64,
        v: f64,
    ) -> f64 {
        let p = &self.params;
        let pen = self.pennation.sin_cos(lce);
        let dcos = self.pennation.dcos_dlength(lce, &pen);
        let l_n = lce / p.optimal_fiber_length;
        let fal = self.curves.active_force_length(l_n);
        let fpe = self.curves.passive_force_length(l_n);
        let fv = self.curves.force_velocity(a, v).value;
        let fiber = a * fal.value * fv + fpe.value + p.fiber_damping * v;
        let dfiber = (a * fal.slope * fv + fpe.slope) / p.optimal_fiber_length;
        // K_T = ∂F_T/∂l_T and the fiber stiffness K_M (both per F_max; only their ratio
        // matters). Millard (estimateMuscleFiberState): K_M = ∂F_AT/∂l_AT, the stiffness along
        // the tendon. Thelen (initMuscleState): K_M = ∂F_AT/∂l · cos α, OpenSim's own
        // approximation of it (it multiplies by cos α where the chain rule divides by
        // ∂l_AT/∂l = cos α + l ∂cos α/∂l); kept, so the split is the one OpenSim initialises
        // Thelen muscles with.
        let df_at = dfiber * pen.cos + fiber * dcos;
        let k_m = match self.kind {
            MuscleKind::Thelen2003 => df_at * pen.cos,
            _ => df_at / (pen.cos + lce * dcos),
        };
        let l_tn = (l_mt - lce * pen.cos) / p.tendon_slack_length;
        let k_t = self.curves.tendon_force_length(l_tn).slope / p.tendon_slack_length;
        // OpenSim: a slack tendon takes all of ℓ̇_MT, a taut one the share K_M / (K_M + K_T).
        // Deviations, so that the rule has a fixed point: the share is clamped to [−1, 1]; a
        // tendon balanced at exactly zero force counts as taut (l̃ᵀ > 1 − 1e-9, rounding); and
        // when both stiffnesses vanish (a fiber that cannot pull at this speed against a
        // tendon at its slack length) the fiber, which offers no resistance, takes it all.
        let v_tendon = if l_tn <= 1.0 - 1e-9 {
            v_mt
        } else if (k_m + k_t).abs() > super::millard::SIGNIFICANT_REAL {
            (k_m / (k_m + k_t)).clamp(-1.0, 1.0) * v_mt
        } else {
            0.0
        };
        // Fixed width: ℓ̇_AT = v / cos α ⇒ v = (ℓ̇_MT − ℓ̇_T) cos α.
        (v_mt - v_tendon) * pen.cos / self.max_fiber_velocity()
    }

    /// One fiber-length solve at fixed velocity rule: the bracket [lo, top] is checked and
    /// the root found. Returns the fiber length and how it was obtained.
    fn fiber_length_at(
        &self,
        a: f64,
        l_mt: f64,
        velocity: FiberVelocity,
        guess: f64,
        settings: &EquilibriumSettings,
    ) -> Inner {
        let p = &self.params;
        let velocity = match velocity {
            FiberVelocity::Fixed(v) => {
                let fv = self.curves.force_velocity(a, v);
                FiberVelocity::FixedWithMultiplier(v, fv.value, fv.slope)
            }
            other => other,
        };
        let dgf = self.kind == MuscleKind::DeGrooteFregly2016;
        let tiny = 1e-9 * p.optimal_fiber_length;
        // Shortest admissible fiber: the minimum length, or (De Groote–Fregly) the one at
        // which the tendon force reaches 5 F_max.
        let lo = if let super::HillCurves::DeGrooteFregly2016(c) = self.curves() {
            let l_at = l_mt - p.tendon_slack_length * c.tendon_length_at_force(5.0);
            self.pennation.fiber_length(l_at.max(0.0)).max(tiny)
        } else {
            p.minimum_fiber_length.max(tiny)
        };
        // Longest: the tendon at its slack length.
        let l_at_slack = l_mt - p.tendon_slack_length;
        let lo_at = lo * self.pennation.sin_cos(lo).cos;
        let (lower, none) = if dgf {
            (InnerKind::NoRoot, InnerKind::NoRoot)
        } else {
            (InnerKind::LowerBound, InnerKind::NoRoot)
        };
        let done = |lce: f64, kind: InnerKind, iterations: u32| Inner {
            lce,
            kind,
            iterations,
        };
        if l_at_slack <= lo_at {
            // The tendon is slack even with the shortest fiber.
            return done(lo, lower, 0);
        }
        let hi = self.pennation.fiber_length(l_at_slack);
        if self.residual(a, l_mt, lo, velocity).0 >= 0.0 {
            return done(lo, lower, 0);
        }
        let mut top = hi;
        let mut r_top = self.residual(a, l_mt, top, velocity).0;
        if r_top < 0.0 && !dgf {
            // A shortening fiber can push (negative damping force) where the tendon goes
            // slack; with a slack tendon the balance is where the fiber force vanishes.
            top = self.pennation.fiber_length(l_mt);
            r_top = self.residual(a, l_mt, top, velocity).0;
        }
        if !(r_top >= 0.0) {
            return done(hi, none, 0);
        }
        let guess = if guess.is_nan() {
            // Start with the tendon at 1% strain, as OpenSim does.
            self.pennation
                .fiber_length((l_mt - 1.01 * p.tendon_slack_length).max(lo_at))
        } else {
            guess
        };
        let solve = self.solve_fiber_length(a, l_mt, velocity, lo, top, guess, settings);
        let kind = if solve.status == MuscleStatus::Ok {
            InnerKind::Root
        } else {
            InnerKind::MaxIterations
        };
        done(solve.lce, kind, solve.iterations)
    }

    /// Elastic-tendon equilibrium for activation `a`, musculotendon length `l_mt` and
    /// lengthening speed `v_mt`: the fiber length l with
    /// (a f_L f_V + f_PE + β ṽ) cos α = f_T, to `settings.tolerance`·F_max, the fiber velocity
    /// following `settings.velocity_split`. Admissible fiber lengths are those above the
    /// minimum fiber length (Thelen, Millard) or those with tendon force in [0, 5] F_max (De
    /// Groote–Fregly, as OpenSim's bisection). Statuses: `Ok`; `FiberAtLowerBound` (the
    /// fiber would be shorter than its minimum, e.g. a slack musculotendon: the state at the
    /// minimum is returned, as OpenSim does); `NoEquilibrium`; `MaxIterations`.
    ///
    /// With [`VelocitySplit::Stiffness`] the normalised fiber velocity ṽ solves
    /// g(ṽ) = split(l(ṽ), ṽ) − ṽ = 0 on [0, 2ℓ̇_MT / v_max] (split() never leaves that range), by
    /// fixed-point and secant steps kept inside a shrinking bracket, each step a fiber-length
    /// solve. Where the split rule jumps (a Thelen tendon going slack) the bracket closes on
    /// the jump; the force balance holds for the returned velocity in every case.
    pub fn state_equilibrium(
        &self,
        activation: f64,
        l_mt: f64,
        v_mt: f64,
        settings: &EquilibriumSettings,
    ) -> MuscleState {
        let valid = activation.is_finite() && l_mt.is_finite() && v_mt.is_finite();
        if !valid || !(settings.tolerance > 0.0) {
            return MuscleState::invalid(MuscleStatus::InvalidInput);
        }
        let a = self.clamp_activation(activation);
        let split = settings
            .velocity_split
            .unwrap_or(VelocitySplit::opensim_default(self.kind));
        let moving = v_mt != 0.0;
        if split != VelocitySplit::Stiffness || !moving {
            let velocity = match split {
                VelocitySplit::RigidTendonVelocity if moving => FiberVelocity::AlongPath(v_mt),
                _ => FiberVelocity::Fixed(0.0),
            };
            let inner = self.fiber_length_at(a, l_mt, velocity, f64::NAN, settings);
            return self.finish(a, l_mt, v_mt, inner, velocity, inner.iterations, true);
        }

        // Stiffness split: bracketed fixed point of ṽ. The split gives the fiber between none
        // and twice ℓ̇_MT (share in [−1, 1], cos α ≤ 1), so g ≥ 0 at 0 and g ≤ 0 at 2ℓ̇_MT/v_max.
        let v_end = 2.0 * v_mt / self.max_fiber_velocity();
        let (mut lo, mut hi) = if v_end > 0.0 {
            (0.0, v_end)
        } else {
            (v_end, 0.0)
        };
        let tol_v = 1e-12;
        let mut iterations = 0u32;
        let mut x = 0.0;
        let mut inner = self.fiber_length_at(a, l_mt, FiberVelocity::Fixed(x), f64::NAN, settings);
        iterations += inner.iterations;
        let mut gx = self.stiffness_split_velocity(a, l_mt, v_mt, inner.lce, x) - x;
        let mut prev: Option<(f64, f64)> = None;
        let mut step_before_last = hi - lo;
        let mut last_step = step_before_last;
        let mut converged = false;
        for _ in 0..settings.max_velocity_iterations.max(1) {
            if gx.abs() <= tol_v * (1.0 + x.abs()) || inner.kind == InnerKind::MaxIterations {
                converged = inner.kind != InnerKind::MaxIterations;
                break;
            }
            // g > 0: the split wants a larger ṽ, so the root lies above x.
            if gx > 0.0 {
                lo = x;
            } else {
                hi = x;
            }
            if hi - lo <= 4.0 * f64::EPSILON * (1.0 + x.abs()) {
                // The bracket closed on a jump of the split rule.
                converged = true;
                break;
            }
            let candidate = match prev {
                Some((xp, gp)) if gp != gx => x - gx * (x - xp) / (gx - gp),
                _ => x + gx,
            };
            let step = if candidate > lo
                && candidate < hi
                && (candidate - x).abs() < 0.5 * step_before_last.abs()
            {
                candidate - x
            } else {
                0.5 * (lo + hi) - x
            };
            step_before_last = last_step;
            last_step = step;
            prev = Some((x, gx));
            x += step;
            inner = self.fiber_length_at(a, l_mt, FiberVelocity::Fixed(x), inner.lce, settings);
            iterations += inner.iterations;
            gx = self.stiffness_split_velocity(a, l_mt, v_mt, inner.lce, x) - x;
        }
        self.finish(
            a,
            l_mt,
            v_mt,
            inner,
            FiberVelocity::Fixed(x),
            iterations,
            converged,
        )
    }

    /// The state for a finished solve.
    #[allow(clippy::too_many_arguments)]
    fn finish(
        &self,
        a: f64,
        l_mt: f64,
        v_mt: f64,
        inner: Inner,
        velocity: FiberVelocity,
        iterations: u32,
        converged: bool,
    ) -> MuscleState {
        let mut s = match inner.kind {
            InnerKind::LowerBound => {
                let mut s = self.state_at_fiber_length(a, l_mt, v_mt, inner.lce);
                s.status = MuscleStatus::FiberAtLowerBound;
                s
            }
            InnerKind::NoRoot => {
                let mut s = self.state_from_solution(a, l_mt, v_mt, inner.lce, velocity);
                s.status = MuscleStatus::NoEquilibrium;
                s
            }
            InnerKind::MaxIterations => {
                let mut s = self.state_from_solution(a, l_mt, v_mt, inner.lce, velocity);
                s.status = MuscleStatus::MaxIterations;
                s
            }
            InnerKind::Root => {
                let mut s = self.state_from_solution(a, l_mt, v_mt, inner.lce, velocity);
                if !converged {
                    s.status = MuscleStatus::MaxIterations;
                }
                s
            }
        };
        s.iterations = iterations;
        s
    }

    fn state_from_solution(
        &self,
        a: f64,
        l_mt: f64,
        v_mt: f64,
        lce: f64,
        velocity: FiberVelocity,
    ) -> MuscleState {
        let v = match velocity {
            FiberVelocity::Fixed(v) | FiberVelocity::FixedWithMultiplier(v, _, _) => v,
            FiberVelocity::AlongPath(_) => self.residual(a, l_mt, lce, velocity).2,
        };
        self.evaluate(a, l_mt, v_mt, lce, v, None, Tendon::Elastic)
    }

    /// The state in the muscle's own tendon mode: rigid if `ignore_tendon_compliance`, else
    /// the elastic equilibrium with the class's default settings.
    pub fn state(&self, activation: f64, l_mt: f64, v_mt: f64) -> MuscleState {
        if self.params.ignore_tendon_compliance {
            self.state_rigid_tendon(activation, l_mt, v_mt)
        } else {
            self.state_equilibrium(activation, l_mt, v_mt, &EquilibriumSettings::default())
        }
    }

    /// Isometric force at full activation, F_iso(ℓ_MT) = tendon force at a = 1, ℓ̇_MT = 0,
    /// in the muscle's own tendon mode (for maximum isometric moments: Σ r_k F_iso,k).
    pub fn isometric_force(&self, l_mt: f64) -> f64 {
        self.state(1.0, l_mt, 0.0).tendon_force
    }
}
