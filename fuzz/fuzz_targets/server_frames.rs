//! The server's frame handling on any stream of frames, from a fresh live state each run
//! (invariants in `digiview::control::checks::handle_stream`).
#![no_main]

use digiview::cli::locate::built_in_lens_cal;
use digiview::control::checks::{controller, handle_stream};
use digiview::lens::LensCal;
use libfuzzer_sys::fuzz_target;
use std::sync::LazyLock;

static CAL: LazyLock<LensCal> = LazyLock::new(built_in_lens_cal);

fuzz_target!(|data: &[u8]| handle_stream(&controller(&CAL), data));
