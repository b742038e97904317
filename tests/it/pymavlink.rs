//! pymavlink, the MAVLink implementation most Python tools and scripts use, against a running
//! `serve` (tests/peers/pymavlink_station.py): stream requests with NaN
//! or 0 in what they do not use, and every gimbal and camera command the same as COMMAND_LONG
//! and as COMMAND_INT.

use crate::common;

use common::autopilot::free_udp_port;
use common::peers::run_peer;
use common::serve::Serve;
use digiview::control::client::Client;
use digiview::geometry::ground::{GeoPoint, to_ned};
use digiview::protocol::Param;
use digiview::protocol::params::CamTarget;
use serde_json::Value;
use std::time::Duration;

#[test]
fn pymavlink_gets_the_streams_with_nan_or_zero_and_each_command_the_same_long_or_int() {
    let link = free_udp_port();
    // The vehicle 100 m above home; the view pointed at a spot on the ground near it.
    let serve = Serve::start(&[
        "--mavlink",
        &format!("udpin:127.0.0.1:{link}"),
        "--position",
        "lat=47.0,lon=8.0,alt=600,rel=100",
    ]);
    let spot = ["47.0004", "8.0002", "500"];
    let (out, err) = run_peer(
        "pymavlink_station.py",
        &[&link.to_string(), spot[0], spot[1], spot[2]],
    );
    let events: Vec<Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}\n{err}")))
        .collect();

    let streams: Vec<&Value> = events.iter().filter(|e| e["event"] == "streams").collect();
    assert_eq!(streams.len(), 4, "{out}");
    for s in streams {
        assert_eq!(s["result"], "MAV_RESULT_ACCEPTED", "{s}");
        assert_eq!(s["ids"], serde_json::json!([1, 2]), "{s}");
    }

    let commands: Vec<&Value> = events.iter().filter(|e| e["event"] == "command").collect();
    assert_eq!(commands.len(), 4, "{out}");
    for c in commands {
        assert_eq!(c["long"][0], "MAV_RESULT_ACCEPTED", "{c}");
        assert_eq!(c["long"][0], c["int"][0], "the same answer either way: {c}");
        assert!(
            alike(&c["long"][1], &c["int"][1]),
            "the same state either way: {c}"
        );
        assert_ne!(
            c["long"][1], c["before"],
            "the command changed something: {c}"
        );
    }

    // CAMERA_FOV_STATUS's image centre is where the DigiView protocol says the centre of the
    // view meets the ground (CAM_TARGET of the pixel a thousandth of the width off centre,
    // some 0.2 m away there), and its hfov is CAM_FOV's (which the protocol rounds).
    let fov = events.iter().find(|e| e["event"] == "fov").expect("fov");
    assert_eq!(fov["result"], "MAV_RESULT_ACCEPTED", "{fov}");
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(3)).unwrap();
    let asked = Param::CamTarget(CamTarget {
        cam_id: 1,
        x: 1e-3,
        ..Default::default()
    });
    let Param::CamTarget(t) = ctl.get_one(asked).unwrap() else {
        panic!("not a CAM_TARGET")
    };
    let said = GeoPoint {
        lat: fov["lat_image"].as_f64().unwrap(),
        lon: fov["lon_image"].as_f64().unwrap(),
        alt: fov["alt_image"].as_f64().unwrap(),
    };
    let centre = GeoPoint {
        lat: t.t_latitude,
        lon: t.t_longitude,
        alt: t.t_altitude,
    };
    let off = to_ned(centre, said).length();
    println!("CAMERA_FOV_STATUS's centre is {off:.3} m from CAM_TARGET's: {fov}");
    assert!(off < 2.0, "{off:.2} m apart: {fov} and {centre:?}");
    assert!(
        (fov["lat_camera"].as_f64().unwrap() - 47.0).abs() < 1e-6,
        "{fov}"
    );
    let hfov = common::gcs::fov(&mut ctl, 1);
    assert!(
        (fov["hfov"].as_f64().unwrap() - hfov).abs() < 0.05,
        "{fov}: {hfov}"
    );

    // Click to track, as pymavlink reads it: following the centre of that same picture, the
    // image status puts it at the centre and the geo status where CAMERA_FOV_STATUS's centre
    // is; after the stop (as COMMAND_INT) the last status says idle.
    let track = events
        .iter()
        .find(|e| e["event"] == "track")
        .expect("track");
    assert_eq!(track["result"], "MAV_RESULT_ACCEPTED", "{track}");
    assert_eq!(track["stop"], "MAV_RESULT_ACCEPTED", "{track}");
    let image = track["image"].as_array().unwrap();
    assert!(!image.is_empty(), "{track}");
    for i in image {
        // Active (1), point mode (1), at the centre, radius 0.05 as clicked.
        let n = |k: usize| i[k].as_f64().unwrap();
        assert_eq!((n(0), n(1)), (1.0, 1.0), "{i}");
        assert!(
            (n(2) - 0.5).abs() < 0.01 && (n(3) - 0.5).abs() < 0.01,
            "{i}"
        );
        assert!((n(4) - 0.05).abs() < 0.005, "{i}");
    }
    let geo = track["geo"]
        .as_array()
        .unwrap()
        .last()
        .cloned()
        .expect("a geo status");
    let at = GeoPoint {
        lat: geo[1].as_f64().unwrap(),
        lon: geo[2].as_f64().unwrap(),
        alt: geo[3].as_f64().unwrap(),
    };
    let off = to_ned(said, at).length();
    println!("CAMERA_TRACKING_GEO_STATUS is {off:.3} m from CAMERA_FOV_STATUS's centre: {geo}");
    assert!(off < 2.0, "{off:.2} m apart: {geo} and {said:?}");
    let idle = track["idle"].as_array().unwrap().last().cloned();
    assert_eq!(idle, Some(serde_json::json!([0, 0])), "{track}");
    drop(serve);
}

/// The same state: equal, but for numbers within 0.002 (COMMAND_LONG carries a latitude as a
/// float, good to about half a metre; COMMAND_INT to a centimetre).
fn alike(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Array(a), Value::Array(b)) => {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| alike(x, y))
        }
        (Value::Number(x), Value::Number(y)) => {
            (x.as_f64().unwrap() - y.as_f64().unwrap()).abs() < 2e-3
        }
        _ => a == b,
    }
}
