//! Glass-to-glass latency on one host: starts `digiview serve` on the demo with its capture
//! timestamp drawn as a barcode at the image centre, one full-frame view looking straight
//! down at it, pulls the RTSP stream with GStreamer (rtspsrc, latency 0, TCP), and for each
//! decoded frame reads the barcode and subtracts it from the time of decoding. Both clocks
//! are CLOCK_MONOTONIC on this host. With `--page` the client is the tuning page in headless
//! Chromium instead (its preview over the WebSocket, decoded with WebCodecs, or with `--mse`
//! played through Media Source Extensions), read from the page's canvas as each frame is
//! drawn. Run by scripts/latency.sh:
//!
//!     cargo run --release --example glass_to_glass -- [--size 1280x720] [--frames 300]
//!         [--page|--mse|--ffmpeg [--udp]|--opencv] [--decoder avdec_h264]
//!
//! The RTSP client decodes with `--decoder` (default `avdec_h264`, FFmpeg's, as most ground
//! stations' players); `decodebin` picks the best installed (NVDEC's `nvh264dec` on an NVIDIA
//! GPU). With `--ffmpeg` the client is the `ffmpeg` program with `-fflags nobuffer -flags
//! low_delay -threads 1`, over TCP or with `--udp` over UDP, writing grey frames to a pipe
//! flushed after each; with `--opencv`, OpenCV's capture (FFmpeg's RTSP client and decoder
//! as a library, as ffplay, mpv and ground stations' Python use it: `scripts/cv_frames.py`
//! in the project's .venv), the same options and one decoding thread.

use digiview::clock::clock_us;
use digiview::lens::LensCal;
use digiview::modes::{LayoutMode, OverlayMode};
use digiview::plan::FramePlan;
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
use std::time::{Duration, SystemTime, UNIX_EPOCH};

// The tests' headless Chromium, for --page (not every helper is used here).
#[allow(dead_code)]
#[path = "../tests/common/browser.rs"]
mod browser;

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
    let mse = std::env::args().any(|a| a == "--mse");
    let page_mode = mse || std::env::args().any(|a| a == "--page");
    let (w, h) = digiview::units::parse_size(&size).expect("--size WxH");

    // One rectilinear view, 60° across, straight down the lens axis at the barcode.
    let mut state = State::default();
    (state.settings.output.width, state.settings.output.height) = (w, h);
    let output = &mut state.settings.output;
    (output.layout, output.overlay) = (LayoutMode::One, OverlayMode::None);
    state.settings.cameras[0] = {
        use digiview::state::view::Field::*;
        let down = [(Yaw, 0.0), (Pitch, -90f64.to_radians()), (Roll, 0.0)];
        let lens = [(Fov, 60f64.to_radians()), (Crop, 1.0), (Lock, 7.0)];
        let view = digiview::state::Camera::default()
            .with(&down)
            .and_then(|c| c.with(&lens));
        view.expect("a view")
    };
    let dir = tempfile::tempdir().unwrap();
    let state_file = dir.path().join("state.toml");
    std::fs::write(&state_file, toml::to_string(&state).unwrap()).unwrap();
    // The head's own figures by stage, every 5 s.
    let config = dir.path().join("digiview.toml");
    std::fs::write(&config, "health_interval_s = 5\n").unwrap();

    let cells = barcode_cells(&state, w);

    let Head {
        mut serve,
        url,
        page,
        stages,
    } = Head::start(&state_file, &config);
    let (client, (mut latencies, unread)) = if page_mode {
        let (client, page) = match mse {
            true => ("page, MSE", format!("{page}?preview=mse")),
            false => ("page, WebCodecs", page),
        };
        (client.to_string(), page_latencies(&page, &cells, w, frames))
    } else if std::env::args().any(|a| a == "--ffmpeg" || a == "--opencv") {
        let udp = std::env::args().any(|a| a == "--udp");
        let transport = if udp { "udp" } else { "tcp" };
        let (client, command) = match std::env::args().any(|a| a == "--opencv") {
            true => ("OpenCV's capture".to_string(), opencv(&url)),
            false => (
                format!("the ffmpeg program over {transport}"),
                ffmpeg(&url, transport),
            ),
        };
        (
            format!("RTSP, {client}"),
            piped_latencies(command, &cells, (w, h), frames),
        )
    } else {
        let decoder = arg("--decoder", "avdec_h264");
        let l = rtsp_latencies(&url, &decoder, &cells, w, frames);
        (format!("RTSP, {decoder}"), l)
    };
    let _ = serve.kill();
    let _ = serve.wait();
    latencies.sort_by(f64::total_cmp);
    let q = |f: f64| latencies[((latencies.len() - 1) as f64 * f) as usize];
    println!(
        "glass-to-glass ({client}) at {w}x{h}, {} frames: median {:.0} ms, p10 {:.0}, p90 {:.0}, \
         min {:.0}, max {:.0} ({unread} unreadable)",
        latencies.len(),
        q(0.5),
        q(0.1),
        q(0.9),
        latencies[0],
        latencies[latencies.len() - 1]
    );
    println!("head's {}", stages.lock().unwrap());
}

/// `digiview serve` on the stamped demo, its RTSP and page addresses, and the last line of
/// its log saying where the frames' time went.
struct Head {
    serve: std::process::Child,
    url: String,
    page: String,
    stages: std::sync::Arc<std::sync::Mutex<String>>,
}

impl Head {
    fn start(state_file: &std::path::Path, config: &std::path::Path) -> Head {
        // target/release/examples/glass_to_glass → target/release/digiview
        let exe = std::env::current_exe().unwrap();
        let digiview = exe
            .parent()
            .and_then(|d| d.parent())
            .unwrap()
            .join("digiview");
        let mut serve = Command::new(digiview)
            .args(["serve", "--control", "127.0.0.1:0", "--rtsp-port", "0"])
            .args(["--http", "127.0.0.1:0"])
            .args(["--demo-hover", "--demo-stamp", "--demo-size", "1280x720"])
            .args(["--state", state_file.to_str().unwrap()])
            .args(["--config", config.to_str().unwrap()])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("digiview serve starts");
        // Its log: the lines saying where the frames' time went, the last kept.
        let stages = std::sync::Arc::new(std::sync::Mutex::new(String::new()));
        {
            let (stages, log) = (stages.clone(), serve.stderr.take().unwrap());
            std::thread::spawn(move || {
                for line in std::io::BufReader::new(log).lines().map_while(Result::ok) {
                    if let Some(i) = line.find("latency over") {
                        *stages.lock().unwrap() = line[i..].to_string();
                    }
                }
            });
        }
        // serve announces its control, RTSP and HTTP addresses, one line each, HTTP last.
        let (mut url, mut page) = (String::new(), String::new());
        for line in std::io::BufReader::new(serve.stdout.take().unwrap()).lines() {
            let line = line.expect("serve announces its addresses");
            if let Some(u) = line.strip_prefix("rtsp serving ") {
                url = u.to_string();
            }
            if let Some(u) = line.strip_prefix("http serving ") {
                page = u.to_string();
                break;
            }
        }
        Head {
            serve,
            url,
            page,
            stages,
        }
    }
}

/// For every output pixel of the one view, the barcode bit it shows (cell interiors only):
/// the pixels' indices in a `w`-wide frame, by bit.
fn barcode_cells(state: &State, w: u32) -> Vec<Vec<usize>> {
    let cal = LensCal::load(std::path::Path::new("lens-cal/lens.cal")).unwrap();
    let lens = cal.entries[0].lens().for_frame(DEMO.0, DEMO.1, None);
    let plan = FramePlan::new(state, &lens).unwrap();
    let centre = plan.lens.centre();
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
    cells
}

/// The stamp's value from a frame's luma: each cell's mean against mid-grey.
fn read_stamp(cells: &[Vec<usize>], w: u32, luma: impl Fn(u32, u32) -> f64) -> u32 {
    let mut value = 0u32;
    for c in cells {
        let mean = c
            .iter()
            .map(|&i| luma(i as u32 % w, i as u32 / w))
            .sum::<f64>()
            / c.len() as f64;
        value = value << 1 | (mean > 126.0) as u32;
    }
    value
}

/// Latency in ms from a stamp (CLOCK_MONOTONIC ms, low 32 bits) read at `now_ms`; None for a
/// misread.
fn latency(now_ms: u64, stamp: u32) -> Option<f64> {
    let l = (now_ms as u32).wrapping_sub(stamp);
    (l < 5000).then_some(l as f64)
}

/// RTSP (rtspsrc, latency 0, TCP) decoded with GStreamer: each frame's latency when decoded.
fn rtsp_latencies(
    url: &str,
    decoder: &str,
    cells: &[Vec<usize>],
    w: u32,
    frames: usize,
) -> (Vec<f64>, usize) {
    gst::init().unwrap();
    let pipeline = gst::parse::launch(&format!(
        "rtspsrc location={url} latency=0 protocols=tcp ! rtph264depay ! h264parse name=parse \
         ! {decoder} ! videoconvert ! video/x-raw,format=GRAY8 ! appsink name=sink sync=false"
    ))
    .unwrap()
    .downcast::<gst::Pipeline>()
    .unwrap();
    // When each access unit was whole here (out of the parser), by its timestamp: the
    // decoded frame with the same timestamp splits its latency into arriving and decoding.
    let received = std::sync::Arc::new(std::sync::Mutex::new(
        std::collections::HashMap::<u64, u64>::new(),
    ));
    {
        let received = received.clone();
        let pad = pipeline
            .by_name("parse")
            .unwrap()
            .static_pad("src")
            .unwrap();
        pad.add_probe(gst::PadProbeType::BUFFER, move |_, info| {
            if let Some(pts) = info.buffer().and_then(|b| b.pts()) {
                received.lock().unwrap().insert(pts.nseconds(), clock_us());
            }
            gst::PadProbeReturn::Ok
        });
    }
    let mut arrivals = vec![];
    let sink = pipeline
        .by_name("sink")
        .unwrap()
        .downcast::<gst_app::AppSink>()
        .unwrap();
    pipeline.set_state(gst::State::Playing).unwrap();
    let (mut latencies, mut unread) = (vec![], 0);
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
        let data = frame.plane_data(0).unwrap();
        let stamp = read_stamp(cells, w, |x, y| {
            data[y as usize * stride + x as usize] as f64
        });
        let Some(l) = latency(now_ms, stamp) else {
            unread += 1;
            continue;
        };
        latencies.push(l);
        let pts = sample.buffer().and_then(|b| b.pts()).map(|p| p.nseconds());
        if let Some(at) = pts.and_then(|p| received.lock().unwrap().remove(&p)) {
            arrivals.push(l - (now_ms as f64 - at as f64 / 1000.0));
        }
    }
    say_where_the_time_went(&pipeline, arrivals, &latencies);
    let _ = pipeline.set_state(gst::State::Null);
    (latencies, unread)
}

/// The `ffmpeg` program as a user tuned for low latency runs it, writing grey frames to its
/// stdout. The pipe is flushed after every frame (`-flush_packets 1`), or a frame's tail
/// would wait in FFmpeg's 32 KiB output buffer for the next frame: a hold of the
/// measurement, not of a player.
fn ffmpeg(url: &str, transport: &str) -> Command {
    let mut c = Command::new("ffmpeg");
    c.args(["-nostdin", "-loglevel", "error"])
        .args([
            "-fflags",
            "nobuffer",
            "-flags",
            "low_delay",
            "-threads",
            "1",
        ])
        .args(["-rtsp_transport", transport, "-i", url])
        .args(["-an", "-fps_mode", "passthrough", "-flush_packets", "1"])
        .args(["-f", "rawvideo", "-pix_fmt", "gray", "pipe:1"]);
    c
}

/// OpenCV's capture in the project's Python environment (scripts/setup.sh), writing grey
/// frames to its stdout.
fn opencv(url: &str) -> Command {
    let mut c = Command::new(".venv/bin/python");
    c.args(["scripts/cv_frames.py", url]);
    c
}

/// Each frame's latency when its last byte comes out of `command`'s stdout (grey frames of
/// `w` x `h`, one after another).
fn piped_latencies(
    mut command: Command,
    cells: &[Vec<usize>],
    (w, h): (u32, u32),
    frames: usize,
) -> (Vec<f64>, usize) {
    use std::io::Read;
    let mut client = command
        .stdout(Stdio::piped())
        .spawn()
        .expect("the client starts (ffmpeg; .venv from scripts/setup.sh)");
    let mut out = client.stdout.take().unwrap();
    let mut frame = vec![0u8; (w * h) as usize];
    let (mut latencies, mut unread) = (vec![], 0);
    // The first seconds are start-up, as for GStreamer's client.
    let start = std::time::Instant::now();
    while latencies.len() < frames {
        out.read_exact(&mut frame)
            .expect("the client decodes the stream");
        let now_ms = clock_us() / 1000;
        if start.elapsed().as_secs_f64() < 3.0 {
            continue;
        }
        let stamp = read_stamp(cells, w, |x, y| frame[(y * w + x) as usize] as f64);
        match latency(now_ms, stamp) {
            Some(l) => latencies.push(l),
            None => unread += 1,
        }
    }
    let _ = client.kill();
    let _ = client.wait();
    (latencies, unread)
}

/// On stderr: how long after capture the units were whole at the client and how long
/// decoding took (medians), and which decoder ran (decodebin's pick, where it chose).
fn say_where_the_time_went(pipeline: &gst::Pipeline, mut arrivals: Vec<f64>, latencies: &[f64]) {
    arrivals.sort_by(f64::total_cmp);
    if !arrivals.is_empty() {
        eprintln!(
            "glass_to_glass: whole at the client (out of h264parse) {:.1} ms after capture, \
             decoded and converted {:.1} ms after that (medians, {} frames)",
            arrivals[arrivals.len() / 2],
            {
                let mut d = latencies.to_vec();
                d.sort_by(f64::total_cmp);
                d[d.len() / 2] - arrivals[arrivals.len() / 2]
            },
            arrivals.len()
        );
    }
    let decoders: Vec<String> = pipeline
        .iterate_recurse()
        .into_iter()
        .flatten()
        .filter_map(|e| e.factory())
        .filter(|f| f.klass().contains("Decoder"))
        .map(|f| f.name().to_string())
        .collect();
    eprintln!("glass_to_glass: decoded with {}", decoders.join(", "));
}

/// The tuning page in headless Chromium: on each frame the preview draws, the page notes the
/// time (Date.now(), the system clock) and the cells' luma from its canvas; the times are
/// brought onto CLOCK_MONOTONIC with the offset between the two clocks read here.
fn page_latencies(page: &str, cells: &[Vec<usize>], w: u32, frames: usize) -> (Vec<f64>, usize) {
    // A few pixels of each cell are enough for the page to read.
    let probe: Vec<Vec<[u32; 2]>> = cells
        .iter()
        .map(|c| {
            let step = (c.len() / 6).max(1);
            c.iter()
                .step_by(step)
                .map(|&i| [i as u32 % w, i as u32 / w])
                .collect()
        })
        .collect();
    let runtime = tokio::runtime::Runtime::new().unwrap();
    runtime.block_on(async {
        let b = browser::Browser::start(1400, 1000).await;
        b.client.goto(page).await.unwrap();
        b.until(
            "the preview plays",
            Duration::from_secs(30),
            "return window.digiview && window.digiview.preview.frames >= 1",
        )
        .await;
        tokio::time::sleep(Duration::from_secs(3)).await; // start-up, as for RTSP
        b.js(
            "const cells = arguments[0];
             const canvas = document.getElementById('video');
             const g = canvas.getContext('2d');
             const all = cells.flat();
             const x0 = Math.min(...all.map((p) => p[0])), y0 = Math.min(...all.map((p) => p[1]));
             const w = Math.max(...all.map((p) => p[0])) - x0 + 1;
             const h = Math.max(...all.map((p) => p[1])) - y0 + 1;
             window.stamps = [];
             window.digiview.preview.addEventListener('frame', () => {
               const now = Date.now();
               const { data, width } = g.getImageData(x0, y0, w, h);
               const lumas = cells.map((c) => c.reduce((sum, [x, y]) => {
                 const i = 4 * ((y - y0) * width + x - x0);
                 return sum + 0.299 * data[i] + 0.587 * data[i + 1] + 0.114 * data[i + 2];
               }, 0) / c.length);
               window.stamps.push([now, lumas]);
             });",
            vec![serde_json::json!(probe)],
        )
        .await;
        b.until_with(
            "the frames measured",
            Duration::from_secs(frames as u64),
            "return window.stamps.length >= arguments[0]",
            vec![serde_json::json!(frames)],
        )
        .await;
        let stamps = b.js("return window.stamps", vec![]).await;
        b.close().await;
        // Milliseconds to subtract from the system clock to get CLOCK_MONOTONIC's.
        let epoch_ms = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap()
            .as_secs_f64()
            * 1e3;
        let offset = epoch_ms - clock_us() as f64 / 1e3;
        let (mut latencies, mut unread) = (vec![], 0);
        for s in stamps.as_array().unwrap().iter().take(frames) {
            let now = s[0].as_f64().unwrap();
            let mut stamp = 0u32;
            for luma in s[1].as_array().unwrap() {
                stamp = stamp << 1 | (luma.as_f64().unwrap() > 126.0) as u32;
            }
            match latency((now - offset).round() as u64, stamp) {
                Some(l) => latencies.push(l),
                None => unread += 1,
            }
        }
        (latencies, unread)
    })
}
