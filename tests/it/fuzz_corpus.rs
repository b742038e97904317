//! Replays the committed fuzz corpus (`fuzz/corpus`) through the same invariants the fuzz
//! targets assert, so every input the fuzzer found interesting stays a regression test.

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
