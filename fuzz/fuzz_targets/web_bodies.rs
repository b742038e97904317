//! The web API's parameter writes on any body (invariants in
//! `digiview::http::checks::put_body`), from a fresh live state each run.
#![no_main]

use digiview::cli::locate::built_in_lens_cal;
use digiview::control::checks::controller;
use digiview::lens::LensCal;
use libfuzzer_sys::fuzz_target;
use std::sync::{Arc, LazyLock};

static CAL: LazyLock<LensCal> = LazyLock::new(built_in_lens_cal);

fuzz_target!(|data: &[u8]| digiview::http::checks::put_body(&Arc::new(controller(&CAL)), data));
