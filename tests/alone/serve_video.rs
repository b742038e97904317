//! The video head end to end: `digiview serve` on the demo source, the stream pulled over
//! RTSP with GStreamer's rtspsrc (and, separately, probed with ffprobe), decoded, and compared
//! with the synthetic world's ground truth; then the layout, a view's fov and the output size
//! changed over the control protocol and seen in the picture, on the same RTSP session.

use crate::common;
use common::{system_status, wait_status};

use common::serve::{CaptureConfig, Serve};
use common::viewer::Viewer;
use common::{four_view_state, landmark_matches, lens_cal, probe_frames, probe_rtsp};
use digiview::control::client::Client;
use digiview::image_ops;
use digiview::layout::Rect;
use digiview::plan::FramePlan;
use digiview::protocol::params::{CamFov, Capture, VideoOutput};
use digiview::protocol::{Param, ParamType};
use digiview::scene::GridWorld;
use digiview::scene::synth::truth;
use digiview::state::State;
use digiview::supervise::WINDOW;
use gstreamer as gst;
use image::RgbImage;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const DEMO: (u32, u32) = (1280, 720);
const FPS: u32 = 15;

fn psnr(a: &RgbImage, b: &RgbImage) -> f64 {
    image_ops::psnr(a, b, Rect::new(0, 0, a.width(), a.height()))
}

fn truth_of(state: &State) -> (FramePlan, RgbImage) {
    let cal = lens_cal();
    let lens = cal
        .entries
        .iter()
        .find(|e| e.lens_id == state.settings.lens)
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
    let _alone = crate::one_at_a_time();
    let dir = tempfile::tempdir().unwrap();
    let mut state = four_view_state(7);
    state.settings.output.fps = FPS;
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
    let probe = probe_rtsp(&url, "codec_name,width,height");
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
    changed.settings.output.layout = digiview::modes::LayoutMode::One;
    let fov = digiview::state::view::Field::Fov;
    changed.settings.cameras[0]
        .put(fov, 60f64.to_radians())
        .unwrap();
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
    (bigger.settings.output.width, bigger.settings.output.height) = (800, 600);
    let (_, want_bigger) = truth_of(&bigger);
    assert!(psnr(&want_bigger, &resized) > 24.0);
}

/// The share of pixels whose green lies in `range`.
fn share(img: &RgbImage, range: std::ops::RangeInclusive<u8>) -> f64 {
    img.pixels().filter(|p| range.contains(&p[1])).count() as f64
        / (img.width() * img.height()) as f64
}

/// "NO SIGNAL": dark grey nearly everywhere.
fn no_signal(img: &RgbImage) -> bool {
    share(img, 18..=40) > 0.7
}

/// The test sequence's light grey fills a good part of the views.
fn picture(img: &RgbImage) -> bool {
    share(img, 150..=190) > 0.2
}

/// Decoded frames until `test` holds for one, within `limit`.
fn until(viewer: &Viewer, limit: Duration, what: &str, test: impl Fn(&RgbImage) -> bool) {
    let t = Instant::now();
    while t.elapsed() < limit {
        if test(&viewer.fresh_frame()) {
            return;
        }
    }
    panic!("no frame showed {what} within {limit:?}");
}

fn capture(ctl: &mut Client) -> Capture {
    match ctl.get_one(ParamType::Capture.zeroed()).unwrap() {
        Param::Capture(c) => c,
        other => panic!("{other:?}"),
    }
}

fn set_capture(ctl: &mut Client, flags: u8) {
    ctl.set(Param::Capture(Capture {
        flags,
        ..Default::default()
    }))
    .unwrap();
}

fn files(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    v.retain(|p| p.extension().is_some_and(|e| e == ext));
    v.sort();
    v
}

/// A looping sequence of plain light-grey fisheye frames in `frames`.
fn write_frames(frames: &Path) {
    std::fs::create_dir_all(frames).unwrap();
    for i in 0..5 {
        RgbImage::from_pixel(640, 360, image::Rgb([170, 170, 170]))
            .save(frames.join(format!("f{i:03}.png")))
            .unwrap();
    }
}

/// A config serving `dir/frames` as a sequence at 640x480 and 15 fps, and the server. The
/// frames are written first when `frames` is true.
fn serve_sequence(dir: &Path, frames: bool) -> (Serve, PathBuf) {
    serve_sequence_with(dir, frames, "")
}

/// As [`serve_sequence`], with `capture` keys added to `[capture]`.
fn serve_sequence_with(dir: &Path, frames: bool, capture: &str) -> (Serve, PathBuf) {
    if frames {
        write_frames(&dir.join("frames"));
    }
    let frames = dir.join("frames");
    let captures = dir.join("captures");
    let config = dir.join("digiview.toml");
    std::fs::write(
        &config,
        format!(
            "source = \"sequence:{}/f%03d.png\"\nsource_fps = 15\nhealth_interval_s = 1\n[encoder]\nkey_interval_s = 10\n\
             [capture]\ndir = \"{}\"\nmin_free_mb = 1\n{capture}",
            frames.display(),
            captures.display()
        ),
    )
    .unwrap();
    let serve = Serve::start_video(&[
        "--config",
        config.to_str().unwrap(),
        "--size",
        "640x480",
        "--fps",
        "15",
    ]);
    (serve, captures)
}

#[test]
fn a_lost_source_shows_no_signal_and_comes_back_while_captures_go_on() {
    let _alone = crate::one_at_a_time();
    // The camera is not there at start: "no signal", error 1 (source), retried with back-off.
    let dir = tempfile::tempdir().unwrap();
    let (serve, captures) = serve_sequence(dir.path(), false);
    let viewer = Viewer::open(serve.rtsp.as_deref().unwrap());
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    until(&viewer, Duration::from_secs(20), "no signal", no_signal);
    assert_eq!(system_status(&mut ctl), (3, 1), "error: the source");

    // It turns up, after several failed attempts: the picture comes within 2 s, without a
    // restart.
    std::thread::sleep(Duration::from_secs(4));
    let frames = dir.path().join("frames");
    write_frames(&frames);
    until(&viewer, Duration::from_secs(2), "the picture", picture);
    wait_status(&mut ctl, (1, 0), Duration::from_secs(5));

    // A client joining mid-stream gets a key frame at once, not at the next periodic one
    // (every 10 s in this config).
    let t = Instant::now();
    let second = Viewer::open(serve.rtsp.as_deref().unwrap());
    second.frame();
    assert!(
        t.elapsed() < Duration::from_secs(4),
        "first frame after {:?}",
        t.elapsed()
    );
    drop(second);

    // A still and a recording.
    set_capture(&mut ctl, 1 | 2);
    assert_eq!(capture(&mut ctl).flags & 2, 2, "recording");

    // The camera goes silent mid-stream: "no signal" after a second, status error 1.
    let away = dir.path().join("away");
    std::thread::sleep(Duration::from_secs(2));
    std::fs::rename(&frames, &away).unwrap();
    until(&viewer, Duration::from_secs(10), "no signal", no_signal);
    assert_eq!(system_status(&mut ctl), (3, 1), "error: the source");

    // It comes back after 4 s away: the picture resumes within 2 s.
    std::thread::sleep(Duration::from_secs(4));
    std::fs::rename(&away, &frames).unwrap();
    until(
        &viewer,
        Duration::from_secs(2),
        "the picture again",
        picture,
    );
    wait_status(&mut ctl, (1, 0), Duration::from_secs(5));

    // Recording stops; the counters say one still and one video; both files are good.
    set_capture(&mut ctl, 0);
    let c = capture(&mut ctl);
    assert_eq!(
        (c.flags & 2, c.images_captured, c.videos_captured),
        (0, 1, 1)
    );
    let stills = files(&captures, "jpg");
    assert_eq!(stills.len(), 1, "{stills:?}");
    let still = image::open(&stills[0]).unwrap().to_rgb8();
    assert_eq!(still.dimensions(), (640, 480));
    assert!(picture(&still), "the still shows the picture");
    let videos = files(&captures, "mp4");
    assert_eq!(videos.len(), 1);
    let (n, size) = probe_frames(&videos[0]);
    assert_eq!(size, "640x480");
    // 2 s of picture at 15 fps, then "no signal" and the picture again.
    assert!(n >= 30, "{n} frames in the recording");
}

#[test]
fn a_recording_survives_kill_9_to_within_a_second_and_sigterm_finishes_it() {
    let _alone = crate::one_at_a_time();
    for container in ["mp4", "ts"] {
        let dir = tempfile::tempdir().unwrap();
        let keys = format!("container = \"{container}\"\n");
        let (mut serve, captures) = serve_sequence_with(dir.path(), true, &keys);
        let mut ctl =
            Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
        wait_status(&mut ctl, (1, 0), Duration::from_secs(20));
        set_capture(&mut ctl, 2);
        let started = Instant::now();
        std::thread::sleep(Duration::from_millis(3500));
        let recorded = started.elapsed().as_secs_f64();
        serve.kill();
        let videos = files(&captures, container);
        assert_eq!(videos.len(), 1);
        // 15 fps: what plays is the recording to within a second of the kill.
        let (n, _) = probe_frames(&videos[0]);
        let kept = n as f64 / 15.0;
        assert!(
            kept >= recorded - 1.0,
            "{container}: {n} frames ({kept:.2} s) of {recorded:.2} s recorded survived a kill -9"
        );
    }

    // SIGTERM: the recording is finished and the process exits cleanly.
    let dir = tempfile::tempdir().unwrap();
    let (mut serve, captures) = serve_sequence(dir.path(), true);
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    wait_status(&mut ctl, (1, 0), Duration::from_secs(20));
    set_capture(&mut ctl, 2);
    std::thread::sleep(Duration::from_millis(2500));
    serve.terminate();
    let exit = serve
        .wait_exit(Duration::from_secs(10))
        .expect("exits after SIGTERM");
    assert!(exit.success(), "{exit:?}");
    let videos = files(&captures, "mp4");
    let (n, _) = probe_frames(&videos[0]);
    assert!(n >= 30, "{n} frames in 2.5 s at 15 fps");
}

#[test]
fn a_gstreamer_camera_with_rtsp_authentication_and_a_full_disk() {
    let _alone = crate::one_at_a_time();
    // Any GStreamer source description stands in for a camera (here a live test pattern).
    let config = CaptureConfig::new(
        "source = \"gst:videotestsrc is-live=true ! video/x-raw,width=640,height=360,framerate=15/1\"\n\
         health_interval_s = 0\n\
         [rtsp]\nuser = \"pilot\"\npassword = \"s3cret\"\n",
        "min_free_mb = 1000000000\n",
    );
    let serve = Serve::start_video(&["--config", config.path(), "--size", "640x480"]);
    let url = serve.rtsp.clone().unwrap();
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    wait_status(&mut ctl, (1, 0), Duration::from_secs(20));

    // Without the password the server says 401; with it the stream plays.
    let refused = probe_rtsp(&url, "width,height");
    assert!(!refused.status.success());
    assert!(
        String::from_utf8_lossy(&refused.stderr).contains("401"),
        "{}",
        String::from_utf8_lossy(&refused.stderr)
    );
    let with = url.replace("rtsp://", "rtsp://pilot:s3cret@");
    let allowed = probe_rtsp(&with, "width,height");
    assert_eq!(String::from_utf8_lossy(&allowed.stdout).trim(), "640,480");
    // The web API asks the same login; the scheme's name in any case (RFC 9110).
    let status = format!("{}api/status", serve.http.as_ref().unwrap());
    let code = |auth| common::gcs::http_get_as(&status, auth).0;
    assert_eq!(code(None), 401);
    assert_eq!(code(Some("Basic cGlsb3Q6czNjcmV0")), 200);
    assert_eq!(code(Some("basic cGlsb3Q6czNjcmV0")), 200);
    assert_eq!(code(Some("BASIC cGlsb3Q6czNjcmV0")), 200);
    assert_eq!(
        code(Some("basic cGlsb3Q6d3Jvbmc=")),
        401,
        "a wrong password"
    );

    // A disk without the free space the config keeps is a refused capture, not a bad file.
    for flags in [1, 2] {
        let e = ctl
            .set(Param::Capture(Capture {
                flags,
                ..Default::default()
            }))
            .unwrap_err()
            .to_string();
        assert!(e.to_lowercase().contains("data"), "{e}");
    }
    assert_eq!(capture(&mut ctl).flags & 2, 0, "not recording");
    assert!(files(&config.captures, "mp4").is_empty() && files(&config.captures, "jpg").is_empty());
}

/// A stage that keeps failing is never a silent zombie: with a fault injected into the frame
/// loop (it panics half a second into each run), SYSTEM_STATUS says error 5 while it is
/// started again, and after the third failure `serve` exits non-zero saying which stage.
/// Each start of the stage opens the GPU and compiles the pipelines of lens.cal's models
/// (about 10 s on lavapipe); the test waits as long as the rule lets three failures count
/// together (`supervise::WINDOW` from the start), as serve would not give up on slower ones.
#[test]
fn a_frame_loop_that_keeps_panicking_is_reported_and_ends_the_process() {
    let _alone = crate::one_at_a_time();
    let t = Instant::now();
    let mut serve = Serve::start_video_faulty("frames", &["--demo-size", "640x480"]);
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(2)).unwrap();
    let mut saw_error = false;
    while t.elapsed() < WINDOW && !saw_error {
        if let Ok(Param::SystemStatus(s)) = ctl.get_one(ParamType::SystemStatus.zeroed()) {
            saw_error = (s.status, s.error) == (3, 5);
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(saw_error, "SYSTEM_STATUS never said error 5");
    let status = serve
        .wait_exit(WINDOW.saturating_sub(t.elapsed()))
        .expect("serve ends once the stage keeps failing");
    eprintln!(
        "serve gave up {:.1} s after it was started",
        t.elapsed().as_secs_f64()
    );
    let log = serve.log();
    assert!(!status.success(), "{status:?}");
    assert!(
        log.contains("the frames service failed (fault injected")
            && log.contains("starting it again")
            && log.contains("the frames stage kept failing"),
        "{log}"
    );
}
