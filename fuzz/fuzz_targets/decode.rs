//! The codec on any bytes (invariants in `digiview::control::checks::decode`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| digiview::control::checks::decode(data));
