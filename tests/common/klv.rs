//! KLV metadata as its readers see it: an MPEG-TS stream recorded by FFmpeg, its data stream
//! extracted by FFmpeg, and the packets read by klvdata (tests/peers/klv_read.py, on the
//! project's Python).

use super::peers::python;
use serde_json::Value;
use std::path::Path;
use std::process::Command;

/// Records `secs` seconds of the MPEG-TS at `url` into `ts` with FFmpeg (stream copy).
pub fn record_ts(url: &str, secs: u32, ts: &Path) {
    let out = Command::new("timeout")
        .args(["30", "ffmpeg", "-loglevel", "error", "-y", "-i", url])
        .args([
            "-t",
            &secs.to_string(),
            "-map",
            "0",
            "-c",
            "copy",
            "-f",
            "mpegts",
        ])
        .arg(ts)
        .output()
        .unwrap();
    let why = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "recording {url}: {why}");
}

/// The packets of `ts`'s KLV data stream, extracted by FFmpeg and read by klvdata: one JSON
/// object each (its tags in order, whether its checksum holds, its values).
pub fn read_ts(ts: &Path) -> Vec<Value> {
    let klv = ts.with_extension("klv");
    let out = Command::new("ffmpeg")
        .args(["-loglevel", "error", "-y", "-i"])
        .arg(ts)
        .args(["-map", "0:d", "-c", "copy", "-f", "data"])
        .arg(&klv)
        .output()
        .unwrap();
    let why = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "extracting the KLV: {why}");
    klvdata(&klv)
}

/// The packets in file `path`, as klvdata reads them.
pub fn klvdata(path: &Path) -> Vec<Value> {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/peers/klv_read.py");
    let out = Command::new(python())
        .arg(script)
        .arg(path)
        .output()
        .unwrap();
    let why = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{why}");
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Tag `tag`'s value in a packet klvdata read.
pub fn value(packet: &Value, tag: u32) -> f64 {
    packet["values"][tag.to_string()]
        .as_f64()
        .unwrap_or_else(|| panic!("tag {tag} missing: {packet}"))
}
