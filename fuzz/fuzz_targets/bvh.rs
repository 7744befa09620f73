//! The BVH reader (hierarchy, motion, forward kinematics to a Motion).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let options = musculo::motion::bvh::BvhOptions::default();
        let _ = musculo::motion::bvh::parse(text, "fuzz.bvh", &options);
    }
});
