//! The .trc marker reader, and the motion made from it.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(trc) = musculo::io::trc::Trc::parse(text, "fuzz.trc")
    {
        let _ = musculo::motion::Motion::from_trc(&trc, "fuzz.trc");
    }
});
