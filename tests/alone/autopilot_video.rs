//! The frame's clock end to end: the demo camera spins (yaw 90°/s, roll ±20° at 1 Hz, by the
//! monotonic clock) while a simulated autopilot reports the same attitude over MAVLink at
//! 200 Hz with its own boot clock and 0 to 20 ms of random delay. With all axes locked the
//! views are fixed in the world, so the ground's landmarks must stay where the ground truth
//! puts them in every decoded frame; rendered with the newest sample instead of the one at
//! the frame's capture time, they visibly do not.

use crate::common;

use common::autopilot::{SimAutopilot, attitude, frame, free_udp_port};
use common::serve::Serve;
use common::viewer::Viewer;
use common::{four_view_state, landmark_matches, lens_cal};
use digiview::geometry::Euler;
use digiview::plan::FramePlan;
use digiview::scene::GridWorld;
use digiview::scene::synth::truth;
use glam::DVec3;
use std::net::UdpSocket;
use std::time::{Duration, Instant};

const DEMO: (u32, u32) = (1280, 720);

pub fn spinning(t: f64) -> DVec3 {
    let e = digiview::source::demo::spin(Euler::default(), t);
    DVec3::new(e.yaw, e.pitch, e.roll)
}

/// Landmarks of at least this area (px²) are located to better than 0.2 px in a still picture
/// of this test's; a smaller one (the orange landmark near the horizon, about 4 px across) is
/// 0.7 to 0.9 px off with nothing moving, so it shows the codec, not the attitude.
const LOCATABLE: f64 = 30.0;

/// Landmark errors (px, sorted) over `frames` decoded frames of `serve` on the spinning demo
/// with the simulated autopilot on its link, frames rendered with `attitude_sample`, of the
/// landmarks of at least [`LOCATABLE`] px² (then of the smaller ones); and the decoded frame
/// rate. `meanwhile(port)` runs on a thread of its own while they are decoded.
fn landmark_errors(
    attitude_sample: &str,
    frames: usize,
    meanwhile: impl FnOnce(u16) + Send + 'static,
) -> (Vec<f64>, Vec<f64>, f64) {
    landmark_errors_with(attitude_sample, Readouts::default(), frames, meanwhile)
}

/// A rolling shutter: the demo camera's readout (ms) and the one the head corrects.
#[derive(Clone, Copy, Default)]
pub struct Readouts {
    pub camera_ms: f64,
    pub corrected_ms: f64,
}

/// [`landmark_errors`] with the demo camera and the head reading out as `readouts` says.
pub fn landmark_errors_with(
    attitude_sample: &str,
    readouts: Readouts,
    frames: usize,
    meanwhile: impl FnOnce(u16) + Send + 'static,
) -> (Vec<f64>, Vec<f64>, f64) {
    let dir = tempfile::tempdir().unwrap();
    let state = four_view_state(7);
    let state_file = dir.path().join("state.toml");
    std::fs::write(&state_file, toml::to_string(&state).unwrap()).unwrap();
    let port = free_udp_port();
    let config = dir.path().join("digiview.toml");
    std::fs::write(
        &config,
        format!(
            "[demo]\nspin = true\nwidth = {}\nheight = {}\nreadout_ms = {}\n\n[mavlink]\n\
             endpoint = \"udpin:127.0.0.1:{port}\"\nattitude_sample = \"{attitude_sample}\"\n\n\
             [readout]\ntime_ms = {}\n",
            DEMO.0, DEMO.1, readouts.camera_ms, readouts.corrected_ms
        ),
    )
    .unwrap();
    // The endpoint is given as a flag too: without one, the tests' `serve` turns the link off.
    let serve = Serve::start_video(&[
        "--config",
        config.to_str().unwrap(),
        "--mavlink",
        &format!("udpin:127.0.0.1:{port}"),
        "--state",
        state_file.to_str().unwrap(),
    ]);
    let _sim = SimAutopilot::start(&format!("udpout:127.0.0.1:{port}"), spinning);

    let cal = lens_cal();
    let lens = cal
        .find("CIL216")
        .unwrap()
        .lens()
        .for_frame(DEMO.0, DEMO.1, None);
    let plan = FramePlan::new(&state, &lens).unwrap();
    let want = truth(&GridWorld::default(), &plan, &state);

    let viewer = Viewer::open(serve.rtsp.as_ref().unwrap());
    // Three seconds for the clock mapping to settle.
    let _ = viewer.frame_after(Duration::from_secs(3));
    let side = std::thread::spawn(move || meanwhile(port));
    let (mut errors, mut small) = (vec![], vec![]);
    let (first, mut last) = (viewer.frame().1, None);
    for _ in 1..frames {
        let (got, pts) = viewer.frame();
        for m in landmark_matches(&plan, &state, &want, &got) {
            match m.area >= LOCATABLE {
                true => errors.push(m.error()),
                false => small.push(m.error()),
            }
        }
        last = Some(pts);
    }
    side.join().unwrap();
    errors.sort_by(f64::total_cmp);
    small.sort_by(f64::total_cmp);
    let fps = (frames - 1) as f64 / (last.unwrap() - first).seconds_f64();
    (errors, small, fps)
}

/// The median and worst of sorted errors (infinite when there are none).
pub fn spread(errors: &[f64]) -> (f64, f64) {
    let at = |i: usize| errors.get(i).copied().unwrap_or(f64::INFINITY);
    (at(errors.len() / 2), at(errors.len().wrapping_sub(1)))
}

pub fn summary(what: &str, errors: &[f64], small: &[f64], fps: f64) -> (f64, f64) {
    let (median, worst) = spread(errors);
    let (s_median, s_worst) = spread(small);
    eprintln!(
        "{what}: {} landmarks, median {median:.2} px, worst {worst:.2} px; {} under {LOCATABLE} \
         px², median {s_median:.2} px, worst {s_worst:.2} px; {fps:.1} fps",
        errors.len(),
        small.len()
    );
    (median, worst)
}

#[test]
fn with_all_axes_locked_the_ground_stays_put_while_the_autopilot_reports_a_spin() {
    let _alone = crate::one_at_a_time();
    let (errors, small, fps) = landmark_errors("interpolated", 31, |_| {});
    let (median, worst) = summary("at capture time", &errors, &small, fps);
    let (latest, l_small, l_fps) = landmark_errors("latest", 31, |_| {});
    let (_, l_worst) = summary("newest sample", &latest, &l_small, l_fps);
    assert!(
        errors.len() >= 250,
        "only {} landmarks seen in 30 frames",
        errors.len()
    );
    assert!(median <= 0.5, "median {median:.2} px from the truth");
    assert!(worst <= 1.0, "a landmark {worst:.2} px from the truth");
    // The small ones, off by up to 0.9 px when still, may not be much worse.
    let (_, s_worst) = spread(&small);
    assert!(
        s_worst <= 2.0,
        "a small landmark {s_worst:.2} px from the truth"
    );
    // How stale the newest sample is at a frame's capture varies from run to run (its
    // median error was 0.78 to 2.73 px in four runs), but at 90°/s some frame always shows
    // the ground jump: its worst landmark (3.98 to 7.83 px) is far beyond the worst at
    // capture time.
    assert!(
        l_worst > 2.0 && l_worst > 3.0 * worst,
        "rendered with the newest sample, the ground should visibly move: worst {l_worst:.2} px"
    );
}

/// 10,000 datagrams a second for 10 s on the autopilot's port: another system's ATTITUDE
/// saying south, bad checksums, cut frames, noise.
fn flood(port: u16) {
    let to = format!("127.0.0.1:{port}");
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    let south = frame(
        9,
        &attitude(Duration::from_secs(1), DVec3::new(3.1, 0.0, 0.0)),
    );
    let mut bad = frame(
        1,
        &attitude(Duration::from_secs(1), DVec3::new(3.1, 0.0, 0.0)),
    );
    let end = bad.len() - 1;
    bad[end] ^= 0xff;
    let cut = south[..12].to_vec();
    let noise: Vec<u8> = (0..64u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
        .collect();
    let start = Instant::now();
    let mut sent = 0u64;
    while start.elapsed() < Duration::from_secs(10) {
        for d in [&south, &bad, &cut, &noise] {
            let _ = socket.send_to(d, &to);
        }
        sent += 4;
        // 10,000 a second: 40 datagrams every 4 ms.
        if sent.is_multiple_of(40) {
            let due = start + Duration::from_micros(sent * 100);
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
        }
    }
    eprintln!(
        "flood: {sent} datagrams in {:.1} s",
        start.elapsed().as_secs_f64()
    );
}

#[test]
fn a_flood_on_the_link_leaves_the_video_and_the_attitude_right() {
    let _alone = crate::one_at_a_time();
    // The frames decoded over the flood's 10 s (about 20 fps here).
    let (errors, small, fps) = landmark_errors("interpolated", 140, flood);
    let (median, worst) = summary("during a flood", &errors, &small, fps);
    assert!(errors.len() >= 1000, "only {} landmarks seen", errors.len());
    // Alone the worst is 0.5-0.7 px; in two of about eight full runs one frame was 1.5 and
    // 2.95 px off (a few milliseconds of timing on one frame, the hosts' threads starved
    // for a moment while 10,000 datagrams a second arrive), so the bound is on the 99th
    // percentile, and no frame may jump visibly.
    let p99 = errors[errors.len() * 99 / 100];
    assert!(
        median <= 0.5 && p99 <= 1.0 && worst <= 4.0,
        "median {median:.2} px, 99th percentile {p99:.2} px, worst {worst:.2} px"
    );
    assert!(fps >= 8.0, "{fps:.1} fps during the flood");
}
