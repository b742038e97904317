//! The views as MAVLink cameras, end to end: a ground station written with the `mavlink`
//! crate (tests/common/gcs.rs) against `digiview serve` on its autopilot link. Cameras are
//! discovered by their heartbeats and answer both REQUEST_MESSAGE and the older commands;
//! zoom and gimbal commands reach the views; hostile commands change nothing; the settings
//! are PARAM_EXT parameters described by a camera definition file served over HTTP.
//! (tests/it/mavlink_camera_video.rs: what the cameras show.)

use crate::common;

use common::autopilot::free_udp_port;
use common::gcs::{Gcs, REQUEST, accepted, cameras, euler, fov, http_get, params, text};
use common::serve::Serve;
use digiview::control::client::Client;
use digiview::protocol::Param;
use mavlink::dialects::common::*;
use std::collections::BTreeSet;
use std::f64::consts::PI;
use std::time::Duration;

const DEG: f64 = PI / 180.0;

#[test]
fn four_cameras_are_discovered_both_ways_and_bad_commands_change_nothing() {
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    // On the demo (layout 4), whose simulated autopilot on the link is system 1.
    let serve = Serve::start_video(&["--mavlink", &link, "--demo-size", "640x480"]);
    let gcs = Gcs::connect(port);
    let (system, seen) = cameras(&gcs);
    assert_eq!(seen, (100..=103).collect(), "layout 4's cameras");

    for c in 100..=103u8 {
        for (how, cmd, p) in [
            ("REQUEST_MESSAGE", REQUEST, params(&[259.0])),
            (
                "REQUEST_CAMERA_INFORMATION",
                #[allow(deprecated)]
                MavCmd::MAV_CMD_REQUEST_CAMERA_INFORMATION,
                params(&[1.0]),
            ),
        ] {
            let then = accepted(gcs.command(system, c, cmd, p), how);
            let info = then
                .iter()
                .find_map(|m| match m {
                    MavMessage::CAMERA_INFORMATION(i) => Some(i.clone()),
                    _ => None,
                })
                .unwrap_or_else(|| panic!("camera {c} by {how}: no CAMERA_INFORMATION"));
            assert_eq!(text(&info.vendor_name), "DigiView");
            assert_eq!(
                text(&info.model_name),
                format!("virtual camera {}", c - 100)
            );
            assert_eq!((info.resolution_h, info.resolution_v), (1280, 720));
            // The default 90° view: an 18 mm lens on a 36 mm wide frame.
            assert!(
                (info.focal_length - 18.0).abs() < 0.01,
                "{}",
                info.focal_length
            );
            assert_eq!(info.sensor_size_h, 36.0);
            use CameraCapFlags as F;
            for f in [
                F::CAMERA_CAP_FLAGS_HAS_VIDEO_STREAM,
                F::CAMERA_CAP_FLAGS_HAS_BASIC_ZOOM,
                F::CAMERA_CAP_FLAGS_CAPTURE_IMAGE,
                F::CAMERA_CAP_FLAGS_CAPTURE_VIDEO,
            ] {
                assert!(info.flags.contains(f), "{f:?}");
            }
            assert_eq!(info.gimbal_device_id, 1);
        }
    }

    // The rest of what a ground station asks a camera, the new way.
    let one = |id: f32, p2: f32| {
        accepted(
            gcs.command(system, 101, REQUEST, params(&[id, p2])),
            "request",
        )
    };
    match &one(260.0, 0.0)[..] {
        [MavMessage::CAMERA_SETTINGS(s), ..] => {
            assert!((0.0..=100.0).contains(&s.zoomLevel), "{}", s.zoomLevel)
        }
        other => panic!("{other:?}"),
    }
    let streams = one(269.0, 0.0);
    let ids: Vec<u8> = streams
        .iter()
        .filter_map(|m| match m {
            MavMessage::VIDEO_STREAM_INFORMATION(v) => {
                assert_eq!(v.count, 2);
                Some(v.stream_id)
            }
            _ => None,
        })
        .collect();
    // The view's own stream first and again last: QGroundControl shows the first stream it
    // hears of, MAVSDK keeps the last; the composed frame between.
    assert_eq!(
        ids,
        [1, 2, 1],
        "the view's own stream and the composed frame"
    );
    assert!(matches!(
        one(261.0, 0.0)[..],
        [MavMessage::STORAGE_INFORMATION(_), ..]
    ));
    assert!(matches!(
        one(262.0, 0.0)[..],
        [MavMessage::CAMERA_CAPTURE_STATUS(_), ..]
    ));
    match &one(280.0, 0.0)[..] {
        [MavMessage::GIMBAL_MANAGER_INFORMATION(g), ..] => {
            assert_eq!(g.gimbal_device_id, 1);
            assert!(g.pitch_min < -1.5 && g.pitch_max > 1.5);
        }
        other => panic!("{other:?}"),
    }

    // Zoom by range (100 %: the narrowest fov, 0.1 rad) and by steps (-4: twice as wide).
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    let zoom = MavCmd::MAV_CMD_SET_CAMERA_ZOOM;
    accepted(
        gcs.command(system, 100, zoom, params(&[2.0, 100.0])),
        "zoom range",
    );
    assert!(
        (fov(&mut ctl, 0) - 0.1 / DEG).abs() < 0.05,
        "{}",
        fov(&mut ctl, 0)
    );
    accepted(
        gcs.command(system, 100, zoom, params(&[0.0, -4.0])),
        "zoom steps",
    );
    assert!(
        (fov(&mut ctl, 0) - 0.2 / DEG).abs() < 0.05,
        "{}",
        fov(&mut ctl, 0)
    );

    // A gimbal with a primary controller takes pointing commands from it alone.
    let configure = MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE;
    let pitch_yaw = MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW;
    // Every axis held in the world (ROLL_LOCK | PITCH_LOCK | YAW_LOCK): the demo flies.
    let aim = params(&[-10.0, 20.0, f32::NAN, f32::NAN, 28.0]);
    accepted(
        gcs.command(system, 100, configure, params(&[42.0, 1.0, -1.0, -1.0])),
        "configure",
    );
    let taken = gcs.command(system, 100, pitch_yaw, aim).map(|a| a.0);
    assert_eq!(
        taken,
        Some(MavResult::MAV_RESULT_DENIED),
        "42/1 is in control"
    );
    accepted(
        gcs.command(system, 100, configure, params(&[-3.0, 0.0, -1.0, -1.0])),
        "release",
    );
    accepted(gcs.command(system, 100, pitch_yaw, aim), "after release");
    let (yaw, pitch, _) = euler(&mut ctl, 0);
    assert!(
        (yaw - 20.0).abs() < 0.05 && (pitch + 10.0).abs() < 0.05,
        "{yaw} {pitch}"
    );

    // Hostile and foreign commands: answered DENIED or UNSUPPORTED, or not at all, and the
    // views stay as they were.
    let before = (euler(&mut ctl, 1), fov(&mut ctl, 1));
    let result = |a: Option<(MavResult, Vec<MavMessage>)>| a.map(|a| a.0);
    let cmd = |cmd, p: &[f32]| result(gcs.command(system, 101, cmd, params(p)));
    use MavCmd::*;
    let denied = MavResult::MAV_RESULT_DENIED;
    for (command, p, want, what) in [
        (
            MAV_CMD_SET_CAMERA_ZOOM,
            &[4.0, f32::NAN][..],
            denied,
            "a NaN fov",
        ),
        (
            MAV_CMD_SET_CAMERA_ZOOM,
            &[4.0, -20.0],
            denied,
            "a negative fov",
        ),
        (
            MAV_CMD_SET_CAMERA_ZOOM,
            &[9.0, 1.0],
            denied,
            "no such zoom type",
        ),
        (
            MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
            &[f32::INFINITY, 10.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            denied,
            "an infinite pitch",
        ),
        (
            MAV_CMD_DO_SET_ROI_LOCATION,
            &[0.0, 0.0, 0.0, 0.0, 123.0, 8.0, 100.0],
            denied,
            "latitude 123°",
        ),
        (
            MAV_CMD_DO_SET_SERVO,
            &[1.0, 1500.0],
            MavResult::MAV_RESULT_UNSUPPORTED,
            "not a camera's command",
        ),
    ] {
        assert_eq!(cmd(command, p), Some(want), "{what}");
    }
    let other_system = system.wrapping_add(1);
    let zoom_in = params(&[4.0, 30.0]);
    assert!(
        gcs.command(other_system, 101, MAV_CMD_SET_CAMERA_ZOOM, zoom_in)
            .is_none(),
        "a command for another system is not answered"
    );
    assert!(
        gcs.command(system, 105, MAV_CMD_SET_CAMERA_ZOOM, zoom_in)
            .is_none(),
        "nor one for a camera the layout does not show"
    );
    // A flood of commands to every camera with values that are no numbers or far out of any
    // range, and of gimbal messages with random bits to camera 3: camera 1 stays as it was
    // and nothing stops answering.
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        rng
    };
    for _ in 0..2000 {
        let hostile = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1e30,
            -1e30,
            f32::MAX,
        ];
        let p: [f32; 7] = std::array::from_fn(|_| hostile[next() as usize % hostile.len()]);
        let bits: [f32; 7] = std::array::from_fn(|_| f32::from_bits(next() as u32));
        let pick = next();
        let msg = match pick % 3 {
            0 => MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
                target_system: system,
                target_component: 100 + (pick >> 8) as u8 % 6,
                command: [
                    MAV_CMD_SET_CAMERA_ZOOM,
                    MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
                    MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE,
                    MAV_CMD_DO_SET_ROI_LOCATION,
                    MAV_CMD_REQUEST_MESSAGE,
                    MAV_CMD_STORAGE_FORMAT,
                ][(pick >> 16) as usize % 6],
                param1: p[0],
                param2: p[1],
                param3: p[2],
                param4: p[3],
                param5: p[4],
                param6: p[5],
                param7: p[6],
                confirmation: 0,
            }),
            1 => MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(GIMBAL_MANAGER_SET_PITCHYAW_DATA {
                flags: GimbalManagerFlags::from_bits_truncate(next() as u32),
                pitch: bits[0],
                yaw: bits[1],
                pitch_rate: bits[2],
                yaw_rate: bits[3],
                target_system: system,
                target_component: 103,
                gimbal_device_id: (pick >> 8) as u8 % 3,
            }),
            _ => MavMessage::GIMBAL_MANAGER_SET_ATTITUDE(GIMBAL_MANAGER_SET_ATTITUDE_DATA {
                flags: GimbalManagerFlags::from_bits_truncate(next() as u32),
                q: [bits[0], bits[1], bits[2], bits[3]],
                angular_velocity_x: bits[4],
                angular_velocity_y: bits[5],
                angular_velocity_z: bits[6],
                target_system: system,
                target_component: 103,
                gimbal_device_id: 0,
            }),
        };
        gcs.send(&msg);
    }
    std::thread::sleep(Duration::from_millis(500));
    assert_eq!(
        (euler(&mut ctl, 1), fov(&mut ctl, 1)),
        before,
        "camera 1 changed"
    );
    // Still alive and answering.
    accepted(
        gcs.command(system, 100, REQUEST, params(&[259.0])),
        "after the flood",
    );
    let e = euler(&mut ctl, 3);
    assert!(
        e.0.is_finite() && e.1.abs() <= 90.05 && e.2.abs() <= 90.05,
        "{e:?}"
    );
}

/// CAMERA_INFORMATION's definition URI and version, and the file there, read over MAVLink
/// FTP as ground stations read it.
fn definition(gcs: &Gcs, system: u8) -> (String, u16, String) {
    let then = accepted(gcs.command(system, 100, REQUEST, params(&[259.0])), "info");
    let info = match &then[..] {
        [MavMessage::CAMERA_INFORMATION(i), ..] => i.clone(),
        other => panic!("{other:?}"),
    };
    let uri = info.cam_definition_uri.to_str().unwrap().to_string();
    let path = uri
        .strip_prefix("mftp://")
        .unwrap_or_else(|| panic!("{uri}"));
    let xml = gcs.ftp_read(system, 100, path);
    (
        uri,
        info.cam_definition_version,
        String::from_utf8(xml).unwrap(),
    )
}

fn ext_value(m: &MavMessage) -> Option<(String, u8, u16)> {
    match m {
        MavMessage::PARAM_EXT_VALUE(v) => Some((
            v.param_id.to_str().unwrap().to_string(),
            v.param_value[0],
            v.param_count,
        )),
        _ => None,
    }
}

fn ext_set(gcs: &Gcs, system: u8, name: &str, v: u8) -> ParamAck {
    let mut value = [0u8; 128];
    value[0] = v;
    gcs.forget();
    gcs.send(&MavMessage::PARAM_EXT_SET(PARAM_EXT_SET_DATA {
        target_system: system,
        target_component: 101,
        param_id: name.into(),
        param_value: value.into(),
        param_type: MavParamExtType::MAV_PARAM_EXT_TYPE_UINT8,
    }));
    gcs.wait_for(Duration::from_secs(3), |h, m| match m {
        MavMessage::PARAM_EXT_ACK(a) if h.component_id == 101 => Some(a.param_result),
        _ => None,
    })
    .expect("PARAM_EXT_ACK")
}

#[test]
fn settings_are_parameters_described_by_a_definition_file_served_over_mavlink_ftp() {
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    let serve = Serve::start(&["--mavlink", &link]);
    let gcs = Gcs::connect(port);
    let (system, _) = cameras(&gcs);

    // The file: the protocol's XML, its version the one CAMERA_INFORMATION gives, a
    // parameter for each setting, the lenses of lens.cal as LENS's options.
    let (uri, version, xml) = definition(&gcs, system);
    assert_eq!(uri, "mftp://camera0.xml");
    // The HTTP server serves the same file, for browsers and tools.
    let page = serve.http.as_deref().unwrap();
    let (status, over_http) = http_get(&format!("{page}camera.xml"));
    assert_eq!(
        (status, String::from_utf8(over_http).unwrap()),
        (200, xml.clone())
    );
    let doc = roxmltree::Document::parse(&xml).unwrap();
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "mavlinkcamera");
    let def = root
        .children()
        .find(|n| n.has_tag_name("definition"))
        .unwrap();
    assert_eq!(def.attribute("version"), Some(version.to_string().as_str()));
    assert_ne!(version, 0);
    let names: Vec<&str> = root
        .descendants()
        .filter(|n| n.has_tag_name("parameter"))
        .map(|n| n.attribute("name").unwrap())
        .collect();
    let want = [
        "LAYOUT",
        "OVERLAY",
        "LENS",
        "CROP",
        "LOCK",
        "CONTROL",
        "SORTING",
        "DETECTION",
        "CAM_MODE",
    ];
    assert_eq!(names, want);
    let lens = root
        .descendants()
        .find(|n| n.attribute("name") == Some("LENS"))
        .unwrap();
    let lenses: Vec<&str> = lens
        .descendants()
        .filter(|n| n.has_tag_name("option"))
        .map(|n| n.attribute("name").unwrap())
        .collect();
    assert_eq!(
        lenses,
        [
            "CIL216", "CIL018", "LN007", "BOSON320", "DUALF", "DUALB", "DUAL"
        ]
    );

    // Every parameter listed with its value from the live state.
    gcs.forget();
    gcs.send(&MavMessage::PARAM_EXT_REQUEST_LIST(
        PARAM_EXT_REQUEST_LIST_DATA {
            target_system: system,
            target_component: 101,
        },
    ));
    let mut listed = vec![];
    gcs.wait_for(Duration::from_secs(3), |h, m| {
        if h.component_id == 101
            && let Some(v) = ext_value(m)
        {
            assert_eq!(v.2 as usize, want.len());
            listed.push((v.0, v.1));
        }
        (listed.len() == want.len()).then_some(())
    });
    let names: Vec<&str> = listed.iter().map(|l| l.0.as_str()).collect();
    assert_eq!(names, want);
    assert_eq!(listed[0].1, 4, "layout 4");
    assert_eq!(listed[4].1, 7, "camera 1 locks every axis");

    // A SET here is a SET there, and the other way round.
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    assert_eq!(
        ext_set(&gcs, system, "LOCK", 3),
        ParamAck::PARAM_ACK_ACCEPTED
    );
    assert_eq!(listed_lock(&mut ctl), 3);
    ctl.set(Param::CamCropMode(
        digiview::protocol::params::CamCropMode { cam_id: 1, mode: 2 },
    ))
    .unwrap();
    gcs.forget();
    gcs.send(&MavMessage::PARAM_EXT_REQUEST_READ(
        PARAM_EXT_REQUEST_READ_DATA {
            target_system: system,
            target_component: 101,
            param_id: "CROP".into(),
            param_index: -1,
        },
    ));
    let crop = gcs.wait_for(Duration::from_secs(3), |h, m| {
        (h.component_id == 101).then(|| ext_value(m)).flatten()
    });
    assert_eq!(crop.map(|c| (c.0, c.1)), Some(("CROP".to_string(), 2)));

    // CAM_MODE is the camera's mode, as CAMERA_SETTINGS tells it.
    assert_eq!(
        ext_set(&gcs, system, "CAM_MODE", 1),
        ParamAck::PARAM_ACK_ACCEPTED
    );
    let then = accepted(
        gcs.command(system, 101, REQUEST, params(&[260.0])),
        "settings",
    );
    assert!(
        matches!(&then[..], [MavMessage::CAMERA_SETTINGS(s)] if s.mode_id == CameraMode::CAMERA_MODE_VIDEO),
        "{then:?}"
    );

    // What is not an option, and what the state cannot take, changes nothing.
    let unsupported = ParamAck::PARAM_ACK_VALUE_UNSUPPORTED;
    assert_eq!(ext_set(&gcs, system, "LOCK", 9), unsupported);
    assert_eq!(
        ext_set(&gcs, system, "CONTROL", 2),
        unsupported,
        "no target yet"
    );
    assert_eq!(
        ext_set(&gcs, system, "NOSUCH", 1),
        ParamAck::PARAM_ACK_FAILED
    );
    assert_eq!(listed_lock(&mut ctl), 3);

    // LAYOUT 2 has two views: cameras 102 and 103 go quiet.
    assert_eq!(
        ext_set(&gcs, system, "LAYOUT", 2),
        ParamAck::PARAM_ACK_ACCEPTED
    );
    std::thread::sleep(Duration::from_millis(200));
    let beats: BTreeSet<u8> = gcs
        .collect(Duration::from_millis(2500))
        .iter()
        .filter(
            |(_, m)| matches!(m, MavMessage::HEARTBEAT(b) if b.mavtype == MavType::MAV_TYPE_CAMERA),
        )
        .map(|(h, _)| h.component_id)
        .collect();
    assert_eq!(beats, [100, 101].into());

    // Another lens.cal, another file: another version.
    let dir = tempfile::tempdir().unwrap();
    let cal = dir.path().join("lens.cal");
    let shipped = std::fs::read_to_string(common::lens_cal_path()).unwrap();
    let start = shipped.find("\n[[lens]]").unwrap() + 1;
    let end = start + shipped[start..].find("\n[[lens]]").unwrap();
    let first = &shipped[start..end];
    let extra = first
        .replace("name = \"CIL216\"", "name = \"SPARE\"")
        .replace("lens_id = 0", "lens_id = 7");
    std::fs::write(&cal, format!("{shipped}\n{extra}\n")).unwrap();
    let port2 = free_udp_port();
    let link2 = format!("udpin:127.0.0.1:{port2}");
    let _serve2 = Serve::start(&["--mavlink", &link2, "--lens-cal", cal.to_str().unwrap()]);
    let gcs2 = Gcs::connect(port2);
    let (system2, _) = cameras(&gcs2);
    let (_, version2, xml2) = definition(&gcs2, system2);
    assert!(xml2.contains("name=\"SPARE\" value=\"7\""), "{xml2}");
    assert_ne!(version2, version, "the version follows the content");
}

fn listed_lock(ctl: &mut Client) -> u8 {
    match ctl
        .get_one(Param::CamLockFlags(
            digiview::protocol::params::CamLockFlags {
                cam_id: 1,
                ..Default::default()
            },
        ))
        .unwrap()
    {
        Param::CamLockFlags(l) => l.flags,
        other => panic!("{other:?}"),
    }
}
