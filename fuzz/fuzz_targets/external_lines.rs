//! The external detector's JSON lines: any bytes are read or refused, never a panic.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok(line) = std::str::from_utf8(data) {
        let _ = digiview::detect::external::parse(line);
    }
});
