//! Glass-to-glass latency on one host: starts `digiview serve` on the demo with its capture
//! timestamp drawn as a barcode at the image centre, one full-frame view looking straight
//! down at it, pulls the RTSP stream with GStreamer (rtspsrc, latency 0, TCP), and for each
//! decoded frame reads the barcode and subtracts it from the time of decoding. Both clocks
//! are CLOCK_MONOTONIC on this host. Run by scripts/latency.sh:
//!
//!     cargo run --release --example glass_to_glass -- [--size 1280x720] [--frames 300]

use digiview::lens::LensCal;
use digiview::render::FramePlan;
use digiview::source::clock_us;
use digiview::source::demo::stamp;
use digiview::state::State;
use glam::DVec2;
use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use gstreamer_video as gst_video;
use gstreamer_video::prelude::*;
use std::io::BufRead;
use std::process::{Command, Stdio};

const DEMO: (u32, u32) = (1280, 720);

fn arg(name: &str, default: &str) -> String {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
        .unwrap_or_else(|| default.to_string())
}

fn main() {
    let size = arg("--size", "1280x720");
    let frames: usize = arg("--frames", "300").parse().expect("--frames N");
    let (w, h) = digiview::units::parse_size(&size).expect("--size WxH");

    // One rectilinear view, 60° across, straight down the lens axis at the barcode.
    let mut state = State::default();
    (state.output.width, state.output.height) = (w, h);
    (state.output.layout, state.output.overlay) = (0, 0);
    let cam = &mut state.cameras[0];
    (cam.yaw, cam.pitch, cam.roll) = (0.0, -90f64.to_radians(), 0.0);
    (cam.fov, cam.crop, cam.lock) = (60f64.to_radians(), 1, 7);
    let dir = tempfile::tempdir().unwrap();
    let state_file = dir.path().join("state.toml");
    std::fs::write(&state_file, toml::to_string(&state).unwrap()).unwrap();

    let cal = LensCal::load(std::path::Path::new("lens-cal/lens.cal")).unwrap();
    let lens = cal.entries[0].lens().for_frame(DEMO.0, DEMO.1, None);
    let plan = FramePlan::new(&state, &lens).unwrap();
    let centre = plan.lens.centre();
    // For every output pixel, the barcode bit it shows (cell interiors only).
    let view = &plan.views[0];
    let mut cells: Vec<Vec<usize>> = vec![vec![]; 32];
    for y in 0..view.rect.h {
        for x in 0..view.rect.w {
            let p = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            let Some(q) = plan.fisheye_pixel(view, p) else {
                continue;
            };
            // Only pixels well inside a cell: its neighbours a third of a cell away agree.
            let bit = stamp::bit_at(q, centre, DEMO.0);
            let d = stamp::CELL_1280 / 3.0;
            let same = [(d, 0.0), (-d, 0.0), (0.0, d), (0.0, -d)]
                .iter()
                .all(|o| stamp::bit_at(q + DVec2::new(o.0, o.1), centre, DEMO.0) == bit);
            if let (Some(Some(b)), true) = (bit, same) {
                cells[b as usize].push(((view.rect.y + y) * w + view.rect.x + x) as usize);
            }
        }
    }
    assert!(
        cells.iter().all(|c| c.len() > 4),
        "the barcode is not in view"
    );

    // target/release/examples/glass_to_glass → target/release/digiview
    let exe = std::env::current_exe().unwrap();
    let digiview = exe
        .parent()
        .and_then(|d| d.parent())
        .unwrap()
        .join("digiview");
    let mut serve = Command::new(digiview)
        .args(["serve", "--control", "127.0.0.1:0", "--rtsp-port", "0"])
        .args(["--demo-hover", "--demo-stamp", "--demo-size", "1280x720"])
        .args(["--state", state_file.to_str().unwrap()])
        .stdout(Stdio::piped())
        .spawn()
        .expect("digiview serve starts");
    let mut lines = std::io::BufReader::new(serve.stdout.take().unwrap()).lines();
    let _control = lines.next().unwrap().unwrap();
    let url = lines.next().unwrap().unwrap().replace("rtsp serving ", "");

    gst::init().unwrap();
    let pipeline = gst::parse::launch(&format!(
        "rtspsrc location={url} latency=0 protocols=tcp ! rtph264depay ! h264parse \
         ! avdec_h264 ! videoconvert ! video/x-raw,format=GRAY8 ! appsink name=sink sync=false"
    ))
    .unwrap()
    .downcast::<gst::Pipeline>()
    .unwrap();
    let sink = pipeline
        .by_name("sink")
        .unwrap()
        .downcast::<gst_app::AppSink>()
        .unwrap();
    pipeline.set_state(gst::State::Playing).unwrap();
    let mut latencies = vec![];
    let mut unread = 0;
    // The first seconds are start-up (GPU, encoder, first key frame): skipped.
    let start = std::time::Instant::now();
    while latencies.len() < frames {
        let sample = sink
            .try_pull_sample(gst::ClockTime::from_seconds(10))
            .expect("a frame within 10 s");
        let now_ms = clock_us() / 1000;
        if start.elapsed().as_secs_f64() < 3.0 {
            continue;
        }
        let info = gst_video::VideoInfo::from_caps(sample.caps().unwrap()).unwrap();
        let frame =
            gst_video::VideoFrameRef::from_buffer_ref_readable(sample.buffer().unwrap(), &info)
                .unwrap();
        let stride = frame.plane_stride()[0] as usize;
        let luma = frame.plane_data(0).unwrap();
        let mut value = 0u32;
        for c in &cells {
            let mean = c
                .iter()
                .map(|&i| luma[(i / w as usize) * stride + i % w as usize] as f64)
                .sum::<f64>()
                / c.len() as f64;
            value = value << 1 | (mean > 126.0) as u32;
        }
        let latency = (now_ms as u32).wrapping_sub(value);
        if latency < 5000 {
            latencies.push(latency as f64);
        } else {
            unread += 1;
        }
    }
    let _ = pipeline.set_state(gst::State::Null);
    let _ = serve.kill();
    let _ = serve.wait();
    latencies.sort_by(f64::total_cmp);
    let q = |f: f64| latencies[((latencies.len() - 1) as f64 * f) as usize];
    println!(
        "glass-to-glass at {w}x{h}, {} frames: median {:.0} ms, p10 {:.0}, p90 {:.0}, min {:.0}, \
         max {:.0} ({unread} unreadable)",
        latencies.len(),
        q(0.5),
        q(0.1),
        q(0.9),
        latencies[0],
        latencies[latencies.len() - 1]
    );
}
