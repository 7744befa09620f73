//! Constant-thickness ("fixed width") pennation, OpenSim's `MuscleFixedWidthPennationModel`:
//! the fiber, of length l, spans a parallelogram of constant height h = l_opt sin α_opt, so
//! sin α = h / l and the fiber's projection on the tendon is l cos α = √(l² − h²).

/// The fixed-width pennation geometry of one muscle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FixedWidthPennation {
    /// h = l_opt sin α_opt (m).
    pub height: f64,
    pub pennation_angle_at_optimal: f64,
    /// Largest pennation angle (rad); π/2 means unlimited (De Groote–Fregly).
    pub maximum_pennation_angle: f64,
    sin_maximum: f64,
}

/// Sine and cosine of the pennation angle, and the angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pennation {
    pub angle: f64,
    pub sin: f64,
    pub cos: f64,
}

impl FixedWidthPennation {
    pub fn new(
        optimal_fiber_length: f64,
        pennation_angle_at_optimal: f64,
        maximum_pennation_angle: f64,
    ) -> Self {
        FixedWidthPennation {
            height: optimal_fiber_length * pennation_angle_at_optimal.sin(),
            pennation_angle_at_optimal,
            maximum_pennation_angle,
            sin_maximum: maximum_pennation_angle.sin(),
        }
    }

    /// OpenSim's minimum fiber length of the pennation model: the length at the maximum
    /// pennation angle, h / sin α_max, or 1% of l_opt when α_max is 0.
    pub fn minimum_fiber_length(&self, optimal_fiber_length: f64) -> f64 {
        if self.maximum_pennation_angle > super::millard::SIGNIFICANT_REAL {
            self.height / self.sin_maximum
        } else {
            0.01 * optimal_fiber_length
        }
    }

    /// Pennation at fiber length l: α = asin(h / l), held at α_max once h / l reaches
    /// sin α_max; 0 for a parallel-fibered muscle (α_opt ≤ ε).
    #[inline]
    pub fn at(&self, fiber_length: f64) -> Pennation {
        if self.pennation_angle_at_optimal <= f64::EPSILON {
            return Pennation {
                angle: 0.0,
                sin: 0.0,
                cos: 1.0,
            };
        }
        let sin = self.height / fiber_length;
        if sin < self.sin_maximum && fiber_length > 0.0 {
            Pennation {
                angle: sin.asin(),
                sin,
                cos: (1.0 - sin * sin).sqrt(),
            }
        } else {
            let a = self.maximum_pennation_angle;
            Pennation {
                angle: a,
                sin: a.sin(),
                cos: a.cos(),
            }
        }
    }

    /// As [`Self::at`] without the angle itself (no arcsine), for the inner loops.
    #[inline]
    pub fn sin_cos(&self, fiber_length: f64) -> Pennation {
        if self.pennation_angle_at_optimal <= f64::EPSILON {
            return Pennation {
                angle: 0.0,
                sin: 0.0,
                cos: 1.0,
            };
        }
        let sin = self.height / fiber_length;
        if sin < self.sin_maximum && fiber_length > 0.0 {
            Pennation {
                angle: f64::NAN,
                sin,
                cos: (1.0 - sin * sin).sqrt(),
            }
        } else {
            let a = self.maximum_pennation_angle;
            Pennation {
                angle: a,
                sin: a.sin(),
                cos: a.cos(),
            }
        }
    }

    /// d(cos α)/dl = h² / (l³ cos α) while α < α_max, else 0.
    #[inline]
    pub fn dcos_dlength(&self, fiber_length: f64, p: &Pennation) -> f64 {
        if p.sin == 0.0 || p.sin >= self.sin_maximum || p.cos <= 0.0 {
            0.0
        } else {
            self.height * self.height / (fiber_length.powi(3) * p.cos)
        }
    }

    /// Fiber length whose projection on the tendon is `along_tendon`: √(h² + l_AT²).
    #[inline]
    pub fn fiber_length(&self, along_tendon: f64) -> f64 {
        (self.height * self.height + along_tendon * along_tendon).sqrt()
    }
}
