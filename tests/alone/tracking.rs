//! Click to track, as a ground station does it: CAMERA_TRACK_POINT on a mover of the demo's
//! world in camera 0's own stream makes the view follow it (judged in the decoded stream),
//! CAMERA_TRACKING_IMAGE_STATUS and _GEO_STATUS report it while it does, and
//! CAMERA_STOP_TRACKING releases it. Alone: the tracker runs on the CPU time the video
//! leaves (SCHED_IDLE), which another test beside it would take.

use crate::common;

use common::autopilot::free_udp_port;
use common::gcs::{Gcs, accepted, cameras, params};
use common::serve::Serve;
use common::viewer::Viewer;
use mavlink::MessageData;
use mavlink::dialects::common::*;
use std::time::{Duration, Instant};

const W: u32 = 640;
const H: u32 = 480;

/// How far `p` is from the picture's centre, as a part of its width.
fn off_centre(p: (f64, f64)) -> f64 {
    (p.0 - W as f64 / 2.0).hypot(p.1 - H as f64 / 2.0) / W as f64
}

#[test]
fn a_view_follows_the_mover_a_ground_station_clicks_until_told_to_stop() {
    let _alone = crate::one_at_a_time();
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("digiview.toml");
    std::fs::write(
        &config,
        format!("[cameras]\nwidth = {W}\nheight = {H}\npublic_host = \"127.0.0.1\"\n"),
    )
    .unwrap();
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    // Camera 0 looks straight down, wide, while the demo flies its circle.
    let serve = Serve::start_video(&[
        "--config",
        config.to_str().unwrap(),
        "--mavlink",
        &link,
        "--detector",
        "motion",
        "--cam",
        "0:yaw=0,pitch=-90deg,fov=120deg",
    ]);
    let gcs = Gcs::connect(port);
    let (system, seen) = cameras(&gcs);
    assert!(seen.contains(&100), "{seen:?}");
    let info = accepted(
        gcs.command(
            system,
            100,
            MavCmd::MAV_CMD_REQUEST_MESSAGE,
            params(&[CAMERA_INFORMATION_DATA::ID as f32]),
        ),
        "camera information",
    );
    let tracks = info.iter().any(|m| {
        matches!(m, MavMessage::CAMERA_INFORMATION(c)
            if c.flags.contains(CameraCapFlags::CAMERA_CAP_FLAGS_HAS_TRACKING_POINT))
    });
    assert!(tracks, "CAMERA_INFORMATION does not offer point tracking");

    // Clicks outside the picture, or not numbers, are refused.
    for (command, p) in [
        (MavCmd::MAV_CMD_CAMERA_TRACK_POINT, &[1.5, 0.5, 0.0][..]),
        (MavCmd::MAV_CMD_CAMERA_TRACK_POINT, &[f32::NAN, 0.5, 0.0]),
        (MavCmd::MAV_CMD_CAMERA_TRACK_POINT, &[0.5, 0.5, -0.1]),
        (
            MavCmd::MAV_CMD_CAMERA_TRACK_RECTANGLE,
            &[0.6, 0.4, 0.4, 0.6],
        ),
    ] {
        let answer = gcs.command(system, 100, command, params(p));
        assert_eq!(
            answer.map(|a| a.0),
            Some(MavResult::MAV_RESULT_DENIED),
            "{command:?} {p:?}"
        );
    }

    // Find the mover in camera 0's picture, and click on it.
    let viewer = Viewer::open(&format!("{}/cam0", serve.rtsp.clone().unwrap()));
    let at = common::first_pink_mover(&viewer);
    let (x, y) = (at.0 / W as f64, at.1 / H as f64);
    eprintln!("clicked the mover at ({x:.3}, {y:.3})");
    let point = MavCmd::MAV_CMD_CAMERA_TRACK_POINT;
    let answer = accepted(
        gcs.command(system, 100, point, params(&[x as f32, y as f32, 0.02])),
        "track point",
    );
    assert!(
        answer
            .iter()
            .any(|m| matches!(m, MavMessage::CAMERA_TRACKING_IMAGE_STATUS(s)
            if s.tracking_mode == CameraTrackingMode::CAMERA_TRACKING_MODE_POINT)),
        "{answer:?}"
    );
    // Closer in, as an operator would once it follows.
    let zoom = MavCmd::MAV_CMD_SET_CAMERA_ZOOM;
    accepted(gcs.command(system, 100, zoom, params(&[4.0, 60.0])), "zoom");

    // Over 10 s, after 2 s to settle: the mover stays near the centre of the decoded picture.
    std::thread::sleep(Duration::from_secs(2));
    gcs.forget();
    let (mut worst, mut frames, mut offs) = (0.0f64, 0, vec![]);
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(10) {
        let img = viewer.frame_after(Duration::from_millis(200));
        let p = common::pink_mover(&img).unwrap_or_else(|| {
            img.save(dir.path().join("lost.png")).unwrap();
            panic!(
                "the mover left camera 0's picture after {:?}",
                start.elapsed()
            )
        });
        let off = off_centre(p);
        offs.push(off);
        worst = worst.max(off);
        frames += 1;
    }
    offs.sort_by(f64::total_cmp);
    eprintln!(
        "following: {frames} frames, the mover {:.1}% of the width from the centre at the \
         median, {:.1}% at worst",
        100.0 * offs[offs.len() / 2],
        100.0 * worst
    );
    assert!(
        worst <= 0.05,
        "the mover was {:.1}% of the width off centre",
        100.0 * worst
    );

    // The statuses streamed meanwhile say what it follows and where.
    let (mut image, mut geo) = (vec![], vec![]);
    for (h, m) in gcs.collect(Duration::from_millis(600)) {
        match m {
            MavMessage::CAMERA_TRACKING_IMAGE_STATUS(s) if h.component_id == 100 => image.push(s),
            MavMessage::CAMERA_TRACKING_GEO_STATUS(s) if h.component_id == 100 => geo.push(s),
            _ => {}
        }
    }
    let last = image
        .last()
        .expect("CAMERA_TRACKING_IMAGE_STATUS streamed while following");
    assert_eq!(
        last.tracking_status,
        CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ACTIVE
    );
    let reported =
        ((last.point_x as f64 - 0.5) * W as f64).hypot((last.point_y as f64 - 0.5) * H as f64);
    assert!(
        reported / (W as f64) < 0.05,
        "it reports the object at {last:?}"
    );
    let g = geo
        .last()
        .expect("CAMERA_TRACKING_GEO_STATUS streamed while following");
    assert!(g.dist > 40.0 && g.dist < 200.0, "{g:?}");
    assert!(
        g.vel_n.is_finite() && g.vel_n.hypot(g.vel_e) < 10.0,
        "{g:?}"
    );

    // Stopped: an idle status, and the view no longer turns with the mover.
    let stop = MavCmd::MAV_CMD_CAMERA_STOP_TRACKING;
    let answer = accepted(gcs.command(system, 100, stop, params(&[])), "stop tracking");
    assert!(
        answer
            .iter()
            .any(|m| matches!(m, MavMessage::CAMERA_TRACKING_IMAGE_STATUS(s)
            if s.tracking_status == CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_IDLE)),
        "{answer:?}"
    );
    std::thread::sleep(Duration::from_secs(5));
    let img = viewer.fresh_frame();
    let after = common::pink_mover(&img).map(off_centre);
    eprintln!("5 s after the stop: the mover at {after:?} of the width off centre");
    assert!(
        after.is_none_or(|o| o > 0.1),
        "the view still follows: {after:?}"
    );
}
