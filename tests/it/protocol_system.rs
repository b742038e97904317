//! The whole-system parameter types of the control protocol (SYSTEM_STATUS, VIDEO_OUTPUT,
//! CAPTURE, DETECTION, DETECTED_ROI, LENS, CAM_SENSOR, GENERAL_SETTINGS) and the replies to
//! malformed requests, rule by rule as the seed and protocol.md give them, in-process through
//! `Controller::handle`. The server itself is tests/it/control_server.rs's.

use crate::common;
use common::DEG;
use common::direct::Direct;
use common::frames::{Client, MRAD, ack, raw_frame, verdict};
use digiview::geometry::GeoPoint;
use digiview::geometry::ground::from_ned;
use digiview::layout::layout;
use digiview::modes::{LayoutMode, OverlayMode};
use digiview::protocol::params::*;
use digiview::protocol::{Body, FRAME_LEN, Message, Param, ParamType, Verdict};
use glam::DVec3;

#[test]
fn every_get_answers_with_its_own_type() {
    let mut c = Direct::start(&["--track", "yaw=10deg,pitch=-40deg,size=3deg"]);
    for &kind in ParamType::ALL {
        let mut q = kind.zeroed();
        if kind == ParamType::CamOffset || kind == ParamType::CamTarget {
            q.set_field("y", 0.25).unwrap();
        }
        if kind.per_camera() {
            q.set_field("cam_id", 3.0).unwrap();
        }
        let p = c.get(q);
        assert_eq!(p.param_type(), kind);
        assert_eq!(p.cam_id(), kind.per_camera().then_some(3));
    }
}

#[test]
fn video_output_reports_the_rendered_rectangles_and_follows_the_seed_rules() {
    let mut c = Direct::start(&[]);
    let get = |c: &mut Direct| match c.get(ParamType::VideoOutput.zeroed()) {
        Param::VideoOutput(v) => v,
        _ => unreachable!(),
    };
    let set = |c: &mut Direct, w, h, fps, layout_mode, overlay| {
        let p = VideoOutput {
            width: w,
            height: h,
            fps,
            layout_mode,
            detection_overlay_mode: overlay,
            ..Default::default()
        };
        assert_eq!(
            c.ask(Body::Set(Param::VideoOutput(p))),
            ack(ParamType::VideoOutput)
        );
    };
    set(&mut c, 1280, 720, 25, 3, 4);
    let v = get(&mut c);
    assert_eq!(
        (
            v.width,
            v.height,
            v.fps,
            v.layout_mode,
            v.detection_overlay_mode
        ),
        (1280, 720, 25, 3, 4)
    );
    let l = layout(1280, 720, LayoutMode::TwoAndPanorama, OverlayMode::Top).unwrap();
    assert_eq!(v.views.len(), l.views.len(), "the layout's views, no more");
    for (b, (r, _)) in v.views.iter().zip(&l.views) {
        assert_eq!(
            (b.x, b.y, b.w, b.h),
            (r.x as u16, r.y as u16, r.w as u16, r.h as u16)
        );
    }
    let o = l.overlay_box;
    let b = v.detection_overlay_box;
    assert_eq!(
        (b.x, b.y, b.w, b.h),
        (o.x as u16, o.y as u16, o.w as u16, o.h as u16)
    );
    assert_eq!(v.single_detection_size, 120);

    // Too large: clamped. fps clamped both ways. Unknown layout and overlay: kept.
    set(&mut c, 4000, 2000, 2, 7, 6);
    let v = get(&mut c);
    assert_eq!(
        (
            v.width,
            v.height,
            v.fps,
            v.layout_mode,
            v.detection_overlay_mode
        ),
        (1920, 1080, 5, 3, 4)
    );
    // Too small: the size is kept, the rest applies. Odd sizes round down to even.
    set(&mut c, 500, 720, 90, 0, 0);
    let v = get(&mut c);
    assert_eq!(
        (v.width, v.height, v.fps, v.layout_mode),
        (1920, 1080, 30, 0)
    );
    set(&mut c, 1001, 701, 30, 0, 0);
    assert_eq!((get(&mut c).width, get(&mut c).height), (1000, 700));
}

/// Offsets in a frame of protocol.md's data offsets (the data area starts at byte 11).
const DATA: usize = 11;

fn u16_at(frame: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([frame[DATA + at], frame[DATA + at + 1]])
}

#[test]
fn video_output_packs_only_the_layouts_views_as_the_original_header_does() {
    let mut c = Direct::start(&["--size", "1920x1080", "--overlay", "2"]);
    for (mode, views) in [(0u8, 1u8), (1, 2), (2, 2), (3, 3), (4, 4), (5, 4), (6, 1)] {
        // A SET as an original client sends one back: with a view count in the high bits
        // (here one that is not the layout's). The low four bits are the layout.
        let mut set = Message::new(Body::Set(Param::VideoOutput(VideoOutput {
            width: 1920,
            height: 1080,
            fps: 30,
            detection_overlay_mode: 2,
            ..Default::default()
        })))
        .encode();
        set[DATA + 5] = 3 << 4 | mode;
        set[75] = digiview::protocol::crc8(&set[..75]);
        c.send_bytes(&set);
        assert_eq!(c.recv().body, ack(ParamType::VideoOutput), "layout {mode}");

        // The reply's bytes, read by protocol.md's offsets.
        c.send(Body::Get(ParamType::VideoOutput.zeroed()));
        let reply = c.recv().encode();
        assert_eq!(
            reply[DATA + 5],
            views << 4 | mode,
            "layout {mode}: views and mode"
        );
        let mode_enum = LayoutMode::try_from(mode).unwrap();
        let want = layout(1920, 1080, mode_enum, OverlayMode::Right).unwrap();
        assert_eq!(want.views.len(), views as usize);
        let boxes: Vec<_> = (0..=views as usize)
            .map(|i| {
                let at = 7 + 8 * i;
                [0, 2, 4, 6].map(|f| u16_at(&reply, at + f) as u32)
            })
            .collect();
        let rects = want.views.iter().map(|(r, _)| *r).chain([want.overlay_box]);
        for (got, r) in boxes.iter().zip(rects) {
            assert_eq!(*got, [r.x, r.y, r.w, r.h], "layout {mode}");
        }
        let size_at = 7 + 8 * (views as usize + 1);
        assert_eq!(
            u16_at(&reply, size_at),
            120,
            "layout {mode}: single_detection_size"
        );
        assert!(
            reply[DATA + size_at + 2..75].iter().all(|&b| b == 0),
            "layout {mode}: nothing after single_detection_size"
        );
    }
}

#[test]
fn detection_keeps_out_of_range_thresholds_and_255_scores_and_clamps_limits() {
    let mut c = Direct::start(&[]);
    let get = |c: &mut Direct| match c.get(ParamType::Detection.zeroed()) {
        Param::Detection(d) => d,
        _ => unreachable!(),
    };
    let before = get(&mut c);
    let p = Detection {
        mode: 7,
        sorting_mode: 1,
        crop_confidence_threshold: 253.0 / 255.0, // 0.992: outside [0, 0.99), kept
        var_confidence_threshold: 0.4,
        crop_box_limit: 5,
        var_box_limit: 900,
        crop_box_overlap: 0.2,
        var_box_overlap: 1.0,
        creation_score_scale: 255,
        bonus_detection_scale: 42,
        bonus_redetection_scale: 255,
        missed_detection_penalty: 0,
        missed_redetection_penalty: 254,
    };
    assert_eq!(
        c.ask(Body::Set(Param::Detection(p))),
        ack(ParamType::Detection)
    );
    let d = get(&mut c);
    assert_eq!(d.mode, before.mode, "mode is ignored");
    assert_eq!(d.sorting_mode, 1);
    assert_eq!(
        d.crop_confidence_threshold,
        before.crop_confidence_threshold
    );
    assert!((d.var_confidence_threshold - 0.4).abs() <= 0.5 / 255.0);
    assert_eq!((d.crop_box_limit, d.var_box_limit), (10, 500));
    assert!((d.crop_box_overlap - 0.2).abs() <= 0.5 / 255.0);
    assert_eq!(d.var_box_overlap, before.var_box_overlap);
    assert_eq!(d.creation_score_scale, before.creation_score_scale);
    assert_eq!(d.bonus_detection_scale, 42);
    assert_eq!(d.bonus_redetection_scale, before.bonus_redetection_scale);
    assert_eq!(
        (d.missed_detection_penalty, d.missed_redetection_penalty),
        (0, 254)
    );
    // A sorting mode above 2 is ignored.
    let p = Detection {
        sorting_mode: 3,
        ..d
    };
    assert_eq!(
        c.ask(Body::Set(Param::Detection(p))),
        ack(ParamType::Detection)
    );
    assert_eq!(get(&mut c).sorting_mode, 1);
}

#[test]
fn sensor_general_settings_and_capture_without_video() {
    let mut c = Direct::start(&[]);
    let s = CamSensor {
        ae: 7,
        target_brightness: 100,
        exposure_value: 100_000,
        gain_value: 3000,
    };
    assert_eq!(
        c.ask(Body::Set(Param::CamSensor(s))),
        ack(ParamType::CamSensor)
    );
    assert_eq!(
        c.get(ParamType::CamSensor.zeroed()),
        Param::CamSensor(CamSensor {
            ae: 1,
            target_brightness: 100,
            exposure_value: 33_333,
            gain_value: 3000
        }),
        "exposure is clamped to the frame time at 30 fps"
    );
    let g = GeneralSettings {
        camera_width: 1920,
        camera_height: 1080,
        roi_width: 3000,
        roi_height: 2000,
        camera_fps: 25,
        mount_yaw: 0.0,
        mount_pitch: -1.0,
        mount_roll: 0.05,
        run_ai: 0,
    };
    assert_eq!(
        c.ask(Body::Set(Param::GeneralSettings(g))),
        ack(ParamType::GeneralSettings)
    );
    assert_eq!(
        c.get(ParamType::GeneralSettings.zeroed()),
        Param::GeneralSettings(g)
    );
    for bad in [
        GeneralSettings {
            camera_width: 0,
            ..g
        },
        GeneralSettings { camera_fps: 0, ..g },
        GeneralSettings {
            roi_width: 5000,
            ..g
        },
    ] {
        assert_eq!(
            c.ask(Body::Set(Param::GeneralSettings(bad))),
            verdict(Verdict::DataError, ParamType::GeneralSettings)
        );
    }
    assert_eq!(
        c.get(ParamType::GeneralSettings.zeroed()),
        Param::GeneralSettings(g),
        "refused SETs changed nothing"
    );

    // No video pipeline: nothing to capture, but "stop recording" is fine.
    let cap = |flags| {
        Body::Set(Param::Capture(Capture {
            flags,
            ..Default::default()
        }))
    };
    assert_eq!(c.ask(cap(0)), ack(ParamType::Capture));
    assert_eq!(
        c.ask(cap(1)),
        verdict(Verdict::DataError, ParamType::Capture)
    );
    assert_eq!(
        c.ask(cap(2)),
        verdict(Verdict::DataError, ParamType::Capture)
    );
    assert_eq!(
        c.get(ParamType::Capture.zeroed()),
        Param::Capture(Capture::default())
    );
    assert_eq!(
        c.get(ParamType::SystemStatus.zeroed()),
        Param::SystemStatus(SystemStatus {
            status: 0,
            error: 0
        }),
        "a control server without video is idle"
    );
}

#[test]
fn unknown_types_bad_versions_reply_types_and_bad_checksums_get_their_replies() {
    let mut c = Direct::start(&[]);
    let answer = |c: &mut Direct, f: [u8; FRAME_LEN]| {
        c.send_bytes(&f);
        c.recv().body
    };
    for pt in [20u8, 99, 255] {
        assert_eq!(
            answer(&mut c, raw_frame(0, 2, pt)),
            Body::Verdict(Verdict::Unknown, pt)
        );
        assert_eq!(
            answer(&mut c, raw_frame(0, 3, pt)),
            Body::Verdict(Verdict::Unknown, pt)
        );
    }
    for mt in [10u8, 200] {
        assert_eq!(
            answer(&mut c, raw_frame(0, mt, 5)),
            Body::Verdict(Verdict::Unknown, 5)
        );
    }
    assert_eq!(
        answer(&mut c, raw_frame(1, 2, 5)),
        Body::Verdict(Verdict::DataError, 5),
        "version 1"
    );
    assert_eq!(
        answer(&mut c, raw_frame(0, 4, 5)),
        Body::Verdict(Verdict::DataError, 5),
        "a reply is not a request"
    );
    assert_eq!(
        answer(&mut c, raw_frame(0, 0, 7)),
        Body::Verdict(Verdict::Acknowledgement, 7),
        "EMPTY"
    );

    // A bad checksum: CHECKSUM_ERROR, and nothing applied.
    let mut f = Message::new(Body::Set(Param::CamFov(CamFov {
        cam_id: 0,
        fov: 0.5,
    })))
    .encode();
    f[75] ^= 0x5a;
    assert_eq!(
        answer(&mut c, f),
        verdict(Verdict::ChecksumError, ParamType::CamFov)
    );
    let Param::CamFov(fov) = c.get(Param::CamFov(CamFov {
        cam_id: 0,
        fov: 0.0,
    })) else {
        unreachable!()
    };
    assert!(
        (fov.fov - 90.0 * DEG).abs() < MRAD,
        "the default fov is untouched"
    );
}

#[test]
fn detected_roi_254_and_255_send_one_reply_per_detection() {
    // Overlay 1 shows a single tile, so 254 (shown) and 255 (known) differ.
    let mut c = Direct::start(&[
        "--overlay",
        "1",
        "--track",
        "yaw=0deg,pitch=-40deg,size=3deg,score=90",
        "--track",
        "yaw=90deg,pitch=-90deg,size=3deg,score=80",
        "--track",
        "yaw=180deg,pitch=10deg,size=3deg,score=70",
    ]);
    let ask_all = |c: &mut Direct, index: u8| -> Vec<DetectedRoi> {
        c.send(Body::Get(Param::DetectedRoi(DetectedRoi {
            index,
            ..Default::default()
        })));
        let first = match c.recv().body {
            Body::Current(Param::DetectedRoi(r)) => r,
            other => panic!("{other:?}"),
        };
        let mut all = vec![first];
        while all.len() < first.total_detections as usize {
            match c.recv().body {
                Body::Current(Param::DetectedRoi(r)) => all.push(r),
                other => panic!("{other:?}"),
            }
        }
        all
    };
    let shown = ask_all(&mut c, 254);
    assert_eq!(shown.len(), 1);
    assert_eq!(
        (shown[0].index, shown[0].total_detections, shown[0].score),
        (0, 1, 90)
    );
    let known = ask_all(&mut c, 255);
    assert_eq!(
        known
            .iter()
            .map(|r| (r.index, r.total_detections, r.score))
            .collect::<Vec<_>>(),
        [(0, 3, 90), (1, 3, 80), (2, 3, 70)]
    );
    // The EMPTY after proves no extra replies were queued.
    assert_eq!(
        c.ask(Body::Empty(0)),
        Body::Verdict(Verdict::Acknowledgement, 0)
    );

    // Forward and 40° down, seen by a level vehicle 50 m up through a lens looking down:
    // 50° from the optical axis towards the image top; 50 m / sin 40° away on the ground.
    let r = known[0];
    assert!((r.yaw_abs).abs() < MRAD && (r.pitch_abs + 40.0 * DEG).abs() < MRAD);
    assert!(
        r.yaw_rel.abs() < MRAD && (r.pitch_rel - 50.0 * DEG).abs() < MRAD,
        "{r:?}"
    );
    assert!(
        (r.distance - 50.0 / (40.0 * DEG).sin()).abs() < 0.002,
        "{r:?}"
    );
    assert!(
        (r.altitude - 100.0).abs() < 0.002,
        "on the ground plane at home altitude"
    );
    // The ground point is 50 m / tan 40° north of the vehicle; DETECTED_ROI carries it in
    // thousandths of a degree (the original header's packing), rounded to the nearest.
    let home = GeoPoint {
        lat: 58.0,
        lon: 15.0,
        alt: 100.0,
    };
    let exact = from_ned(home, DVec3::new(50.0 / (40.0 * DEG).tan(), 0.0, 0.0));
    let thousandths = |deg: f64| (deg * 1000.0).round() / 1000.0;
    assert_eq!(
        (r.latitude, r.longitude),
        (thousandths(exact.lat), thousandths(exact.lon)),
        "exact {exact:?}"
    );
    // Straight down is the optical axis.
    assert!(known[1].yaw_rel.abs() < MRAD && known[1].pitch_rel.abs() < MRAD);
    // Above the horizon: no ground point.
    assert_eq!(known[2].distance, 0.0);

    let one = c.get(Param::DetectedRoi(DetectedRoi {
        index: 2,
        ..Default::default()
    }));
    assert_eq!(one, Param::DetectedRoi(known[2]));
    assert_eq!(
        c.ask(Body::Get(Param::DetectedRoi(DetectedRoi {
            index: 3,
            ..Default::default()
        }))),
        verdict(Verdict::DataError, ParamType::DetectedRoi)
    );
}

#[test]
fn no_detections_is_one_reply_with_total_zero() {
    let mut c = Direct::start(&[]);
    for index in [254, 255] {
        let r = c.get(Param::DetectedRoi(DetectedRoi {
            index,
            ..Default::default()
        }));
        assert_eq!(r, Param::DetectedRoi(DetectedRoi::default()));
    }
    assert_eq!(
        c.ask(Body::Empty(0)),
        Body::Verdict(Verdict::Acknowledgement, 0)
    );
}
