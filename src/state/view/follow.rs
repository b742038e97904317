//! A view that follows a tracked object: what a ground station clicked in a camera's picture
//! (MAVLink's CAMERA_TRACK_POINT and CAMERA_TRACK_RECTANGLE), the object the detection stage
//! took it to be, and how the view is aimed at it. The command starts it (`Op::Follow`), the
//! detection stage keeps it (the object adopted, found again by each scan, or lost), and the
//! frame loop aims the view where the object has got to by each frame's capture time.

use super::Camera;
use super::ops::{Seen, look_along};
use crate::geometry::ground::ray_to_target;
use crate::geometry::rotation::direction;
use crate::geometry::{GeoPoint, GeoPosition};
use crate::state::sensed::Tracked;
use glam::DVec3;

/// What was clicked: a point (with a radius) or a rectangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    Point,
    Rectangle,
}

/// What a camera follows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Follow {
    pub shape: Shape,
    /// Where it was clicked: a world direction (yaw, pitch) and angular size, radians.
    pub yaw: f64,
    pub pitch: f64,
    pub size: f64,
    /// Where that ray meets the ground (None above the horizon): what the view holds on
    /// until the detection stage takes the click on, so a spot stays put while the vehicle
    /// moves.
    pub ground: Option<GeoPoint>,
    /// When it was clicked (`crate::clock::clock_us`): tells one click from the next.
    pub since_us: u64,
    /// The tracked object it is, once the detection stage took it on.
    pub object: Option<u32>,
}

/// The object view `c` follows, as `tracked` has it; None while it follows a click the
/// detection stage has not taken on yet.
pub fn followed<'a>(c: &Camera, tracked: &'a [Tracked]) -> Option<&'a Tracked> {
    let id = c.follow?.object?;
    tracked.iter().find(|o| o.id == id)
}

/// The world direction view `c` follows: its object's where `tracked` has it, else the
/// clicked ground point's from the vehicle at `position`, else the clicked direction. None
/// when it follows nothing.
pub fn followed_ray(c: &Camera, tracked: &[Tracked], position: &GeoPosition) -> Option<DVec3> {
    let f = c.follow?;
    Some(match (followed(c, tracked), f.ground) {
        (Some(o), _) => direction(o.yaw, o.pitch),
        (None, Some(g)) => ray_to_target(position, g).unwrap_or_else(|| direction(f.yaw, f.pitch)),
        (None, None) => direction(f.yaw, f.pitch),
    })
}

/// Aims every following view along [`followed_ray`] (the caller moves the tracked list on to
/// the frame's time first). Their roll, fov and lock flags are kept.
pub fn aim_followers(cameras: &mut [Camera], seen: &Seen) {
    let vehicle = seen.vehicle.attitude.euler();
    for c in cameras {
        if let Some(ray) = followed_ray(c, seen.tracked, &seen.vehicle.position) {
            look_along(c, ray, vehicle);
        }
    }
}

/// The detection stage took view `i`'s click made at `since_us` to be `object` (unless
/// another click replaced it since).
pub fn adopt(cameras: &mut [Camera], i: usize, since_us: u64, object: u32) {
    if let Some(f) = cameras[i]
        .follow
        .as_mut()
        .filter(|f| f.since_us == since_us)
    {
        f.object = Some(object);
    }
}

/// After the tracked list changed: each view whose object is no longer in it has lost it and
/// stops following, aimed where it last was. Returns those views.
pub fn drop_lost(cameras: &mut [Camera], tracked: &[Tracked]) -> Vec<usize> {
    let mut lost = vec![];
    for (i, c) in cameras.iter_mut().enumerate() {
        let gone = c
            .follow
            .is_some_and(|f| f.object.is_some() && followed(c, tracked).is_none());
        if gone {
            c.follow = None;
            lost.push(i);
        }
    }
    lost
}
