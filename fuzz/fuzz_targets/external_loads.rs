//! An ExternalLoads .xml and its data file, resolved against the demo model: the input is
//! the .xml, a NUL byte, then the data file (without a NUL, a fixed valid data file).
#![no_main]

use libfuzzer_sys::fuzz_target;

use musculo::io::Table;
use musculo::io::external_loads::ExternalLoads;
use musculo::solve::external_loads::ExternalLoadSet;
use std::sync::OnceLock;

const GRF: &str = "grf\nversion=1\nnRows=3\nnColumns=10\ninDegrees=no\nendheader\n\
time\tf_vx\tf_vy\tf_vz\tf_px\tf_py\tf_pz\tt_x\tt_y\tt_z\n\
0\t0\t700\t0\t0.1\t0\t0\t0\t0\t0\n0.1\t0\t710\t0\t0.1\t0\t0\t0\t0\t0\n\
0.2\t0\t720\t0\t0.1\t0\t0\t0\t0\t0\n";

fuzz_target!(|data: &[u8]| {
    static MODEL: OnceLock<musculo::Model> = OnceLock::new();
    let model = MODEL.get_or_init(musculo::Model::demo);
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let (xml, grf) = text.split_once('\0').unwrap_or((text, GRF));
    let Ok(loads) = ExternalLoads::parse(xml, "fuzz.xml") else {
        return;
    };
    if let Ok(table) = Table::parse(grf, "fuzz.mot") {
        let _ = ExternalLoadSet::new(model, &loads, &table, "fuzz.mot");
    }
});
