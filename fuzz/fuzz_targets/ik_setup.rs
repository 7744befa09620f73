//! The InverseKinematicsTool setup reader.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = musculo::io::ik_setup::IkSetup::parse(text, std::path::Path::new("fuzz/ik.xml"));
    }
});
