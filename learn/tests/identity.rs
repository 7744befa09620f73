//! The training set reads each tensor file's model identity: a clip of another base model is
//! refused, naming both models, and every other clip is judged by the physics terms on its own
//! body (a variant's mass, a HumanML3D clip scaled to its bones), rebuilt from the identity.
//! The check that the right body is used is the physics: the Euler–Lagrange residual of the
//! augmented tensors is zero (float32 rounding) on the body they were computed on and large on
//! the unscaled model. The terms of a batch of several bodies are the mean over the whole batch.

use musculo::augment::chain::{Chain, ChainOptions};
use musculo::augment::output::{self, fnv1a_hex};
use musculo::augment::perturb::{PerturbationRanges, Variant};
use musculo::augment::runner::{self, RunOptions};
use musculo::augment::{demo, describe};
use musculo_learn::data::{ClipSet, Normalizer};
use musculo_learn::physics::{Physics, PhysicsWeights};
use musculo_learn::train::{self, Reconstruction, ReconstructionQuality};
use std::path::PathBuf;
use std::sync::Arc;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "musculo-learn-identity-{name}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The Euler–Lagrange residual of `set`'s own frames through the learned module
/// ([`train::quality`] with the data as their reconstruction), each clip on its body.
fn data_residual(set: &ClipSet, model: &musculo::model::Model) -> ReconstructionQuality {
    let recon: Vec<Reconstruction> = set
        .clips
        .iter()
        .map(|c| Reconstruction {
            name: c.name.clone(),
            frames: c.frames,
            y: c.y.clone(),
        })
        .collect();
    train::quality(set, &recon, model).unwrap()
}

#[test]
fn clips_of_another_model_are_refused_and_other_bodies_judged_on_their_own() {
    let chain = Chain::default_model(ChainOptions::default()).unwrap();
    let dir = scratch("demo");
    let (_, motion) = demo::clips(&chain.model)
        .unwrap()
        .into_iter()
        .next()
        .unwrap();
    let heavier = Variant {
        mass_scale: 1.1,
        ..Variant::identity()
    };
    for (name, variant) in [("plain", Variant::identity()), ("heavier", heavier)] {
        let out = chain.run(&motion, None, &variant).unwrap();
        output::write_clip_output(&dir, name, &out).unwrap();
    }
    let hash = fnv1a_hex(musculo::DEFAULT_MODEL_OSIM);
    let set = ClipSet::read_for(std::slice::from_ref(&dir), &chain.model, Some(&hash)).unwrap();
    let body = |name: &str| set.clips.iter().find(|c| c.name == name).unwrap().body;
    assert_eq!(body("plain"), Some(0));
    assert_eq!(body("heavier"), Some(1));
    assert_eq!(set.bodies.len(), 2);
    // the heavier body: the base model's mass × 1.1
    let mass = |m: &musculo::model::Model| m.bodies.iter().map(|b| b.mass).sum::<f64>();
    let ratio = mass(&set.bodies[1].model) / mass(&chain.model);
    assert!((ratio - 1.1).abs() < 1e-12, "mass ratio {ratio}");
    let q = data_residual(&set, &chain.model);
    println!("demo, plain and heavier on their bodies: {q:?}");
    assert!(q.residual_rms_data <= 1e-5 * q.tau_rms, "{q:?}");
    // the heavier clip on the base model's body is not balanced
    let mut forced = set.clone();
    forced.clips.retain(|c| c.name == "heavier");
    forced.clips[0].body = Some(0);
    let f = data_residual(&forced, &chain.model);
    println!("demo, heavier forced onto the base model: {f:?}");
    assert!(f.residual_rms_data > 1e-3 * f.tau_rms, "{f:?}");

    let other = "0123456789abcdef";
    let e = ClipSet::read_for(std::slice::from_ref(&dir), &chain.model, Some(other))
        .unwrap_err()
        .to_string();
    for named in ["musculo_fullbody", hash.as_str(), other] {
        assert!(e.contains(named), "{named} not in: {e}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_humanml3d_clip_scaled_to_its_bones_is_judged_on_its_scaled_body() {
    let Some(hml) = musculo::reference::file("humanml3d/new_joints_012314.npy") else {
        println!("skipped: reference data not found");
        return;
    };
    let chain = Chain::default_model(ChainOptions::default()).unwrap();
    assert!(chain.options.scale_to_clip);
    let dir = scratch("hml");
    let layout = describe(&chain).unwrap();
    let clips = runner::list_inputs(&[hml], None).unwrap();
    // variant 0 as recorded, variant 1 with a perturbed height, mass and load (its speed kept:
    // a training set has one frame rate)
    let options = RunOptions {
        variants: 2,
        perturbation: PerturbationRanges {
            speed: 0.0,
            ..PerturbationRanges::default()
        },
        ..RunOptions::new(&dir)
    };
    runner::run(&chain, &layout, &clips, &options, &|_| {}).unwrap();
    let hash = fnv1a_hex(musculo::DEFAULT_MODEL_OSIM);
    let set = ClipSet::read_for(std::slice::from_ref(&dir), &chain.model, Some(&hash)).unwrap();
    assert_eq!(set.clips.len(), 2);
    for clip in &set.clips {
        assert!(
            clip.body.is_some_and(|b| b > 0),
            "{}: body {:?}",
            clip.name,
            clip.body
        );
    }
    assert_eq!(set.bodies.len(), 3, "the base model and one body per clip");
    let own = data_residual(&set, &chain.model);
    println!("HumanML3D 012314 on its own bodies: {own:?}");
    assert!(own.residual_rms_data <= 1e-5 * own.tau_rms, "{own:?}");
    // each clip forced onto the unscaled model
    for clip in &set.clips {
        let mut forced = set.clone();
        forced.clips.retain(|c| c.name == clip.name);
        forced.clips[0].body = Some(0);
        let base = data_residual(&forced, &chain.model);
        println!("{} forced onto the unscaled model: {base:?}", clip.name);
        assert!(base.residual_rms_data > 1e-2 * base.tau_rms, "{base:?}");
    }

    // the physics terms of a batch: each sequence on its body, the mean over the whole batch.
    // Windows of 8 frames: the two clips on their bodies and, with them, the first clip on a
    // copy of its body (a third body, the same model).
    let normalizer = Normalizer::of(&set);
    let d = set.layout.width();
    let mut models = set.body_models();
    models.push(Arc::new((*models[set.clips[0].body.unwrap()]).clone()));
    let weights = PhysicsWeights {
        euler: 1.0,
        muscle: 0.5,
        muscle_stride: 3,
    };
    let physics =
        Physics::with_bodies(&models, set.layout.clone(), normalizer.clone(), weights).unwrap();
    assert_eq!(physics.bodies(), 4);
    let t = 8;
    let window = |c: usize, start: usize| -> Vec<f32> {
        let mut z = set.clips[c].y[start * d..(start + t) * d].to_vec();
        normalizer.normalize(&mut z);
        // perturbed, so that the residuals are not zero
        let mut state = (c * 1000 + start) as u64;
        for v in &mut z {
            state = musculo::random::mix(state);
            *v += 0.3 * ((state >> 11) as f32 / (1u64 << 53) as f32 - 0.5);
        }
        z
    };
    let (b0, b1) = (set.clips[0].body, set.clips[1].body);
    let windows = [window(0, 10), window(1, 20), window(0, 30)];
    let z: Vec<f32> = windows.concat();
    let alone: Vec<_> = windows
        .iter()
        .zip([b0, b1, b0])
        .map(|(w, b)| physics.evaluate(w, 1, t, &[b], true).unwrap())
        .collect();
    let batch = physics.evaluate(&z, 3, t, &[b0, b1, b0], true).unwrap();
    let mean = alone.iter().map(|v| v.loss).sum::<f64>() / 3.0;
    assert!(
        (batch.loss - mean).abs() <= 1e-12 * mean,
        "batch {} vs the mean of the sequences alone {mean}",
        batch.loss
    );
    // ∂L/∂z of the batch: each sequence's gradient alone, divided by the 3 sequences
    for (s, a) in alone.iter().enumerate() {
        for (g, h) in batch.grad[s * t * d..(s + 1) * t * d].iter().zip(&a.grad) {
            assert!(
                (g - h / 3.0).abs() <= 1e-5 * h.abs().max(1e-3),
                "{g} vs {h}/3"
            );
        }
    }
    // one body split over two (the same model): the value of the one body, to rounding
    let copy = Some(models.len() - 1);
    let split = physics.evaluate(&z, 3, t, &[b0, b1, copy], true).unwrap();
    assert!((split.loss - batch.loss).abs() <= 1e-12 * batch.loss);
    assert!((split.euler - batch.euler).abs() <= 1e-12 * batch.euler);
    assert!((split.muscle - batch.muscle).abs() <= 1e-12 * batch.muscle);
    for (g, h) in split.grad.iter().zip(&batch.grad) {
        assert!((g - h).abs() <= 1e-6 * h.abs().max(1e-3), "{g} vs {h}");
    }
    // a sequence left out adds nothing; a body the terms do not have is an error
    let without = physics.evaluate(&z, 3, t, &[b0, None, b0], false).unwrap();
    let two = (alone[0].loss + alone[2].loss) / 2.0;
    assert!((without.loss - two).abs() <= 1e-12 * two);
    let e = physics
        .evaluate(&z, 3, t, &[b0, Some(9), b0], false)
        .unwrap_err()
        .to_string();
    assert!(e.contains("body 9"), "{e}");
    let _ = std::fs::remove_dir_all(dir);
}
