//! One path for every change to a view: the same random aim, zoom and target requests go to
//! one running `serve` through the DigiView protocol (over TCP, and over UDP every other
//! case), the web API and a pymavlink ground station (COMMAND_LONG and COMMAND_INT),
//! each to a camera of its own, from the same start, and the four cameras' settings come out
//! equal: to the bit between the protocol and the web API, and within what MAVLink's
//! f32 degrees carry (1e-6 rad) for its angles. Every request is accepted and changes the
//! camera. A pitch past straight up or down stops there on every path (docs/decisions.md,
//! "One rule for a view's pitch"); on the web API's and the protocol's it used to wrap.

use crate::common;

use common::autopilot::free_udp_port;
use common::peers::LinePeer;
use common::serve::Serve;
use digiview::control::client::Client;
use digiview::protocol::Param;
use digiview::protocol::params::{
    CamControlMode, CamEuler, CamFov, CamLockFlags, CamTarget, CamZoom,
};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use serde_json::{Value, json};
use std::cell::{Cell, RefCell};
use std::time::Duration;

/// What a ground station asks of a view, in the units the DigiView protocol carries exactly
/// (milliradians) and places every wire carries exactly (1/64°, whole metres).
#[derive(Clone, Copy, Debug)]
enum Request {
    Aim { yaw: i32, pitch: i32 },
    Fov(i32),
    Step(i8),
    Target { lat: i32, lon: i32, alt: i32 },
}

/// Requests that change the start (`reset`): a step of 0, or the start's own angles or
/// fov, would show nothing of the path they took.
fn requests() -> impl Strategy<Value = Request> {
    prop_oneof![
        (-3141..=3141, -2500..=2500)
            .prop_filter("not the start", |&(yaw, pitch)| (yaw, pitch) != (300, -500))
            .prop_map(|(yaw, pitch)| Request::Aim { yaw, pitch }),
        (50..=6283)
            .prop_filter("not the start", |&f| f != 1200)
            .prop_map(Request::Fov),
        prop_oneof![-15i8..=-1, 1i8..=15].prop_map(Request::Step),
        (-89 * 64..=89 * 64, -179 * 64..=179 * 64, -500..=5000)
            .prop_map(|(lat, lon, alt)| Request::Target { lat, lon, alt }),
    ]
}

/// Milliradians as radians, as the DigiView protocol decodes them (a division: the nearest
/// number to the quotient, which `mrad * 1e-3` is not always).
fn rad(mrad: i32) -> f64 {
    mrad as f64 / 1000.0
}
/// MAVLink's gimbal flags: roll, pitch and yaw held in the world, yaw from north.
const HELD: f64 = (4 | 8 | 16 | 64) as f64;

impl Request {
    /// As the DigiView protocol's SET (and the web API's PUT of the same fields).
    fn param(self, cam_id: u8) -> Param {
        match self {
            Request::Aim { yaw, pitch } => Param::CamEuler(CamEuler {
                cam_id,
                is_delta: 0,
                yaw: rad(yaw),
                pitch: rad(pitch),
                roll: 0.0,
            }),
            Request::Fov(f) => Param::CamFov(CamFov {
                cam_id,
                fov: rad(f),
            }),
            Request::Step(v) => Param::CamZoom(CamZoom {
                cam_id,
                zoom: 8 * v,
            }),
            Request::Target { lat, lon, alt } => Param::CamTarget(CamTarget {
                cam_id,
                x: 0.0,
                y: 0.0,
                t_latitude: lat as f64 / 64.0,
                t_longitude: lon as f64 / 64.0,
                t_altitude: alt as f64,
            }),
        }
    }

    /// As a MAVLink command to `camera`: COMMAND_LONG's seven params, or COMMAND_INT's.
    fn command(self, camera: u8, int: bool) -> Value {
        let deg = |mrad: i32| rad(mrad).to_degrees();
        let (command, params, place) = match self {
            // DO_GIMBAL_MANAGER_PITCHYAW: pitch, yaw, no rates, the flags.
            Request::Aim { yaw, pitch } => (
                1000,
                vec![json!(deg(pitch)), json!(deg(yaw)), Value::Null, Value::Null],
                None,
            ),
            // SET_CAMERA_ZOOM: a horizontal fov in degrees, or a step.
            Request::Fov(f) => (531, vec![json!(4), json!(deg(f))], None),
            Request::Step(v) => (531, vec![json!(0), json!(v)], None),
            // DO_SET_ROI_LOCATION: the place, above sea level.
            Request::Target { lat, lon, alt } => {
                let (lat, lon) = (lat as f64 / 64.0, lon as f64 / 64.0);
                (195, vec![json!(0); 4], Some((lat, lon, alt as f64)))
            }
        };
        let flags = matches!(self, Request::Aim { .. }).then_some(HELD);
        match (int, place) {
            (false, None) => {
                let mut p = params;
                p.extend([json!(flags.unwrap_or(0.0)), json!(0), json!(0)]);
                json!({ "camera": camera, "as": "long", "command": command, "params": p })
            }
            (false, Some((lat, lon, alt))) => {
                let p = [&params[..], &[json!(lat), json!(lon), json!(alt)]].concat();
                json!({ "camera": camera, "as": "long", "command": command, "params": p })
            }
            (true, place) => {
                let (x, y, z) = place
                    .map_or((flags.unwrap_or(0.0), 0.0, 0.0), |(lat, lon, alt)| {
                        ((lat * 1e7).round(), (lon * 1e7).round(), alt)
                    });
                json!({ "camera": camera, "as": "int", "command": command, "frame": 0,
                        "params": params, "x": x, "y": y, "z": z })
            }
        }
    }
}

/// The pymavlink ground station, a line of JSON each way.
struct Station(LinePeer);

impl Station {
    fn start(port: u16) -> Station {
        let (peer, ready) = LinePeer::start("pymavlink_steer.py", &[&port.to_string()]);
        assert_eq!(ready["ready"], true, "the station found DigiView's cameras");
        Station(peer)
    }

    /// The COMMAND_ACK's result.
    fn ask(&mut self, command: &Value) -> Value {
        self.0.ask(command)["result"].clone()
    }
}

/// The four cameras' steering as the web API reports it: per camera, the numbers each
/// parameter type holds.
fn settings(http: &str) -> Vec<Vec<(String, f64)>> {
    let (code, body) = common::gcs::http_get(&format!("{http}api/params"));
    assert_eq!(code, 200);
    let all: Value = serde_json::from_slice(&body).unwrap();
    let kinds = [
        "CAM_EULER",
        "CAM_FOV",
        "CAM_ZOOM",
        "CAM_LOCK_FLAGS",
        "CAM_CONTROL_MODE",
        "CAM_CROP_MODE",
        "CAM_TARGET",
    ];
    (0..4)
        .map(|cam| {
            let mut fields = vec![];
            for kind in kinds {
                let Some(object) = all[kind][cam].as_object() else {
                    fields.push((format!("{kind} none"), 0.0));
                    continue;
                };
                for (name, v) in object
                    .iter()
                    .filter(|(n, _)| !matches!(n.as_str(), "cam_id" | "x" | "y"))
                {
                    fields.push((format!("{kind} {name}"), v.as_f64().unwrap_or(f64::NAN)));
                }
            }
            fields
        })
        .collect()
}

/// Whether camera `b`'s settings are camera `a`'s: exactly, or an angle within what MAVLink
/// carries (yaw the same one turn either way).
fn same(a: &[(String, f64)], b: &[(String, f64)], exact: bool) -> Result<(), String> {
    for ((name, x), (_, y)) in a.iter().zip(b) {
        let angle = matches!(
            name.as_str(),
            "CAM_EULER yaw" | "CAM_EULER pitch" | "CAM_EULER roll" | "CAM_FOV fov"
        );
        let off = match name.as_str() {
            "CAM_EULER yaw" => digiview::geometry::wrap_pi(x - y).abs(),
            _ => (x - y).abs(),
        };
        let tolerance = if angle && !exact { 1e-6 } else { 0.0 };
        // NaN on either side is no match.
        if off.is_nan() || off > tolerance {
            return Err(format!("{name}: {x} against {y}"));
        }
    }
    Ok(())
}

/// Every camera as the same start: 0.3 rad east of north, 0.5 rad down, 1.2 rad across,
/// held in the world, steered by its angles.
fn reset(ctl: &mut Client) {
    for cam_id in 0..4 {
        let euler = CamEuler {
            cam_id,
            is_delta: 0,
            yaw: 0.3,
            pitch: -0.5,
            roll: 0.0,
        };
        ctl.set(Param::CamEuler(euler)).unwrap();
        ctl.set(Param::CamFov(CamFov { cam_id, fov: 1.2 })).unwrap();
        ctl.set(Param::CamLockFlags(CamLockFlags { cam_id, flags: 7 }))
            .unwrap();
        ctl.set(Param::CamControlMode(CamControlMode { cam_id, mode: 1 }))
            .unwrap();
    }
}

#[test]
fn aim_zoom_and_target_requests_set_the_same_settings_whichever_way_they_come() {
    let link = free_udp_port();
    let serve = Serve::start(&["--mavlink", &format!("udpin:127.0.0.1:{link}")]);
    let http = serve.http.clone().expect("the web API serves");
    let host = http
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .to_string();
    let control = serve.addr.to_string();
    let timeout = Duration::from_secs(5);
    let tcp = RefCell::new(Client::connect(&control, false, timeout).unwrap());
    let udp = RefCell::new(Client::connect(&control, true, timeout).unwrap());
    let station = RefCell::new(Station::start(link));
    let mut runner = TestRunner::new(Config {
        cases: 48,
        ..Config::default()
    });
    let case = Cell::new(0);
    let result = runner.run(&requests(), |request| {
        case.set(case.get() + 1);
        reset(&mut tcp.borrow_mut());
        let start = settings(&http);
        // Camera 0 over the protocol (UDP every other case), 1 over the web API.
        let mut protocol = if case.get() % 2 == 0 {
            udp.borrow_mut()
        } else {
            tcp.borrow_mut()
        };
        protocol
            .set(request.param(0))
            .map_err(|e| TestCaseError::fail(format!("protocol: {e}")))?;
        drop(protocol);
        let p = request.param(1);
        let name = p.param_type().name();
        let (code, body) = common::raw_request(
            &host,
            "PUT",
            &format!("/api/params/{name}"),
            &[("Host", &host)],
            &json!(p).to_string(),
        )
        .unwrap();
        prop_assert_eq!(code, 200, "web API: {}", body);
        // Cameras 2 and 3 from pymavlink, as COMMAND_LONG and as COMMAND_INT.
        for (cam, int) in [(2, false), (3, true)] {
            let result = station.borrow_mut().ask(&request.command(100 + cam, int));
            prop_assert_eq!(
                result,
                json!("MAV_RESULT_ACCEPTED"),
                "camera {} int {}",
                cam,
                int
            );
        }
        let got = settings(&http);
        prop_assert!(
            same(&start[0], &got[0], true).is_err(),
            "{:?} changed nothing",
            request
        );
        prop_assert_eq!(
            same(&got[0], &got[1], true),
            Ok(()),
            "web API against protocol"
        );
        for cam in [2, 3] {
            prop_assert_eq!(
                same(&got[0], &got[cam], false),
                Ok(()),
                "MAVLink camera {}",
                cam
            );
        }
        Ok(())
    });
    if let Err(e) = result {
        panic!("{e}");
    }
    println!("{} requests, each the same four ways", case.get());
}
