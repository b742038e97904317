//! The payload SDK's app in the picture (tests/peers/payload_sdk.py, the C++ SDK 3.0.0
//! replayed): its gimbal angle and rate, in GB_MODE lock, point view 0 where the decoded
//! picture shows it within 1° while the vehicle spins (the demo's `spin` flight, yawing
//! 90°/s) and one core is kept busy, and the SDK's own attitude messages (at 10 Hz or more)
//! say so; a USER_4 box on a mover starts tracking,
//! the status items report it, and the detection packets list the mover where the picture
//! shows it. Alone: the picture checks and the tracker want the CPU the suite would take.

use crate::common;

use common::autopilot::free_udp_port;
use common::peers::LinePeer;
use common::serve::Serve;
use common::viewer::Viewer;
use common::{Load, four_view_state, view, view0_landmark_errors};
use serde_json::{Value, json};
use std::time::Duration;

const DEMO: (u32, u32) = (1280, 720);

/// `serve` on the spinning demo with its payload link driving view 0, and the SDK on it.
fn spinning() -> (Serve, LinePeer, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let state_file = dir.path().join("state.toml");
    std::fs::write(&state_file, toml::to_string(&four_view_state(7)).unwrap()).unwrap();
    let config = dir.path().join("digiview.toml");
    let demo = format!(
        "[demo]\nspin = true\nwidth = {}\nheight = {}\n",
        DEMO.0, DEMO.1
    );
    std::fs::write(&config, demo).unwrap();
    let (link, payload) = (free_udp_port(), free_udp_port());
    let serve = Serve::start_video(&[
        "--config",
        config.to_str().unwrap(),
        "--mavlink",
        &format!("udpin:127.0.0.1:{link}"),
        "--payload",
        &format!("udpin:127.0.0.1:{payload}"),
        "--state",
        state_file.to_str().unwrap(),
    ]);
    let (sdk, ready) = LinePeer::start("payload_sdk.py", &[&payload.to_string()]);
    assert_eq!(ready["ready"], true, "{ready}");
    (serve, sdk, dir)
}

/// The earth-frame yaw and pitch of the last attitude in `statuses`.
fn aim(statuses: &Value) -> (f64, f64) {
    let last = statuses.as_array().unwrap().last().unwrap();
    (
        last["yaw"].as_f64().unwrap(),
        last["pitch"].as_f64().unwrap(),
    )
}

/// How far the earth-frame yaw turned over `statuses` (degrees, unwrapped), and their rate.
fn turned(statuses: &Value) -> (f64, f64) {
    let all = statuses.as_array().unwrap();
    let yaws: Vec<f64> = all.iter().map(|s| s["yaw"].as_f64().unwrap()).collect();
    let total: f64 = yaws
        .windows(2)
        .map(|w| (w[1] - w[0] + 540.0).rem_euclid(360.0) - 180.0)
        .sum();
    let span = all.last().unwrap()["t"].as_f64().unwrap() - all[0]["t"].as_f64().unwrap();
    (total, (all.len() - 1) as f64 / span)
}

/// The worst landmark error in view 0 over 20 decoded frames, in degrees, with view 0 aimed
/// at `yaw`, `pitch` in the earth frame.
fn worst_landmark(viewer: &Viewer, (yaw, pitch): (f64, f64)) -> (f64, usize) {
    let mut want_state = four_view_state(7);
    want_state.settings.cameras[0] = view(yaw, pitch, 90.0, 1, 7);
    let run = (20, Duration::from_millis(500));
    let (errors, px_per_degree) = view0_landmark_errors(viewer, &want_state, DEMO, run);
    let worst = errors.iter().copied().fold(0.0, f64::max);
    (worst / px_per_degree, errors.len())
}

#[test]
fn the_sdks_gimbal_angle_and_rate_point_the_view_where_the_picture_shows_it() {
    let _alone = crate::one_at_a_time();
    let _load = Load::start();
    let (serve, mut sdk, _dir) = spinning();
    let viewer = Viewer::open(serve.rtsp.as_ref().unwrap());

    // Lock: the angle is in the earth frame and stays there while the vehicle spins.
    assert_eq!(sdk.ask(&json!({"set": ["GB_MODE", 1]}))["result"], 0);
    let held = sdk.ask(&json!({"gimbal": {"angle": [-30, 0, 20], "for": 2.0}}));
    let (yaw, pitch) = aim(&held);
    assert!(
        (yaw - 20.0).abs() < 0.5 && (pitch + 30.0).abs() < 0.5,
        "{yaw}, {pitch}"
    );
    let still = sdk.ask(&json!({"listen": 1.0}))["attitudes"].clone();
    let (drift, hz) = turned(&still);
    assert!(
        drift.abs() < 1.0,
        "locked, the view turned {drift:.1}° in 1 s"
    );
    assert!(hz >= 5.0, "the attitude at {hz:.1} Hz");
    assert!(still[0]["mode"] == "LOCK_MODE", "{still}");
    let (worst, n) = worst_landmark(&viewer, (20.0, -30.0));
    eprintln!("angle: {n} landmarks, the worst {worst:.2}° off");
    assert!(
        n >= 40 && worst <= 1.0,
        "{n} landmarks, the worst {worst:.2}° off"
    );

    // A rate of 20°/s for 2 s, then 0: the view turned 40°, where the picture shows it.
    sdk.ask(&json!({"gimbal": {"rate": [0, 0, 20], "for": 2.0}}));
    let stopped = sdk.ask(&json!({"gimbal": {"rate": [0, 0, 0], "for": 0.5}}));
    let (yaw, pitch) = aim(&stopped);
    let moved = (yaw - 20.0 + 540.0).rem_euclid(360.0) - 180.0;
    assert!(
        (moved - 40.0).abs() < 6.0,
        "a rate of 20°/s for 2 s turned {moved:.1}°"
    );
    let (worst, n) = worst_landmark(&viewer, (yaw, pitch));
    eprintln!("rate: {n} landmarks at {yaw:.1}°, the worst {worst:.2}° off");
    assert!(
        n >= 40 && worst <= 1.0,
        "{n} landmarks, the worst {worst:.2}° off"
    );
}

#[test]
fn a_user_4_box_on_a_mover_is_tracked_reported_and_listed_in_the_detection_packets() {
    let _alone = crate::one_at_a_time();
    let (w, h) = (640.0, 480.0);
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("digiview.toml");
    let cameras = format!("[cameras]\nwidth = {w}\nheight = {h}\npublic_host = \"127.0.0.1\"\n");
    std::fs::write(&config, cameras).unwrap();
    let (link, payload) = (free_udp_port(), free_udp_port());
    // View 0 looks straight down, wide, while the demo flies its circle.
    let serve = Serve::start_video(&[
        "--config",
        config.to_str().unwrap(),
        "--mavlink",
        &format!("udpin:127.0.0.1:{link}"),
        "--payload",
        &format!("udpin:127.0.0.1:{payload}"),
        "--detector",
        "motion",
        "--cam",
        "0:yaw=0,pitch=-90deg,fov=120deg",
    ]);
    let (mut sdk, ready) = LinePeer::start("payload_sdk.py", &[&payload.to_string()]);
    assert_eq!(ready["ready"], true, "{ready}");
    let viewer = Viewer::open(&format!("{}/cam0", serve.rtsp.clone().unwrap()));
    let at = common::first_pink_mover(&viewer);
    // The payload_do_object_tracking example: tracking mode, OSD, the tracker's items at
    // 10 Hz, then a box on the mover.
    assert_eq!(sdk.ask(&json!({"set": ["TRACK_MODE", 0]}))["result"], 0);
    assert_eq!(sdk.ask(&json!({"set": ["OSD_MODE", 2]}))["result"], 0);
    let items: Vec<Value> = (3..=7).map(|i| json!([i, 100])).collect();
    sdk.ask(&json!({"rates": items}));
    let (x, y) = (at.0 / w * 1920.0, at.1 / h * 1080.0);
    let track = sdk.ask(&json!({"track": [x, y, 128, 128]}));
    assert_eq!(
        (&track["mode"], &track["box"]),
        (&json!(0), &json!(0)),
        "{track}"
    );
    std::thread::sleep(Duration::from_secs(2));
    let heard = sdk.ask(&json!({"listen": 1.0}));
    let item = |i: &str| heard["items"][i]["value"].as_f64().unwrap_or(f64::NAN);
    assert_eq!(item("7"), 1.0, "TRK_STATUS tracked: {heard}");
    // The view follows the mover, so its box is near the centre, as the picture shows it.
    let (bx, by) = (item("3"), item("4"));
    let seen = common::pink_mover(&viewer.fresh_frame()).expect("the mover in view");
    let (px, py) = (seen.0 / w * 1920.0, seen.1 / h * 1080.0);
    assert!(
        (bx - px).hypot(by - py) < 1920.0 * 0.08,
        "reported at {bx:.0}, {by:.0}; in the picture at {px:.0}, {py:.0}"
    );
    // Detection: the packets list the mover where the picture shows it.
    assert_eq!(sdk.ask(&json!({"set": ["TRACK_MODE", 1]}))["result"], 0);
    let heard = sdk.ask(&json!({"listen": 2.0}));
    let packets = heard["detections"].as_array().unwrap();
    assert!(packets.len() >= 8, "{} packets in 2 s", packets.len());
    let seen = common::pink_mover(&viewer.fresh_frame()).expect("the mover in view");
    let (px, py) = (seen.0 / w * 1920.0, seen.1 / h * 1080.0);
    let listed = packets.iter().rev().take(3).any(|p| {
        p["boxes"].as_array().unwrap().iter().any(|b| {
            let (bx, by) = (b["x"].as_f64().unwrap(), b["y"].as_f64().unwrap());
            let (bw, bh) = (b["w"].as_f64().unwrap(), b["h"].as_f64().unwrap());
            let margin = 60.0;
            (bx - margin..=bx + bw + margin).contains(&px)
                && (by - margin..=by + bh + margin).contains(&py)
        })
    });
    assert!(
        listed,
        "the mover at {px:.0}, {py:.0} in none of {packets:?}"
    );
    assert!(
        packets
            .iter()
            .all(|p| p["magic"] == 0x4744 && p["version"] == 1)
    );

    // Stopped: idle.
    assert_eq!(sdk.ask(&json!({"track_mode": 0})), 0);
    let heard = sdk.ask(&json!({"listen": 0.5}));
    assert_eq!(heard["items"]["7"]["value"], 0.0, "{heard}");
}
