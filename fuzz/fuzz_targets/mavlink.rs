//! MAVLink messages into DigiView's link, its cameras and gimbals (invariants in
//! `digiview::app::checks::mavlink_messages`; the bytes' layout in `digiview::autopilot::checks`).
#![no_main]

use digiview::app::checks::{mavlink_bench, mavlink_messages};
use digiview::cli::locate::built_in_lens_cal;
use digiview::lens::LensCal;
use libfuzzer_sys::fuzz_target;
use std::sync::LazyLock;

static CAL: LazyLock<LensCal> = LazyLock::new(built_in_lens_cal);

fuzz_target!(|data: &[u8]| mavlink_messages(&mut mavlink_bench(&CAL), data));
