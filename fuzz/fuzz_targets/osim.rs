//! The .osim model reader on arbitrary text.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = musculo::Model::from_osim_str(text, "fuzz.osim");
    }
});
