//! MAVLink messages into DigiView's link, its cameras and gimbals (invariants in
//! `digiview::app::checks::mavlink_messages`; the bytes' layout in `digiview::autopilot::checks`).
#![no_main]

use digiview::app::checks::{mavlink_bench, mavlink_messages};
use digiview::lens::LensCal;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let cal = LensCal::parse(Path::new("lens.cal"), include_str!("../../lens-cal/lens.cal"))
        .expect("the shipped lens.cal parses");
    mavlink_messages(&mut mavlink_bench(&cal), data);
});
