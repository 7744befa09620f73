//! The MarkerSet file reader (a ScaleTool's marker_set_file).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = musculo::io::scale_setup::parse_marker_set(
            text,
            std::path::Path::new("fuzz/markers.xml"),
        );
    }
});
