//! MAVLink behind the one trust boundary, tried as a hostile or careless peer would with a
//! ground station written with the `mavlink` crate (tests/common/gcs.rs) against `digiview
//! serve`: an interval no `Duration` holds is denied and the cameras go on beating; an
//! unsigned STORAGE_FORMAT is denied and every file stays, a signed one leaves the running
//! recording whole and playable; `--allow-set none` denies every state-changing command and
//! message; a flood of refused commands writes a few log lines a second.

use crate::common;

use common::autopilot::free_udp_port;
use common::gcs::{Gcs, REQUEST, cameras, euler, fov, params};
use common::serve::Serve;
use digiview::control::client::Client;
use mavlink::dialects::common::*;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

const KEY: &str = "correct horse battery staple";

/// `serve` on the demo with video, captures in `dir`, the link at a free port.
fn serve_with_captures(dir: &Path, mavlink_section: &str) -> (Serve, u16) {
    let config = dir.join("digiview.toml");
    std::fs::write(
        &config,
        format!(
            "[cameras]\nwidth = 640\nheight = 480\n[capture]\ndir = {:?}\nmin_free_mb = 1\n\
             [mavlink]\n{mavlink_section}\n",
            dir.join("captures").to_str().unwrap()
        ),
    )
    .unwrap();
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    // Warnings logged into a pipe: a still not written says why there.
    let serve = Serve::start_video_logging(
        "warn",
        &[
            "--config",
            config.to_str().unwrap(),
            "--mavlink",
            &link,
            "--demo-size",
            "640x480",
            "--size",
            "640x480",
        ],
    );
    (serve, port)
}

/// The files in `dir` and their sizes.
fn files(dir: &Path) -> BTreeMap<String, u64> {
    std::fs::read_dir(dir)
        .map(|d| {
            d.map(|e| e.unwrap())
                .map(|e| {
                    let name = e.file_name().to_string_lossy().into_owned();
                    (name, e.metadata().unwrap().len())
                })
                .collect()
        })
        .unwrap_or_default()
}

fn result(answer: Option<(MavResult, Vec<MavMessage>)>, what: &str) -> MavResult {
    answer.unwrap_or_else(|| panic!("{what}: no COMMAND_ACK")).0
}

/// Heartbeats per camera component heard within `limit`.
fn beats(gcs: &Gcs, limit: Duration) -> BTreeMap<u8, usize> {
    let mut n = BTreeMap::new();
    for (h, m) in gcs.collect(limit) {
        if let MavMessage::HEARTBEAT(b) = m
            && b.mavtype == MavType::MAV_TYPE_CAMERA
        {
            *n.entry(h.component_id).or_default() += 1;
        }
    }
    n
}

/// Starts camera `recording`'s recording, has camera 0 take one still (waited for: its
/// CAMERA_IMAGE_CAPTURED and its file) and puts a file of the pilot's beside them.
fn record_and_shoot(serve: &mut Serve, gcs: &Gcs, system: u8, recording: u8, captures: &Path) {
    let video = MavCmd::MAV_CMD_VIDEO_START_CAPTURE;
    let r = result(gcs.command(system, recording, video, params(&[])), "video");
    assert_eq!(r, MavResult::MAV_RESULT_ACCEPTED);
    let images = MavCmd::MAV_CMD_IMAGE_START_CAPTURE;
    let (r, then) = gcs
        .command(system, 100, images, params(&[0.0, 0.0, 1.0]))
        .expect("one image: no COMMAND_ACK");
    assert_eq!(r, MavResult::MAV_RESULT_ACCEPTED);
    let captured = |m: &MavMessage| match m {
        MavMessage::CAMERA_IMAGE_CAPTURED(c) => Some(c.capture_result),
        _ => None,
    };
    std::fs::write(captures.join("notes.txt"), "the pilot's").unwrap();
    let announced = then.iter().find_map(captured).or_else(|| {
        gcs.wait_for(Duration::from_secs(10), |h, m| {
            (h.component_id == 100).then(|| captured(m)).flatten()
        })
    });
    let deadline = Instant::now() + Duration::from_secs(5);
    while !files(captures).keys().any(|n| n.ends_with(".jpg")) {
        if Instant::now() > deadline {
            serve.terminate();
            serve.wait_exit(Duration::from_secs(10));
            panic!(
                "no still (CAMERA_IMAGE_CAPTURED result {announced:?}): {:?}\n{}",
                files(captures),
                serve.log()
            );
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn unsigned_peers_cannot_silence_the_cameras_or_delete_the_captures() {
    let dir = tempfile::tempdir().unwrap();
    let (mut serve, port) = serve_with_captures(dir.path(), "");
    let captures = dir.path().join("captures");
    let gcs = Gcs::connect(port);
    let (system, seen) = cameras(&gcs);
    assert_eq!(seen.len(), 4, "{seen:?}");
    let images = MavCmd::MAV_CMD_IMAGE_START_CAPTURE;

    // Intervals no time holds, or out of 0.1 s..=a day: denied, nothing scheduled.
    for (interval, count) in [
        (1e30, 1.0),
        (f32::INFINITY, 0.0),
        (f32::NAN, 0.0),
        (-1.0, 0.0),
        (f32::from_bits(1), 0.0),
        (86_401.0, 3.0),
    ] {
        let p = params(&[0.0, interval, count]);
        let r = result(gcs.command(system, 100, images, p), "image capture");
        assert_eq!(
            r,
            MavResult::MAV_RESULT_DENIED,
            "{count} every {interval} s"
        );
    }
    // Every camera goes on beating (it was the first to stop: its thread had panicked).
    let heard = beats(&gcs, Duration::from_secs(5));
    for c in 100..=103u8 {
        assert!(heard.get(&c).copied().unwrap_or(0) >= 4, "{heard:?}");
    }

    // A recording runs and a still is taken; an unsigned format is denied, every file stays.
    record_and_shoot(&mut serve, &gcs, system, 101, &captures);
    let before: Vec<String> = files(&captures).into_keys().collect();
    let format = MavCmd::MAV_CMD_STORAGE_FORMAT;
    let r = result(
        gcs.command(system, 101, format, params(&[1.0, 1.0, 1.0])),
        "format",
    );
    assert_eq!(r, MavResult::MAV_RESULT_DENIED, "an unsigned format");
    let after: Vec<String> = files(&captures).into_keys().collect();
    assert_eq!(after, before, "every file stays");

    let stop = MavCmd::MAV_CMD_VIDEO_STOP_CAPTURE;
    let r = result(gcs.command(system, 101, stop, params(&[])), "stop");
    assert_eq!(r, MavResult::MAV_RESULT_ACCEPTED);
    let mp4 = files(&captures)
        .into_keys()
        .find(|n| n.ends_with("-cam1.mp4"))
        .expect("the recording");
    let (frames, size) = common::probe_frames(&captures.join(mp4));
    assert!(frames > 0);
    assert_eq!(size, "640x480");
    drop(serve);
}

#[test]
fn a_signed_format_removes_the_captures_and_keeps_the_running_recording_playable() {
    let dir = tempfile::tempdir().unwrap();
    let (mut serve, port) = serve_with_captures(dir.path(), &format!("signing_key = {KEY:?}"));
    let captures = dir.path().join("captures");
    let gcs = Gcs::connect_signed(port, Some(digiview::autopilot::signing_key(KEY)));
    let (system, seen) = cameras(&gcs);
    assert_eq!(seen.len(), 4, "{seen:?}");
    record_and_shoot(&mut serve, &gcs, system, 102, &captures);
    std::thread::sleep(Duration::from_secs(1));

    let format = MavCmd::MAV_CMD_STORAGE_FORMAT;
    let r = result(
        gcs.command(system, 102, format, params(&[1.0, 1.0, 1.0])),
        "format",
    );
    assert_eq!(r, MavResult::MAV_RESULT_ACCEPTED, "a signed format");
    let left: Vec<String> = files(&captures).into_keys().collect();
    assert_eq!(left.len(), 2, "{left:?}");
    assert!(left.contains(&"notes.txt".to_string()), "{left:?}");
    let mp4 = left
        .iter()
        .find(|n| n.ends_with("-cam2.mp4"))
        .expect("the running recording stays")
        .clone();
    // Param 3 started the image indices again.
    let gone = gcs
        .command(system, 102, REQUEST, params(&[263.0, 0.0]))
        .map(|a| a.0);
    assert_eq!(
        gone,
        Some(MavResult::MAV_RESULT_DENIED),
        "image indices start again"
    );

    // The recording goes on into the same file, and is whole when it stops.
    std::thread::sleep(Duration::from_secs(1));
    let stop = MavCmd::MAV_CMD_VIDEO_STOP_CAPTURE;
    let r = result(gcs.command(system, 102, stop, params(&[])), "stop");
    assert_eq!(r, MavResult::MAV_RESULT_ACCEPTED);
    let (frames, size) = common::probe_frames(&captures.join(&mp4));
    assert!(frames >= 10, "{frames} frames");
    assert_eq!(size, "640x480");
    drop(serve);
}

#[test]
fn allow_set_none_reaches_mavlink_and_refusals_do_not_flood_the_log() {
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    let mut serve =
        Serve::start_logging("info", None, &["--mavlink", &link, "--allow-set", "none"]);
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    let gcs = Gcs::connect(port);
    let (system, seen) = cameras(&gcs);
    assert_eq!(seen.len(), 4, "{seen:?}");
    let before = (euler(&mut ctl, 1), fov(&mut ctl, 1));
    let layout = |ctl: &mut Client| {
        ctl.get_one(digiview::control::client::query(
            digiview::protocol::ParamType::VideoOutput,
            0,
        ))
        .unwrap()
    };
    let layout_before = layout(&mut ctl);

    use MavCmd::*;
    for (command, p) in [
        (MAV_CMD_SET_CAMERA_ZOOM, params(&[4.0, 30.0])),
        (MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, params(&[-30.0, 45.0])),
        (MAV_CMD_DO_SET_ROI_NONE, params(&[])),
        (MAV_CMD_IMAGE_START_CAPTURE, params(&[0.0, 1.0, 0.0])),
        (MAV_CMD_VIDEO_START_CAPTURE, params(&[])),
        (MAV_CMD_SET_CAMERA_MODE, params(&[0.0, 1.0])),
        (MAV_CMD_STORAGE_FORMAT, params(&[1.0, 1.0])),
        (MAV_CMD_CAMERA_TRACK_POINT, params(&[0.5, 0.5, 0.1])),
        (
            MAV_CMD_CAMERA_TRACK_RECTANGLE,
            params(&[0.4, 0.4, 0.6, 0.6]),
        ),
        (MAV_CMD_CAMERA_STOP_TRACKING, params(&[])),
    ] {
        let r = result(gcs.command(system, 101, command, p), "command");
        assert_eq!(r, MavResult::MAV_RESULT_DENIED, "{command:?}");
    }
    // Reading is still open.
    let r = result(
        gcs.command(system, 101, MAV_CMD_REQUEST_MESSAGE, params(&[259.0])),
        "request",
    );
    assert_eq!(r, MavResult::MAV_RESULT_ACCEPTED);
    // A parameter: PARAM_EXT_ACK says it failed.
    gcs.forget();
    let mut id = [0u8; 16];
    id[..6].copy_from_slice(b"LAYOUT");
    let mut value = [0u8; 128];
    value[0] = 0;
    gcs.send(&MavMessage::PARAM_EXT_SET(PARAM_EXT_SET_DATA {
        target_system: system,
        target_component: 101,
        param_id: id.into(),
        param_value: value.into(),
        param_type: MavParamExtType::MAV_PARAM_EXT_TYPE_UINT8,
    }));
    let ack = gcs.wait_for(Duration::from_secs(3), |h, m| match m {
        MavMessage::PARAM_EXT_ACK(a) if h.component_id == 101 => Some(a.param_result),
        _ => None,
    });
    assert_eq!(ack, Some(ParamAck::PARAM_ACK_FAILED));
    // The gimbal's own messages, unanswered, change nothing either.
    gcs.send(&MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(
        GIMBAL_MANAGER_SET_PITCHYAW_DATA {
            flags: GimbalManagerFlags::empty(),
            pitch: -0.5,
            yaw: 1.0,
            pitch_rate: f32::NAN,
            yaw_rate: f32::NAN,
            target_system: system,
            target_component: 101,
            gimbal_device_id: 0,
        },
    ));
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(
        (euler(&mut ctl, 1), fov(&mut ctl, 1)),
        before,
        "camera 1 changed"
    );
    assert_eq!(layout(&mut ctl), layout_before, "the layout changed");

    // A flood of 10,000 refused commands: a few lines a second in the log.
    let flood_started = Instant::now();
    for _ in 0..10_000 {
        gcs.send(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: system,
            target_component: 100,
            command: MAV_CMD_SET_CAMERA_ZOOM,
            param1: 4.0,
            param2: 30.0,
            ..Default::default()
        }));
    }
    // Still answering after it.
    std::thread::sleep(Duration::from_millis(500));
    let r = result(
        gcs.command(system, 101, MAV_CMD_REQUEST_MESSAGE, params(&[259.0])),
        "request after the flood",
    );
    assert_eq!(r, MavResult::MAV_RESULT_ACCEPTED);
    let seconds = flood_started.elapsed().as_secs_f64();
    drop(gcs);
    serve.terminate();
    serve.wait_exit(Duration::from_secs(10));
    let log = serve.log();
    let refusals = log.lines().filter(|l| l.contains("refused")).count();
    println!("{refusals} refusal lines over {seconds:.1} s of flood");
    assert!(
        log.contains("more refused in the last second, the last: MAV_CMD_SET_CAMERA_ZOOM"),
        "the summary names what was refused"
    );
    // The policy's 5 lines a second, plus a summary each second, over the flood and the
    // commands before it.
    let bound = (6.0 * (seconds + 12.0)) as usize;
    assert!(
        refusals <= bound,
        "{refusals} refusal lines (at most {bound})"
    );
}
