//! The web API's parameter writes on any body (invariants in
//! `digiview::http::checks::put_body`), from a fresh live state each run.
#![no_main]

use digiview::control::checks::controller;
use digiview::lens::LensCal;
use libfuzzer_sys::fuzz_target;
use std::path::Path;
use std::sync::{Arc, LazyLock};

static CAL: LazyLock<LensCal> = LazyLock::new(|| {
    LensCal::parse(Path::new("lens.cal"), include_str!("../../lens-cal/lens.cal"))
        .expect("the shipped lens.cal parses")
});

fuzz_target!(|data: &[u8]| digiview::http::checks::put_body(&Arc::new(controller(&CAL)), data));
