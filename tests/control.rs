//! The control protocol over real sockets against `digiview serve --no-video`: every GET and
//! SET, the seed's rules field by field, every error reply, permissions, QUIT, pipelining,
//! stalled clients and load.

mod common;
use common::serve::{Raw, Serve, udp_exchange};
use digiview::geometry::GeoPoint;
use digiview::geometry::ground::{from_ned, to_ned};
use digiview::layout::layout;
use digiview::protocol::params::*;
use digiview::protocol::{Body, FRAME_LEN, Message, Param, ParamType, Verdict, crc8};
use glam::DVec3;
use std::io::{Read, Write};
use std::time::Duration;

const DEG: f64 = std::f64::consts::PI / 180.0;
/// Milliradian fixed point: a value read back is within half a step.
const MRAD: f64 = 0.0005 + 1e-9;

fn ack(pt: ParamType) -> Body {
    Body::Verdict(Verdict::Acknowledgement, pt as u8)
}
fn verdict(v: Verdict, pt: ParamType) -> Body {
    Body::Verdict(v, pt as u8)
}

/// A frame with arbitrary header bytes and a correct checksum.
fn raw_frame(version: u8, message_type: u8, param_type: u8) -> [u8; FRAME_LEN] {
    let mut f = [0u8; FRAME_LEN];
    f[8] = version;
    f[9] = message_type;
    f[10] = param_type;
    f[75] = crc8(&f[..75]);
    f
}

fn cam_param<P>(raw: &mut Raw, make: impl Fn(u8) -> Param, pick: impl Fn(Param) -> P) -> P {
    pick(raw.get(make(0)))
}

#[test]
fn every_get_answers_with_its_own_type() {
    let server = Serve::start(&["--track", "yaw=10deg,pitch=-40deg,size=3deg"]);
    let mut c = server.tcp();
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
    let server = Serve::start(&[]);
    let mut c = server.tcp();
    let get = |c: &mut Raw| match c.get(ParamType::VideoOutput.zeroed()) {
        Param::VideoOutput(v) => v,
        _ => unreachable!(),
    };
    let set = |c: &mut Raw, w, h, fps, layout_mode, overlay| {
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
    let l = layout(1280, 720, 3, 4).unwrap();
    for (i, b) in v.views.iter().enumerate() {
        match l.views.get(i) {
            Some((r, _)) => assert_eq!(
                (b.x, b.y, b.w, b.h),
                (r.x as u16, r.y as u16, r.w as u16, r.h as u16)
            ),
            None => assert_eq!(*b, Default::default(), "unused view {i} is zero"),
        }
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

#[test]
fn detection_keeps_out_of_range_thresholds_and_255_scores_and_clamps_limits() {
    let server = Serve::start(&[]);
    let mut c = server.tcp();
    let get = |c: &mut Raw| match c.get(ParamType::Detection.zeroed()) {
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
fn camera_settings_follow_the_seed_and_protocol_rules() {
    let server = Serve::start(&[]);
    let mut c = server.tcp();
    let set = |c: &mut Raw, p: Param| c.ask(Body::Set(p));
    let euler = |c: &mut Raw| match c.get(Param::CamEuler(CamEuler {
        cam_id: 1,
        ..Default::default()
    })) {
        Param::CamEuler(e) => e,
        _ => unreachable!(),
    };
    // CAM_EULER absolute, then a delta; yaw wraps.
    let e = CamEuler {
        cam_id: 1,
        is_delta: 0,
        yaw: 3.0,
        pitch: -0.4,
        roll: 0.1,
    };
    assert_eq!(set(&mut c, Param::CamEuler(e)), ack(ParamType::CamEuler));
    let d = CamEuler {
        cam_id: 1,
        is_delta: 1,
        yaw: 0.5,
        pitch: 0.1,
        roll: 0.0,
    };
    assert_eq!(set(&mut c, Param::CamEuler(d)), ack(ParamType::CamEuler));
    let got = euler(&mut c);
    assert!(
        (got.yaw - (3.5 - 2.0 * std::f64::consts::PI)).abs() < MRAD,
        "{got:?}"
    );
    assert!(
        (got.pitch + 0.3).abs() < MRAD && (got.roll - 0.1).abs() < MRAD,
        "{got:?}"
    );

    // Lock flags: every value 0..=7 is taken as is; higher bits are dropped.
    for flags in 0..=7u8 {
        assert_eq!(
            set(
                &mut c,
                Param::CamLockFlags(CamLockFlags { cam_id: 2, flags })
            ),
            ack(ParamType::CamLockFlags)
        );
        let got = c.get(Param::CamLockFlags(CamLockFlags {
            cam_id: 2,
            flags: 0,
        }));
        assert_eq!(got, Param::CamLockFlags(CamLockFlags { cam_id: 2, flags }));
    }
    set(
        &mut c,
        Param::CamLockFlags(CamLockFlags {
            cam_id: 2,
            flags: 13,
        }),
    );
    assert_eq!(
        c.get(Param::CamLockFlags(CamLockFlags {
            cam_id: 2,
            flags: 0
        })),
        Param::CamLockFlags(CamLockFlags {
            cam_id: 2,
            flags: 5
        })
    );

    // Fov: clamped to the crop mode's range; zoom is a relative step.
    let fov = |c: &mut Raw| {
        cam_param(
            c,
            |id| {
                Param::CamFov(CamFov {
                    cam_id: id,
                    fov: 0.0,
                })
            },
            |p| match p {
                Param::CamFov(f) => f.fov,
                _ => unreachable!(),
            },
        )
    };
    set(
        &mut c,
        Param::CamFov(CamFov {
            cam_id: 0,
            fov: 1.2,
        }),
    );
    assert!((fov(&mut c) - 1.2).abs() < MRAD);
    set(
        &mut c,
        Param::CamZoom(CamZoom {
            cam_id: 0,
            zoom: 32,
        }),
    );
    assert!((fov(&mut c) - 0.6).abs() < MRAD, "+32 halves the fov");
    assert_eq!(
        c.get(Param::CamZoom(CamZoom { cam_id: 0, zoom: 0 })),
        Param::CamZoom(CamZoom {
            cam_id: 0,
            zoom: 32
        })
    );
    set(
        &mut c,
        Param::CamZoom(CamZoom {
            cam_id: 0,
            zoom: -32,
        }),
    );
    assert!((fov(&mut c) - 1.2).abs() < MRAD, "-32 restores it");
    set(
        &mut c,
        Param::CamFov(CamFov {
            cam_id: 0,
            fov: 0.01,
        }),
    );
    assert!((fov(&mut c) - 0.1).abs() < MRAD);
    set(
        &mut c,
        Param::CamFov(CamFov {
            cam_id: 0,
            fov: 3.5,
        }),
    );
    assert!(
        (fov(&mut c) - 3.1).abs() < MRAD,
        "a rectilinear view stops at 3.1 rad"
    );
    // A panorama may be wider; switching back to rectilinear brings the fov into range.
    set(
        &mut c,
        Param::CamCropMode(CamCropMode { cam_id: 0, mode: 2 }),
    );
    set(
        &mut c,
        Param::CamFov(CamFov {
            cam_id: 0,
            fov: 5.0,
        }),
    );
    assert!((fov(&mut c) - 5.0).abs() < MRAD);
    set(
        &mut c,
        Param::CamCropMode(CamCropMode { cam_id: 0, mode: 1 }),
    );
    assert!((fov(&mut c) - 3.1).abs() < MRAD);
    // An unknown crop mode is taken (the view renders black).
    assert_eq!(
        set(
            &mut c,
            Param::CamCropMode(CamCropMode { cam_id: 3, mode: 9 })
        ),
        ack(ParamType::CamCropMode)
    );
    assert_eq!(
        c.get(Param::CamCropMode(CamCropMode { cam_id: 3, mode: 0 })),
        Param::CamCropMode(CamCropMode { cam_id: 3, mode: 9 })
    );

    // Control mode: 0..=3, but coordinate control needs a target first.
    let mode = |m| Param::CamControlMode(CamControlMode { cam_id: 1, mode: m });
    assert_eq!(set(&mut c, mode(3)), ack(ParamType::CamControlMode));
    assert_eq!(
        set(&mut c, mode(4)),
        verdict(Verdict::DataError, ParamType::CamControlMode)
    );
    assert_eq!(
        set(&mut c, mode(2)),
        verdict(Verdict::DataError, ParamType::CamControlMode)
    );
    assert_eq!(c.get(mode(0)), mode(3), "refused SETs changed nothing");

    // Lens: only ids lens.cal has.
    assert_eq!(
        set(&mut c, Param::Lens(Lens { lens_id: 2 })),
        ack(ParamType::Lens)
    );
    assert_eq!(
        set(&mut c, Param::Lens(Lens { lens_id: 9 })),
        verdict(Verdict::DataError, ParamType::Lens)
    );
    assert_eq!(
        c.get(Param::Lens(Lens { lens_id: 0 })),
        Param::Lens(Lens { lens_id: 2 })
    );
}

#[test]
fn sensor_general_settings_and_capture_without_video() {
    let server = Serve::start(&[]);
    let mut c = server.tcp();
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

/// Every camera's value of every per-camera type that a GET with only cam_id reads.
fn camera_values(c: &mut Raw) -> Vec<Param> {
    (6..=13u8)
        .filter(|&t| t != 11 && t != 13)
        .flat_map(|t| (0..4).map(move |cam| (t, cam)))
        .map(|(t, cam)| {
            c.get(digiview::control::client::query(
                ParamType::from_u8(t).unwrap(),
                cam,
            ))
        })
        .collect()
}

#[test]
fn cam_ids_outside_0_to_3_and_sets_of_get_only_types_are_data_errors() {
    let server = Serve::start(&[]);
    let mut c = server.tcp();
    let before = camera_values(&mut c);
    for t in 6..=13u8 {
        let kind = ParamType::from_u8(t).unwrap();
        for cam in [4.0, 255.0] {
            let mut p = kind.zeroed();
            p.set_field("cam_id", cam).unwrap();
            assert_eq!(
                c.ask(Body::Get(p)),
                verdict(Verdict::DataError, kind),
                "GET {kind} cam {cam}"
            );
            assert_eq!(
                c.ask(Body::Set(p)),
                verdict(Verdict::DataError, kind),
                "SET {kind} cam {cam}"
            );
        }
    }
    let after = camera_values(&mut c);
    assert_eq!(before, after);
    for kind in [ParamType::SystemStatus, ParamType::DetectedRoi] {
        assert_eq!(
            c.ask(Body::Set(kind.zeroed())),
            verdict(Verdict::DataError, kind)
        );
    }
}

#[test]
fn unknown_types_bad_versions_reply_types_and_bad_checksums_get_their_replies() {
    let server = Serve::start(&[]);
    let mut c = server.tcp();
    let answer = |c: &mut Raw, f: [u8; FRAME_LEN]| {
        c.send_bytes(&f);
        c.recv().body
    };
    for pt in [16u8, 99, 255] {
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

    // 16 bad frames in a row: the stream is misaligned, the server hangs up.
    for _ in 0..16 {
        c.send_bytes(&f);
    }
    for _ in 0..16 {
        assert_eq!(
            c.recv().body,
            verdict(Verdict::ChecksumError, ParamType::CamFov)
        );
    }
    let mut rest = Vec::new();
    assert_eq!(
        c.stream.read_to_end(&mut rest).unwrap_or(0),
        0,
        "closed after 16 bad frames"
    );
}

#[test]
fn udp_answers_each_datagram_and_calls_short_ones_data_errors() {
    let server = Serve::start(&[]);
    let reply = |d: &[u8]| Message::decode(&udp_exchange(server.addr, d)).unwrap().body;
    let get = Message::new(Body::Get(ParamType::Lens.zeroed())).encode();
    assert_eq!(reply(&get), Body::Current(Param::Lens(Lens { lens_id: 0 })));
    assert_eq!(
        reply(&get[..40]),
        Body::Verdict(Verdict::DataError, 0),
        "short datagram"
    );
    let mut long = get.to_vec();
    long.push(0);
    assert_eq!(
        reply(&long),
        Body::Verdict(Verdict::DataError, 0),
        "long datagram"
    );
    let set = Message::new(Body::Set(Param::Lens(Lens { lens_id: 1 }))).encode();
    assert_eq!(reply(&set), ack(ParamType::Lens));
    assert_eq!(reply(&get), Body::Current(Param::Lens(Lens { lens_id: 1 })));
}

#[test]
fn clients_without_permission_are_forbidden_and_change_nothing() {
    let mut server = Serve::start(&["--allow-set", "10.0.0.0/8", "--allow-quit", "none"]);
    let mut c = server.tcp();
    let set = Body::Set(Param::Lens(Lens { lens_id: 1 }));
    assert_eq!(c.ask(set), verdict(Verdict::Forbidden, ParamType::Lens));
    let udp_set = Message::decode(&udp_exchange(server.addr, &Message::new(set).encode())).unwrap();
    assert_eq!(udp_set.body, verdict(Verdict::Forbidden, ParamType::Lens));
    assert_eq!(
        c.get(ParamType::Lens.zeroed()),
        Param::Lens(Lens { lens_id: 0 }),
        "GET is open, the SET was not applied"
    );
    assert_eq!(c.ask(Body::Quit(0)), Body::Verdict(Verdict::Forbidden, 0));
    assert!(
        server.wait_exit(Duration::from_millis(300)).is_none(),
        "a forbidden QUIT does not stop the server"
    );
    assert_eq!(
        c.ask(Body::Empty(0)),
        Body::Verdict(Verdict::Acknowledgement, 0)
    );
}

#[test]
fn quit_from_loopback_acknowledges_then_ends_the_process_cleanly() {
    let mut server = Serve::start(&[]);
    let mut other = server.tcp();
    assert_eq!(
        other.ask(Body::Empty(0)),
        Body::Verdict(Verdict::Acknowledgement, 0)
    );
    let mut c = server.tcp();
    assert_eq!(
        c.ask(Body::Quit(0)),
        Body::Verdict(Verdict::Acknowledgement, 0)
    );
    let status = server
        .wait_exit(Duration::from_secs(5))
        .expect("the server exits");
    assert!(status.success(), "{status:?}");
    let mut rest = Vec::new();
    assert_eq!(
        other.stream.read_to_end(&mut rest).unwrap_or(0),
        0,
        "other clients are closed"
    );
}

#[test]
fn detected_roi_254_and_255_send_one_reply_per_detection() {
    // Overlay 1 shows a single tile, so 254 (shown) and 255 (known) differ.
    let server = Serve::start(&[
        "--overlay",
        "1",
        "--track",
        "yaw=0deg,pitch=-40deg,size=3deg,score=90",
        "--track",
        "yaw=90deg,pitch=-90deg,size=3deg,score=80",
        "--track",
        "yaw=180deg,pitch=10deg,size=3deg,score=70",
    ]);
    let mut c = server.tcp();
    let ask_all = |c: &mut Raw, index: u8| -> Vec<DetectedRoi> {
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
    let ned = to_ned(
        GeoPoint {
            lat: 58.0,
            lon: 15.0,
            alt: 150.0,
        },
        GeoPoint {
            lat: r.latitude,
            lon: r.longitude,
            alt: r.altitude,
        },
    );
    assert!(
        (ned.x - 50.0 / (40.0 * DEG).tan()).abs() < 0.15 && ned.y.abs() < 0.15,
        "{ned}"
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
    let server = Serve::start(&[]);
    let mut c = server.tcp();
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

fn offset(c: &mut Raw, cam: u8, x: f64, y: f64, frame_rel: u8) -> CamOffset {
    let q = CamOffset {
        cam_id: cam,
        x,
        y,
        frame_rel,
        ..Default::default()
    };
    match c.ask(Body::Get(Param::CamOffset(q))) {
        Body::Current(Param::CamOffset(o)) => o,
        other => panic!("GET {q:?}: {other:?}"),
    }
}

/// The view's centre looks along (yaw, pitch), within two fixed-point steps (each reading
/// is rounded once).
fn assert_looks(centre: CamOffset, yaw: f64, pitch: f64) {
    assert!(
        (centre.yaw - yaw).abs() < 2.0 * MRAD && (centre.pitch - pitch).abs() < 2.0 * MRAD,
        "{centre:?} vs yaw {yaw}, pitch {pitch}"
    );
}

#[test]
fn cam_offset_reports_a_pixels_direction_and_set_turns_the_view_there() {
    let server = Serve::start(&[]);
    let mut c = server.tcp();
    // Camera 0: yaw 0, pitch -30°, 90° rectilinear, all axes locked, vehicle level.
    let centre = offset(&mut c, 0, 0.0, 0.0, 0);
    assert!(
        centre.yaw.abs() < MRAD && (centre.pitch + 30.0 * DEG).abs() < MRAD,
        "{centre:?}"
    );
    let own = offset(&mut c, 0, 0.0, 0.0, 1);
    assert!(own.yaw.abs() < MRAD && own.pitch.abs() < MRAD);
    // A quarter of the width right of centre in a 90° view: atan(0.5) in the view's frame.
    let right = offset(&mut c, 0, 0.25, 0.0, 1);
    assert!(
        (right.yaw - 0.5f64.atan()).abs() < MRAD && right.pitch.abs() < MRAD,
        "{right:?}"
    );
    let up = offset(&mut c, 0, 0.0, -0.1, 1);
    assert!(
        up.yaw.abs() < MRAD && (up.pitch - 0.2f64.atan()).abs() < MRAD,
        "{up:?}"
    );
    // Nearer the horizon the fisheye's image circle is cut by the frame: nothing to see.
    let hidden = CamOffset {
        cam_id: 0,
        y: -0.25,
        ..Default::default()
    };
    assert_eq!(
        c.ask(Body::Get(Param::CamOffset(hidden))),
        verdict(Verdict::DataError, ParamType::CamOffset)
    );

    let target = offset(&mut c, 0, 0.25, -0.1, 0);
    let set = CamOffset {
        cam_id: 0,
        x: 0.25,
        y: -0.1,
        ..Default::default()
    };
    assert_eq!(
        c.ask(Body::Set(Param::CamOffset(set))),
        ack(ParamType::CamOffset)
    );
    let now = offset(&mut c, 0, 0.0, 0.0, 0);
    assert_looks(now, target.yaw, target.pitch);
}

#[test]
fn cam_target_finds_ground_points_and_keeps_a_view_on_its_target() {
    let server = Serve::start(&[]);
    let mut c = server.tcp();
    let home = GeoPoint {
        lat: 58.0,
        lon: 15.0,
        alt: 150.0,
    };
    let target = |c: &mut Raw, cam, x, y| {
        c.ask(Body::Get(Param::CamTarget(CamTarget {
            cam_id: cam,
            x,
            y,
            ..Default::default()
        })))
    };
    // No target yet.
    assert_eq!(
        target(&mut c, 0, 0.0, 0.0),
        verdict(Verdict::DataError, ParamType::CamTarget)
    );
    // Camera 0 looks north 30° down: the pixel a quarter height below centre looks
    // 30° + atan(0.5) down, so it meets the ground 50 m below at 50 / tan(56.57°) north.
    let Body::Current(Param::CamTarget(t)) = target(&mut c, 0, 0.0, 0.25) else {
        panic!()
    };
    let ned = to_ned(
        home,
        GeoPoint {
            lat: t.t_latitude,
            lon: t.t_longitude,
            alt: t.t_altitude,
        },
    );
    let north = 50.0 / (30.0 * DEG + 0.5f64.atan()).tan();
    assert!(
        (ned.x - north).abs() < 0.15 && ned.y.abs() < 0.15 && (ned.z - 50.0).abs() < 0.01,
        "{ned}"
    );
    // Above the horizon: nothing on the ground.
    assert_eq!(
        target(&mut c, 0, 0.0, -0.45),
        verdict(Verdict::DataError, ParamType::CamTarget)
    );

    // Aim camera 2 at coordinates 100 m east on the ground.
    let east = from_ned(home, DVec3::new(0.0, 100.0, 50.0));
    let set = CamTarget {
        cam_id: 2,
        x: 0.0,
        y: 0.0,
        t_latitude: east.lat,
        t_longitude: east.lon,
        t_altitude: east.alt,
    };
    assert_eq!(
        c.ask(Body::Set(Param::CamTarget(set))),
        ack(ParamType::CamTarget)
    );
    let Body::Current(Param::CamTarget(now)) = target(&mut c, 2, 0.0, 0.0) else {
        panic!()
    };
    assert!((now.t_latitude - east.lat).abs() < 1e-6 && (now.t_longitude - east.lon).abs() < 1e-6);
    assert_eq!(
        c.get(Param::CamControlMode(CamControlMode { cam_id: 2, mode: 0 })),
        Param::CamControlMode(CamControlMode { cam_id: 2, mode: 2 })
    );
    assert_looks(offset(&mut c, 2, 0.0, 0.0, 0), 90.0 * DEG, -0.5f64.atan());
    // Steering by angles ends coordinate control.
    let e = CamEuler {
        cam_id: 2,
        is_delta: 1,
        ..Default::default()
    };
    assert_eq!(
        c.ask(Body::Set(Param::CamEuler(e))),
        ack(ParamType::CamEuler)
    );
    assert_eq!(
        c.get(Param::CamControlMode(CamControlMode { cam_id: 2, mode: 0 })),
        Param::CamControlMode(CamControlMode { cam_id: 2, mode: 1 })
    );
    // A pixel target: the view then points at that ground point.
    let set = CamTarget {
        cam_id: 1,
        x: 0.2,
        y: 0.3,
        ..Default::default()
    };
    let Body::Current(Param::CamTarget(seen)) = target(&mut c, 1, 0.2, 0.3) else {
        panic!()
    };
    let dir = offset(&mut c, 1, 0.2, 0.3, 0);
    assert_eq!(
        c.ask(Body::Set(Param::CamTarget(set))),
        ack(ParamType::CamTarget)
    );
    let Body::Current(Param::CamTarget(kept)) = target(&mut c, 1, 0.0, 0.0) else {
        panic!()
    };
    assert!(
        (kept.t_latitude - seen.t_latitude).abs() < 1e-6
            && (kept.t_longitude - seen.t_longitude).abs() < 1e-6
    );
    assert_looks(offset(&mut c, 1, 0.0, 0.0, 0), dir.yaw, dir.pitch);
}

#[test]
fn pipelined_requests_are_answered_in_order() {
    let server = Serve::start(&[]);
    let mut c = server.tcp();
    let requests: Vec<Body> = (0..300)
        .map(|i| match i % 3 {
            0 => Body::Get(Param::CamFov(CamFov {
                cam_id: (i % 4) as u8,
                fov: 0.0,
            })),
            1 => Body::Set(Param::CamLockFlags(CamLockFlags {
                cam_id: (i % 4) as u8,
                flags: (i % 8) as u8,
            })),
            _ => Body::Get(Param::CamLockFlags(CamLockFlags {
                cam_id: (i % 4) as u8,
                flags: 0,
            })),
        })
        .collect();
    let bytes: Vec<u8> = requests
        .iter()
        .flat_map(|b| Message::new(*b).encode())
        .collect();
    c.send_bytes(&bytes);
    let mut last_flags = [7u8; 4];
    for (i, req) in requests.iter().enumerate() {
        let cam = (i % 4) as u8;
        match (req, c.recv().body) {
            (Body::Get(Param::CamFov(_)), Body::Current(Param::CamFov(f))) => {
                assert_eq!(f.cam_id, cam)
            }
            (Body::Set(Param::CamLockFlags(p)), b) => {
                assert_eq!(b, ack(ParamType::CamLockFlags));
                last_flags[cam as usize] = p.flags;
            }
            (Body::Get(_), Body::Current(Param::CamLockFlags(f))) => {
                assert_eq!(
                    (f.cam_id, f.flags),
                    (cam, last_flags[cam as usize]),
                    "reply {i}"
                )
            }
            (req, reply) => panic!("reply {i} to {req:?} is {reply:?}"),
        }
    }
}

#[test]
fn a_client_that_never_reads_is_dropped_and_others_carry_on() {
    let server = Serve::start(&[]);
    let hog = std::net::TcpStream::connect(server.addr).unwrap();
    let frame = Message::new(Body::Get(ParamType::VideoOutput.zeroed())).encode();
    let burst: Vec<u8> = std::iter::repeat_n(frame, 4096).flatten().collect();
    let writer = {
        let mut hog = hog.try_clone().unwrap();
        std::thread::spawn(move || {
            // Up to 64 MB of requests whose replies are never read: the server must give up
            // on this client (the write then fails) rather than queue without bound.
            for _ in 0..200 {
                if hog.write_all(&burst).is_err() {
                    return true;
                }
            }
            false
        })
    };
    // Meanwhile, another client is served.
    let mut c = server.tcp();
    for _ in 0..50 {
        assert_eq!(
            c.ask(Body::Empty(0)),
            Body::Verdict(Verdict::Acknowledgement, 0)
        );
    }
    assert!(
        writer.join().unwrap(),
        "the server dropped the client that never reads"
    );
    assert_eq!(
        c.ask(Body::Empty(0)),
        Body::Verdict(Verdict::Acknowledgement, 0)
    );
}

#[test]
fn fifty_pipelining_clients_all_get_correct_replies_beside_a_stalled_one() {
    let server = Serve::start(&[]);
    let r = digiview::control::load::run(server.addr, 50, 2000, true).unwrap();
    assert_eq!((r.replies, r.wrong), (100_000, 0), "{r:?}");
    // One client pipelining far more than its reply queue holds is slowed, not dropped.
    let r = digiview::control::load::run(server.addr, 1, 50_000, false).unwrap();
    assert_eq!((r.replies, r.wrong), (50_000, 0), "{r:?}");
}

fn ctl(addr: &str, args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args(["ctl", "--addr", addr])
        .args(args)
        .output()
        .unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn ctl_reads_and_changes_values_for_people_and_scripts() {
    let mut server = Serve::start(&["--track", "yaw=10deg,pitch=-40deg,size=3deg"]);
    let addr = server.addr.to_string();
    let o = ctl(&addr, &["get", "cam_euler", "cam=1"]);
    let out = text(&o.stdout);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(
        out.starts_with("CAM_EULER\n") && out.contains("yaw       1.571 rad (90.01°)"),
        "{out}"
    );

    // Set only the layout: the client reads first, so the size is kept.
    let o = ctl(&addr, &["set", "video_output", "layout_mode=0"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let o = ctl(&addr, &["--json", "get", "video_output"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["param"], "VIDEO_OUTPUT");
    assert_eq!(
        (
            v["values"]["width"].as_u64(),
            v["values"]["layout_mode"].as_u64()
        ),
        (Some(1920), Some(0))
    );

    // Degrees on the command line, radians on the wire; over UDP too.
    assert!(
        ctl(&addr, &["--udp", "set", "cam_fov", "cam=0", "fov=50deg"])
            .status
            .success()
    );
    let o = ctl(&addr, &["--json", "--udp", "get", "cam_fov", "cam=0"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!((v["values"]["fov"].as_f64().unwrap() - 50.0 * DEG).abs() < MRAD);

    // One JSON line per detection.
    let o = ctl(&addr, &["--json", "get", "detected_roi", "index=255"]);
    assert_eq!(text(&o.stdout).lines().count(), 1);

    // Error replies and bad input are explained.
    let o = ctl(&addr, &["get", "cam_fov", "cam=4"]);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains("DATA_ERROR to GET CAM_FOV"),
        "{}",
        text(&o.stderr)
    );
    let o = ctl(&addr, &["set", "cam_fov", "cam=0", "fvo=1"]);
    assert!(
        text(&o.stderr).contains("CAM_FOV has no field `fvo`; its fields: cam_id, fov"),
        "{}",
        text(&o.stderr)
    );
    let o = ctl(&addr, &["get", "cam_angles"]);
    assert!(
        text(&o.stderr).contains("`cam_angles` is not a parameter type"),
        "{}",
        text(&o.stderr)
    );

    // watch prints the first value and each change.
    let watcher = std::process::Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args([
            "ctl",
            "--addr",
            &addr,
            "--json",
            "watch",
            "lens",
            "--interval",
            "0.05",
            "--count",
            "2",
        ])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    assert!(ctl(&addr, &["set", "lens", "lens_id=2"]).status.success());
    let out = watcher.wait_with_output().unwrap();
    let lines: Vec<String> = text(&out.stdout).lines().map(String::from).collect();
    assert_eq!(lines.len(), 2, "{lines:?}");
    assert!(
        lines[0].contains("\"lens_id\":0") && lines[1].contains("\"lens_id\":2"),
        "{lines:?}"
    );

    let o = ctl(&addr, &["quit"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(server.wait_exit(Duration::from_secs(5)).unwrap().success());
}

#[test]
fn ctl_says_when_no_server_answers() {
    // A port nothing listens on (bound, then released).
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let addr = format!("127.0.0.1:{port}");
    let o = ctl(&addr, &["get", "lens"]);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains(&format!(
            "cannot reach the DigiView control server at {addr}"
        )),
        "{}",
        text(&o.stderr)
    );
    let o = ctl(&addr, &["--udp", "--timeout", "0.3", "get", "lens"]);
    assert!(!o.status.success());
    let e = text(&o.stderr);
    assert!(
        e.contains("cannot reach") || e.contains("no reply from"),
        "{e}"
    );
    let o = ctl("nowhere", &["get", "lens"]);
    assert!(
        text(&o.stderr).contains("`nowhere` is not a HOST:PORT address"),
        "{}",
        text(&o.stderr)
    );
}

#[test]
fn sigterm_stops_the_server_even_when_nobody_reads_its_log() {
    // `digiview serve 2>&1 | head -1`, or a terminal closed under it: its log lines go
    // nowhere, and it must still stop on SIGTERM (it used to keep running).
    let mut serve = Serve::start_unread(&[]);
    // A client connecting is logged at info level: a write into the dead pipe before the
    // signal.
    let status = serve.tcp().get(ParamType::SystemStatus.zeroed());
    assert_eq!(status.param_type(), ParamType::SystemStatus);
    serve.terminate();
    let exit = serve
        .wait_exit(Duration::from_secs(10))
        .expect("serve exits on SIGTERM with nobody reading its log");
    assert!(exit.success(), "{exit:?}");
}
