//! A user view's orientation from its control mode, angles, lock flags, target and the
//! vehicle's attitude and position; the chain from the world to the fisheye lens; and the fov
//! and zoom rules per crop mode.

use super::ground::{GeoPoint, GeoPosition, ray_to_target};
use super::rotation::{Euler, MOUNT_FROM_LENS, wrap_pi, yaw_pitch};
use crate::modes::{Control, Crop};
use glam::{DMat3, DVec3};
use std::f64::consts::TAU;

/// Lock flags: bit 0 roll, bit 1 pitch, bit 2 yaw. A locked axis is held in the world frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(transparent)]
pub struct LockFlags(pub u8);

impl LockFlags {
    pub const ROLL: u8 = 1;
    pub const PITCH: u8 = 2;
    pub const YAW: u8 = 4;
    pub const ALL: LockFlags = LockFlags(7);
    pub const NONE: LockFlags = LockFlags(0);

    pub fn roll(self) -> bool {
        self.0 & Self::ROLL != 0
    }
    pub fn pitch(self) -> bool {
        self.0 & Self::PITCH != 0
    }
    pub fn yaw(self) -> bool {
        self.0 & Self::YAW != 0
    }

    /// The angles the view actually uses: each unlocked axis adds the vehicle's angle.
    pub fn compose(self, cam: Euler, vehicle: Euler) -> Euler {
        let follow = |locked: bool, v: f64| if locked { 0.0 } else { v };
        Euler {
            yaw: wrap_pi(cam.yaw + follow(self.yaw(), vehicle.yaw)),
            pitch: cam.pitch + follow(self.pitch(), vehicle.pitch),
            roll: cam.roll + follow(self.roll(), vehicle.roll),
        }
    }

    /// The camera angles that make the composed view point along `yaw`/`pitch` (world), the
    /// inverse of [`LockFlags::compose`] for those two axes; roll is left to the caller.
    pub fn decompose(self, yaw: f64, pitch: f64, vehicle: Euler) -> (f64, f64) {
        let follow = |locked: bool, v: f64| if locked { 0.0 } else { v };
        (
            wrap_pi(yaw - follow(self.yaw(), vehicle.yaw)),
            pitch - follow(self.pitch(), vehicle.pitch),
        )
    }
}

/// R_world_view for a user camera.
pub fn view_orientation(cam: Euler, locks: LockFlags, vehicle: Euler) -> DMat3 {
    locks.compose(cam, vehicle).matrix()
}

/// How a user view is aimed: what CAM_CONTROL_MODE, CAM_EULER, CAM_LOCK_FLAGS and CAM_TARGET
/// set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Steering {
    pub control: Control,
    pub angles: Euler,
    pub locks: LockFlags,
    pub target: Option<GeoPoint>,
}

impl Steering {
    /// R_world_view by the control mode: pilot (0) looks along the vehicle's nose; coordinate
    /// (2) aims at its target, recomputed from the vehicle's position; the others compose the
    /// view's angles with the vehicle's per the lock flags.
    pub fn world_from_view(&self, vehicle: Euler, position: &GeoPosition) -> DMat3 {
        let (angles, locks) = (self.angles, self.locks);
        match (self.control, self.target) {
            (Control::Pilot, _) => vehicle.matrix(),
            (Control::Coordinate, Some(target)) => match ray_to_target(position, target) {
                Some(ray) => view_orientation(aim(ray, angles, locks, vehicle), locks, vehicle),
                None => view_orientation(angles, locks, vehicle),
            },
            _ => view_orientation(angles, locks, vehicle),
        }
    }
}

/// R_lens_world = (R_world_body · R_body_mount · M)ᵀ: carries world (NED) rays into the lens frame.
pub fn lens_from_world(vehicle: Euler, mount: Euler) -> DMat3 {
    (vehicle.matrix() * mount.matrix() * MOUNT_FROM_LENS).transpose()
}

/// The cam angles (yaw, pitch, roll kept) that point a view's forward axis along a world ray.
pub fn aim(ray_world: DVec3, cam: Euler, locks: LockFlags, vehicle: Euler) -> Euler {
    let (yaw, pitch) = yaw_pitch(ray_world);
    let (yaw, pitch) = locks.decompose(yaw, pitch, vehicle);
    Euler {
        yaw,
        pitch,
        roll: cam.roll,
    }
}

/// The narrowest fov any view may have (the seed's 0.1 rad).
pub const MIN_FOV: f64 = 0.1;
/// The widest rectilinear fov: a pinhole view cannot reach π, and near it nothing is usable.
pub const MAX_RECTILINEAR_FOV: f64 = 3.1;

/// The fov range a view accepts in a crop mode: rectilinear views stop short of π, the others
/// (panoramas, fisheye crops, debug) may take up to a full turn.
pub const fn fov_range(crop: Crop) -> (f64, f64) {
    match crop.pinhole() {
        true => (MIN_FOV, MAX_RECTILINEAR_FOV),
        false => (MIN_FOV, TAU),
    }
}

pub fn clamp_fov(fov: f64, crop_mode: Crop) -> f64 {
    let (lo, hi) = fov_range(crop_mode);
    if fov.is_nan() { lo } else { fov.clamp(lo, hi) }
}

/// CAM_ZOOM: a relative step; +32 halves the fov, -32 doubles it, then the crop mode's range.
pub fn zoomed_fov(fov: f64, zoom: i8, crop_mode: Crop) -> f64 {
    clamp_fov(fov * 2f64.powf(-(zoom as f64) / 32.0), crop_mode)
}

/// Angles of a ray relative to a frame, as CAM_OFFSET's frame_rel = 1 reports them: the ray
/// in image axes (X right, Y down, Z forward), yaw = atan2(X, Z), pitch = atan2(-Y, √(X²+Z²)).
pub fn relative_angles(ray_frd: DVec3) -> (f64, f64) {
    let (x, y, z) = (ray_frd.y, ray_frd.z, ray_frd.x);
    (x.atan2(z), (-y).atan2(x.hypot(z)))
}
