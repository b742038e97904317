//! Any text as lens.cal, a state file and the serve configuration (invariants in
//! `digiview::app::checks::text_files`).
#![no_main]

use digiview::cli::locate::built_in_lens_cal;
use digiview::lens::LensCal;
use libfuzzer_sys::fuzz_target;
use std::sync::LazyLock;

static CAL: LazyLock<LensCal> = LazyLock::new(built_in_lens_cal);

fuzz_target!(|data: &[u8]| digiview::app::checks::text_files(&CAL, data));
