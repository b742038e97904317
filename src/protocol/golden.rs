//! Golden frames: each hex string below was built by `scripts/golden_frames.py` straight from
//! protocol.md's offset tables, with its own CRC-8, not by this crate's encoder. Each must
//! decode to the intended values and encode back to the same 80 bytes.

use super::params::*;
use super::wire::{BoundingBox, ViewBoxes};
use super::{Body, Message, crc8};

const FRAMES_LENS: &str = "ee ff c0 00 e1 f5 05 00 00 03 05 02 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 a4 00 00 00 00";
const TS: u64 = 0x0005_F5E1_00C0_FFEE;

fn bytes(hex: &str) -> Vec<u8> {
    hex.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap())
        .collect()
}

/// Decodes the golden frame, checks it says `body`, and that encoding `body` gives it back.
fn golden(hex: &str, body: Body) {
    let frame = bytes(hex);
    assert_eq!(frame.len(), 80);
    let m = Message::decode(&frame).unwrap();
    assert_eq!(
        m,
        Message {
            timestamp: TS,
            body
        }
    );
    assert_eq!(m.encode().as_slice(), frame.as_slice(), "{body:?}");
}

#[test]
fn crc8_check_value_is_0x26() {
    assert_eq!(crc8(b"123456789"), 0x26);
}

#[test]
fn system_status() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 04 00 01 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 09 00 00 00 00",
        Body::Current(Param::SystemStatus(SystemStatus {
            status: 1,
            error: 0,
        })),
    );
}

fn bbox(x: u16, y: u16, w: u16, h: u16) -> BoundingBox {
    BoundingBox { x, y, w, h }
}

/// A VIDEO_OUTPUT reply at 1920x1080 with the overlay column at the right.
fn video_output(layout_mode: u8, views: &[BoundingBox]) -> Body {
    Body::Current(Param::VideoOutput(VideoOutput {
        width: 1920,
        height: 1080,
        fps: 30,
        layout_mode,
        detection_overlay_mode: 2,
        views: ViewBoxes::new(views.iter().copied()),
        detection_overlay_box: bbox(1800, 0, 120, 1080),
        single_detection_size: 120,
    }))
}

#[test]
fn video_output_layout_0() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 04 01 80 07 38 04 1e 10 02 68 01 00 00 38 04 38 04 08 07 00 00 78 00 38 04 78 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 9f 00 00 00 00",
        video_output(0, &[bbox(360, 0, 1080, 1080)]),
    );
}

#[test]
fn video_output_layout_1() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 04 01 80 07 38 04 1e 21 02 76 02 00 00 1c 02 1c 02 76 02 1c 02 1c 02 1c 02 08 07 00 00 78 00 38 04 78 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 9e 00 00 00 00",
        video_output(1, &[bbox(630, 0, 540, 540), bbox(630, 540, 540, 540)]),
    );
}

#[test]
fn video_output_layout_4() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 04 01 80 07 38 04 1e 44 02 68 01 00 00 1c 02 1c 02 84 03 00 00 1c 02 1c 02 68 01 1c 02 1c 02 1c 02 84 03 1c 02 1c 02 1c 02 08 07 00 00 78 00 38 04 78 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 e3 00 00 00 00",
        video_output(
            4,
            &[
                bbox(360, 0, 540, 540),
                bbox(900, 0, 540, 540),
                bbox(360, 540, 540, 540),
                bbox(900, 540, 540, 540),
            ],
        ),
    );
}

#[test]
fn video_output_layout_6() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 04 01 80 07 38 04 1e 16 02 00 00 00 00 08 07 38 04 08 07 00 00 78 00 38 04 78 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 b7 00 00 00 00",
        video_output(6, &[bbox(0, 0, 1800, 1080)]),
    );
}

#[test]
fn capture() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 04 02 02 07 00 03 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 bb 00 00 00 00",
        Body::Current(Param::Capture(Capture {
            flags: 2,
            images_captured: 7,
            videos_captured: 3,
        })),
    );
}

#[test]
fn detection() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 03 03 00 02 80 66 64 00 f4 01 33 4c 0a ff 05 ff 14 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 6c 00 00 00 00",
        Body::Set(Param::Detection(Detection {
            mode: 0,
            sorting_mode: 2,
            crop_confidence_threshold: 128.0 / 255.0,
            var_confidence_threshold: 102.0 / 255.0,
            crop_box_limit: 100,
            var_box_limit: 500,
            crop_box_overlap: 51.0 / 255.0,
            var_box_overlap: 76.0 / 255.0,
            creation_score_scale: 10,
            bonus_detection_scale: 255,
            bonus_redetection_scale: 5,
            missed_detection_penalty: 255,
            missed_redetection_penalty: 20,
        })),
    );
}

#[test]
fn detected_roi() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 04 04 01 c8 03 dd f9 ff ff ef fc ff ff 64 00 00 00 18 fc ff ff 91 e2 00 00 67 c5 ff ff a0 86 01 00 37 14 01 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 c5 00 00 00 00",
        Body::Current(Param::DetectedRoi(DetectedRoi {
            index: 1,
            score: 200,
            total_detections: 3,
            yaw_abs: -1.571,
            pitch_abs: -0.785,
            yaw_rel: 0.1,
            pitch_rel: -1.0,
            latitude: 58.001,
            longitude: -15.001,
            altitude: 100.0,
            distance: 70.711,
        })),
    );
}

#[test]
fn lens() {
    golden(FRAMES_LENS, Body::Set(Param::Lens(Lens { lens_id: 2 })));
}

#[test]
fn cam_euler() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 03 06 02 01 11 03 00 00 f4 fd ff ff 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 e7 00 00 00 00",
        Body::Set(Param::CamEuler(CamEuler {
            cam_id: 2,
            is_delta: 1,
            yaw: 0.785,
            pitch: -0.524,
            roll: 0.0,
        })),
    );
}

#[test]
fn cam_zoom() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 03 07 01 e0 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 31 00 00 00 00",
        Body::Set(Param::CamZoom(CamZoom {
            cam_id: 1,
            zoom: -32,
        })),
    );
}

#[test]
fn cam_lock_flags() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 03 08 03 05 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 01 00 00 00 00",
        Body::Set(Param::CamLockFlags(CamLockFlags {
            cam_id: 3,
            flags: 5,
        })),
    );
}

#[test]
fn cam_control_mode() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 03 09 00 02 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 92 00 00 00 00",
        Body::Set(Param::CamControlMode(CamControlMode { cam_id: 0, mode: 2 })),
    );
}

#[test]
fn cam_crop_mode() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 03 0a 01 04 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 8b 00 00 00 00",
        Body::Set(Param::CamCropMode(CamCropMode { cam_id: 1, mode: 4 })),
    );
}

#[test]
fn cam_offset() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 04 0b 00 00 40 01 80 01 90 01 00 00 d4 fe ff ff 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 55 00 00 00 00",
        Body::Current(Param::CamOffset(CamOffset {
            cam_id: 0,
            x: 16384.0 / 32767.0,
            y: -1.0,
            frame_rel: 1,
            yaw: 0.4,
            pitch: -0.3,
        })),
    );
}

#[test]
fn cam_fov() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 03 0c 02 23 06 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 2b 00 00 00 00",
        Body::Set(Param::CamFov(CamFov {
            cam_id: 2,
            fov: 1.571,
        })),
    );
}

#[test]
fn cam_target() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 03 0d 01 00 00 00 00 80 02 75 03 40 1e 1b ff a0 86 01 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 48 00 00 00 00",
        Body::Set(Param::CamTarget(CamTarget {
            cam_id: 1,
            x: 0.0,
            y: 0.0,
            t_latitude: 58.0,
            t_longitude: -15.0,
            t_altitude: 100.0,
        })),
    );
}

#[test]
fn cam_sensor() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 03 0e 01 80 35 82 00 00 b0 04 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 3e 00 00 00 00",
        Body::Set(Param::CamSensor(CamSensor {
            ae: 1,
            target_brightness: 128,
            exposure_value: 33333,
            gain_value: 1200,
        })),
    );
}

#[test]
fn general_settings() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 03 0f 00 0f 70 08 00 00 00 00 1e 00 00 00 00 dd f9 ff ff 00 00 00 00 01 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 df 00 00 00 00",
        Body::Set(Param::GeneralSettings(GeneralSettings {
            camera_width: 3840,
            camera_height: 2160,
            roi_width: 0,
            roi_height: 0,
            camera_fps: 30,
            mount_yaw: 0.0,
            mount_pitch: -1.571,
            mount_roll: 0.0,
            run_ai: 1,
        })),
    );
}

#[test]
fn thermal() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 03 12 02 01 59 0b 48 0d 80 04 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 82 00 00 00 00",
        Body::Set(Param::Thermal(Thermal {
            palette: 2,
            gain: 1,
            span_low: 290.5,
            span_high: 340.0,
            blend: 128.0 / 255.0,
            zoom: 4,
        })),
    );
}

#[test]
fn cam_thermal() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 03 13 01 02 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 4a 00 00 00 00",
        Body::Set(Param::CamThermal(CamThermal { cam_id: 1, show: 2 })),
    );
}

#[test]
fn get_cam_euler_carries_only_cam_id() {
    golden(
        "ee ff c0 00 e1 f5 05 00 00 02 06 03 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 92 00 00 00 00",
        Body::Get(Param::CamEuler(CamEuler {
            cam_id: 3,
            ..Default::default()
        })),
    );
}

#[test]
fn padding_is_ignored_and_a_flipped_bit_is_a_checksum_error() {
    let mut frame = bytes(FRAMES_LENS);
    frame[76..].copy_from_slice(&[0xde, 0xad, 0xbe, 0xef]);
    assert!(matches!(
        Message::decode(&frame).unwrap().body,
        Body::Set(Param::Lens(Lens { lens_id: 2 }))
    ));
    frame[11] ^= 0x10;
    assert!(matches!(
        Message::decode(&frame),
        Err(super::DecodeError::Checksum { param_type: 5, .. })
    ));
}
