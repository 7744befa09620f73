//! A force-set file (reserve actuators) read with the demo model.
#![no_main]

use libfuzzer_sys::fuzz_target;

const DEMO: &str = include_str!("../../models/demo.osim");

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let sets = musculo::model::ForceSetFiles {
            files: vec![(text.to_string(), "fuzz.xml".to_string())],
            replace: data.len().is_multiple_of(2),
        };
        let _ = musculo::Model::from_osim_str_with_force_sets(
            DEMO,
            "demo.osim",
            &Default::default(),
            &sets,
        );
    }
});
