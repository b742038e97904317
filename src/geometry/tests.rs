use super::ground::*;
use super::rotation::*;
use super::view::*;
use super::*;
use crate::modes::{Control, Crop};
use glam::{DMat3, DVec2, DVec3, EulerRot};
use std::f64::consts::{FRAC_PI_2, PI};

const DEG: f64 = PI / 180.0;

fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
    (a - b).length() < tol
}

#[test]
fn euler_is_rz_ry_rx_with_the_conventions_signs() {
    let e = Euler::new(0.3, -0.4, 1.1);
    let g = DMat3::from_euler(EulerRot::ZYX, 0.3, -0.4, 1.1);
    assert!(e.matrix().abs_diff_eq(g, 1e-12));
    // Yaw 90°: the nose points east. Pitch +: the nose goes up (-down). Roll +: right side down.
    assert!(close(
        Euler::new(FRAC_PI_2, 0.0, 0.0).matrix() * DVec3::X,
        DVec3::Y,
        1e-12
    ));
    assert!(close(
        Euler::new(0.0, 0.3, 0.0).matrix() * DVec3::X,
        DVec3::new(0.3f64.cos(), 0.0, -0.3f64.sin()),
        1e-12
    ));
    assert!((Euler::new(0.0, 0.0, 0.3).matrix() * DVec3::Y).z > 0.0);
}

#[test]
fn euler_angles_survive_matrix_and_quaternion_round_trips() {
    for &(y, p, r) in &[
        (0.1, 0.2, 0.3),
        (-3.0, 1.2, -2.5),
        (3.1, -1.5, 0.0),
        (-0.7, 0.0, 3.0),
    ] {
        let e = Euler::new(y, p, r);
        for back in [Euler::from_matrix(&e.matrix()), Euler::from_quat(e.quat())] {
            assert!(
                back.matrix().abs_diff_eq(e.matrix(), 1e-9),
                "{e:?} -> {back:?}"
            );
            assert!((back.yaw - wrap_pi(y)).abs() < 1e-9 && (back.pitch - p).abs() < 1e-9);
        }
    }
    assert_eq!(wrap_pi(PI), PI);
    assert!((wrap_pi(-PI) - PI).abs() < 1e-15, "yaw wraps to (-π, π]");
    assert!((wrap_pi(3.0 * PI + 0.1) - (-PI + 0.1)).abs() < 1e-12);
}

#[test]
fn the_default_mount_looks_down_with_the_image_top_towards_the_nose() {
    let r = lens_from_world(Euler::default(), Euler::new(0.0, -FRAC_PI_2, 0.0)).transpose();
    assert!(
        close(r * DVec3::Z, DVec3::Z, 1e-12),
        "optical axis points down"
    );
    assert!(
        close(r * DVec3::NEG_Y, DVec3::X, 1e-12),
        "image up is north (the nose)"
    );
    assert!(
        close(r * DVec3::X, DVec3::Y, 1e-12),
        "image right is east (the right wing)"
    );
}

#[test]
fn all_locked_views_ignore_the_vehicle_and_unlocked_views_follow_it() {
    let cam = Euler::new(0.5, -0.3, 0.1);
    let v1 = Euler::new(0.2, 0.1, -0.3);
    let v2 = Euler::new(-1.0, -0.2, 0.4);
    assert!(
        view_orientation(cam, LockFlags::ALL, v1)
            .abs_diff_eq(view_orientation(cam, LockFlags::ALL, v2), 1e-12)
    );
    let zero = Euler::default();
    assert!(view_orientation(zero, LockFlags::NONE, v1).abs_diff_eq(v1.matrix(), 1e-12));
    // Each bit locks its own axis only.
    let c = LockFlags(LockFlags::YAW).compose(cam, v1);
    assert!((c.yaw - cam.yaw).abs() < 1e-12 && (c.pitch - (cam.pitch + v1.pitch)).abs() < 1e-12);
    let c = LockFlags(LockFlags::ROLL | LockFlags::PITCH).compose(cam, v1);
    assert!((c.yaw - (cam.yaw + v1.yaw)).abs() < 1e-12 && (c.roll - cam.roll).abs() < 1e-12);
}

#[test]
fn aiming_points_the_views_forward_axis_along_the_ray_under_any_locks() {
    let vehicle = Euler::new(0.7, 0.15, -0.25);
    let ray = DVec3::new(0.3, -0.8, 0.5).normalize();
    for locks in 0..8 {
        let cam = aim(ray, Euler::new(0.0, 0.0, 0.2), LockFlags(locks), vehicle);
        assert_eq!(cam.roll, 0.2, "roll is kept");
        let fwd = view_orientation(cam, LockFlags(locks), vehicle) * DVec3::X;
        assert!(close(fwd, ray, 1e-12), "locks {locks}: {fwd} vs {ray}");
    }
}

#[test]
fn pilot_views_look_along_the_nose_and_coordinate_views_at_their_target() {
    let vehicle = Euler::new(0.3, 0.1, -0.2);
    let position = GeoPosition {
        lat: 58.0,
        lon: 15.0,
        alt: 150.0,
        relative_alt: 50.0,
    };
    let mut steering = Steering {
        control: Control::Pilot,
        angles: Euler::new(0.0, -0.5, 0.0),
        locks: LockFlags::ALL,
        target: None,
    };
    let nose = steering.world_from_view(vehicle, &position) * DVec3::X;
    assert!((nose - vehicle.matrix() * DVec3::X).length() < 1e-12);
    // A target 100 m east on the ground, 50 m below: the view points at it.
    steering.control = Control::Coordinate;
    steering.target = Some(from_ned(position.point(), DVec3::new(0.0, 100.0, 50.0)));
    let fwd = steering.world_from_view(vehicle, &position) * DVec3::X;
    assert!(
        (fwd - DVec3::new(0.0, 100.0, 50.0).normalize()).length() < 1e-6,
        "{fwd}"
    );
}

#[test]
fn relative_angles_follow_the_frame_rel_formulas() {
    let (yaw, pitch) = relative_angles(direction(0.4, -0.2));
    assert!((yaw - 0.4).abs() < 1e-12 && (pitch + 0.2).abs() < 1e-12);
}

#[test]
fn zoom_steps_are_relative_and_clamped_per_crop_mode() {
    let f = 1.2;
    let z = zoomed_fov(f, 32, Crop::Rectilinear);
    assert!((z - 0.6).abs() < 1e-12);
    assert!((zoomed_fov(z, -32, Crop::Rectilinear) - f).abs() < 1e-12);
    assert_eq!(
        zoomed_fov(3.0, -127, Crop::Rectilinear),
        MAX_RECTILINEAR_FOV
    );
    assert_eq!(zoomed_fov(3.0, -127, Crop::Panorama), 2.0 * PI);
    assert_eq!(zoomed_fov(0.2, 127, Crop::Panorama), MIN_FOV);
}

#[test]
fn wgs84_conversions_round_trip_and_match_known_distances() {
    let origin = GeoPoint {
        lat: 59.3293,
        lon: 18.0686,
        alt: 30.0,
    };
    let p = GeoPoint {
        lat: 59.34,
        lon: 18.09,
        alt: 120.0,
    };
    let back = from_ecef(to_ecef(p));
    assert!(
        (back.lat - p.lat).abs() < 1e-10
            && (back.lon - p.lon).abs() < 1e-10
            && (back.alt - p.alt).abs() < 1e-6
    );
    let ned = to_ned(origin, p);
    let again = from_ned(origin, ned);
    assert!((again.lat - p.lat).abs() < 1e-10 && (again.alt - p.alt).abs() < 1e-6);
    // A degree of latitude at the equator is 110.574 km, of longitude 111.320 km; over a
    // thousandth of a degree the tangent plane and the arc agree to the millimetre.
    let eq = GeoPoint {
        lat: 0.0,
        lon: 0.0,
        alt: 0.0,
    };
    let n = to_ned(eq, GeoPoint { lat: 0.001, ..eq });
    let e = to_ned(eq, GeoPoint { lon: 0.001, ..eq });
    assert!((n.x - 110.574).abs() < 0.002, "{n}");
    assert!((e.y - 111.320).abs() < 0.002, "{e}");
    let n = to_ned(eq, GeoPoint { lat: 1.0, ..eq });
    assert!(
        n.z > 0.0,
        "the curved earth falls away below the tangent plane"
    );
}

#[test]
fn rays_meet_the_ground_plane_below_the_vehicle_or_nowhere() {
    let pos = GeoPosition {
        lat: 47.0,
        lon: 8.0,
        alt: 550.0,
        relative_alt: 50.0,
    };
    assert!(close(
        ray_to_ground(&pos, DVec3::Z).unwrap(),
        DVec3::new(0.0, 0.0, 50.0),
        1e-9
    ));
    let d = ray_to_ground(&pos, direction(0.0, -45.0 * DEG)).unwrap();
    assert!((d.x - 50.0).abs() < 1e-9 && (d.z - 50.0).abs() < 1e-9);
    assert_eq!(
        ray_to_ground(&pos, DVec3::X),
        None,
        "the horizon never meets the ground"
    );
    assert_eq!(
        ray_to_ground(&pos, direction(0.0, 0.1)),
        None,
        "nor does a ray above it"
    );
    assert_eq!(
        ray_to_ground(&pos, direction(0.0, -0.004)),
        None,
        "12.5 km is beyond 10 km"
    );
    let (geo, range) = ground_point(&pos, direction(1.0, -0.5)).unwrap();
    assert!((range - 50.0 / 0.5f64.sin()).abs() < 1e-6);
    let aim = ray_to_target(&pos, geo).unwrap();
    assert!(
        close(aim, direction(1.0, -0.5), 1e-9),
        "aiming at a ground point gives its ray back"
    );
}

#[test]
fn attitude_is_slerped_between_the_samples_around_the_capture_time() {
    let mut track = AttitudeTrack::new(8);
    assert_eq!(track.at(5), None);
    track.push(2_000, Euler::new(30.0 * DEG, 0.0, 0.0));
    track.push(1_000, Euler::new(10.0 * DEG, 0.0, 0.0)); // out of order
    let mid = track.at(1_500).unwrap();
    assert!((mid.yaw - 20.0 * DEG).abs() < 1e-12, "{mid:?}");
    assert!(
        (track.at(0).unwrap().yaw - 10.0 * DEG).abs() < 1e-12,
        "before the span: the first sample"
    );
    // After it: turning on as the last two samples did, for 50 ms at most.
    let mut turning = AttitudeTrack::new(8);
    turning.push(0, Euler::new(0.0, 0.0, 5.0 * DEG));
    turning.push(10_000, Euler::new(1.0 * DEG, 0.0, 5.0 * DEG)); // 100°/s of yaw
    let ahead = |t: u64| turning.at(t).unwrap();
    assert!(
        (ahead(15_000).yaw - 1.5 * DEG).abs() < 1e-9,
        "{:?}",
        ahead(15_000)
    );
    assert!((ahead(15_000).roll - 5.0 * DEG).abs() < 1e-9);
    assert!((ahead(60_000).yaw - 6.0 * DEG).abs() < 1e-9);
    assert!(
        (ahead(900_000).yaw - 6.0 * DEG).abs() < 1e-9,
        "a silent autopilot: held"
    );
    let one = {
        let mut t = AttitudeTrack::new(4);
        t.push(1_000, Euler::new(30.0 * DEG, 0.0, 0.0));
        t.at(9_000).unwrap()
    };
    assert!((one.yaw - 30.0 * DEG).abs() < 1e-12, "one sample: held");
    // Across ±180° the short way round.
    let mut t = AttitudeTrack::new(4);
    t.push(0, Euler::new(170.0 * DEG, 0.0, 0.0));
    t.push(100, Euler::new(-170.0 * DEG, 0.0, 0.0));
    assert!((t.at(50).unwrap().yaw.abs() - PI).abs() < 1e-9);
    // Capacity bounds the history.
    for i in 0..20 {
        t.push(1_000 + i, Euler::default());
    }
    assert_eq!(t.len(), 4);
}

#[test]
fn rectilinear_and_panorama_pixels_round_trip_and_centre_on_the_forward_axis() {
    let views = [
        Projection::Rectilinear {
            width: 320.0,
            height: 240.0,
            fov: 90.0 * DEG,
        },
        Projection::Panorama {
            width: 640.0,
            height: 160.0,
            fov: 2.0 * PI,
            pitch: -20.0 * DEG,
        },
    ];
    for v in views {
        let c = match v {
            Projection::Rectilinear { width, height, .. }
            | Projection::Panorama { width, height, .. } => DVec2::new(width / 2.0, height / 2.0),
        };
        assert!(close(v.ray(c), DVec3::X, 1e-12), "{v:?}");
        for p in [
            DVec2::new(3.0, 7.5),
            DVec2::new(300.0, 150.0),
            DVec2::new(100.5, 20.0),
        ] {
            let q = v.point(v.ray(p)).unwrap();
            assert!((q - p).length() < 1e-9, "{v:?}: {p} -> {q}");
        }
    }
    // The rectilinear edge is at half the fov; the panorama spans its fov linearly.
    let r = views[0].ray(DVec2::new(320.0, 120.0));
    assert!((r.y.atan2(r.x) - 45.0 * DEG).abs() < 1e-12);
    let world = Euler::new(0.0, -20.0 * DEG, 0.0).matrix();
    let (yaw, pitch) = yaw_pitch(world * views[1].ray(DVec2::new(480.0, 80.0)));
    assert!(
        (yaw - 90.0 * DEG).abs() < 1e-9 && (pitch + 20.0 * DEG).abs() < 1e-9,
        "level cylinder: {yaw} {pitch}"
    );
}
