//! Stills read as mapping software checks them: with exiftool, an independent reader
//! (scripts/setup.sh installs libimage-exiftool-perl).

use serde_json::Value;
use std::path::Path;
use std::process::Command;

/// exiftool's reading of each file: every tag, numbers as numbers, keyed by group and name
/// (`SourceFile` says which file).
pub fn read(files: &[&Path]) -> Vec<Value> {
    let out = Command::new("exiftool")
        .args(["-j", "-n", "-G1"])
        .args(files)
        .output()
        .expect("exiftool runs (scripts/setup.sh installs libimage-exiftool-perl)");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    match serde_json::from_slice(&out.stdout).unwrap() {
        Value::Array(all) => all,
        other => panic!("{other}"),
    }
}

/// exiftool's reading of one JPEG's bytes.
pub fn read_jpeg(jpeg: &[u8]) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("still.jpg");
    std::fs::write(&path, jpeg).unwrap();
    read(&[&path]).remove(0)
}

/// A tag's number: exiftool gives XMP's signed texts ("+30.0000", as DJI writes them) as
/// text.
pub fn number(tags: &Value, key: &str) -> f64 {
    let v = &tags[key];
    v.as_f64()
        .or_else(|| v.as_str().and_then(|s| s.parse().ok()))
        .unwrap_or_else(|| panic!("no {key} in {tags:#}"))
}
