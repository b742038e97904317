//! The video head end to end: `digiview serve` on the demo source, the stream pulled over
//! RTSP with GStreamer's rtspsrc (and, separately, probed with ffprobe), decoded, and compared
//! with the synthetic world's ground truth; then the layout, a view's fov and the output size
//! changed over the control protocol and seen in the picture, on the same RTSP session.

mod common;

use common::serve::Serve;
use common::{four_view_state, landmark_matches, lens_cal};
use digiview::control::client::Client;
use digiview::image_ops;
use digiview::layout::Rect;
use digiview::protocol::Param;
use digiview::protocol::params::{CamFov, VideoOutput};
use digiview::render::FramePlan;
use digiview::scene::GridWorld;
use digiview::scene::synth::truth;
use digiview::state::State;
use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use gstreamer_video as gst_video;
use gstreamer_video::prelude::*;
use image::RgbImage;
use std::time::{Duration, Instant};

const DEMO: (u32, u32) = (1280, 720);
const FPS: u32 = 15;

/// A decoding RTSP client: rtspsrc → H.264 decoder → RGB frames with their timestamps.
struct Viewer {
    pipeline: gst::Pipeline,
    sink: gst_app::AppSink,
}

impl Viewer {
    fn open(url: &str) -> Viewer {
        gst::init().unwrap();
        let pipeline = gst::parse::launch(&format!(
            "rtspsrc location={url} latency=0 protocols=tcp ! rtph264depay ! h264parse \
             ! avdec_h264 ! videoconvert ! video/x-raw,format=RGB ! appsink name=sink sync=false"
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
        Viewer { pipeline, sink }
    }

    /// The next decoded frame and its presentation time.
    fn frame(&self) -> (RgbImage, gst::ClockTime) {
        let sample = self
            .sink
            .try_pull_sample(gst::ClockTime::from_seconds(20))
            .expect("a frame within 20 s");
        let info = gst_video::VideoInfo::from_caps(sample.caps().unwrap()).unwrap();
        let buffer = sample.buffer().unwrap();
        let frame = gst_video::VideoFrameRef::from_buffer_ref_readable(buffer, &info).unwrap();
        let (w, h) = (info.width(), info.height());
        let stride = frame.plane_stride()[0] as usize;
        let data = frame.plane_data(0).unwrap();
        let mut img = RgbImage::new(w, h);
        for y in 0..h as usize {
            let row = &data[y * stride..y * stride + 3 * w as usize];
            img.as_mut()[y * 3 * w as usize..(y + 1) * 3 * w as usize].copy_from_slice(row);
        }
        (img, buffer.pts().unwrap())
    }

    /// The newest frame after `wait` has passed (everything before it is skipped).
    fn frame_after(&self, wait: Duration) -> RgbImage {
        let until = Instant::now() + wait;
        loop {
            let (img, _) = self.frame();
            if Instant::now() >= until {
                return img;
            }
        }
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        let _ = self.pipeline.set_state(gst::State::Null);
    }
}

fn psnr(a: &RgbImage, b: &RgbImage) -> f64 {
    image_ops::psnr(a, b, Rect::new(0, 0, a.width(), a.height()))
}

fn truth_of(state: &State) -> (FramePlan, RgbImage) {
    let cal = lens_cal();
    let lens = cal
        .entries
        .iter()
        .find(|e| e.lens_id == state.lens)
        .unwrap()
        .lens()
        .for_frame(DEMO.0, DEMO.1, None);
    let plan = FramePlan::new(state, &lens).unwrap();
    let img = truth(&GridWorld::default(), &plan, state);
    (plan, img)
}

/// Landmarks matched between the decoded frame and the truth, and the worst error (px).
fn landmarks(state: &State, got: &RgbImage) -> (usize, f64) {
    let (plan, want) = truth_of(state);
    let m = landmark_matches(&plan, state, &want, got);
    let worst = m.iter().map(|m| m.error()).fold(0.0, f64::max);
    (m.len(), worst)
}

#[test]
fn the_demo_streams_over_rtsp_and_follows_the_control_protocol() {
    let dir = tempfile::tempdir().unwrap();
    let mut state = four_view_state(7);
    state.output.fps = FPS;
    let state_file = dir.path().join("state.toml");
    std::fs::write(&state_file, toml::to_string(&state).unwrap()).unwrap();
    let serve = Serve::start_video(&[
        "--state",
        state_file.to_str().unwrap(),
        "--demo-hover",
        "--demo-size",
        &format!("{}x{}", DEMO.0, DEMO.1),
        "--capture-dir",
        dir.path().join("captures").to_str().unwrap(),
    ]);
    let url = serve.rtsp.clone().unwrap();

    // 60 frames at the configured size and rate.
    let viewer = Viewer::open(&url);
    let frames: Vec<(RgbImage, gst::ClockTime)> = (0..61).map(|_| viewer.frame()).collect();
    for (img, _) in &frames {
        assert_eq!(img.dimensions(), (640, 480));
    }
    let span = frames[60].1 - frames[0].1;
    let fps = 60.0 / span.seconds_f64();
    assert!(
        (FPS as f64 * 0.85..FPS as f64 * 1.15).contains(&fps),
        "decoded {fps:.2} fps, configured {FPS}"
    );

    // The world's landmarks where the ground truth puts them.
    let last = &frames[60].0;
    let (found, worst) = landmarks(&state, last);
    let (_, want) = truth_of(&state);
    let quality = psnr(&want, last);
    eprintln!("first state: {found} landmarks, worst {worst:.2} px, {quality:.1} dB vs truth");
    assert!(found >= 3, "only {found} landmarks seen");
    assert!(worst < 2.5, "a landmark is {worst:.2} px from the truth");
    assert!(quality > 24.0, "{quality:.1} dB against the truth");

    // ffprobe, a different RTSP client, sees the same stream.
    let probe = std::process::Command::new("ffprobe")
        .args([
            "-v",
            "error",
            "-rtsp_transport",
            "tcp",
            "-select_streams",
            "v:0",
        ])
        .args([
            "-show_entries",
            "stream=codec_name,width,height",
            "-of",
            "csv=p=0",
        ])
        .arg(&url)
        .output()
        .expect("ffprobe runs (scripts/setup.sh installs ffmpeg)");
    assert_eq!(
        String::from_utf8_lossy(&probe.stdout).trim(),
        "h264,640,480",
        "{}",
        String::from_utf8_lossy(&probe.stderr)
    );

    // Layout 0 and a narrower view 0 over the control protocol: the picture follows.
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    let output = |w, h, layout| {
        Param::VideoOutput(VideoOutput {
            width: w,
            height: h,
            fps: FPS as u8,
            layout_mode: layout,
            detection_overlay_mode: 0,
            ..Default::default()
        })
    };
    ctl.set(output(640, 480, 0)).unwrap();
    ctl.set(Param::CamFov(CamFov {
        cam_id: 0,
        fov: 60f64.to_radians(),
    }))
    .unwrap();
    let mut changed = state.clone();
    changed.output.layout = 0;
    changed.cameras[0].fov = 60f64.to_radians();
    let after = viewer.frame_after(Duration::from_secs(2));
    let (_, want_changed) = truth_of(&changed);
    let (now, before) = (psnr(&want_changed, &after), psnr(&want, &after));
    eprintln!("after SET: {now:.1} dB vs the new truth, {before:.1} dB vs the old");
    assert!(
        now > 24.0 && now > before + 3.0,
        "the picture did not follow"
    );
    let (found, worst) = landmarks(&changed, &after);
    assert!(
        found >= 1 && worst < 2.5,
        "{found} landmarks, worst {worst:.2} px"
    );

    // A new output size renegotiates the encoder; the same session goes on at the new size.
    ctl.set(output(800, 600, 0)).unwrap();
    let resized = viewer.frame_after(Duration::from_secs(2));
    assert_eq!(resized.dimensions(), (800, 600));
    let mut bigger = changed.clone();
    (bigger.output.width, bigger.output.height) = (800, 600);
    let (_, want_bigger) = truth_of(&bigger);
    assert!(psnr(&want_bigger, &resized) > 24.0);
}
