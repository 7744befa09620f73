//! The C3D reader (header, parameters, points, analog channels, force plates).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(c) = musculo::motion::c3d::C3d::parse(data, "fuzz.c3d") {
        let _ = c.ground_reactions(20.0);
    }
});
