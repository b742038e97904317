//! The per-camera parameter types of the control protocol (CAM_EULER to CAM_TARGET), rule by
//! rule as the seed and protocol.md give them, in-process through `Controller::handle`: angles,
//! zoom, locks, control and crop modes, fov, cam_id ranges, the pixel-to-direction and
//! pixel-to-ground queries. The server itself is tests/it/control_server.rs's.

use crate::common;
use common::DEG;
use common::direct::Direct;
use common::frames::{Client, MRAD, ack, verdict};
use digiview::geometry::GeoPoint;
use digiview::geometry::ground::{from_ned, to_ned};
use digiview::protocol::params::*;
use digiview::protocol::{Body, Param, ParamType, Verdict};
use glam::DVec3;

fn cam_param<P>(raw: &mut Direct, make: impl Fn(u8) -> Param, pick: impl Fn(Param) -> P) -> P {
    pick(raw.get(make(0)))
}

#[test]
fn camera_settings_follow_the_seed_and_protocol_rules() {
    let mut c = Direct::start(&[]);
    let set = |c: &mut Direct, p: Param| c.ask(Body::Set(p));
    let euler = |c: &mut Direct| match c.get(Param::CamEuler(CamEuler {
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
    let fov = |c: &mut Direct| {
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

/// Every camera's value of every per-camera type that a GET with only cam_id reads.
fn camera_values(c: &mut Direct) -> Vec<Param> {
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
    let mut c = Direct::start(&[]);
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

fn offset(c: &mut Direct, cam: u8, x: f64, y: f64, frame_rel: u8) -> CamOffset {
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
    let mut c = Direct::start(&[]);
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
    let mut c = Direct::start(&[]);
    let home = GeoPoint {
        lat: 58.0,
        lon: 15.0,
        alt: 150.0,
    };
    let target = |c: &mut Direct, cam, x, y| {
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
