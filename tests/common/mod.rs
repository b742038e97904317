//! Shared by the integration tests: the shipped lenses, a standard test state, and landmark
//! measurement in rendered frames.
#![allow(dead_code)]

pub mod autopilot;
pub mod browser;
pub mod direct;
pub mod exif;
pub mod frames;
pub mod gcs;
pub mod gpu;
pub mod klv;
pub mod peers;
pub mod relay;
pub mod serve;
pub mod thermal;
pub mod viewer;

use digiview::geometry::rotation::yaw_pitch;
use digiview::image_ops::{centroid, pixel};
use digiview::layout::Rect;
use digiview::lens::{Lens, LensCal};
use digiview::modes::{LayoutMode, OverlayMode};
use digiview::plan::{FramePlan, ViewMap};
use digiview::scene::GridWorld;
use digiview::scene::synth::eye;
use digiview::state::{Camera, State, Tracked};
use glam::{DVec2, DVec3};
use image::RgbImage;
use std::path::PathBuf;

pub const DEG: f64 = std::f64::consts::PI / 180.0;

/// The shipped lens.cal.
/// Where setup.sh unpacks darknet's photographs (person, dog, horses, kite, giraffe, eagle,
/// scream): real pictures for the tests that need them.
pub fn photos() -> PathBuf {
    let cache = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .unwrap_or_else(|| std::path::Path::new(&std::env::var_os("HOME").unwrap()).join(".cache"));
    let dir = cache.join("digiview/darknet/usr/share/darknet/data");
    assert!(
        dir.join("person.jpg").is_file(),
        "{}: no photographs; run scripts/setup.sh",
        dir.display()
    );
    dir
}

pub fn lens_cal_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("lens-cal/lens.cal")
}

pub fn lens_cal() -> LensCal {
    LensCal::load(&lens_cal_path()).expect("the shipped lens.cal parses")
}

/// A shipped lens scaled to a small fisheye frame (tests keep frames small).
pub fn small_lens(name: &str) -> Lens {
    lens_cal()
        .find(name)
        .unwrap()
        .lens()
        .for_frame(1280, 720, None)
}

/// Layout 4 at 640x480 with views at pitch 0, -45°, -90° and (yaw 180°) -45°, 90° rectilinear.
pub fn four_view_state(lock: u8) -> State {
    let mut s = State::default();
    s.settings.output.width = 640;
    s.settings.output.height = 480;
    s.settings.output.layout = LayoutMode::Four;
    s.settings.output.overlay = OverlayMode::None;
    let views = [(0.0, 0.0), (0.0, -45.0), (0.0, -90.0), (180.0, -45.0)];
    for (cam, (yaw, pitch)) in s.settings.cameras.iter_mut().zip(views) {
        *cam = view(yaw, pitch, 90.0, 1, lock);
    }
    s
}

/// A view described whole, as a state file or a `--cam` flag describes it (angles in
/// degrees, roll 0, directional control): nothing clamped, the state's one check to come.
pub fn view(yaw: f64, pitch: f64, fov: f64, crop: u8, lock: u8) -> Camera {
    use digiview::state::view::Field;
    Camera::default()
        .with(&[
            (Field::Yaw, yaw * DEG),
            (Field::Pitch, pitch * DEG),
            (Field::Roll, 0.0),
            (Field::Fov, fov * DEG),
            (Field::Crop, crop as f64),
            (Field::Lock, lock as f64),
        ])
        .expect("a view")
}

/// A landmark's centroid in a rendered view and in the ground truth.
#[derive(Debug)]
pub struct Match {
    pub name: &'static str,
    pub view: usize,
    pub truth: DVec2,
    pub got: DVec2,
    pub area: f64,
}

impl Match {
    pub fn error(&self) -> f64 {
        (self.truth - self.got).length()
    }
}

/// Where each landmark of the grid world should appear in each rectified view (from the
/// geometry), measured as a colour centroid in the truth and in `got` over the same window.
/// Landmarks too small (under 12 px of weight) or too close to a view's edge are skipped.
pub fn landmark_matches(
    plan: &FramePlan,
    state: &State,
    truth: &RgbImage,
    got: &RgbImage,
) -> Vec<Match> {
    let world = GridWorld::default();
    let eye = eye(state);
    let mut out = vec![];
    for (vi, view) in plan.views.iter().enumerate() {
        let ViewMap::Rays {
            projection,
            world_from_view,
        } = view.map
        else {
            continue;
        };
        for l in &world.landmarks {
            let ray = (DVec3::new(l.position.x, l.position.y, 0.0) - eye).normalize();
            let Some(p) = projection.point(world_from_view.transpose() * ray) else {
                continue;
            };
            let r = view.rect;
            let margin = 16.0;
            if p.x < margin
                || p.y < margin
                || p.x > r.w as f64 - margin
                || p.y > r.h as f64 - margin
            {
                continue;
            }
            let (cx, cy) = (r.x + p.x as u32, r.y + p.y as u32);
            if plan.world_ray(view, p).is_none() {
                continue; // outside the lens's image
            }
            let window = Rect::new(cx - 14, cy - 14, 28, 28);
            let colour = pixel(truth, cx, cy);
            let (Some((t, area)), Some((g, _))) = (
                centroid(truth, window, colour, 70.0),
                centroid(got, window, colour, 70.0),
            ) else {
                continue;
            };
            if area < 12.0 {
                continue;
            }
            out.push(Match {
                name: l.name,
                view: vi,
                truth: t,
                got: g,
                area,
            });
        }
    }
    out
}

/// Yaw and pitch of a landmark seen from the state's eye, for messages.
pub fn landmark_direction(state: &State, position: DVec2) -> (f64, f64) {
    yaw_pitch(DVec3::new(position.x, position.y, 0.0) - eye(state))
}

/// Three tracked objects 50° down, spread over 80° of yaw, 12° across: three detection tiles.
pub fn three_tracked() -> Vec<Tracked> {
    (0..3)
        .map(|i| Tracked {
            id: i,
            yaw: (40.0 * i as f64 - 30.0) * DEG,
            pitch: -50.0 * DEG,
            size: 12.0 * DEG,
            score: 90,
            ..Tracked::default()
        })
        .collect()
}

/// A synthetic 1280x720 fisheye still at `path` (`digiview synth`), for an image source.
pub fn synth_still(path: &std::path::Path) {
    let synth = std::process::Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args(["synth", "--sensor", "1280x720", "--out"])
        .arg(path)
        .env("DIGIVIEW_LENS_CAL", lens_cal_path())
        .output()
        .unwrap();
    assert!(
        synth.status.success(),
        "{}",
        String::from_utf8_lossy(&synth.stderr)
    );
}

/// The `ffmpeg` program pulling `url` over RTSP with `transport` (tcp or udp), quiet on
/// stdin; its output arguments are the caller's.
pub fn ffmpeg_from(url: &str, transport: &str) -> std::process::Command {
    let mut c = std::process::Command::new("ffmpeg");
    c.args([
        "-hide_banner",
        "-nostdin",
        "-rtsp_transport",
        transport,
        "-i",
        url,
    ]);
    c
}

/// ffprobe pulling `url` over RTSP (TCP) and printing the first video stream's `entries`
/// (for example `"width,height"`) as one CSV line.
pub fn probe_rtsp(url: &str, entries: &str) -> std::process::Output {
    std::process::Command::new("ffprobe")
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
            &format!("stream={entries}"),
            "-of",
            "csv=p=0",
        ])
        .arg(url)
        .output()
        .expect("ffprobe runs (scripts/setup.sh installs ffmpeg)")
}

/// ffprobe's count of decodable video frames in `path`, and their size.
pub fn probe_frames(path: &std::path::Path) -> (u64, String) {
    let out = std::process::Command::new("ffprobe")
        .args(["-v", "error", "-count_frames", "-select_streams", "v:0"])
        .args([
            "-show_entries",
            "stream=nb_read_frames,width,height",
            "-of",
            "csv=p=0",
        ])
        .arg(path)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).trim().to_string();
    // An MPEG-TS lists its stream under its program too: the first line is the stream's.
    let mut parts = text.lines().next().unwrap_or("").split(',');
    let (w, h, n) = (parts.next(), parts.next(), parts.next());
    match (w, h, n.and_then(|n| n.parse().ok())) {
        (Some(w), Some(h), Some(n)) => (n, format!("{w}x{h}")),
        _ => panic!(
            "ffprobe cannot read {}: {text} {}",
            path.display(),
            String::from_utf8_lossy(&out.stderr)
        ),
    }
}

/// A fitted lens against the truth: the worst distance between where each projects rays
/// within `half_fov` of the axis (where the truth's projection is in its frame).
pub fn worst_gap(fitted: &Lens, truth: &Lens, half_fov: f64) -> f64 {
    let mut worst: f64 = 0.0;
    for i in 0..=40 {
        let theta = half_fov * i as f64 / 40.0;
        for j in 0..24 {
            let phi = j as f64 * std::f64::consts::TAU / 24.0;
            let ray = glam::DVec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            if let (Some(a), Some(b)) = (fitted.project(ray), truth.project(ray))
                && truth.in_frame(b)
            {
                worst = worst.max(a.distance(b));
            }
        }
    }
    worst
}

/// Encodes the PNG sequence `dir/%03d.png` to an H.264 MP4 at 10 fps and constant
/// `quantizer`, with GStreamer's own tools (independent of DigiView's encoder).
pub fn encode_sequence(dir: &std::path::Path, clip: &std::path::Path, quantizer: u32) {
    let made = std::process::Command::new("gst-launch-1.0")
        .arg("-q")
        .arg("multifilesrc")
        .arg(format!("location={}/%03d.png", dir.display()))
        .args([
            "caps=image/png,framerate=10/1",
            "!",
            "pngdec",
            "!",
            "videoconvert",
        ])
        .args([
            "!",
            "x264enc",
            "pass=quant",
            &format!("quantizer={quantizer}"),
        ])
        .args(["!", "h264parse", "!", "mp4mux", "!", "filesink"])
        .arg(format!("location={}", clip.display()))
        .status()
        .unwrap();
    assert!(made.success());
}

/// `digiview ctl --addr ADDR ARGS...`, run to its end.
pub fn ctl(addr: &str, args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args(["ctl", "--addr", addr])
        .args(args)
        .output()
        .unwrap()
}

/// One HTTP/1.1 request written by hand to `addr` (`HOST:PORT`), `Connection: close`, with
/// `headers` (`Host` among them) and a JSON `body`: the status and the body of the reply, or
/// the error when nothing answers at `addr`.
pub fn raw_request(
    addr: &str,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &str,
) -> std::io::Result<(u16, String)> {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr)?;
    let mut head = format!("{method} {path} HTTP/1.1\r\nConnection: close\r\n");
    for (name, value) in headers {
        head.push_str(&format!("{name}: {value}\r\n"));
    }
    if !body.is_empty() {
        head.push_str(&format!(
            "Content-Type: application/json\r\nContent-Length: {}\r\n",
            body.len()
        ));
    }
    write!(s, "{head}\r\n{body}")?;
    let mut reply = String::new();
    s.read_to_string(&mut reply)?;
    let bad = || std::io::Error::other(format!("not an HTTP reply: {reply:?}"));
    let (head, body) = reply.split_once("\r\n\r\n").ok_or_else(bad)?;
    let status = head
        .get(9..12)
        .and_then(|c| c.parse().ok())
        .ok_or_else(bad)?;
    Ok((status, body.to_string()))
}

/// How far a ground point (north, east of the demo world's origin, metres) is from the
/// nearest of the demo's movers' circles: 0 on one, wherever on it the mover is now.
pub fn off_the_movers_circles(at: glam::DVec2) -> f64 {
    digiview::scene::GridWorld::default()
        .movers
        .iter()
        .map(|m| (at.distance(m.centre) - m.orbit).abs())
        .fold(f64::INFINITY, f64::min)
}

/// A process that keeps one core busy until dropped: the load generator of the tests that
/// measure under load. A suite run whole under such a load (`DIGIVIEW_TEST_LOAD=1`, the
/// README's loaded run) adds none: the condition is one core kept busy, and a second busy
/// core on a 2-core machine leaves the SCHED_IDLE detection thread nothing, by design.
pub struct Load(Option<std::process::Child>);

impl Load {
    pub fn start() -> Load {
        if std::env::var_os("DIGIVIEW_TEST_LOAD").is_some() {
            eprintln!("a core is kept busy for the whole run (DIGIVIEW_TEST_LOAD): none added");
            return Load(None);
        }
        let child = std::process::Command::new("sh")
            .args(["-c", "while :; do :; done"])
            .stdout(std::process::Stdio::null())
            .spawn()
            .unwrap();
        Load(Some(child))
    }
}

impl Drop for Load {
    fn drop(&mut self) {
        if let Some(child) = &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// Asserts that each of `lines` is in `log`.
pub fn assert_logged(log: &str, lines: &[&str]) {
    for line in lines {
        assert!(log.contains(line), "{line:?} not in the log:\n{log}");
    }
}

/// The centroid of the pink mover's pixels in `img` (red high, green and blue between, as
/// nothing else in the synthetic world is), with their count, when there are enough.
pub fn pink_mover(img: &RgbImage) -> Option<(f64, f64)> {
    let (mut n, mut sx, mut sy) = (0usize, 0.0, 0.0);
    for (x, y, p) in img.enumerate_pixels() {
        let [r, g, b] = p.0.map(i32::from);
        if r > 190 && (100..=205).contains(&g) && (120..=235).contains(&b) && r - g > 40 && b > g {
            n += 1;
            sx += x as f64 + 0.5;
            sy += y as f64 + 0.5;
        }
    }
    (n >= 12).then(|| (sx / n as f64, sy / n as f64))
}

/// Landmark errors (px) in view 0 of `frames` decoded frames of `viewer`, after `settle`,
/// against the ground truth `want` draws from the demo's CIL216 lens at `demo` pixels, and
/// the picture's pixels a degree (view 0 is 90° wide).
pub fn view0_landmark_errors(
    viewer: &viewer::Viewer,
    want: &State,
    demo: (u32, u32),
    (frames, settle): (usize, std::time::Duration),
) -> (Vec<f64>, f64) {
    let lens = lens_cal()
        .find("CIL216")
        .unwrap()
        .lens()
        .for_frame(demo.0, demo.1, None);
    let plan = FramePlan::new(want, &lens).unwrap();
    let truth = digiview::scene::synth::truth(&GridWorld::default(), &plan, want);
    let px_per_degree = plan.views[0].rect.w as f64 / 90.0;
    let _ = viewer.frame_after(settle);
    let mut errors = vec![];
    for _ in 0..frames {
        let (got, _) = viewer.frame();
        let matches = landmark_matches(&plan, want, &truth, &got);
        errors.extend(matches.iter().filter(|m| m.view == 0).map(|m| m.error()));
    }
    (errors, px_per_degree)
}

/// Where the pink mover first shows in `viewer`'s fresh frames, within 20 s.
pub fn first_pink_mover(viewer: &viewer::Viewer) -> (f64, f64) {
    let start = std::time::Instant::now();
    loop {
        if let Some(p) = pink_mover(&viewer.fresh_frame()) {
            return p;
        }
        assert!(
            start.elapsed() < std::time::Duration::from_secs(20),
            "no pink mover in view"
        );
    }
}

/// SYSTEM_STATUS's (status, error) as the control client `ctl` reads it.
pub fn system_status(ctl: &mut digiview::control::client::Client) -> (u8, u8) {
    use digiview::protocol::{Param, ParamType};
    match ctl.get_one(ParamType::SystemStatus.zeroed()).unwrap() {
        Param::SystemStatus(s) => (s.status, s.error),
        other => panic!("{other:?}"),
    }
}

/// Waits until SYSTEM_STATUS reads `want` (status, error), at most `limit`.
pub fn wait_status(
    ctl: &mut digiview::control::client::Client,
    want: (u8, u8),
    limit: std::time::Duration,
) {
    let t = std::time::Instant::now();
    loop {
        let now = system_status(ctl);
        if now == want {
            return;
        }
        assert!(t.elapsed() < limit, "status stays {now:?}, not {want:?}");
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
}
