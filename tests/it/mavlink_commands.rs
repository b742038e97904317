//! Camera and gimbal commands as MAVSDK sends them (the `mavlink` crate's ground station,
//! tests/common/gcs.rs, sending the same fields): parameters a command does not use come as
//! NaN, and COMMAND_INT carries params 5 and 6 as whole numbers except where the command
//! names a place. A stream request with NaN for its stream id gets every stream; a gimbal
//! rate started and stopped over COMMAND_INT with its flags in x turns the view, then stops it.

use crate::common;

use common::autopilot::{SimAutopilot, free_udp_port};
use common::gcs::{Gcs, REQUEST, cameras, euler, params};
use common::serve::Serve;
use digiview::control::client::Client;
use mavlink::dialects::common::*;
use std::collections::BTreeSet;
use std::time::Duration;

/// COMMAND_INT `command` to `(system, component)` with params 1 to 4, x, y and z; its ACK's
/// result (None: no ACK within 3 s).
fn command_int(
    gcs: &Gcs,
    (system, component): (u8, u8),
    command: MavCmd,
    p: [f32; 4],
    (x, y, z): (i32, i32, f32),
) -> Option<MavResult> {
    gcs.forget();
    gcs.send(&MavMessage::COMMAND_INT(COMMAND_INT_DATA {
        target_system: system,
        target_component: component,
        frame: MavFrame::MAV_FRAME_GLOBAL,
        command,
        param1: p[0],
        param2: p[1],
        param3: p[2],
        param4: p[3],
        x,
        y,
        z,
        ..Default::default()
    }));
    gcs.wait_for(Duration::from_secs(3), |h, m| match m {
        MavMessage::COMMAND_ACK(a) if h.component_id == component && a.command == command => {
            Some(a.result)
        }
        _ => None,
    })
}

#[test]
fn nan_for_what_is_not_used_and_command_int_decoded_per_command() {
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    let serve = Serve::start(&["--mavlink", &link]);
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    let gcs = Gcs::connect(port);
    let (system, seen) = cameras(&gcs);
    assert_eq!(seen.len(), 4, "{seen:?}");

    // Stream information and status with NaN for the stream id: every stream of the camera.
    for id in [269.0, 270.0] {
        let (r, then) = gcs
            .command(system, 101, REQUEST, params(&[id, f32::NAN]))
            .expect("an ACK");
        assert_eq!(r, MavResult::MAV_RESULT_ACCEPTED, "message {id}");
        let streams: BTreeSet<u8> = then
            .iter()
            .filter_map(|m| match m {
                MavMessage::VIDEO_STREAM_INFORMATION(v) => Some(v.stream_id),
                MavMessage::VIDEO_STREAM_STATUS(v) => Some(v.stream_id),
                _ => None,
            })
            .collect();
        assert_eq!(streams, [1, 2].into(), "message {id}: {then:?}");
    }
    #[allow(deprecated)]
    let old = MavCmd::MAV_CMD_REQUEST_VIDEO_STREAM_INFORMATION;
    let (r, _) = gcs
        .command(system, 101, old, params(&[f32::NAN]))
        .expect("an ACK");
    assert_eq!(r, MavResult::MAV_RESULT_ACCEPTED);
    // A stream that is not there is still refused.
    let (r, _) = gcs
        .command(system, 101, REQUEST, params(&[269.0, 7.0]))
        .expect("an ACK");
    assert_eq!(r, MavResult::MAV_RESULT_DENIED);

    // MAVSDK's set_angular_rates: COMMAND_INT, angles NaN, the flags in x, the device in z.
    let pitch_yaw = MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW;
    let flags = (GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_ROLL_LOCK
        | GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_PITCH_LOCK)
        .bits() as i32;
    let cam = (system, 102);
    let nan = f32::NAN;
    let r = command_int(&gcs, cam, pitch_yaw, [nan, nan, 0.0, 20.0], (flags, 0, 0.0));
    assert_eq!(
        r,
        Some(MavResult::MAV_RESULT_ACCEPTED),
        "a rate with flags in x"
    );
    // Degrees.
    let yaw = |ctl: &mut Client| euler(ctl, 2).0;
    let a = yaw(&mut ctl);
    std::thread::sleep(Duration::from_millis(500));
    let b = yaw(&mut ctl);
    let turned = (b - a).rem_euclid(360.0);
    assert!(
        (turned - 10.0).abs() < 4.0,
        "turned {turned:.1} deg in 0.5 s at 20 deg/s"
    );
    let r = command_int(&gcs, cam, pitch_yaw, [nan, nan, 0.0, 0.0], (flags, 0, 0.0));
    assert_eq!(
        r,
        Some(MavResult::MAV_RESULT_ACCEPTED),
        "a rate of 0 stops it"
    );
    let c = yaw(&mut ctl);
    std::thread::sleep(Duration::from_millis(500));
    let d = yaw(&mut ctl);
    assert!((d - c).abs() < 1e-4, "still turning: {:.4} deg", d - c);

    // A place still comes in degE7.
    let roi = MavCmd::MAV_CMD_DO_SET_ROI_LOCATION;
    let r = command_int(&gcs, cam, roi, [nan; 4], (473_977_000, 85_456_000, 0.0));
    assert_eq!(r, Some(MavResult::MAV_RESULT_ACCEPTED));
    let r = command_int(&gcs, cam, roi, [nan; 4], (i32::MAX, 85_456_000, 0.0));
    assert_eq!(r, Some(MavResult::MAV_RESULT_DENIED), "latitude 214.7 deg");
}

#[test]
fn two_autopilots_sending_as_one_system_are_named_in_a_warning() {
    // Two simulators as system 1, their clocks 1.5 s apart: the clock mapping sees the
    // autopilot's clock go back at every turn, which no reboot explains.
    let port = free_udp_port();
    let to = format!("udpout:127.0.0.1:{port}");
    let level = |_: f64| glam::DVec3::ZERO;
    let _first = SimAutopilot::start(&to, level);
    std::thread::sleep(Duration::from_millis(1500));
    let _second = SimAutopilot::start(&to, level);
    let link = format!("udpin:127.0.0.1:{port}");
    let mut serve = Serve::start_logging("warn", None, &["--mavlink", &link]);
    // The link's first report is 3 s after the start.
    std::thread::sleep(Duration::from_millis(4500));
    serve.terminate();
    serve.wait_exit(Duration::from_secs(10));
    let log = serve.log();
    assert!(
        log.contains("two autopilots (or simulators) are sending as system 1"),
        "{log}"
    );
}
