//! The views as gimbal devices (`serve --mavlink-gimbal device`), managed by an autopilot's
//! MAVLink gimbal driver replayed from its source with pymavlink (tests/peers/
//! gimbal_driver.py): ArduPilot's finds view 0 at component 154 by its heartbeat, gets its
//! information and points it by angle (from the nose and in the earth frame), by rate and
//! retracts it; PX4's finds it by asking everyone and points it with its own flags. The view
//! turns where the driver asked (its CAM_EULER and lock flags over the DigiView protocol, and
//! the attitude the device reports), the vehicle's heading coming from the driver's
//! AUTOPILOT_STATE_FOR_GIMBAL_DEVICE; the device's attitude never pauses over 0.5 s; and
//! `--allow-set none` holds on this path too. A ground station behind a router (MAVProxy)
//! sees each view's camera and gimbal device.

use crate::common;

use common::autopilot::free_udp_port;
use common::gcs::euler;
use common::gcs::{Gcs, REQUEST, accepted, params, text};
use common::peers::{LinePeer, python};
use common::serve::Serve;
use digiview::control::client::Client;
use digiview::protocol::Param;
use digiview::protocol::params::CamLockFlags;
use mavlink::MessageData;
use mavlink::dialects::common::*;
use serde_json::{Value, json};
use std::collections::BTreeSet;
use std::process::{Command, Stdio};
use std::time::Duration;

/// The vehicle's heading the driver reports, degrees.
const HEADING: f64 = 40.0;

/// `serve` (no video) with its four views as gimbal devices on a free link port (returned),
/// `extra` flags beside.
fn devices(extra: &[&str]) -> (Serve, u16) {
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    let mut flags = vec![
        "--mavlink",
        &link,
        "--mavlink-gimbal",
        "device",
        "--layout",
        "4",
    ];
    flags.extend_from_slice(extra);
    (Serve::start(&flags), port)
}

/// As [`devices`], with the driver `flavour` managing them once it has found its device.
fn managed(flavour: &str, extra: &[&str]) -> (Serve, Client, LinePeer, Value) {
    let (serve, port) = devices(extra);
    let ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(3)).unwrap();
    let (driver, ready) = LinePeer::start(
        "gimbal_driver.py",
        &[&port.to_string(), flavour, &HEADING.to_string()],
    );
    assert_eq!(
        ready["ready"], true,
        "the {flavour} driver found its device: {ready}"
    );
    (serve, ctl, driver, ready)
}

fn lock_flags(ctl: &mut Client, cam: u8) -> u8 {
    match ctl
        .get_one(Param::CamLockFlags(CamLockFlags {
            cam_id: cam,
            ..Default::default()
        }))
        .unwrap()
    {
        Param::CamLockFlags(l) => l.flags,
        other => panic!("{other:?}"),
    }
}

/// The difference of two angles in degrees, within ±180.
fn off(a: f64, b: f64) -> f64 {
    (a - b + 540.0).rem_euclid(360.0) - 180.0
}

/// The view's yaw, pitch and roll in the earth frame as the device last reported them.
fn reported(answer: &Value, which: &str) -> (f64, f64, f64) {
    let s = &answer[which];
    let deg = |k: &str| s[k].as_f64().unwrap_or_else(|| panic!("{k} in {answer}"));
    (deg("yaw"), deg("pitch"), deg("roll"))
}

/// The device's attitude came on at least 8 Hz and never paused over 0.5 s (ArduPilot
/// counts a gimbal unhealthy after 1 s without it).
fn steady(answer: &Value, since_start: f64) {
    let (count, longest) = (
        answer["statuses"].as_f64().unwrap(),
        answer["longest_pause"].as_f64().unwrap(),
    );
    assert!(
        longest <= 0.5,
        "the device's attitude paused {longest:.3} s"
    );
    assert!(
        count >= 8.0 * since_start,
        "{count} statuses in {since_start:.1} s"
    );
}

#[test]
fn ardupilots_mount_driver_finds_view_0_at_154_and_points_retracts_and_turns_it() {
    let (_serve, mut ctl, mut driver, ready) = managed("ardupilot", &[]);
    let view_1 = (euler(&mut ctl, 1), lock_flags(&mut ctl, 1));
    // A gimbal device per view, heartbeating where ArduPilot's mounts 1 to 4 look.
    assert_eq!(ready["gimbals"], json!([154, 171, 172, 173]), "{ready}");
    let info = &ready["info"];
    assert_eq!(info["component"], 154, "{info}");
    assert_eq!(info["vendor_name"], "DigiView", "{info}");
    let limit = |k: &str| info[k].as_f64().unwrap().to_degrees();
    assert!((limit("pitch_min") + 90.0).abs() < 0.01 && (limit("pitch_max") - 90.0).abs() < 0.01);
    assert!((limit("yaw_max") - 180.0).abs() < 0.01, "{info}");
    let mut elapsed = 0.0;
    let mut ask = |driver: &mut LinePeer, ask: Value| {
        elapsed += ask["for"].as_f64().unwrap();
        let answer = driver.ask(&ask);
        steady(&answer, elapsed);
        answer
    };

    // Yaw from the nose (flags 0): 20° right of the vehicle's 40° heading, 30° down. Pitch is
    // from the horizon as ArduPilot's targets are; the view follows the vehicle.
    let a = ask(
        &mut driver,
        json!({"do": "angle", "pitch": -30, "yaw": 20, "for": 1.0}),
    );
    let (yaw, pitch, _) = reported(&a, "last");
    assert!(
        off(yaw, HEADING + 20.0).abs() < 1.0 && (pitch + 30.0).abs() < 1.0,
        "{a}"
    );
    let (cy, cp, _) = euler(&mut ctl, 0);
    assert!(
        off(cy, 20.0).abs() < 1.0 && (cp + 30.0).abs() < 1.0,
        "CAM_EULER {cy} {cp}"
    );
    assert_eq!(
        lock_flags(&mut ctl, 0),
        0,
        "an angle from the nose locks nothing"
    );

    // Earth frame (ROLL|PITCH|YAW_LOCK): due north-west, 10° down, held in the world.
    let a = ask(
        &mut driver,
        json!({"do": "angle", "pitch": -10, "yaw": -45, "earth": true, "for": 1.0}),
    );
    let (yaw, pitch, _) = reported(&a, "last");
    assert!(
        off(yaw, -45.0).abs() < 1.0 && (pitch + 10.0).abs() < 1.0,
        "{a}"
    );
    assert_eq!(
        lock_flags(&mut ctl, 0),
        7,
        "an earth-frame angle locks every axis"
    );
    let (cy, _, _) = euler(&mut ctl, 0);
    assert!(off(cy, -45.0).abs() < 1.0, "CAM_EULER yaw {cy}");
    // The all-zero quaternion is no rotation: refused whole, the axes stay locked.
    ask(&mut driver, json!({"do": "zero", "for": 0.5}));
    assert_eq!(
        lock_flags(&mut ctl, 0),
        7,
        "the all-zero quaternion unlocked the view"
    );

    // A rate: 30°/s of yaw, measured between two of the device's reports once it turns
    // (by the device's own times).
    let a = ask(
        &mut driver,
        json!({"do": "rate", "yaw": 30, "earth": true, "for": 2.0, "settle": 0.5}),
    );
    let (first, last) = (reported(&a, "first"), reported(&a, "last"));
    let dt = a["last"]["t"].as_f64().unwrap() - a["first"]["t"].as_f64().unwrap();
    assert!(dt >= 1.0, "{a}");
    let rate = off(last.0, first.0) / dt;
    eprintln!(
        "turned at {rate:.2}°/s; {} statuses, the longest pause {:.3} s",
        a["statuses"], a["longest_pause"]
    );
    assert!(
        (rate - 30.0).abs() < 1.5,
        "turned at {rate:.1}°/s, not 30: {a}"
    );
    assert!((last.1 - first.1).abs() < 0.5, "the pitch stayed: {a}");

    // Retract: the view as a camera fixed to the airframe, ahead and level, following it.
    let a = ask(&mut driver, json!({"do": "retract", "for": 1.0}));
    let (yaw, pitch, _) = reported(&a, "last");
    assert!(off(yaw, HEADING).abs() < 1.0 && pitch.abs() < 1.0, "{a}");
    assert_eq!(lock_flags(&mut ctl, 0), 0);
    let (cy, cp, cr) = euler(&mut ctl, 0);
    assert!(
        cy.abs() < 0.01 && cp.abs() < 0.01 && cr.abs() < 0.01,
        "{cy} {cp} {cr}"
    );
    // The other views were not the driver's to move.
    assert_eq!((euler(&mut ctl, 1), lock_flags(&mut ctl, 1)), view_1);
}

#[test]
fn px4s_gimbal_output_finds_the_first_view_by_asking_everyone_and_points_it() {
    let (_serve, mut ctl, mut driver, ready) = managed("px4", &[]);
    // Every device answered; the last to answer, the one PX4 keeps, is the first view's.
    assert_eq!(ready["device"], 154, "{ready}");
    // Before any setpoint PX4 holds roll and pitch on the horizon and lets yaw follow.
    assert_eq!(lock_flags(&mut ctl, 0), 3);
    // Yaw absolute (YAW_LOCK, no frame flag): 100° in the earth frame, 20° down.
    let a =
        driver.ask(&json!({"do": "angle", "pitch": -20, "yaw": 100, "earth": true, "for": 1.0}));
    steady(&a, 1.0);
    let (yaw, pitch, _) = reported(&a, "last");
    assert!(
        off(yaw, 100.0).abs() < 1.0 && (pitch + 20.0).abs() < 1.0,
        "{a}"
    );
    assert_eq!(lock_flags(&mut ctl, 0), 7);
    // Yaw following the vehicle (ROLL|PITCH_LOCK): 100° from the nose.
    let a = driver.ask(&json!({"do": "angle", "pitch": -20, "yaw": 100, "for": 1.0}));
    let (yaw, _, _) = reported(&a, "last");
    assert!(off(yaw, HEADING + 100.0).abs() < 1.0, "{a}");
    assert_eq!(lock_flags(&mut ctl, 0), 3);
}

#[test]
fn with_allow_set_none_the_gimbal_driver_moves_no_view() {
    let (_serve, mut ctl, mut driver, _) = managed("ardupilot", &["--allow-set", "none"]);
    let before = (euler(&mut ctl, 0), lock_flags(&mut ctl, 0));
    let a = driver.ask(&json!({"do": "angle", "pitch": -60, "yaw": 90, "for": 1.0}));
    // Still a healthy device to its autopilot: it reports, and reports the view unmoved
    // (held in the world ahead of north, 30° down, as it starts).
    steady(&a, 1.0);
    assert_eq!((euler(&mut ctl, 0), lock_flags(&mut ctl, 0)), before);
    let ((yaw, pitch, _), locks) = before;
    assert!(
        yaw.abs() < 0.1 && (pitch + 30.0).abs() < 0.1 && locks == 7,
        "{before:?}"
    );
    let (yaw, pitch, _) = reported(&a, "last");
    assert!(
        off(yaw, 0.0).abs() < 1.0 && (pitch + 30.0).abs() < 1.0,
        "{a}"
    );
}

/// A ground station that reaches DigiView only through a router on the companion computer
/// (MAVProxy, forwarding between its master and its outputs as mavlink-router does) sees
/// each view's camera and its gimbal device, and gets the device's information and the
/// camera's pairing with it through the router.
#[test]
fn a_ground_station_behind_a_router_sees_each_views_camera_and_gimbal_device() {
    let (_serve, port) = devices(&[]);
    let dir = tempfile::tempdir().unwrap();
    let gcs_port = free_udp_port();
    let router = Command::new(python())
        .arg(python().with_file_name("mavproxy.py"))
        .arg(format!("--master=udpout:127.0.0.1:{port}"))
        .arg(format!("--out=udpin:127.0.0.1:{gcs_port}"))
        .args([
            "--daemon",
            "--non-interactive",
            "--default-modules=",
            "--state-basedir",
        ])
        .arg(dir.path())
        .current_dir(dir.path())
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("MAVProxy starts (scripts/setup.sh installs it)");
    let _router = Killed(router);
    let gcs = Gcs::connect(gcs_port);
    let heard = gcs.collect(Duration::from_secs(8));
    let kinds = |t: MavType| -> BTreeSet<u8> {
        heard
            .iter()
            .filter(|(_, m)| matches!(m, MavMessage::HEARTBEAT(h) if h.mavtype == t))
            .map(|(h, _)| h.component_id)
            .collect()
    };
    assert_eq!(
        kinds(MavType::MAV_TYPE_CAMERA),
        BTreeSet::from([100, 101, 102, 103])
    );
    assert_eq!(
        kinds(MavType::MAV_TYPE_GIMBAL),
        BTreeSet::from([154, 171, 172, 173])
    );
    let system = heard[0].0.system_id as u8;
    let info = |component: u8, id: u32| {
        let answer = gcs.command(system, component, REQUEST, params(&[id as f32]));
        accepted(answer, "through the router")
    };
    let device = info(154, GIMBAL_DEVICE_INFORMATION_DATA::ID);
    assert!(
        device
            .iter()
            .any(|m| matches!(m, MavMessage::GIMBAL_DEVICE_INFORMATION(d)
            if text(d.vendor_name.as_ref()) == "DigiView")),
        "{device:?}"
    );
    let camera = info(100, CAMERA_INFORMATION_DATA::ID);
    assert!(
        camera
            .iter()
            .any(|m| matches!(m, MavMessage::CAMERA_INFORMATION(c)
            if c.gimbal_device_id == 154)),
        "{camera:?}"
    );
}

/// A child process killed when dropped.
struct Killed(std::process::Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}
