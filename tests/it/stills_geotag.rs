//! A view's stills as metric photos, read with exiftool (an independent reader, the one
//! mapping pipelines check their inputs with): each JPEG a MAVLink camera takes carries the
//! position of the frame it was drawn from (EXIF GPS), the frame's capture time
//! (DateTimeOriginal with its sub-seconds, the same µs CAMERA_IMAGE_CAPTURED reports), the
//! view's orientation in the world (XMP, DJI's gimbal angles as OpenSfM reads them) and, for
//! a view drawn as a pinhole, a focal length that gives its field of view; a panorama claims
//! none.

use crate::common;

use common::exif::{number, read_jpeg as exiftool};
use common::gcs::{Gcs, cameras, http_get, image_capture, params};
use common::serve::{CaptureConfig, Serve, with_stills};
use mavlink::dialects::common::*;
use std::process::Command;

/// Where the vehicle hovers: south and east of the equator and meridian, so each sign counts.
const LAT: f64 = -33.856_784_1;
const LON: f64 = 151.215_297_3;
const ALT: f64 = 123.4;

/// Camera `component`'s stills, 0.5 s apart: each CAMERA_IMAGE_CAPTURED with its JPEG.
fn stills(
    gcs: &Gcs,
    system: u8,
    component: u8,
    count: usize,
) -> Vec<(CAMERA_IMAGE_CAPTURED_DATA, Vec<u8>)> {
    image_capture(gcs, (system, component), count, 0.5)
        .into_iter()
        .map(|c| {
            assert_eq!(c.capture_result, MavBool::MAV_BOOL_TRUE);
            let (status, jpeg) = http_get(c.file_url.to_str().unwrap());
            assert_eq!(status, 200);
            (c, jpeg)
        })
        .collect()
}

/// `serve` on the hovering demo with its cameras' stills written to a directory of the
/// test's, `extra` flags beside; and a ground station on its link.
fn serve_with_stills(extra: &[&str]) -> (CaptureConfig, Serve, Gcs) {
    let flags = [&["--demo-hover"], extra].concat();
    let (config, serve, port) = with_stills(&flags, None);
    (config, serve, Gcs::connect(port))
}

#[test]
fn each_still_says_where_when_and_how_its_frame_was_taken_as_exiftool_reads_it() {
    let position = format!("lat={LAT},lon={LON},alt={ALT},rel=100");
    let (_config, _serve, gcs) = serve_with_stills(&[
        "--position",
        &position,
        "--attitude",
        "yaw=10deg",
        // Held in the world: 30° east of north, 45° down; camera 1 a panorama.
        "--cam",
        "0:yaw=30deg,pitch=-45deg,fov=90deg,crop=1,lock=7",
        "--cam",
        "1:yaw=0deg,pitch=-20deg,fov=180deg,crop=2,lock=7",
    ]);
    let (system, _) = cameras(&gcs);

    for (captured, jpeg) in stills(&gcs, system, 100, 2) {
        let tags = exiftool(&jpeg);
        let lat = number(&tags, "Composite:GPSLatitude");
        let lon = number(&tags, "Composite:GPSLongitude");
        let alt = number(&tags, "Composite:GPSAltitude");
        assert!(
            (lat - LAT).abs() < 1e-6 && (lon - LON).abs() < 1e-6,
            "{lat} {lon}"
        );
        assert!((alt - ALT).abs() < 0.1, "altitude {alt}");
        // CAMERA_IMAGE_CAPTURED says the same place, to its 1e-7 degree.
        assert_eq!(captured.lat, (lat * 1e7).round() as i32);
        assert_eq!(captured.lon, (lon * 1e7).round() as i32);
        // ... and the same orientation of the view.
        let [w, x, y, z] = captured.q.map(|v| v as f64);
        let q = glam::DQuat::from_xyzw(x, y, z, w);
        let (yaw, pitch, _) = q.to_euler(glam::EulerRot::ZYX);
        let (yaw, pitch) = (yaw.to_degrees(), pitch.to_degrees());
        assert!(
            (yaw - 30.0).abs() < 0.1 && (pitch + 45.0).abs() < 0.1,
            "{yaw} {pitch}"
        );
        // The view in the world: where camera 0 is held.
        let angle = |k: &str| number(&tags, &format!("XMP-drone-dji:Gimbal{k}Degree"));
        assert!((angle("Yaw") - 30.0).abs() < 0.1, "{tags:#}");
        assert!((angle("Pitch") + 45.0).abs() < 0.1, "{tags:#}");
        assert!(angle("Roll").abs() < 0.1, "{tags:#}");
        // 90° across on a 36 mm wide frame is 18 mm, and that is its 35 mm equivalent.
        assert!(
            (number(&tags, "ExifIFD:FocalLength") - 18.0).abs() < 0.001,
            "{tags:#}"
        );
        assert_eq!(number(&tags, "ExifIFD:FocalLengthIn35mmFormat"), 18.0);
        // exiftool's own field of view from them.
        assert!(
            (number(&tags, "Composite:FOV") - 90.0).abs() < 0.01,
            "{tags:#}"
        );
        assert_eq!(tags["IFD0:Make"], "DigiView");
        assert_eq!(
            (
                number(&tags, "File:ImageWidth"),
                number(&tags, "File:ImageHeight")
            ),
            (640.0, 480.0)
        );
        // The frame's capture time, to the µs CAMERA_IMAGE_CAPTURED reports.
        let when = tags["Composite:SubSecDateTimeOriginal"]
            .as_str()
            .unwrap()
            .to_string();
        let unix_us = captured.time_utc;
        let secs = unix_us / 1_000_000;
        let expect = format!("{:06}+00:00", unix_us % 1_000_000);
        assert!(when.ends_with(&expect), "{when} against {unix_us}");
        let gps_time = tags["Composite:GPSDateTime"]
            .as_str()
            .unwrap_or_default()
            .to_string();
        assert!(!gps_time.is_empty(), "{tags:#}");
        let date = Command::new("date")
            .args(["-u", "-d", &format!("@{secs}"), "+%Y:%m:%d %H:%M:%S"])
            .output()
            .unwrap();
        let date = String::from_utf8_lossy(&date.stdout).trim().to_string();
        assert!(when.starts_with(&date), "{when} against {date}");
    }
    // A panorama is no pinhole: it claims no focal length, and says where it was.
    let (_, jpeg) = stills(&gcs, system, 101, 1).remove(0);
    let tags = exiftool(&jpeg);
    assert!(tags.get("ExifIFD:FocalLength").is_none(), "{tags:#}");
    assert!((number(&tags, "Composite:GPSLatitude") - LAT).abs() < 1e-6);
    assert!((number(&tags, "XMP-drone-dji:GimbalPitchDegree") + 20.0).abs() < 0.1);
}

/// IMAGE_START_CAPTURE for one image carries a sequence number (param 4) so that a command sent
/// again for want of an ACK (PX4's command sender resends after 0.5 s) is not a second
/// picture: the same number again is accepted and taken once; the next number is a new one.
/// Nothing heard is dropped between the two sends: a CAMERA_IMAGE_CAPTURED may come at any
/// time after the first ACK.
#[test]
fn one_image_asked_for_again_with_its_sequence_number_is_taken_once() {
    let (config, _serve, gcs) = serve_with_stills(&[]);
    let (system, _) = cameras(&gcs);
    let start = MavCmd::MAV_CMD_IMAGE_START_CAPTURE;
    // Image `sequence` asked for twice, 0.5 s apart: the ACKs accepting it and the images
    // captured, counted until both ACKs and one image came (15 s at most), then 3 s more.
    let shoot_twice = |sequence: f32| {
        let mut heard = (0, 0);
        let count =
            |(acks, images): &mut (usize, usize), h: &mavlink::MavHeader, m: &MavMessage| match m {
                _ if h.component_id != 100 => {}
                MavMessage::COMMAND_ACK(a) if a.command == start => {
                    assert_eq!(a.result, MavResult::MAV_RESULT_ACCEPTED, "image {sequence}");
                    *acks += 1;
                }
                MavMessage::CAMERA_IMAGE_CAPTURED(_) => *images += 1,
                _ => {}
            };
        gcs.forget();
        gcs.send_command(system, 100, start, params(&[0.0, 0.0, 1.0, sequence]));
        std::thread::sleep(std::time::Duration::from_millis(500));
        gcs.send_command(system, 100, start, params(&[0.0, 0.0, 1.0, sequence]));
        gcs.wait_for(std::time::Duration::from_secs(15), |h, m| {
            count(&mut heard, h, m);
            (heard.0 == 2 && heard.1 >= 1).then_some(())
        });
        for (h, m) in gcs.collect(std::time::Duration::from_secs(3)) {
            count(&mut heard, &h, &m);
        }
        heard
    };
    assert_eq!(shoot_twice(7.0), (2, 1), "image 7 sent twice: ACKs, images");
    assert_eq!(shoot_twice(8.0), (2, 1), "image 8 sent twice: ACKs, images");
    let stills = std::fs::read_dir(&config.captures).unwrap().count();
    assert_eq!(stills, 2);
}
