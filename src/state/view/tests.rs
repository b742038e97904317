use super::follow::{adopt, aim_followers, drop_lost};
use super::*;
use crate::geometry::rotation::yaw_pitch;
use crate::geometry::view::LockFlags;
use crate::state::sensed::{Tracked, Vehicle};
use std::f64::consts::{FRAC_PI_2, PI};

fn seen(vehicle: &Vehicle) -> Seen<'_> {
    Seen {
        vehicle,
        tracked: &[],
    }
}

/// Where view `c` looks in the world: yaw from north, pitch from the horizon, degrees.
fn looks(c: &Camera, v: &Vehicle) -> (f64, f64) {
    let m = c
        .steering()
        .world_from_view(v.attitude.euler(), &v.position);
    let (yaw, pitch) = yaw_pitch(m * glam::DVec3::X);
    (yaw.to_degrees(), pitch.to_degrees())
}

fn near(a: (f64, f64), b: (f64, f64)) -> bool {
    (a.0 - b.0).abs() < 1e-6 && (a.1 - b.1).abs() < 1e-6
}

fn run(c: &mut Camera, op: Op) -> Result<(), ViewError> {
    apply(c, &op, &seen(&Vehicle::default()))
}

fn place() -> GeoPoint {
    GeoPoint {
        lat: 58.001,
        lon: 15.0,
        alt: 100.0,
    }
}

#[test]
fn angles_wrap_the_yaw_and_hold_pitch_and_roll_within_a_quarter_turn_absolute_or_added() {
    let mut c = Camera::default();
    let angles = |yaw, pitch, roll, delta| Op::Angles {
        yaw,
        pitch,
        roll,
        delta,
    };
    run(&mut c, angles(4.0, 2.0, -3.0, false)).unwrap();
    assert!((c.yaw() - (4.0 - 2.0 * PI)).abs() < 1e-12);
    assert_eq!((c.pitch(), c.roll()), (FRAC_PI_2, -FRAC_PI_2));
    // Added: past straight down it stops there, as a gimbal does.
    run(&mut c, angles(0.5, -4.0, 0.2, true)).unwrap();
    assert!((c.yaw() - (4.5 - 2.0 * PI)).abs() < 1e-12);
    assert_eq!(c.pitch(), -FRAC_PI_2);
    assert!((c.roll() - (-FRAC_PI_2 + 0.2)).abs() < 1e-12);
}

#[test]
fn a_gimbal_command_points_the_view_in_the_world_under_its_lock_flags() {
    let mut v = Vehicle::default();
    v.attitude.yaw = 30f64.to_radians();
    v.attitude.pitch = 5f64.to_radians();
    let point = |yaw: f64, earth, locks| {
        Op::Point(Pointing {
            yaw: Some(yaw.to_radians()),
            pitch: Some((-30f64).to_radians()),
            roll: None,
            earth,
            locks: LockFlags(locks),
        })
    };
    for (earth, locks, world_yaw) in [(true, 7, 40.0), (false, 7, 70.0), (false, 0, 70.0)] {
        let mut c = Camera::default();
        apply(&mut c, &point(40.0, earth, locks), &seen(&v)).unwrap();
        assert_eq!(c.locks(), LockFlags(locks));
        assert!(
            near(looks(&c, &v), (world_yaw, -30.0)),
            "earth {earth}, locks {locks}: {:?}",
            looks(&c, &v)
        );
    }
}

/// The rule every path shares: a pitch past straight up or down stops there, whether it came
/// as CAM_EULER's angles or as a gimbal's.
#[test]
fn a_pitch_past_straight_up_stops_there_by_angles_and_by_gimbal_alike() {
    let (mut by_angles, mut by_gimbal) = (Camera::default(), Camera::default());
    let pitch = 100f64.to_radians();
    run(
        &mut by_angles,
        Op::Angles {
            yaw: 0.0,
            pitch,
            roll: 0.0,
            delta: false,
        },
    )
    .unwrap();
    let point = Pointing {
        yaw: Some(0.0),
        pitch: Some(pitch),
        roll: Some(0.0),
        earth: true,
        locks: LockFlags::ALL,
    };
    run(&mut by_gimbal, Op::Point(point)).unwrap();
    assert_eq!(by_angles, by_gimbal);
    assert_eq!(by_angles.pitch(), FRAC_PI_2);
}

#[test]
fn zooms_step_set_a_level_or_a_focal_length_and_a_zoom_to_nothing_changes_nothing() {
    let mut c = Camera::default();
    run(&mut c, Op::Zoom(Zoom::Step(32))).unwrap();
    assert!((c.fov() - 45f64.to_radians()).abs() < 1e-12);
    assert_eq!(c.zoom(), 32);
    run(&mut c, Op::Zoom(Zoom::Fov(9.0))).unwrap();
    assert_eq!(c.fov(), 3.1, "a rectilinear view stops short of π");
    run(&mut c, Op::Zoom(Zoom::FocalLength(18.0))).unwrap();
    assert!((c.fov() - FRAC_PI_2).abs() < 1e-12);
    run(&mut c, Op::Zoom(Zoom::Level(100.0))).unwrap();
    assert!((c.fov() - 0.1).abs() < 1e-12);
    let before = c.clone();
    assert_eq!(
        run(&mut c, Op::Zoom(Zoom::FocalLength(0.0))),
        Err(ViewError::NoFov(0.0))
    );
    assert_eq!(c, before);
}

#[test]
fn coordinate_control_needs_a_target_and_a_target_starts_it() {
    let mut c = Camera::default();
    assert_eq!(run(&mut c, Op::Control(2)), Err(ViewError::NeedsTarget));
    assert!(matches!(
        run(&mut c, Op::Control(4)),
        Err(ViewError::Mode(_))
    ));
    let not_a_place = GeoPoint {
        lat: 91.0,
        ..place()
    };
    assert_eq!(
        run(&mut c, Op::Target(not_a_place)),
        Err(ViewError::NotAPlace(not_a_place))
    );
    assert_eq!(c, Camera::default());
    run(&mut c, Op::Target(place())).unwrap();
    assert_eq!(
        (c.control(), c.target()),
        (Control::Coordinate, Some(place()))
    );
    run(&mut c, Op::Control(0)).unwrap();
    run(&mut c, Op::Control(2)).unwrap();
    // Steering by hand ends it.
    run(&mut c, Op::LookAlong(glam::DVec3::X)).unwrap();
    assert_eq!(c.control(), Control::Directional);
}

#[test]
fn a_released_target_leaves_the_view_pointing_where_it_pointed() {
    let v = Vehicle::default();
    let mut c = Camera::default();
    apply(&mut c, &Op::Target(place()), &seen(&v)).unwrap();
    let at = looks(&c, &v);
    apply(&mut c, &Op::ReleaseTarget, &seen(&v)).unwrap();
    assert_eq!(c.control(), Control::Directional);
    assert!(
        near(looks(&c, &v), at),
        "{:?} against {at:?}",
        looks(&c, &v)
    );
}

#[test]
fn a_crop_mode_is_taken_with_the_fov_brought_into_its_range_and_locks_keep_three_bits() {
    let mut c = Camera::default();
    run(&mut c, Op::Crop(2)).unwrap();
    run(&mut c, Op::Zoom(Zoom::Fov(5.0))).unwrap();
    run(&mut c, Op::Crop(1)).unwrap();
    assert_eq!((c.crop(), c.fov()), (Crop::Rectilinear, 3.1));
    run(&mut c, Op::Crop(9)).unwrap();
    assert_eq!((c.crop(), c.fov()), (Crop::Unknown(9), 3.1));
    run(&mut c, Op::Locks(13.0)).unwrap();
    assert_eq!(c.locks(), LockFlags(5));
}

fn clicked(yaw: f64, pitch: f64) -> Follow {
    Follow {
        shape: Shape::Point,
        yaw,
        pitch,
        size: 0.05,
        ground: None,
        since_us: 1,
        object: None,
    }
}

#[test]
fn a_follower_looks_at_its_object_then_stays_where_it_last_was_once_the_object_is_gone() {
    let mut v = Vehicle::default();
    v.attitude.yaw = 0.4;
    let tracked = [Tracked {
        id: 7,
        yaw: 1.0,
        pitch: -0.6,
        ..Tracked::default()
    }];
    let mut cams = vec![Camera::numbered(0), Camera::numbered(1)];
    apply(&mut cams[1], &Op::Follow(clicked(-2.0, -0.3)), &seen(&v)).unwrap();
    adopt(&mut cams, 1, 1, 7);
    let with = Seen {
        vehicle: &v,
        tracked: &tracked,
    };
    aim_followers(&mut cams, &with);
    let at = looks(&cams[1], &v);
    assert!(
        near(at, (1f64.to_degrees(), (-0.6f64).to_degrees())),
        "{at:?}"
    );
    assert_eq!(cams[0], Camera::numbered(0), "the others are left alone");
    assert_eq!(drop_lost(&mut cams, &[]), vec![1]);
    assert_eq!(cams[1].follow(), None);
    assert!(near(looks(&cams[1], &v), at));
}

#[test]
fn a_click_not_taken_on_yet_holds_its_direction_and_a_hand_on_the_view_ends_it() {
    let v = Vehicle::default();
    let mut cams = vec![Camera::default()];
    apply(&mut cams[0], &Op::Follow(clicked(0.5, -1.0)), &seen(&v)).unwrap();
    assert!(near(
        looks(&cams[0], &v),
        (0.5f64.to_degrees(), -1f64.to_degrees())
    ));
    assert!(drop_lost(&mut cams, &[]).is_empty());
    adopt(&mut cams, 0, 2, 9);
    assert_eq!(cams[0].follow().unwrap().object, None, "another click's");
    let turn = Op::Angles {
        yaw: 0.1,
        pitch: 0.0,
        roll: 0.0,
        delta: true,
    };
    apply(&mut cams[0], &turn, &seen(&v)).unwrap();
    assert_eq!(cams[0].follow(), None);
}
