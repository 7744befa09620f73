//! Augmentation by perturbation: N seeded variants of every clip, each a physically
//! consistent sample of its own. Variant 0 is the clip as recorded; variant v ≥ 1 draws,
//! from a generator seeded by (run seed, clip name, v):
//! - a body-height scale s ~ U[1 − h, 1 + h]: the clip's positions are scaled by s about the
//!   ground origin (the floor stays at y = 0), so the model scaled to the clip grows with it
//!   and the motion keeps its shape;
//! - a body-mass scale k ~ U[1 − m, 1 + m]: every body's mass and inertia × k (mass
//!   distribution kept, as OpenSim's `preserve_mass_distribution`);
//! - a carried load L ~ U[0, L_max] kg on the torso (at its centre of mass) or split between
//!   the hands (at the distal end of each radius), chosen with equal odds: a point mass that
//!   moves the body's centre of mass and adds its parallel-axis inertia;
//! - a speed factor c ~ U[1 − w, 1 + w]: time warping t' = t / c (the same frames played
//!   c times faster: velocities × c, accelerations × c²).
//!
//! The generator is SplitMix64 ([`crate::random`]), so that the draws are fixed by musculo
//! alone and never change with a dependency's version.

use crate::error::Error;
use crate::model::Model;
use crate::motion::Motion;
use crate::random::{SplitMix64, mix};
use crate::spatial::{Mat3, Vec3};

/// Ranges of the perturbations (half-widths as fractions; the load's maximum in kg).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PerturbationRanges {
    pub height: f64,
    pub mass: f64,
    pub load_kg: f64,
    pub speed: f64,
}

impl Default for PerturbationRanges {
    fn default() -> Self {
        PerturbationRanges {
            height: 0.10,
            mass: 0.20,
            load_kg: 10.0,
            speed: 0.15,
        }
    }
}

impl PerturbationRanges {
    pub fn validate(&self) -> crate::Result<()> {
        for (name, v, max) in [
            ("height", self.height, 0.5),
            ("mass", self.mass, 0.5),
            ("load_kg", self.load_kg, 100.0),
            ("speed", self.speed, 0.5),
        ] {
            if !(v >= 0.0 && v <= max) {
                return Err(Error::invalid(
                    "perturbation",
                    format!("{name} = {v} must lie in [0, {max}]"),
                ));
            }
        }
        Ok(())
    }
}

/// Where a carried load sits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LoadSite {
    None,
    Torso,
    Hands,
}

/// One variant's parameters (written to the manifest).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Variant {
    pub index: usize,
    pub seed: u64,
    pub height_scale: f64,
    pub mass_scale: f64,
    pub load_kg: f64,
    pub load_site: LoadSite,
    pub speed: f64,
}

impl Variant {
    /// The clip as recorded.
    pub fn identity() -> Variant {
        Variant {
            index: 0,
            seed: 0,
            height_scale: 1.0,
            mass_scale: 1.0,
            load_kg: 0.0,
            load_site: LoadSite::None,
            speed: 1.0,
        }
    }

    /// Variant `index` of clip `clip` (index 0: the identity).
    pub fn draw(run_seed: u64, clip: &str, index: usize, ranges: &PerturbationRanges) -> Variant {
        if index == 0 {
            return Variant::identity();
        }
        // seed = SplitMix64 mix of (run seed, FNV-1a of the clip name, index)
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in clip.bytes() {
            h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
        let seed = mix(run_seed ^ mix(h ^ mix(index as u64)));
        let mut rng = SplitMix64(seed);
        let mut uniform = |half: f64| 1.0 + half * (2.0 * rng.unit() - 1.0);
        let height_scale = uniform(ranges.height);
        let mass_scale = uniform(ranges.mass);
        let speed = uniform(ranges.speed);
        let load_kg = ranges.load_kg * rng.unit();
        let load_site = if load_kg == 0.0 {
            LoadSite::None
        } else if rng.unit() < 0.5 {
            LoadSite::Torso
        } else {
            LoadSite::Hands
        };
        Variant {
            index,
            seed,
            height_scale,
            mass_scale,
            load_kg,
            load_site,
            speed,
        }
    }

    /// The clip seen by this variant: positions × height scale, times ÷ speed.
    pub fn apply_to_motion(&self, motion: &Motion) -> crate::Result<Motion> {
        if self.height_scale == 1.0 && self.speed == 1.0 {
            return Ok(motion.clone());
        }
        let mut m = motion.clone();
        for p in &mut m.positions {
            *p *= self.height_scale;
        }
        m.rate_hz *= self.speed;
        for t in &mut m.time {
            *t /= self.speed;
        }
        m.validate()?;
        Ok(m)
    }

    /// Mass scaling and the carried load on `model`.
    pub fn apply_to_model(&self, model: &mut Model) -> crate::Result<()> {
        if self.mass_scale != 1.0 {
            for b in model.bodies.iter_mut().skip(1) {
                b.mass *= self.mass_scale;
                b.inertia_about_com *= self.mass_scale;
            }
        }
        match self.load_site {
            LoadSite::None => {}
            LoadSite::Torso => {
                let torso = body(model, "torso")?;
                let at = model.bodies[torso].com_in_body;
                add_point_mass(model, torso, at, self.load_kg);
            }
            LoadSite::Hands => {
                for side in ["r", "l"] {
                    let radius = body(model, &format!("radius_{side}"))?;
                    let at = distal_end(model, radius);
                    add_point_mass(model, radius, at, 0.5 * self.load_kg);
                }
            }
        }
        Ok(())
    }
}

fn body(model: &Model, name: &str) -> crate::Result<usize> {
    model.body_index(name).ok_or_else(|| {
        Error::invalid(
            "variant",
            format!(
                "a carried load needs body `{name}`, which model {} lacks",
                model.name
            ),
        )
    })
}

/// The hand's position on the radius: the radius' point farthest from its joint along the
/// bone, taken as its centre of mass mirrored through the joint-to-COM line (twice the COM
/// distance from the joint frame origin; the forearm's COM lies near its middle).
fn distal_end(model: &Model, body: usize) -> Vec3 {
    let b = &model.bodies[body];
    let joint_origin = b
        .joint
        .map(|j| model.joints[j].child_offset.pos)
        .unwrap_or_else(Vec3::zeros);
    joint_origin + 2.0 * (b.com_in_body - joint_origin)
}

/// Adds a point mass `m` at `at` (body frame) to `body`: new COM c′ = (M c + m p)/(M + m),
/// inertia about c′ by the parallel-axis theorem, I′ = I + M (|d₁|² E − d₁d₁ᵀ) +
/// m (|d₂|² E − d₂d₂ᵀ) with d₁ = c − c′, d₂ = p − c′.
fn add_point_mass(model: &mut Model, body: usize, at: Vec3, m: f64) {
    let b = &mut model.bodies[body];
    let total = b.mass + m;
    let c_new = (b.com_in_body * b.mass + at * m) / total;
    let shift =
        |d: Vec3, mass: f64| (Mat3::identity() * d.norm_squared() - d * d.transpose()) * mass;
    b.inertia_about_com += shift(b.com_in_body - c_new, b.mass) + shift(at - c_new, m);
    b.com_in_body = c_new;
    b.mass = total;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_mass_keeps_total_inertia_about_a_fixed_point() {
        // the inertia about the body origin must equal the sum of both parts' inertias
        let mut model = Model::default_fullbody();
        let torso = model.body_index("torso").unwrap();
        let before = model.bodies[torso].clone();
        let at = Vec3::new(0.1, 0.3, -0.05);
        add_point_mass(&mut model, torso, at, 7.0);
        let after = &model.bodies[torso];
        let about_origin = |i: Mat3, m: f64, c: Vec3| {
            i + (Mat3::identity() * c.norm_squared() - c * c.transpose()) * m
        };
        let expected = about_origin(before.inertia_about_com, before.mass, before.com_in_body)
            + about_origin(Mat3::zeros(), 7.0, at);
        let got = about_origin(after.inertia_about_com, after.mass, after.com_in_body);
        assert!((expected - got).norm() < 1e-12 * expected.norm());
        assert!((after.mass - before.mass - 7.0).abs() < 1e-12);
    }

    #[test]
    fn draws_are_reproducible_and_within_ranges() {
        let r = PerturbationRanges::default();
        let a = Variant::draw(7, "000021", 3, &r);
        assert_eq!(a, Variant::draw(7, "000021", 3, &r));
        assert_ne!(a, Variant::draw(7, "000022", 3, &r));
        assert_ne!(a, Variant::draw(8, "000021", 3, &r));
        let mut hands = 0;
        for i in 1..200 {
            let v = Variant::draw(1, "clip", i, &r);
            assert!((v.height_scale - 1.0).abs() <= r.height);
            assert!((v.mass_scale - 1.0).abs() <= r.mass);
            assert!((v.speed - 1.0).abs() <= r.speed);
            assert!((0.0..=r.load_kg).contains(&v.load_kg));
            hands += (v.load_site == LoadSite::Hands) as usize;
        }
        // equal odds for the two sites: 199 draws, 99.5 expected, 5 σ ≈ 35
        assert!((65..=135).contains(&hands), "{hands} hand loads of 199");
        assert_eq!(Variant::draw(1, "clip", 0, &r), Variant::identity());
    }
}
