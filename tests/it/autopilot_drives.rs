//! A real autopilot on DigiView's link, ArduPilot replayed from its source with pymavlink
//! (tests/peers/autopilot.py): it takes the place of the demo's simulated flight, which is
//! also system 1, component 1 (the status, the log and ground stations are told, and its
//! attitude is asked for at once); a second sender of attitude is a warning; and a survey
//! line triggered by distance at 2 photos a second yields one still and one
//! CAMERA_IMAGE_CAPTURED per trigger, in order, each placed (as exiftool reads it) where the
//! autopilot was at its frame's time and looking where the view looked.

use crate::common;

use common::exif::{number, read};
use common::gcs::http_get;
use common::peers::LinePeer;
use common::serve::{CaptureConfig, Serve, with_stills};
use digiview::control::client::Client;
use digiview::protocol::Param;
use digiview::protocol::params::Autopilot;
use serde_json::{Value, json};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Where the autopilot starts: south and east of the equator and meridian.
const LAT: f64 = -35.363_261_8;
const LON: f64 = 149.165_230_2;
const ALT: f64 = 584.0;
/// Its heading, degrees: view 0, held to the airframe 30° right of the nose, looks east.
const HEADING: f64 = 60.0;

struct Head {
    serve: Serve,
    ctl: Client,
    port: u16,
    config: CaptureConfig,
}

/// `serve` on the demo, its link on a free UDP port, view 0 held to the airframe 30° right
/// of the nose and 45° down with a 90° pinhole, stills written to a directory of the test's.
fn head(extra: &[&str]) -> Head {
    let view_0 = ["--cam", "0:yaw=30deg,pitch=-45deg,fov=90deg,crop=1,lock=0"];
    let (config, serve, port) = with_stills(&[&view_0, extra].concat(), Some("info"));
    let ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(3)).unwrap();
    Head {
        serve,
        ctl,
        port,
        config,
    }
}

fn autopilot_param(ctl: &mut Client) -> Autopilot {
    match ctl.get_one(Param::Autopilot(Autopilot::default())).unwrap() {
        Param::Autopilot(a) => a,
        other => panic!("{other:?}"),
    }
}

/// AUTOPILOT once `ok` holds, within `limit`.
fn until(
    ctl: &mut Client,
    limit: Duration,
    what: &str,
    ok: impl Fn(&Autopilot) -> bool,
) -> Autopilot {
    let end = Instant::now() + limit;
    loop {
        let a = autopilot_param(ctl);
        if ok(&a) {
            return a;
        }
        assert!(Instant::now() < end, "{what} within {limit:?}: {a:?}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// ArduPilot (or PX4, with `px4` in `more`) as system `system`, heading `heading`, on
/// `head`'s link, once it has found DigiView's camera.
fn autopilot(head: &Head, system: u8, heading: f64, more: &[&str]) -> LinePeer {
    let args = [
        head.port.to_string(),
        system.to_string(),
        LAT.to_string(),
        LON.to_string(),
        ALT.to_string(),
        heading.to_string(),
    ];
    let mut args: Vec<&str> = args.iter().map(String::as_str).collect();
    args.extend_from_slice(more);
    let (peer, ready) = LinePeer::start("autopilot.py", &args);
    assert_eq!(
        ready["ready"], true,
        "the autopilot found camera 100: {ready}"
    );
    peer
}

/// Yaw and pitch in degrees of CAMERA_IMAGE_CAPTURED's quaternion (w, x, y, z).
fn yaw_pitch(captured: &Value) -> (f64, f64) {
    let q: Vec<f64> = captured["q"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let q = glam::DQuat::from_xyzw(q[1], q[2], q[3], q[0]);
    let (yaw, pitch, _) = q.to_euler(glam::EulerRot::ZYX);
    (yaw.to_degrees().rem_euclid(360.0), pitch.to_degrees())
}

/// A still the autopilot asked for was taken where it was, looking where view 0 looks from
/// its heading.
fn shot_from(peer: &mut LinePeer, heading: f64) {
    let shot = &peer.ask(&json!({"shoot": true}))["captured"];
    assert_eq!(shot["result"], 1, "{shot}");
    let truth = &shot["truth"];
    for k in ["lat", "lon"] {
        let (got, want) = (shot[k].as_f64().unwrap(), truth[k].as_f64().unwrap());
        assert!((got - want).abs() < 1e-6, "{k} {got} against {want}");
    }
    let (yaw, pitch) = yaw_pitch(shot);
    assert!((yaw - (heading + 30.0)).abs() < 0.1, "yaw {yaw}: {shot}");
    assert!((pitch + 45.0).abs() < 0.1, "pitch {pitch}: {shot}");
}

fn api_autopilot(serve: &Serve) -> Value {
    let url = format!("{}api/status", serve.http.as_ref().unwrap());
    let (status, body) = http_get(&url);
    assert_eq!(status, 200);
    serde_json::from_slice::<Value>(&body).unwrap()["autopilot"].clone()
}

#[test]
fn a_real_autopilot_takes_the_demos_place_and_a_second_sender_of_attitude_is_a_warning() {
    let mut head = head(&[]);
    // The demo's flight drives the views first, as system 1, component 1, and says so.
    let a = until(
        &mut head.ctl,
        Duration::from_secs(20),
        "the demo flying",
        |a| a.link == 3 && a.simulated == 1,
    );
    assert_eq!((a.system_id, a.component_id), (1, 1));
    assert_eq!(api_autopilot(&head.serve)["simulated"], 1);

    let mut ardupilot = autopilot(&head, 1, HEADING, &[]);
    let a = until(
        &mut head.ctl,
        Duration::from_secs(5),
        "the autopilot in its place",
        |a| a.simulated == 0 && a.link == 3 && a.attitude_rate >= 50,
    );
    assert_eq!((a.system_id, a.component_id, a.others), (1, 1, 0));
    let heard = ardupilot.ask(&json!({"heard": true}));
    let asked = heard["asked"].as_array().unwrap();
    assert!(
        asked.iter().any(|a| a[0] == 30 && a[2] == 1 && a[3] == 1),
        "its attitude asked for: {heard}"
    );
    let texts = heard["texts"].to_string();
    assert!(
        texts.contains("DigiView: autopilot 1/1 replaces demo flight"),
        "{texts}"
    );
    let status = api_autopilot(&head.serve);
    assert_eq!(
        (status["simulated"].clone(), status["system_id"].clone()),
        (json!(0), json!(1))
    );
    // The views follow it: view 0 looks 30° right of its heading, from where it is.
    shot_from(&mut ardupilot, HEADING);

    // A second vehicle's attitude on the same link is ignored, and said.
    let _other = autopilot(&head, 2, 0.0, &[]);
    let a = until(
        &mut head.ctl,
        Duration::from_secs(5),
        "the second sender",
        |a| a.others == 1,
    );
    assert_eq!((a.other_system, a.other_component, a.system_id), (2, 1, 1));
    assert_eq!(api_autopilot(&head.serve)["other_system"], 2);
    let texts = ardupilot.ask(&json!({"heard": true}))["texts"].to_string();
    assert!(
        texts.contains("DigiView: attitude from 2/1 ignored"),
        "{texts}"
    );
    shot_from(&mut ardupilot, HEADING);

    drop((ardupilot, _other));
    head.serve.terminate();
    let log = head.serve.log();
    common::assert_logged(
        &log,
        &[
            "the demo's simulated flight drives the views as system 1, component 1",
            "the autopilot is system 1, component 1",
            "the demo's simulated flight steps aside",
            "two senders of attitude: mavlink 2/1",
        ],
    );
}

/// A survey line flown by `flavour`'s autopilot for `seconds`: 10 m/s east-north-east,
/// climbing 0.5 m/s, a picture every 5 m. Every trigger is one still and one
/// CAMERA_IMAGE_CAPTURED, in order, each placed where the autopilot was at its frame's time.
fn survey(flavour: &[&str], seconds: f64) {
    let mut head = head(&["--demo-hover"]);
    let mut ardupilot = autopilot(&head, 1, HEADING, flavour);
    until(
        &mut head.ctl,
        Duration::from_secs(5),
        "the autopilot's attitude",
        |a| a.simulated == 0 && a.attitude_rate >= 50,
    );
    let fly = json!({"fly": {"speed": 10.0, "climb": 0.5, "for": seconds, "trigg_dist": 5.0}});
    let flown = ardupilot.ask(&fly);
    let triggers = flown["triggers"].as_array().unwrap();
    let captured = flown["captured"].as_array().unwrap();
    assert!(
        triggers.len() as f64 >= 2.0 * seconds - 5.0,
        "2 a second for {seconds} s: {}",
        triggers.len()
    );
    assert_eq!(
        captured.len(),
        triggers.len(),
        "one CAMERA_IMAGE_CAPTURED per trigger"
    );
    // Each IMAGE_START_CAPTURE accepted (PX4's DO_DIGICAM_CONTROL beside it is not one).
    let acks = flown["acks"].as_array().unwrap();
    let resent: u64 = triggers
        .iter()
        .map(|t| t["sent"].as_u64().unwrap() - 1)
        .sum();
    assert!(
        acks.len() >= triggers.len() && acks.iter().all(|r| r == 0),
        "{acks:?}"
    );
    for pair in captured.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        assert_eq!(
            b["image_index"].as_i64(),
            a["image_index"].as_i64().map(|i| i + 1)
        );
        assert!(
            b["time_utc"].as_u64() > a["time_utc"].as_u64(),
            "in order: {a} {b}"
        );
    }
    let files: Vec<PathBuf> = captured
        .iter()
        .map(|c| {
            assert_eq!(c["result"], 1, "{c}");
            let url = c["url"].as_str().unwrap();
            head.config.captures.join(url.rsplit('/').next().unwrap())
        })
        .collect();
    let written = std::fs::read_dir(&head.config.captures).unwrap().count();
    assert_eq!(written, files.len(), "one still per trigger, and no other");
    let paths: Vec<&std::path::Path> = files.iter().map(PathBuf::as_path).collect();
    let mut worst = (0f64, 0f64, 0f64);
    for (c, tags) in captured.iter().zip(read(&paths)) {
        let truth = &c["truth"];
        let off = |tag: &str, k: &str| (number(&tags, tag) - truth[k].as_f64().unwrap()).abs();
        let (lat, lon) = (
            off("Composite:GPSLatitude", "lat"),
            off("Composite:GPSLongitude", "lon"),
        );
        let alt = off("Composite:GPSAltitude", "alt");
        assert!(
            lat < 1e-6 && lon < 1e-6 && alt < 0.1,
            "{lat} {lon} {alt}: {c} {tags:#}"
        );
        worst = (worst.0.max(lat), worst.1.max(lon), worst.2.max(alt));
        let angle = |k: &str| number(&tags, &format!("XMP-drone-dji:Gimbal{k}Degree"));
        let yaw = (angle("Yaw") - (HEADING + 30.0) + 540.0).rem_euclid(360.0) - 180.0;
        assert!(yaw.abs() < 0.1, "{tags:#}");
        assert!(
            (angle("Pitch") + 45.0).abs() < 0.1 && angle("Roll").abs() < 0.1,
            "{tags:#}"
        );
        // 90° across on a 36 mm wide frame is 18 mm.
        assert!(
            (number(&tags, "ExifIFD:FocalLength") - 18.0).abs() < 0.001,
            "{tags:#}"
        );
    }
    eprintln!(
        "{flavour:?}: {} triggers ({resent} sent again), {} stills; worst off the line: {:.1e}° latitude, {:.1e}° longitude, {:.3} m altitude",
        triggers.len(),
        files.len(),
        worst.0,
        worst.1,
        worst.2
    );
}

/// ArduPilot's camera backend for the 60 s of a survey's leg.
#[test]
fn a_survey_triggered_by_distance_at_two_photos_a_second_loses_none_and_places_each() {
    survey(&[], 60.0);
}

/// PX4 sends each trigger twice over (IMAGE_START_CAPTURE to the camera and
/// DO_DIGICAM_CONTROL to everyone): still one picture each.
#[test]
fn px4s_trigger_by_distance_gives_one_still_per_trigger() {
    survey(&["px4"], 20.0);
}
