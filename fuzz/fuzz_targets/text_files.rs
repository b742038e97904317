//! Any text as lens.cal, a state file and the serve configuration (invariants in
//! `digiview::app::checks::text_files`).
#![no_main]

use digiview::lens::LensCal;
use libfuzzer_sys::fuzz_target;
use std::path::Path;
use std::sync::LazyLock;

static CAL: LazyLock<LensCal> = LazyLock::new(|| {
    LensCal::parse(Path::new("lens.cal"), include_str!("../../lens-cal/lens.cal"))
        .expect("the shipped lens.cal parses")
});

fuzz_target!(|data: &[u8]| digiview::app::checks::text_files(&CAL, data));
