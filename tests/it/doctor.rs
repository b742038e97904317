//! `digiview doctor` on this machine: every check passes with a working configuration (a
//! simulated autopilot speaking real MAVLink on the configured endpoint), and each check fails
//! with its own message when its piece is taken away: a broken lens.cal, a GStreamer plugin
//! removed from the registry, a port another program holds, no autopilot.

use crate::common;

use common::autopilot::{SimAutopilot, free_udp_port};
use glam::DVec3;
use gstreamer as gst;
use gstreamer::prelude::PluginFeatureExt;
use std::net::TcpListener;
use std::path::Path;
use std::process::Command;

/// Runs `digiview doctor` with `config` (TOML), `args` and `env`: exit code and the lines it
/// printed.
pub(crate) fn doctor(
    dir: &Path,
    config: &str,
    args: &[&str],
    env: &[(&str, &str)],
) -> (i32, Vec<String>) {
    let path = dir.join("digiview.toml");
    std::fs::write(&path, config).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args(["doctor", "--config"])
        .arg(&path)
        .args(args)
        .env("DIGIVIEW_LENS_CAL", common::lens_cal_path())
        .envs(env.iter().copied())
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    println!("{text}{}", String::from_utf8_lossy(&out.stderr));
    (
        out.status.code().unwrap_or(-1),
        text.lines().map(String::from).collect(),
    )
}

/// A configuration that passes: ports the system picks, captures in `dir`, the autopilot
/// link on `mavlink`.
pub(crate) fn good_config(dir: &Path, mavlink: &str) -> String {
    format!(
        "[control]\nlisten = \"127.0.0.1:0\"\n[rtsp]\nport = 0\n[http]\nlisten = \"127.0.0.1:0\"\n\
         [mavlink]\nendpoint = \"{mavlink}\"\n[capture]\ndir = \"{}\"\n",
        dir.join("captures").display()
    )
}

/// The checks that failed, by name.
fn failed(lines: &[String]) -> Vec<String> {
    lines
        .iter()
        .filter_map(|l| l.strip_prefix("FAIL  "))
        .map(|l| l.split_whitespace().next().unwrap().to_string())
        .collect()
}

fn hover(_: f64) -> DVec3 {
    DVec3::ZERO
}

#[test]
fn every_check_passes_here_with_an_autopilot_on_the_link() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_udp_port();
    let _autopilot = SimAutopilot::start(&format!("udpout:127.0.0.1:{port}"), hover);
    let config = good_config(dir.path(), &format!("udpin:127.0.0.1:{port}"));
    let (code, lines) = doctor(dir.path(), &config, &[], &[]);
    assert_eq!(failed(&lines), Vec::<String>::new());
    assert_eq!(code, 0);
    let names: Vec<&str> = lines
        .iter()
        .filter_map(|l| l.strip_prefix("ok    "))
        .map(|l| l.split_whitespace().next().unwrap())
        .collect();
    for name in [
        "config",
        "lens.cal",
        "gpu",
        "gstreamer",
        "source",
        "ports",
        "mavlink",
        "disk",
    ] {
        assert!(names.contains(&name), "{name} not checked: {lines:?}");
    }
    assert!(
        lines.iter().any(|l| l.contains("HEARTBEAT from system 1")),
        "{lines:?}"
    );
    assert!(
        lines.last().unwrap().starts_with("all 12 checks passed"),
        "{lines:?}"
    );
}

#[test]
fn a_broken_lens_cal_fails_its_check_and_says_where() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("lens.cal");
    std::fs::write(&bad, "[[lens]]\nname = \"X\"\nlens_id = 0\nmodel = ").unwrap();
    let config = good_config(dir.path(), "off");
    let (code, lines) = doctor(
        dir.path(),
        &config,
        &["--lens-cal", bad.to_str().unwrap()],
        &[],
    );
    assert_ne!(code, 0);
    let line = lines
        .iter()
        .find(|l| l.starts_with("FAIL  lens.cal"))
        .expect("lens.cal fails");
    assert!(line.contains(bad.to_str().unwrap()), "{line}");
    assert!(
        failed(&lines)
            .iter()
            .all(|f| f == "lens.cal" || f == "source"),
        "{lines:?}"
    );
}

#[test]
fn a_missing_gstreamer_element_names_the_package_to_install() {
    let dir = tempfile::tempdir().unwrap();
    // Every plugin of the system's folder but x264's, in a registry of its own.
    gst::init().unwrap();
    let x264 = gst::ElementFactory::find("x264enc")
        .unwrap()
        .plugin()
        .unwrap();
    let x264 = x264.filename().unwrap();
    let plugins = dir.path().join("plugins");
    std::fs::create_dir(&plugins).unwrap();
    for entry in std::fs::read_dir(x264.parent().unwrap()).unwrap() {
        let from = entry.unwrap().path();
        if from != x264 {
            std::os::unix::fs::symlink(&from, plugins.join(from.file_name().unwrap())).unwrap();
        }
    }
    let registry = dir.path().join("registry.bin");
    let config = good_config(dir.path(), "off");
    let (code, lines) = doctor(
        dir.path(),
        &config,
        &[],
        &[
            ("GST_PLUGIN_SYSTEM_PATH_1_0", plugins.to_str().unwrap()),
            ("GST_PLUGIN_PATH_1_0", ""),
            ("GST_PLUGIN_PATH", ""),
            ("GST_REGISTRY_1_0", registry.to_str().unwrap()),
        ],
    );
    assert_ne!(code, 0);
    assert_eq!(failed(&lines), ["gstreamer"]);
    let line = lines
        .iter()
        .find(|l| l.starts_with("FAIL  gstreamer"))
        .unwrap();
    assert!(
        line.contains("x264enc (install gstreamer1.0-plugins-ugly)"),
        "{line}"
    );
}

#[test]
fn a_taken_port_and_a_silent_autopilot_each_fail_their_check() {
    let dir = tempfile::tempdir().unwrap();
    let holder = TcpListener::bind("127.0.0.1:0").unwrap();
    let taken = holder.local_addr().unwrap().to_string();
    let silent = format!("udpin:127.0.0.1:{}", free_udp_port());
    let config = good_config(dir.path(), &silent);
    let (code, lines) = doctor(dir.path(), &config, &["--control", &taken], &[]);
    assert_ne!(code, 0);
    assert_eq!(failed(&lines), ["ports", "mavlink"]);
    let line = lines.iter().find(|l| l.starts_with("FAIL  ports")).unwrap();
    assert!(
        line.contains(&format!("control tcp {taken}: taken by another program")),
        "{line}"
    );
    let line = lines
        .iter()
        .find(|l| l.starts_with("FAIL  mavlink"))
        .unwrap();
    assert!(line.contains("no HEARTBEAT within 3 s"), "{line}");
}
