//! Replays the committed fuzz corpus (`fuzz/corpus`, grown by `scripts/fuzz.sh`) through the
//! same invariants the fuzz targets assert, so every input the fuzzer found interesting stays
//! a regression test on stable Rust.

use crate::common;
use digiview::control::checks;
use std::path::Path;

fn corpus(target: &str) -> Vec<Vec<u8>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus")
        .join(target);
    let inputs: Vec<Vec<u8>> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| std::fs::read(e.unwrap().path()).unwrap())
        .collect();
    assert!(inputs.len() >= 20, "{} holds a corpus", dir.display());
    inputs
}

#[test]
fn the_decoder_corpus_holds_its_invariants() {
    for input in corpus("decode") {
        checks::decode(&input);
    }
}

#[test]
fn the_server_frames_corpus_holds_its_invariants() {
    let cal = common::lens_cal();
    for input in corpus("server_frames") {
        checks::handle_stream(&checks::controller(&cal), &input);
    }
}

#[test]
fn the_mavlink_corpus_holds_its_invariants() {
    let cal = common::lens_cal();
    for input in corpus("mavlink") {
        digiview::app::checks::mavlink_messages(
            &mut digiview::app::checks::mavlink_bench(&cal),
            &input,
        );
    }
}

#[test]
fn the_web_bodies_corpus_holds_its_invariants() {
    let cal = common::lens_cal();
    for input in corpus("web_bodies") {
        digiview::http::checks::put_body(&std::sync::Arc::new(checks::controller(&cal)), &input);
    }
}

#[test]
fn the_text_files_corpus_holds_its_invariants() {
    let cal = common::lens_cal();
    for input in corpus("text_files") {
        digiview::app::checks::text_files(&cal, &input);
    }
}

#[test]
fn the_external_lines_corpus_holds_its_invariants() {
    for input in corpus("external_lines") {
        if let Ok(line) = std::str::from_utf8(&input) {
            let _ = digiview::detect::external::parse(line);
        }
    }
}
