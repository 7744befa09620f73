//! The .npy reader, then HumanML3D's and KIT-ML's reading of the array.
#![no_main]

use libfuzzer_sys::fuzz_target;

use musculo::motion::{humanml3d, kit, npy};

fuzz_target!(|data: &[u8]| {
    if let Ok(a) = npy::parse_array_as_f64(data, "fuzz.npy") {
        let _ = humanml3d::from_array(a.view(), "fuzz.npy", &humanml3d::Options::default());
        let _ = kit::from_array(a.view(), "fuzz.npy", &kit::Options::default());
    }
});
