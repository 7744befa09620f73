//! The ScaleTool setup reader.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = musculo::io::scale_setup::ScaleSetup::parse(
            text,
            std::path::Path::new("fuzz/scale.xml"),
        );
    }
});
