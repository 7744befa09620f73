//! The training set reads each tensor file's model identity: a clip of another base model is
//! refused, naming both models, and a clip whose body is not the model's own (a variant's
//! mass) is kept for reconstruction but left out of the physics terms.

use musculo::augment::chain::{Chain, ChainOptions};
use musculo::augment::demo;
use musculo::augment::output::{self, fnv1a_hex};
use musculo::augment::perturb::Variant;
use musculo_learn::data::ClipSet;

#[test]
fn clips_of_another_model_are_refused_and_other_bodies_left_out_of_the_physics() {
    let chain = Chain::default_model(ChainOptions::default()).unwrap();
    let dir = std::env::temp_dir().join(format!("musculo-learn-identity-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
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
    let own = |name: &str| {
        set.clips
            .iter()
            .find(|c| c.name == name)
            .unwrap()
            .body_is_model
    };
    assert!(own("plain"));
    assert!(!own("heavier"));
    let other = "0123456789abcdef";
    let e = ClipSet::read_for(std::slice::from_ref(&dir), &chain.model, Some(other))
        .unwrap_err()
        .to_string();
    for named in ["musculo_fullbody", hash.as_str(), other] {
        assert!(e.contains(named), "{named} not in: {e}");
    }
    let _ = std::fs::remove_dir_all(dir);
}
