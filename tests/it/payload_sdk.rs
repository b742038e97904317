//! An app written with Gremsy's PayloadSdk on DigiView's payload link, replayed with pymavlink
//! from the SDK's source (tests/peers/payload_sdk.py; the C++ SDK 3.0.0 and the Python SDK
//! 3.0.0, as the script names them) on the flying demo: it finds one camera (100) and one
//! gimbal (154) and nothing else, lists and sets its settings under Gremsy's names, zooms in
//! each form, takes exactly one still with interval 0 and count 0, records on the same view,
//! reads its status items and the gimbal's attitude at 10 Hz without a ground station's
//! heartbeat, and every command or parameter a view cannot take is answered and logged. With
//! `--allow-set none` nothing it sends changes a view.

use crate::common;

use common::autopilot::free_udp_port;
use common::peers::LinePeer;
use common::serve::{CaptureConfig, Serve, with_stills};
use digiview::control::client::Client;
use digiview::protocol::Param;
use digiview::protocol::params::{CamFov, CamLockFlags};
use serde_json::{Value, json};
use std::time::Duration;

/// The view the app drives: the layout's second camera.
const VIEW: u8 = 1;
/// MAVLink's results and PARAM_EXT_ACK's.
const ACCEPTED: u64 = 0;
const DENIED: u64 = 2;
const UNSUPPORTED: u64 = 3;
const PARAM_VALUE_UNSUPPORTED: u64 = 1;
const PARAM_FAILED: u64 = 2;

struct Head {
    serve: Serve,
    ctl: Client,
    config: CaptureConfig,
    sdk: LinePeer,
}

/// `serve` with its payload link on a free port driving view [`VIEW`], and the SDK (`python`:
/// the Python SDK's capture) connected to it.
fn head(extra: &[&str], python: bool) -> Head {
    let port = free_udp_port();
    let payload = format!("udpin:127.0.0.1:{port}");
    let view = VIEW.to_string();
    let flags = [&["--payload", &payload, "--payload-view", &view][..], extra].concat();
    let (config, serve, _) = with_stills(&flags, Some("info"));
    let ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(3)).unwrap();
    let mut args = vec![port.to_string()];
    if python {
        args.push("python".into());
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let (sdk, ready) = LinePeer::start("payload_sdk.py", &args);
    assert_eq!(ready["ready"], true, "the SDK connected: {ready}");
    assert_eq!(
        (&ready["camera"], &ready["gimbal"]),
        (&json!(100), &json!(154))
    );
    Head {
        serve,
        ctl,
        config,
        sdk,
    }
}

fn lock_flags(ctl: &mut Client) -> u8 {
    let ask = Param::CamLockFlags(CamLockFlags {
        cam_id: VIEW,
        ..Default::default()
    });
    match ctl.get_one(ask).unwrap() {
        Param::CamLockFlags(l) => l.flags,
        other => panic!("{other:?}"),
    }
}

fn fov_degrees(ctl: &mut Client) -> f64 {
    let ask = Param::CamFov(CamFov {
        cam_id: VIEW,
        ..Default::default()
    });
    match ctl.get_one(ask).unwrap() {
        Param::CamFov(f) => f.fov.to_degrees(),
        other => panic!("{other:?}"),
    }
}

fn set(sdk: &mut LinePeer, name: &str, v: u32) -> (u64, u64) {
    let a = sdk.ask(&json!({"set": [name, v]}));
    (a["result"].as_u64().unwrap(), a["value"].as_u64().unwrap())
}

/// The files in the captures directory ending in `ext`.
fn captured(config: &CaptureConfig, ext: &str) -> Vec<std::path::PathBuf> {
    let Ok(dir) = std::fs::read_dir(&config.captures) else {
        return vec![];
    };
    let mut files: Vec<_> = dir
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().ends_with(ext))
        .collect();
    files.sort();
    files
}

#[test]
fn an_sdk_app_drives_one_view_through_its_settings_zoom_capture_and_recording() {
    let mut h = head(&[], false);
    let sdk = &mut h.sdk;

    // The settings list, under Gremsy's names; the gimbal modes are the view's locks.
    let list = sdk.ask(&json!({"settings": true}));
    for name in [
        "GB_MODE",
        "C_SOURCE",
        "OSD_MODE",
        "TRACK_MODE",
        "C_V_ZM_CB_LV",
        "C_V_SP",
    ] {
        assert!(list.get(name).is_some(), "{name} listed: {list}");
    }
    assert_eq!(set(sdk, "GB_MODE", 1), (ACCEPTED, 1));
    assert_eq!(lock_flags(&mut h.ctl), 7, "lock holds every axis");
    assert_eq!(set(sdk, "GB_MODE", 2), (ACCEPTED, 2));
    assert_eq!(lock_flags(&mut h.ctl), 3, "follow lets yaw follow the nose");
    assert_eq!(sdk.ask(&json!({"read": "GB_MODE"})), 2);

    // What a virtual view cannot do is refused with its reason, and changes nothing.
    assert_eq!(set(sdk, "C_V_DEFOG", 2).0, PARAM_FAILED);
    assert_eq!(set(sdk, "C_T_PALETTE", 1).0, PARAM_FAILED);
    assert_eq!(set(sdk, "C_SOURCE", 2), (PARAM_VALUE_UNSUPPORTED, 1));
    assert_eq!(set(sdk, "GB_MODE", 9), (PARAM_VALUE_UNSUPPORTED, 2));
    assert_eq!(lock_flags(&mut h.ctl), 3);

    // Zoom: the camera protocol's range (0: the widest), a combined level, then a step and
    // continuous zoom.
    let range = sdk.ask(&json!({"zoom": [2, 0]}));
    assert_eq!(range["ack"], ACCEPTED, "{range}");
    let widest = range["hfov"].as_f64().unwrap();
    assert!(
        (widest - fov_degrees(&mut h.ctl)).abs() < 0.1,
        "FOV status is the view's"
    );
    assert_eq!(set(sdk, "C_V_ZM_CB_LV", 2), (ACCEPTED, 2), "4x");
    let at_4x = fov_degrees(&mut h.ctl);
    assert!(
        (at_4x - widest / 4.0).abs() < 0.1,
        "4x: {at_4x:.2}° from {widest:.2}°"
    );
    let step = sdk.ask(&json!({"zoom": [0, -1]}));
    assert_eq!(step["ack"], ACCEPTED, "{step}");
    let hfov = step["hfov"].as_f64().unwrap();
    assert!(
        hfov > at_4x + 1.0,
        "a step out widens {at_4x:.1}° to {hfov:.1}°"
    );
    assert_eq!(sdk.ask(&json!({"zoom": [1, 1]}))["ack"], ACCEPTED);
    std::thread::sleep(Duration::from_millis(500));
    let stopped = sdk.ask(&json!({"zoom": [1, 0]}));
    assert!(
        stopped["hfov"].as_f64().unwrap() < hfov - 1.0,
        "continuous zoom in: {stopped}"
    );

    // The capture example: interval 0, count 0 is one still, and only one.
    let shot = sdk.ask(&json!({"capture": true}));
    assert_eq!(shot["capture_ack"], ACCEPTED, "{shot}");
    assert_eq!(shot["images_after"], 1, "{shot}");
    std::thread::sleep(Duration::from_secs(2));
    let stills = captured(&h.config, ".jpg");
    assert_eq!(stills.len(), 1, "{stills:?}");

    // Recording starts and stops on the one view; the file plays.
    let start = sdk.ask(&json!({"command": [100, 2500, 0]}));
    assert_eq!(start, ACCEPTED);
    std::thread::sleep(Duration::from_secs(3));
    assert_eq!(sdk.ask(&json!({"command": [100, 2501, 0]})), ACCEPTED);
    std::thread::sleep(Duration::from_secs(1));
    let videos = captured(&h.config, ".mp4");
    assert_eq!(videos.len(), 1, "{videos:?}");
    assert!(
        videos[0]
            .to_string_lossy()
            .ends_with(&format!("-cam{VIEW}.mp4")),
        "{videos:?}"
    );
    // Played to the end: at least a frame a second recorded (the view's own stream's rate
    // under the suite's load is not this test's to judge).
    let (frames, _) = common::probe_frames(&videos[0]);
    assert!(frames >= 3, "{frames} frames in 3 s");

    // Only the payload's components spoke on its link.
    let ids = sdk.ask(&json!({"ids": true}));
    assert_eq!(ids["heard"], json!([26, 100, 154]), "{ids}");
}

#[test]
fn the_sdk_reads_its_status_items_and_the_gimbal_and_is_answered_for_what_a_view_has_not() {
    let mut h = head(&[], true);
    let sdk = &mut h.sdk;
    assert_eq!(set(sdk, "GB_MODE", 2), (ACCEPTED, 2), "follow");
    // EO zoom, the tracker's status and the gimbal mode 5 times a second, the payload's
    // position twice; the IR temperatures are refused (no thermal sensor).
    assert_eq!(
        sdk.ask(&json!({"rates": [[0, 200], [7, 200], [24, 200], [14, 500]]})),
        true
    );
    let ir = sdk.ask(&json!({"command": [26, 511, 25, 100_000]}));
    assert_eq!(ir, UNSUPPORTED);
    let heard = sdk.ask(&json!({"listen": 2.0}));
    let items = &heard["items"];
    for (index, at_least) in [("0", 8), ("7", 8), ("24", 8), ("14", 3)] {
        let n = items[index]["count"].as_u64().unwrap_or(0);
        assert!(n >= at_least, "item {index} {n} times in 2 s: {items}");
    }
    assert!(items.get("25").is_none_or(|i| i["count"] == 1), "{items}");
    assert_eq!(items["7"]["value"], 0.0, "not tracking");
    assert_eq!(items["24"]["value"], 2.0, "follow");
    // The gimbal's attitude at 10 Hz, though no ground station heartbeats.
    let attitudes = heard["attitudes"].as_array().unwrap();
    assert!(attitudes.len() >= 16, "{} statuses in 2 s", attitudes.len());
    assert!(
        attitudes.iter().all(|a| a["mode"] == "FOLLOW_MODE"),
        "{heard}"
    );

    // The Python SDK's one photo (count 1).
    let shot = sdk.ask(&json!({"capture": true}));
    assert_eq!(shot["images_after"], 1, "{shot}");

    // Commands a view has nothing for: answered, and logged.
    let calibrate = sdk.ask(&json!({"command": [154, 179, 0, 0, 0, 0, 0, 0, 1]}));
    assert_eq!(calibrate, UNSUPPORTED, "search home");
    let bitrate = sdk.ask(&json!({"command": [26, 31013, 4, 2, 4_000_000]}));
    assert_eq!(bitrate, UNSUPPORTED, "stream bitrate");
    let focus = sdk.ask(&json!({"command": [100, 532, 1, 1]}));
    assert_eq!(focus, UNSUPPORTED, "focus");
    // The Python SDK's setFormatSDCard: deleting takes a signed message and allow_delete.
    let format = sdk.ask(&json!({"command": [100, 526, 1, 1]}));
    assert_eq!(format, DENIED, "storage format");
    assert_eq!(captured(&h.config, ".jpg").len(), 1, "the still is kept");
    drop(h.sdk);
    h.serve.terminate();
    let log = h.serve.log();
    common::assert_logged(
        &log,
        &[
            "MAV_CMD_DO_SET_HOME to the payload's gimbal 154",
            "MAV_CMD_USER_4 4 2",
            "MAV_CMD_SET_CAMERA_FOCUS is not a command DigiView's cameras take",
            "status item 25 (IR_TEMP_MAX): DigiView has no such sensor",
        ],
    );
}

#[test]
fn with_allow_set_none_the_app_changes_nothing() {
    let mut h = head(&["--allow-set", "none"], false);
    let before = (lock_flags(&mut h.ctl), fov_degrees(&mut h.ctl));
    let sdk = &mut h.sdk;
    assert_eq!(set(sdk, "GB_MODE", 1).0, PARAM_FAILED);
    assert_eq!(set(sdk, "C_V_ZM_CB_LV", 3).0, PARAM_FAILED);
    let track = sdk.ask(&json!({"track": [960, 540, 200, 200]}));
    assert_eq!(track["box"], 2, "DENIED: {track}");
    let aim = |heard: &Value| {
        let last = heard
            .as_array()
            .unwrap()
            .last()
            .cloned()
            .unwrap_or(Value::Null);
        (
            last["pitch"].as_f64().unwrap(),
            last["yaw"].as_f64().unwrap(),
        )
    };
    let was = aim(&sdk.ask(&json!({"listen": 0.5}))["attitudes"]);
    let turned = aim(&sdk.ask(&json!({"gimbal": {"angle": [-60, 0, 45], "for": 0.5}})));
    assert!(
        (was.0 - turned.0).abs() < 0.5 && (was.1 - turned.1).abs() < 0.5,
        "the gimbal turned from {was:?} to {turned:?}"
    );
    assert_eq!(before, (lock_flags(&mut h.ctl), fov_degrees(&mut h.ctl)));
}

/// How far the earth-frame yaw turned over `statuses` (degrees, unwrapped).
fn turned(statuses: &Value) -> f64 {
    let yaws: Vec<f64> = statuses
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["yaw"].as_f64().unwrap())
        .collect();
    yaws.windows(2)
        .map(|w| (w[1] - w[0] + 540.0).rem_euclid(360.0) - 180.0)
        .sum()
}

#[test]
fn gb_mode_lock_holds_the_view_to_the_earth_and_follow_turns_it_with_the_nose() {
    // The demo flies its circle (a lap in 90 s: the nose turns 4° a second).
    let mut h = head(&[], false);
    let sdk = &mut h.sdk;
    assert_eq!(set(sdk, "GB_MODE", 1), (ACCEPTED, 1));
    sdk.ask(&json!({"gimbal": {"angle": [-30, 0, 20], "for": 0.5}}));
    let held = sdk.ask(&json!({"listen": 2.5}))["attitudes"].clone();
    assert!(
        turned(&held).abs() < 0.5,
        "locked, it turned {:.2}°",
        turned(&held)
    );
    assert!(
        held.as_array()
            .unwrap()
            .iter()
            .all(|a| a["mode"] == "LOCK_MODE")
    );
    assert_eq!(set(sdk, "GB_MODE", 2), (ACCEPTED, 2));
    sdk.ask(&json!({"gimbal": {"angle": [-30, 0, 20], "for": 0.5}}));
    let following = sdk.ask(&json!({"listen": 2.5}))["attitudes"].clone();
    let t = following.as_array().unwrap().last().unwrap()["t"]
        .as_f64()
        .unwrap()
        - following[0]["t"].as_f64().unwrap();
    let rate = turned(&following) / t;
    assert!(
        (rate.abs() - 4.0).abs() < 1.0,
        "following, it turned {rate:.2}°/s"
    );
    assert!(
        following
            .as_array()
            .unwrap()
            .iter()
            .all(|a| a["mode"] == "FOLLOW_MODE")
    );
    // Mapping: straight down, its top towards the nose.
    assert_eq!(set(sdk, "GB_MODE", 3), (ACCEPTED, 3));
    let down = sdk.ask(&json!({"listen": 0.5}))["attitudes"].clone();
    let last = down.as_array().unwrap().last().unwrap();
    assert!(last["pitch"].as_f64().unwrap() < -89.5, "{last}");
    assert_eq!(last["mode"], "MAPPING_MODE");
}
