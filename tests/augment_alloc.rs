//! The augmentation chain's per-frame work allocates nothing: a clip twice as long (the
//! same motion played twice) costs the same number of heap allocations as the clip itself,
//! counted by a global allocator on the calling thread. Allocations that do not depend on
//! the number of frames (workspaces, one array per output, one spline per coordinate and per
//! muscle) are allowed; anything per frame would add at least one per frame.

#[path = "common/counting_alloc.rs"]
mod counting_alloc;
use counting_alloc::allocations_during;
use musculo::augment::chain::{Chain, ChainOptions};
use musculo::augment::demo;
use musculo::augment::perturb::Variant;
use musculo::motion::Motion;

/// `motion` followed by itself, shifted by its duration.
fn twice(motion: &Motion) -> Motion {
    let mut positions = motion.positions.clone();
    positions.extend_from_slice(&motion.positions);
    Motion::uniform(
        motion.source.clone(),
        motion.names.clone(),
        motion.rate_hz,
        positions,
    )
    .unwrap()
}

#[test]
fn a_clip_twice_as_long_costs_no_more_allocations() {
    let chain = Chain::new(
        musculo::DEFAULT_MODEL_OSIM.to_string(),
        "models/musculo_fullbody.osim".into(),
        ChainOptions::default(),
    )
    .unwrap();
    let (_, squat) = demo::clips(&chain.model).unwrap().remove(1);
    let (long, longer) = (twice(&squat), twice(&twice(&squat)));
    let v = Variant::identity();
    // warm-up (lazily initialised statics)
    chain.run(&squat, None, &v).unwrap();
    // IK keeps, per frame, the list of coordinates at a bound: one small allocation for each
    // frame that has one (its output, not its work); those are subtracted.
    let count = |m: &Motion| {
        let mut at_bound = 0;
        let n = allocations_during(|| {
            at_bound = chain.run(m, None, &v).unwrap().quality.ik_frames_at_bound;
        });
        (n - at_bound, at_bound)
    };
    let ((a1, b1), (a2, b2), (a4, b4)) = (count(&squat), count(&long), count(&longer));
    println!(
        "allocations (less IK's frames at a bound): {a1} for {} frames ({b1} at a bound), {a2} \
         for {} ({b2}), {a4} for {} ({b4})",
        squat.n_frames(),
        long.n_frames(),
        longer.n_frames()
    );
    // Result vectors that grow by doubling add about the same number of allocations each
    // time the clip doubles; one allocation per frame would add 240, then 480.
    let (d1, d2) = (a2 - a1, a4 - a2);
    assert!(
        d2 <= d1 + 16,
        "doubling {} → {} frames added {d2} allocations, {} → {} added {d1}: something \
         allocates per frame",
        long.n_frames(),
        longer.n_frames(),
        squat.n_frames(),
        long.n_frames()
    );
}
