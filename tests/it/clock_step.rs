//! The system clock set an hour forward and then back under a running head, for its process
//! alone (libfaketime preloaded, its offset read from a file the test rewrites; the monotonic
//! clock untouched, as a clock set by NTP or GPS leaves it): the stream goes on, and the times
//! DigiView gives never go back: the control protocol's frame times, the KLV metadata's,
//! CAMERA_IMAGE_CAPTURED's time_utc, the recordings' names; the recording across both steps
//! (MPEG-TS) plays whole and its KLV time stamps, read by klvdata, follow the step forward and
//! never go back.

use crate::common;

use common::gcs::{Gcs, cameras, http_get, image_capture};
use common::klv::{read_ts, value};
use common::serve::{Serve, with_stills_env};
use common::viewer::Viewer;
use digiview::control::client::Client;
use digiview::protocol::params::Capture;
use digiview::protocol::{Body, Param, ParamType};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Where Debian's libfaketime is, whatever the architecture.
fn libfaketime() -> PathBuf {
    std::fs::read_dir("/usr/lib")
        .unwrap()
        .map(|e| e.unwrap().path().join("faketime/libfaketime.so.1"))
        .find(|p| p.exists())
        .expect("libfaketime (scripts/setup.sh installs it)")
}

/// The times DigiView gives at one moment, µs since 1970.
#[derive(Debug, Clone, Copy)]
struct Times {
    frame: u64,
    klv: u64,
    image: u64,
}

struct Head {
    serve: Serve,
    ctl: Client,
    gcs: Gcs,
    camera: (u8, u8),
    viewer: Viewer,
}

impl Head {
    fn times(&mut self) -> Times {
        let reply = self
            .ctl
            .request(Body::Get(ParamType::SystemStatus.zeroed()))
            .unwrap();
        // The KLV metadata comes once the demo's flight has given a position.
        let url = format!("{}api/status", self.serve.http.as_ref().unwrap());
        let t = Instant::now();
        let klv = loop {
            let status: serde_json::Value = serde_json::from_slice(&http_get(&url).1).unwrap();
            if let Some(us) = status["video"]["klv"]["time_us"].as_u64() {
                break us;
            }
            assert!(t.elapsed() < Duration::from_secs(5), "no KLV: {status}");
            std::thread::sleep(Duration::from_millis(100));
        };
        let image = image_capture(&self.gcs, self.camera, 1, 0.0)[0].time_utc;
        Times {
            frame: reply[0].timestamp,
            klv,
            image,
        }
    }

    /// Frames keep coming: one decoded within a second, after `what`.
    fn streams(&self, what: &str) {
        let t = Instant::now();
        self.viewer.fresh_frame();
        assert!(
            t.elapsed() < Duration::from_secs(1),
            "the stream stalled {what}"
        );
    }
}

/// The times once each has moved from `was` by seconds within `range`, within 5 s (the last
/// frame's KLV comes with the next frame).
fn moved(head: &mut Head, was: Times, range: std::ops::Range<f64>, when: &str) -> Times {
    let t = Instant::now();
    loop {
        let now = head.times();
        let off = [
            (was.frame, now.frame, "frame time"),
            (was.klv, now.klv, "KLV time"),
            (was.image, now.image, "time_utc"),
        ]
        .into_iter()
        .map(|(was, now, what)| (now as f64 / 1e6 - was as f64 / 1e6, what))
        .find(|(moved, _)| !range.contains(moved));
        let Some((moved, what)) = off else {
            return now;
        };
        assert!(
            t.elapsed() < Duration::from_secs(5),
            "{what} moved {moved:.1} s {when}"
        );
    }
}

fn capture(ctl: &mut Client, flags: u8) {
    ctl.set(Param::Capture(Capture {
        flags,
        ..Default::default()
    }))
    .unwrap();
}

fn recordings(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".ts"))
        .collect();
    names.sort();
    names
}

/// Sets the process's clock `ahead_s` seconds from the real one (libfaketime reads the file at
/// every call: every thread sees it at once). A step forward is awaited on the web server's
/// Date header; one back cannot be (hyper's cached Date waits for the clock to pass its next
/// second again), and needs no wait.
fn set_clock(file: &Path, serve: &Serve, ahead_s: i64) {
    std::fs::write(file, format!("{ahead_s:+}")).unwrap();
    if ahead_s <= 0 {
        return;
    }
    let t = Instant::now();
    loop {
        let off = (process_ahead_s(serve) - ahead_s).rem_euclid(86_400);
        if off <= 2 || off >= 86_398 {
            return;
        }
        assert!(
            t.elapsed() < Duration::from_secs(10),
            "the process's clock is {} s ahead, not {ahead_s}",
            process_ahead_s(serve)
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// How far the process's system clock is ahead of the real one, seconds within a day, as its
/// web server's Date header gives it (to the second).
fn process_ahead_s(serve: &Serve) -> i64 {
    use std::io::{Read, Write};
    let url = serve.http.as_ref().unwrap();
    let addr = url.trim_start_matches("http://").trim_end_matches('/');
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    write!(
        s,
        "GET /api/lenses HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut reply = String::new();
    s.read_to_string(&mut reply).unwrap();
    // date: Fri, 27 Nov 2026 13:20:05 GMT
    let date = reply
        .lines()
        .find_map(|l| {
            l.to_ascii_lowercase()
                .strip_prefix("date: ")
                .map(String::from)
        })
        .unwrap_or_else(|| panic!("no Date header: {reply}"));
    let hms: Vec<i64> = date
        .split(' ')
        .nth(4)
        .unwrap()
        .split(':')
        .map(|x| x.parse().unwrap())
        .collect();
    let theirs = hms[0] * 3600 + hms[1] * 60 + hms[2];
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap();
    (theirs - (now.as_secs() % 86_400) as i64).rem_euclid(86_400)
}

#[test]
fn the_clock_set_an_hour_forward_and_back_leaves_every_time_going_forward() {
    let dir = tempfile::tempdir().unwrap();
    let clock = dir.path().join("faketime");
    std::fs::write(&clock, "+0").unwrap();
    let lib = libfaketime();
    let env = [
        ("LD_PRELOAD", lib.to_str().unwrap()),
        ("FAKETIME_TIMESTAMP_FILE", clock.to_str().unwrap()),
        // Read at every call, so every thread sees a step at once, as with a real clock.
        ("FAKETIME_NO_CACHE", "1"),
        ("FAKETIME_DONT_FAKE_MONOTONIC", "1"),
    ];
    let (config, serve, port) = with_stills_env(&[], None, &env, "container = \"ts\"\n");
    let ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    let gcs = Gcs::connect(port);
    let (system, ids) = cameras(&gcs);
    let viewer = Viewer::open(serve.rtsp.as_deref().unwrap());
    let mut head = Head {
        serve,
        ctl,
        gcs,
        camera: (system, *ids.first().unwrap()),
        viewer,
    };
    // The first frame (the client's set-up and first key frame) before anything is timed.
    head.viewer.frame();
    capture(&mut head.ctl, 2);
    let recording = Instant::now();
    let before = head.times();

    set_clock(&clock, &head.serve, 3600);
    head.streams("once the clock went forward");
    // Forward is followed.
    let forward = "with the clock set an hour forward";
    let ahead = moved(&mut head, before, 3600.0..3620.0, forward);

    set_clock(&clock, &head.serve, 0);
    head.streams("once the clock went back");
    moved(
        &mut head,
        ahead,
        0.0..20.0,
        "with the clock set an hour back",
    );

    // The recording across both steps plays whole; the next one's name sorts after it.
    capture(&mut head.ctl, 0);
    let seconds = recording.elapsed().as_secs_f64();
    capture(&mut head.ctl, 2);
    std::thread::sleep(Duration::from_millis(1500));
    capture(&mut head.ctl, 0);
    let names = recordings(&config.captures);
    assert_eq!(names.len(), 2, "{names:?}");
    let first = config.captures.join(&names[0]);
    let (n, _) = common::probe_frames(&first);
    let fps = n as f64 / seconds;
    assert!(fps > 5.0, "{n} frames in {seconds:.1} s of recording");
    // Its KLV, as klvdata reads it: the step forward followed once, never a step back.
    let stamps: Vec<f64> = read_ts(&first).iter().map(|p| value(p, 2)).collect();
    assert!(
        stamps.len() as f64 > seconds * 2.0,
        "{} KLV packets",
        stamps.len()
    );
    let steps: Vec<f64> = stamps.windows(2).map(|w| (w[1] - w[0]) / 1e6).collect();
    let back = steps.iter().copied().fold(f64::INFINITY, f64::min);
    // (Two packets of one camera frame, drawn again for a new attitude, share its time.)
    assert!(back >= 0.0, "a KLV time went back by {:.3} s", -back);
    let forward = steps.iter().filter(|&&s| s > 60.0).count();
    let largest = steps.iter().copied().fold(0.0, f64::max);
    assert_eq!(forward, 1, "KLV time steps over a minute: {steps:?}");
    assert!(
        (3598.0..3602.0).contains(&largest),
        "the step forward was {largest:.1} s"
    );
}
