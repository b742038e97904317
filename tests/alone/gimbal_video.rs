//! The views as gimbal devices in the picture: ArduPilot's and PX4's gimbal drivers, replayed
//! with pymavlink (tests/peers/gimbal_driver.py), point view 0 in the earth frame while the
//! vehicle spins (the demo's `spin` flight, yawing 90°/s and rolling ±20° at 1 Hz, which the
//! driver reports in AUTOPILOT_STATE_FOR_GIMBAL_DEVICE as the autopilot does) and one core is
//! kept busy. In every decoded frame the ground's landmarks sit where the driver's angle
//! puts them, within 1°; the device's attitude never pauses over 0.5 s.

use crate::common;

use common::autopilot::free_udp_port;
use common::peers::LinePeer;
use common::serve::Serve;
use common::viewer::Viewer;
use common::{Load, four_view_state, view, view0_landmark_errors};
use serde_json::json;
use std::time::Duration;

const DEMO: (u32, u32) = (1280, 720);
/// Where the driver points view 0, in the earth frame: 20° east of north, 30° down.
const YAW: f64 = 20.0;
const PITCH: f64 = -30.0;

/// Landmark errors (px, sorted) in 30 decoded frames with `flavour`'s driver pointing view 0,
/// the longest pause of the device's attitude over the run (s), and pixels a degree.
fn pointed(flavour: &str) -> (Vec<f64>, f64, f64) {
    let _load = Load::start();
    let dir = tempfile::tempdir().unwrap();
    let state = four_view_state(7);
    let state_file = dir.path().join("state.toml");
    std::fs::write(&state_file, toml::to_string(&state).unwrap()).unwrap();
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    let config = dir.path().join("digiview.toml");
    let demo = format!(
        "[demo]\nspin = true\nwidth = {}\nheight = {}\n",
        DEMO.0, DEMO.1
    );
    std::fs::write(&config, demo).unwrap();
    let serve = Serve::start_video(&[
        "--config",
        config.to_str().unwrap(),
        "--mavlink",
        &link,
        "--mavlink-gimbal",
        "device",
        "--state",
        state_file.to_str().unwrap(),
    ]);
    let (mut driver, ready) =
        LinePeer::start("gimbal_driver.py", &[&port.to_string(), flavour, "spin"]);
    assert_eq!(ready["ready"], true, "{ready}");
    let ask = json!({"do": "angle", "pitch": PITCH, "yaw": YAW, "earth": true, "for": 2.0});
    driver.ask(&ask);

    // What the driver asked for, drawn from the ground truth.
    let mut want_state = state.clone();
    want_state.settings.cameras[0] = view(YAW, PITCH, 90.0, 1, 7);
    let viewer = Viewer::open(serve.rtsp.as_ref().unwrap());
    let run = (30, Duration::from_secs(1));
    let (mut errors, px_per_degree) = view0_landmark_errors(&viewer, &want_state, DEMO, run);
    // The device's attitude over the whole run, the video's included.
    let again = json!({"do": "angle", "pitch": PITCH, "yaw": YAW, "earth": true, "for": 0.5});
    let answer = driver.ask(&again);
    errors.sort_by(f64::total_cmp);
    let pause = answer["longest_pause"].as_f64().unwrap();
    (errors, pause, px_per_degree)
}

fn check(flavour: &str) {
    let _alone = crate::one_at_a_time();
    let (errors, pause, px) = pointed(flavour);
    let (median, worst) = (errors[errors.len() / 2], errors[errors.len() - 1]);
    eprintln!(
        "{flavour}, one core busy: {} landmarks in view 0, median {:.2}°, worst {:.2}° \
         ({px:.2} px a degree); the device's attitude paused {pause:.3} s at most",
        errors.len(),
        median / px,
        worst / px
    );
    assert!(
        errors.len() >= 60,
        "{} landmarks in 30 frames",
        errors.len()
    );
    assert!(
        worst <= px,
        "a landmark {:.2}° from where the driver pointed",
        worst / px
    );
    assert!(pause <= 0.5, "the device's attitude paused {pause:.3} s");
}

#[test]
fn ardupilots_driver_points_the_view_where_the_picture_shows_it_while_the_vehicle_spins() {
    check("ardupilot");
}

#[test]
fn px4s_driver_points_the_view_where_the_picture_shows_it_while_the_vehicle_spins() {
    check("px4");
}
