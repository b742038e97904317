//! A disk that fills during a recording, as the operator sees it: the recording stops and its
//! file plays to its end; SYSTEM_STATUS says error 6 (capture) over the DigiView protocol,
//! `/api/status` says why, the page shows it, ground stations (the `mavlink` crate's and
//! pymavlink's) get the STATUSTEXT; new captures are refused
//! with the reason and leave no empty file; once space is freed, recording works again and
//! the status is back to running. The disk is a real one: a tmpfs of a few MB, mounted for
//! the test (CI runs as root, as this test needs), with a filler file taking most of it.

use crate::common;
use common::wait_status;

use common::autopilot::free_udp_port;
use common::browser::Browser;
use common::gcs::{Gcs, http_get, text};
use common::peers::LinePeer;
use common::serve::{CaptureConfig, Serve};
use digiview::control::client::Client;
use digiview::protocol::Param;
use digiview::protocol::params::Capture;
use mavlink::dialects::common::{MavMessage, MavSeverity};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;
use tokio::runtime::Runtime;

/// A tmpfs of `mb` MB mounted on a directory of the test's, unmounted when dropped.
struct Tmpfs {
    dir: PathBuf,
    _parent: tempfile::TempDir,
}

impl Tmpfs {
    fn mount(mb: u32) -> Tmpfs {
        let parent = tempfile::tempdir().unwrap();
        let dir = parent.path().join("captures");
        std::fs::create_dir(&dir).unwrap();
        let size = format!("size={mb}m");
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &size, "tmpfs"])
            .arg(&dir)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "mounting a {mb} MB tmpfs needs root: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        Tmpfs {
            dir,
            _parent: parent,
        }
    }

    /// A file of `mb` MB taking that much of the disk.
    fn fill(&self, mb: usize) -> PathBuf {
        let path = self.dir.join("filler");
        std::fs::write(&path, vec![1u8; mb << 20]).unwrap();
        path
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.dir).status();
    }
}

/// `serve` on the demo at 640x480, its captures on `disk` keeping `min_free_mb`, its
/// MAVLink link on a free port (returned) with a ground station on it.
fn serve(disk: &Tmpfs, min_free_mb: u32) -> (Serve, Client, Gcs, CaptureConfig, u16) {
    let config = CaptureConfig::new(
        "[encoder]\nbitrate_kbps = 6000\n",
        &format!("min_free_mb = {min_free_mb}\n"),
    );
    let text = std::fs::read_to_string(config.path()).unwrap();
    let text = text.replace(
        &format!("{:?}", config.captures),
        &format!("{:?}", disk.dir),
    );
    std::fs::write(config.path(), text).unwrap();
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    let serve = Serve::start_video(&[
        "--config",
        config.path(),
        "--demo-size",
        "960x540",
        "--size",
        "640x480",
        "--mavlink",
        &link,
    ]);
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    wait_status(&mut ctl, (1, 0), Duration::from_secs(20));
    let gcs = Gcs::connect(port);
    gcs.wait_for(Duration::from_secs(5), |_, m| {
        matches!(m, MavMessage::HEARTBEAT(_)).then_some(())
    })
    .expect("DigiView's heartbeat");
    (serve, ctl, gcs, config, port)
}

fn capture(ctl: &mut Client, flags: u8) -> Result<(), String> {
    ctl.set(Param::Capture(Capture {
        flags,
        ..Default::default()
    }))
    .map_err(|e| e.to_string())
}

fn recording(ctl: &mut Client) -> bool {
    match ctl.get_one(digiview::protocol::ParamType::Capture.zeroed()) {
        Ok(Param::Capture(c)) => c.flags & 2 != 0,
        other => panic!("{other:?}"),
    }
}

/// The recordings on `dir`, oldest first.
fn videos(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "mp4"))
        .collect();
    v.sort();
    v
}

/// A recording's frame count, after FFmpeg decoded it whole without a complaint (ffprobe
/// decoding every frame: a file cut mid-fragment says "partial file").
fn plays(path: &Path) -> u64 {
    let out = Command::new("ffprobe")
        .args(["-v", "error", "-count_frames", "-select_streams", "v:0"])
        .args(["-show_entries", "stream=nb_read_frames", "-of", "csv=p=0"])
        .arg(path)
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && said.trim().is_empty(),
        "{} does not play cleanly: {said}",
        path.display()
    );
    String::from_utf8_lossy(&out.stdout).trim().parse().unwrap()
}

/// The STATUSTEXT heard within `limit` holding `words`, and its severity.
fn told(gcs: &Gcs, words: &str, limit: Duration) -> MavSeverity {
    gcs.wait_for(limit, |_, m| match m {
        MavMessage::STATUSTEXT(t) if text(&t.text[..]).contains(words) => Some(t.severity),
        _ => None,
    })
    .unwrap_or_else(|| panic!("no STATUSTEXT saying {words:?}"))
}

/// What `/api/status` says of the captures.
fn api_capture(serve: &Serve) -> serde_json::Value {
    let url = format!("{}api/status", serve.http.as_ref().unwrap());
    let (code, body) = http_get(&url);
    assert_eq!(code, 200);
    serde_json::from_slice::<serde_json::Value>(&body).unwrap()["capture"].clone()
}

/// The page's status line and its capture row (the text, and whether it is shown as a
/// fault), once the status line starts with `status`.
fn page_shows(rt: &Runtime, b: &Browser, status: &str) -> serde_json::Value {
    rt.block_on(b.until_with(
        &format!("the page saying {status:?}"),
        Duration::from_secs(5),
        "const s = document.getElementById('status').textContent;
         if (!s.startsWith(arguments[0])) return null;
         const row = [...document.querySelectorAll('#figures dt')]
           .find((d) => d.textContent === 'capture');
         const dd = row ? row.nextElementSibling : null;
         return {status: s, capture: dd && dd.textContent, bad: dd && dd.classList.contains('bad')};",
        vec![json!(status)],
    ))
}

#[test]
fn a_disk_that_fills_stops_the_recording_playable_says_why_and_records_again_once_freed() {
    let disk = Tmpfs::mount(4);
    let filler = disk.fill(2);
    // Nothing kept free: the disk itself runs out under the recording.
    let (serve, mut ctl, gcs, _config, port) = serve(&disk, 0);
    // A second ground station, written with pymavlink, hears the same words.
    let (mut station, ready) = LinePeer::start("statustext_station.py", &[&port.to_string()]);
    assert_eq!(ready["ready"], true, "{ready}");
    capture(&mut ctl, 2).unwrap();
    wait_status(&mut ctl, (3, 6), Duration::from_secs(30));
    assert!(!recording(&mut ctl), "still recording on a full disk");
    assert_eq!(
        told(
            &gcs,
            "DigiView: the recording stopped",
            Duration::from_secs(3)
        ),
        MavSeverity::MAV_SEVERITY_ERROR
    );
    let heard = station.ask(&json!({"wait": "DigiView: the recording stopped", "for": 3}));
    assert_eq!(
        heard["text"], "DigiView: the recording stopped: disk full",
        "{heard}"
    );
    assert_eq!(heard["severity"], "MAV_SEVERITY_ERROR", "{heard}");
    let why = api_capture(&serve);
    assert_eq!(why["brief"], "the recording stopped: disk full", "{why}");
    assert!(why["why"].as_str().unwrap().contains("is kept"), "{why}");
    // The page, opened now, shows the fault and why, in red.
    let rt = Runtime::new().unwrap();
    let b = rt.block_on(Browser::start(1024, 768));
    rt.block_on(b.client.goto(serve.http.as_deref().unwrap()))
        .unwrap();
    let page = page_shows(&rt, &b, "error (capture)");
    assert_eq!(page["capture"], why["why"], "{page}");
    assert_eq!(page["bad"], true, "{page}");
    let first = videos(&disk.dir);
    assert_eq!(first.len(), 1, "{first:?}");
    let frames = plays(&first[0]);
    assert!(frames >= 10, "{frames} frames kept");

    // Full: a recording or a still is refused, saying so, and leaves no file.
    for flags in [2, 1] {
        let refused = capture(&mut ctl, flags).unwrap_err();
        assert!(refused.contains("is full"), "{refused}");
    }
    std::thread::sleep(Duration::from_millis(500));
    assert_eq!(videos(&disk.dir), first, "a refused capture left a file");
    assert_eq!(std::fs::read_dir(&disk.dir).unwrap().count(), 2);

    // Space freed: recording works again and the status is back to running.
    std::fs::remove_file(filler).unwrap();
    capture(&mut ctl, 2).unwrap();
    wait_status(&mut ctl, (1, 0), Duration::from_secs(2));
    assert_eq!(api_capture(&serve), serde_json::Value::Null);
    assert_eq!(
        told(&gcs, "DigiView: running again", Duration::from_secs(3)),
        MavSeverity::MAV_SEVERITY_INFO
    );
    let heard = station.ask(&json!({"wait": "DigiView: running again", "for": 3}));
    assert_eq!(heard["severity"], "MAV_SEVERITY_INFO", "{heard}");
    // The page, kept open, says so without a reload: running, and no capture row.
    let page = page_shows(&rt, &b, "running");
    assert_eq!(page["capture"], serde_json::Value::Null, "{page}");
    rt.block_on(b.close());
    std::thread::sleep(Duration::from_millis(1500));
    capture(&mut ctl, 0).unwrap();
    let now = videos(&disk.dir);
    assert_eq!(now.len(), 2, "{now:?}");
    assert!(plays(&now[1]) >= 10);
}

#[test]
fn with_space_kept_free_the_recording_ends_cleanly_before_the_disk_is_full() {
    let disk = Tmpfs::mount(5);
    let _filler = disk.fill(2);
    let (serve, mut ctl, gcs, _config, _) = serve(&disk, 2);
    capture(&mut ctl, 2).unwrap();
    wait_status(&mut ctl, (3, 6), Duration::from_secs(30));
    told(
        &gcs,
        "the recording stopped: disk full",
        Duration::from_secs(3),
    );
    let why = api_capture(&serve)["why"].as_str().unwrap().to_string();
    assert!(why.contains("under the 2 MB kept free"), "{why}");
    assert!(
        why.ends_with("is kept"),
        "the file was cut, not ended: {why}"
    );
    let kept = videos(&disk.dir);
    assert_eq!(kept.len(), 1);
    assert!(plays(&kept[0]) >= 10);
    // The check is four times a second: what came in meanwhile (a quarter of a second at
    // 6 Mb/s, 0.2 MB) may take from the space kept, no more.
    let free = rustix::fs::statvfs(&disk.dir).unwrap();
    let free_mb = (free.f_bavail * free.f_frsize) as f64 / (1 << 20) as f64;
    assert!(
        free_mb >= 1.75,
        "{free_mb:.2} MB left of the 2 MB kept free"
    );
}
