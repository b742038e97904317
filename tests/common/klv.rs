//! KLV metadata as its readers see it: an MPEG-TS stream recorded by FFmpeg, its data stream
//! extracted by FFmpeg, and the packets read by klvdata (tests/peers/klv_read.py) and by
//! stanag4609, which also reads the ST 0903 VMTI nested in them (tests/peers/misb_read.py),
//! both on the project's Python.

use super::peers::python;
use digiview::geometry::GeoPosition;
use glam::DVec2;
use serde_json::Value;
use std::path::Path;
use std::process::Command;

/// Where the KLV tests put the vehicle: 120 m over home, 620 m above sea level.
pub const POSITION: GeoPosition = GeoPosition {
    lat: 47.397,
    lon: 8.546,
    alt: 620.0,
    relative_alt: 120.0,
};

/// Metres between two points `(lat, lon)` a few hundred metres apart.
pub fn metres((lat, lon): (f64, f64), (lat2, lon2): (f64, f64)) -> f64 {
    let north = (lat - lat2) * 111_320.0;
    let east = (lon - lon2) * 111_320.0 * lat.to_radians().cos();
    north.hypot(east)
}

/// A pixel number of ST 0903 (from 1, along rows of `width`) as (x, y).
pub fn pixel(n: &Value, width: u64) -> DVec2 {
    let n = n.as_u64().unwrap() - 1;
    DVec2::new((n % width) as f64, (n / width) as f64)
}

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
    klvdata(&extract(ts))
}

/// `ts`'s KLV data stream, extracted by FFmpeg into a file beside it.
pub fn extract(ts: &Path) -> std::path::PathBuf {
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
    klv
}

/// The packets in file `path`, as klvdata reads them.
pub fn klvdata(path: &Path) -> Vec<Value> {
    read_with("klv_read.py", path)
}

/// The packets in file `path`, as stanag4609 reads them: each packet's tags and values, and
/// its VMTI set (`vmti`: `fields`, `ontologies`, `targets`), or `error` where it refused it.
pub fn misb(path: &Path) -> Vec<Value> {
    read_with("misb_read.py", path)
}

/// The JSON lines tests/peers/`script` prints for `path`.
fn read_with(script: &str, path: &Path) -> Vec<Value> {
    let script = format!("{}/tests/peers/{script}", env!("CARGO_MANIFEST_DIR"));
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
