//! SplitMix64 (Steele, Lea & Flood 2014, "Fast splittable pseudorandom number generators",
//! OOPSLA): a small deterministic generator, written out here so that seeded draws (augmentation
//! variants, the random poses of `musculo check`) are fixed by this file alone and never change
//! with a dependency's version or the platform.
//!
//! ```text
//! state ← state + γ,  γ = 0x9e3779b97f4a7c15 (2⁶⁴/φ)
//! z ← (z ⊕ z≫30)·0xbf58476d1ce4e5b9;  z ← (z ⊕ z≫27)·0x94d049bb133111eb;  z ⊕ z≫31
//! ```

const GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

/// SplitMix64's finaliser of `z + γ`: a bijective mix of 64 bits (also used to derive seeds).
pub fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(GAMMA);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The generator; its state is the seed advanced by γ per draw.
#[derive(Clone, Debug)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        let z = mix(self.0);
        self.0 = self.0.wrapping_add(GAMMA);
        z
    }

    /// A uniform number in [0, 1) from the top 53 bits.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A uniform number in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_outputs_match_the_published_reference_sequence() {
        // SplitMix64 seeded with 1234567 (the reference C implementation by Vigna, splitmix64.c)
        let mut g = SplitMix64(1234567);
        assert_eq!(g.next_u64(), 6457827717110365317);
        assert_eq!(g.next_u64(), 3203168211198807973);
        assert_eq!(g.next_u64(), 9817491932198370423);
    }

    #[test]
    fn unit_draws_lie_in_the_half_open_interval_with_the_right_mean() {
        let mut g = SplitMix64(42);
        let n = 100_000;
        let mut sum = 0.0;
        for _ in 0..n {
            let u = g.unit();
            assert!((0.0..1.0).contains(&u));
            sum += u;
        }
        // mean 1/2, standard error 1/sqrt(12 n) ≈ 9.1e-4
        assert!((sum / n as f64 - 0.5).abs() < 5e-3);
    }
}
