//! The frame loop runs without a server: in place of the RTSP server, a fake viewer
//! (`head::Clients`) keeps the access units it is handed and says that one view alone is
//! watched. With the demo as the source, the composed stream and that view's own stream
//! decode (FFmpeg) to pictures of the output's and the views' size; the views nobody watches
//! are not encoded; the status runs while frames flow and says finished once stopped.

use crate::common;

use digiview::app::Config;
use digiview::head::capture::Capture;
use digiview::head::{Clients, Head, HeadParts};
use digiview::policy::{Permissions, Policy};
use digiview::state::{Gate, LiveSettings, Report, RunStatus, Sensed, State};
use digiview::telemetry::Telemetry;
use gstreamer as gst;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The view the fake viewer watches.
const WATCHED: usize = 2;

/// What the fake viewer was handed: each stream's H.264 byte stream, and its units.
#[derive(Default)]
struct Viewer {
    composed: Stream,
    views: [Stream; 4],
}

type Stream = Mutex<(Vec<u8>, usize)>;

fn keep(stream: &Stream, unit: &gst::Buffer) {
    let map = unit.map_readable().expect("an access unit is readable");
    let mut stream = stream.lock().unwrap();
    stream.0.extend_from_slice(map.as_slice());
    stream.1 += 1;
}

impl Clients for Viewer {
    fn push(&self, unit: &gst::Buffer) {
        keep(&self.composed, unit)
    }
    fn push_view(&self, i: usize, unit: &gst::Buffer) {
        keep(&self.views[i], unit)
    }
    fn view_watched(&self, i: usize) -> bool {
        i == WATCHED
    }
    fn view_key_wanted(&self, _: usize) -> bool {
        false
    }
    fn clients(&self) -> usize {
        1
    }
}

/// The head on the demo (640x480 camera), a 640x480 composed frame, 320x240 views.
fn head(viewer: Arc<Viewer>) -> Arc<Head> {
    let mut cfg = Config::default();
    (cfg.demo.width, cfg.demo.height) = (640, 480);
    (cfg.cameras.width, cfg.cameras.height) = (320, 240);
    let mut state = State::default();
    (state.settings.output.width, state.settings.output.height) = (640, 480);
    let settings = LiveSettings::new(state.settings, &common::lens_cal()).expect("valid");
    let sensed = Sensed::new(state.vehicle, state.tracked);
    let policy = Arc::new(Policy::new(Permissions::default()));
    let report = Arc::<Report>::default();
    let parts = HeadParts {
        gate: Arc::new(Gate::new(Arc::new(settings), Arc::new(sensed), policy)),
        report: report.clone(),
        capture: Arc::new(Capture::new(cfg.capture.clone(), report)),
        clients: viewer,
        publishers: vec![],
        view_publishers: Default::default(),
        view_key_wanted: Default::default(),
        telemetry: Arc::new(Telemetry::new(cfg.mavlink.attitude_sample)),
        key_wanted: Default::default(),
        demo_autopilot: None,
        thermal: None,
    };
    Head::new(cfg.head().expect("the default configuration"), parts)
}

/// FFmpeg's count of frames in an H.264 byte stream, and their size.
fn decoded(dir: &std::path::Path, name: &str, stream: &Stream) -> (u64, String) {
    let path = dir.join(format!("{name}.h264"));
    std::fs::write(&path, &stream.lock().unwrap().0).unwrap();
    common::probe_frames(&path)
}

#[test]
fn the_frame_loop_feeds_a_fake_viewer_the_composed_stream_and_the_watched_view_alone() {
    let viewer = Arc::new(Viewer::default());
    let head = head(viewer.clone());
    let running = head.clone();
    let thread = std::thread::spawn(move || running.run());
    let deadline = Instant::now() + Duration::from_secs(60);
    let units = |s: &Stream| s.lock().unwrap().1;
    // Some units of both streams (their rate is the benchmarks' business).
    let mut running_seen = false;
    while units(&viewer.composed) < 20 || units(&viewer.views[WATCHED]) < 10 {
        assert!(Instant::now() < deadline, "no stream within 60 s");
        running_seen |= head.report.status() == RunStatus::Running;
        std::thread::sleep(Duration::from_millis(50));
    }
    running_seen |= head.report.status() == RunStatus::Running;
    assert!(running_seen, "the status never said running");
    assert!(
        head.report.rendered().is_some(),
        "no demo frame was rendered"
    );
    head.stop.store(true, std::sync::atomic::Ordering::Relaxed);
    thread
        .join()
        .expect("no panic")
        .expect("the head stops cleanly");
    assert_eq!(head.report.status(), RunStatus::Finished);

    let dir = tempfile::tempdir().unwrap();
    let (frames, size) = decoded(dir.path(), "composed", &viewer.composed);
    assert_eq!(
        frames,
        units(&viewer.composed) as u64,
        "composed frames decoded"
    );
    assert_eq!(size, "640x480", "the composed stream's pictures");
    let (frames, size) = decoded(dir.path(), "view", &viewer.views[WATCHED]);
    let watched = units(&viewer.views[WATCHED]) as u64;
    assert_eq!(frames, watched, "frames of the watched view decoded");
    assert_eq!(size, "320x240", "the watched view's own pictures");
    for (i, stream) in viewer.views.iter().enumerate() {
        if i != WATCHED {
            assert_eq!(units(stream), 0, "view {i}, unwatched, was encoded");
        }
    }
}
