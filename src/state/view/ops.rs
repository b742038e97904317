//! The view operations: aim, point as a gimbal, zoom, lock, crop, show the thermal camera,
//! choose a control mode,
//! look along a ray, target a place, release it, follow a click and stop. Each is a pure
//! function of the view, the operation and what the vehicle and the detector see, and takes
//! its values through the one table of rules (`crate::state::rules`), so a request means the
//! same whichever way it came in. A view steered by hand (its angles, a gimbal command, a
//! ray) stops following its target and its object.

use super::Camera;
use super::follow::{Follow, followed_ray};
use super::zoom::{fov_at_level, fov_of_focal_length};
use crate::geometry::GeoPoint;
use crate::geometry::rotation::Euler;
use crate::geometry::view::{LockFlags, aim, clamp_fov, zoomed_fov};
use crate::modes::{Control, Crop, NotAMode, ThermalShow};
use crate::state::rules::{
    CAMERA_LOCK, CAMERA_PITCH, CAMERA_ROLL, CAMERA_TARGET_ALT, CAMERA_TARGET_LAT,
    CAMERA_TARGET_LON, CAMERA_YAW,
};
use crate::state::sensed::{Tracked, Vehicle};
use glam::DVec3;

/// One change to one view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Op {
    /// CAM_EULER: the view's angles, absolute or added to them (`delta`). Yaw wraps into
    /// (-π, π]; pitch and roll are held within ±π/2.
    Angles {
        yaw: f64,
        pitch: f64,
        roll: f64,
        delta: bool,
    },
    /// A gimbal manager's command: where the view points in the world.
    Point(Pointing),
    Zoom(Zoom),
    /// The lock flags (only the low three bits mean anything).
    Locks(f64),
    /// The control mode, by its number; coordinate control needs a target.
    Control(u8),
    /// The crop mode, by its number (one that names no mode draws the view black); the fov
    /// is brought into the new mode's range.
    Crop(u8),
    /// How the view shows the thermal camera, by its number.
    Thermal(u8),
    /// Turns the view's forward axis along a world ray (CAM_OFFSET SET), roll kept.
    LookAlong(DVec3),
    /// Aims the view at a place and follows it as the vehicle moves (coordinate control).
    Target(GeoPoint),
    /// Leaves coordinate control, the view pointing where it points now.
    ReleaseTarget,
    /// Follows what was clicked in the view's picture.
    Follow(Follow),
    StopFollowing,
}

/// A gimbal manager's pointing: yaw from the vehicle's nose (or from north where `earth`),
/// pitch and roll from the horizon; an axis left None keeps pointing where it points. The
/// lock flags become the view's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pointing {
    pub yaw: Option<f64>,
    pub pitch: Option<f64>,
    pub roll: Option<f64>,
    pub earth: bool,
    pub locks: LockFlags,
}

/// How a zoom is asked for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Zoom {
    /// CAM_ZOOM's relative step: +32 halves the fov, -32 doubles it; remembered as the view's
    /// zoom.
    Step(i8),
    /// A horizontal field of view, radians.
    Fov(f64),
    /// A zoom level, 0 (widest) to 100 (narrowest) on the crop mode's range.
    Level(f64),
    /// The focal length (mm, 35 mm frame) that gives the fov.
    FocalLength(f64),
    /// The fov multiplied by a factor (a continuous zoom's tick).
    Scale(f64),
}

/// What the vehicle and the detector see as an operation is applied.
#[derive(Clone, Copy, Debug)]
pub struct Seen<'a> {
    pub vehicle: &'a Vehicle,
    pub tracked: &'a [Tracked],
}

/// Why an operation was refused; the view is left as it was.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ViewError {
    #[error(transparent)]
    Mode(#[from] NotAMode),
    #[error(
        "coordinate control needs a target: give one first (CAM_TARGET, or DO_SET_ROI_LOCATION)"
    )]
    NeedsTarget,
    #[error("{}, {}, {} m is not a place (latitude ±90°, longitude ±180°, altitude -1000..=20000 m)", .0.lat, .0.lon, .0.alt)]
    NotAPlace(GeoPoint),
    #[error("a zoom to {0} is no field of view")]
    NoFov(f64),
}

/// Applies `op` to view `c`; refused, `c` is left as it was.
pub fn apply(c: &mut Camera, op: &Op, seen: &Seen) -> Result<(), ViewError> {
    let vehicle = seen.vehicle.attitude.euler();
    match *op {
        Op::Angles {
            yaw,
            pitch,
            roll,
            delta,
        } => angles(c, Euler::new(yaw, pitch, roll), delta),
        Op::Point(p) => point(c, &p, seen.vehicle),
        Op::Zoom(z) => return zoom(c, z),
        Op::Locks(v) => c.lock = LockFlags(CAMERA_LOCK.take(v, c.lock.0 as f64) as u8),
        Op::Control(m) => return control(c, m),
        Op::Crop(m) => crop(c, m),
        // The table's range is the displays' numbers.
        Op::Thermal(m) => c.thermal = ThermalShow::try_from(m)?,
        Op::LookAlong(ray) => {
            look_along(c, ray, vehicle);
            steer_by_hand(c);
        }
        Op::Target(g) => return target(c, g),
        Op::ReleaseTarget => release(c, seen.vehicle),
        Op::Follow(f) => {
            steer_by_hand(c);
            c.follow = Some(f);
            if let Some(ray) = followed_ray(c, seen.tracked, &seen.vehicle.position) {
                look_along(c, ray, vehicle);
            }
        }
        Op::StopFollowing => c.follow = None,
    }
    Ok(())
}

/// The view is steered by hand (its angles, a gimbal command, a ray): it follows neither its
/// geographic target nor an object any more.
fn steer_by_hand(c: &mut Camera) {
    if matches!(c.control, Control::Pilot | Control::Coordinate) {
        c.control = Control::Directional;
    }
    c.follow = None;
}

fn angles(c: &mut Camera, a: Euler, delta: bool) {
    let a = match delta {
        true => Euler::new(c.yaw + a.yaw, c.pitch + a.pitch, c.roll + a.roll),
        false => a,
    };
    c.yaw = CAMERA_YAW.take(a.yaw, c.yaw);
    c.pitch = CAMERA_PITCH.take(a.pitch, c.pitch);
    c.roll = CAMERA_ROLL.take(a.roll, c.roll);
    steer_by_hand(c);
}

/// Points the view where a gimbal command says: each axis given is turned into the view's
/// angles under the command's lock flags, so the view points there; the others keep
/// pointing where the view points now.
fn point(c: &mut Camera, p: &Pointing, v: &Vehicle) {
    let vehicle = v.attitude.euler();
    let now = Euler::from_matrix(&c.steering().world_from_view(vehicle, &v.position));
    let from_nose = if p.earth { 0.0 } else { vehicle.yaw };
    let yaw = p.yaw.map_or(now.yaw, |y| y + from_nose);
    let pitch = p
        .pitch
        .map_or(now.pitch, |x| CAMERA_PITCH.take(x, now.pitch));
    let roll = p.roll.map_or(now.roll, |r| CAMERA_ROLL.take(r, now.roll));
    let (yaw, pitch) = p.locks.decompose(yaw, pitch, vehicle);
    let roll = roll - if p.locks.roll() { 0.0 } else { vehicle.roll };
    c.lock = p.locks;
    c.yaw = CAMERA_YAW.take(yaw, c.yaw);
    // Held within ±π/2 also once the vehicle's own pitch is taken off an unlocked view's (90°
    // down from a vehicle pitched 4° down).
    c.pitch = CAMERA_PITCH.take(pitch, c.pitch);
    c.roll = CAMERA_ROLL.take(roll, c.roll);
    steer_by_hand(c);
}

fn zoom(c: &mut Camera, z: Zoom) -> Result<(), ViewError> {
    let fov = match z {
        Zoom::Step(step) => {
            c.zoom = step;
            zoomed_fov(c.fov, step, c.crop)
        }
        Zoom::Fov(f) => clamp_fov(f, c.crop),
        Zoom::Level(l) if l.is_finite() => fov_at_level(l, c.crop),
        Zoom::FocalLength(mm) if mm > 0.0 => clamp_fov(fov_of_focal_length(mm), c.crop),
        Zoom::Scale(k) if k > 0.0 => clamp_fov(c.fov * k, c.crop),
        Zoom::Level(v) | Zoom::FocalLength(v) | Zoom::Scale(v) => return Err(ViewError::NoFov(v)),
    };
    c.fov = fov;
    Ok(())
}

/// A control mode chosen ends following an object.
fn control(c: &mut Camera, mode: u8) -> Result<(), ViewError> {
    let mode = Control::try_from(mode)?;
    if mode == Control::Coordinate && c.target.is_none() {
        return Err(ViewError::NeedsTarget);
    }
    c.control = mode;
    c.follow = None;
    Ok(())
}

fn crop(c: &mut Camera, mode: u8) {
    c.crop = Crop::from(mode);
    if let Crop::Unknown(m) = c.crop {
        tracing::warn!("crop mode {m} is not one of 0..=4: the view is black");
    } else {
        c.fov = clamp_fov(c.fov, c.crop);
    }
}

/// The view's forward axis along `ray` (world), roll kept, pitch held within ±π/2.
pub(super) fn look_along(c: &mut Camera, ray: DVec3, vehicle: Euler) {
    let a = aim(ray, c.euler(), c.lock, vehicle);
    c.yaw = CAMERA_YAW.take(a.yaw, c.yaw);
    c.pitch = CAMERA_PITCH.take(a.pitch, c.pitch);
}

fn target(c: &mut Camera, g: GeoPoint) -> Result<(), ViewError> {
    let takes = |rule: &crate::state::rules::Rule, v: f64| rule.apply(v, v).is_some();
    let place = takes(&CAMERA_TARGET_LAT, g.lat)
        && takes(&CAMERA_TARGET_LON, g.lon)
        && takes(&CAMERA_TARGET_ALT, g.alt);
    if !place {
        return Err(ViewError::NotAPlace(g));
    }
    c.target = Some(g);
    c.control = Control::Coordinate;
    c.follow = None;
    Ok(())
}

/// Out of coordinate control, pointing where the view points now; a region of interest
/// released also ends following an object.
fn release(c: &mut Camera, v: &Vehicle) {
    c.follow = None;
    if c.control == Control::Coordinate {
        let vehicle = v.attitude.euler();
        let m = c.steering().world_from_view(vehicle, &v.position);
        look_along(c, m * DVec3::X, vehicle);
        c.control = Control::Directional;
    }
}
