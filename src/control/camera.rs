//! GET and SET of the per-camera parameter types (6..=13): angles, zoom, lock flags, control
//! and crop modes, fov, and the pixel-to-direction (CAM_OFFSET) and pixel-to-ground
//! (CAM_TARGET) queries, computed with the same frame plan the renderer draws.

use super::Refusal;
use crate::geometry::GeoPoint;
use crate::geometry::ground::ground_point;
use crate::geometry::rotation::yaw_pitch;
use crate::geometry::view::{aim, clamp_fov, control, crop, relative_angles, zoomed_fov};
use crate::protocol::ParamType;
use crate::protocol::params::{
    CamControlMode, CamCropMode, CamEuler, CamFov, CamLockFlags, CamOffset, CamTarget, CamZoom,
};
use crate::render::FramePlan;
use crate::state::{Camera, Live, State, rules};
use glam::{DVec2, DVec3};

pub fn euler(c: &Camera, cam_id: u8) -> CamEuler {
    CamEuler {
        cam_id,
        is_delta: 0,
        yaw: c.yaw,
        pitch: c.pitch,
        roll: c.roll,
    }
}

/// Absolute, or added to the current angles when is_delta is non-zero. Yaw and pitch wrap to
/// (-π, π], roll is clamped to [-π/2, π/2]. Steering by angles ends coordinate control.
pub fn set_euler(c: &mut Camera, p: &CamEuler) -> Result<(), Refusal> {
    let (yaw, pitch, roll) = if p.is_delta != 0 {
        (c.yaw + p.yaw, c.pitch + p.pitch, c.roll + p.roll)
    } else {
        (p.yaw, p.pitch, p.roll)
    };
    c.yaw = rules::take(ParamType::CamEuler, "yaw", yaw, c.yaw);
    c.pitch = rules::take(ParamType::CamEuler, "pitch", pitch, c.pitch);
    c.roll = rules::take(ParamType::CamEuler, "roll", roll, c.roll);
    c.steer_by_hand();
    Ok(())
}

pub fn zoom(c: &Camera, cam_id: u8) -> CamZoom {
    CamZoom {
        cam_id,
        zoom: c.zoom,
    }
}

/// A relative step: the fov is multiplied by 2^(-zoom/32), then clamped.
pub fn set_zoom(c: &mut Camera, p: &CamZoom) -> Result<(), Refusal> {
    c.fov = zoomed_fov(c.fov, p.zoom, c.crop);
    c.zoom = p.zoom;
    Ok(())
}

pub fn lock_flags(c: &Camera, cam_id: u8) -> CamLockFlags {
    CamLockFlags {
        cam_id,
        flags: c.lock,
    }
}

/// Only the low three bits mean anything (the seed); the rest are dropped.
pub fn set_lock_flags(c: &mut Camera, p: &CamLockFlags) -> Result<(), Refusal> {
    c.lock = rules::take(
        ParamType::CamLockFlags,
        "flags",
        p.flags as f64,
        c.lock as f64,
    ) as u8;
    Ok(())
}

pub fn control_mode(c: &Camera, cam_id: u8) -> CamControlMode {
    CamControlMode {
        cam_id,
        mode: c.control,
    }
}

/// Modes 0..=3; coordinate control (2) needs a target set by CAM_TARGET first.
pub fn set_control_mode(c: &mut Camera, p: &CamControlMode) -> Result<(), Refusal> {
    match p.mode {
        control::COORDINATE if c.target.is_none() => Err(Refusal::data(
            "coordinate control needs a target: send CAM_TARGET first",
        )),
        0..=control::PASS => {
            c.control = p.mode;
            // A control mode chosen ends following an object.
            c.follow = None;
            Ok(())
        }
        m => Err(Refusal::Data(format!(
            "control mode {m} is outside 0..={}",
            control::PASS
        ))),
    }
}

pub fn crop_mode(c: &Camera, cam_id: u8) -> CamCropMode {
    CamCropMode {
        cam_id,
        mode: c.crop,
    }
}

/// Any mode is taken (an unknown one renders black, as the seed says); the fov is brought
/// into the new mode's range.
pub fn set_crop_mode(c: &mut Camera, p: &CamCropMode) -> Result<(), Refusal> {
    crate::geometry::view::warn_unknown_crop(p.cam_id as usize, p.mode);
    c.crop = p.mode;
    if c.crop <= crop::DEBUG {
        c.fov = clamp_fov(c.fov, c.crop);
    }
    Ok(())
}

pub fn fov(c: &Camera, cam_id: u8) -> CamFov {
    CamFov { cam_id, fov: c.fov }
}

/// Clamped to the crop mode's range (rectilinear 0.1..=3.1 rad, others 0.1..=2π).
pub fn set_fov(c: &mut Camera, p: &CamFov) -> Result<(), Refusal> {
    c.fov = clamp_fov(p.fov, c.crop);
    Ok(())
}

/// The world ray through the normalized offset (x, y) of camera `i`'s view, as drawn.
fn pixel_ray(live: &Live, s: &State, i: usize, x: f64, y: f64) -> Result<DVec3, Refusal> {
    let sensor = (s.sensor.width, s.sensor.height);
    let lens = live
        .lenses()
        .for_frame(s.lens, sensor, s.sensor.roi())
        .map_err(Refusal::data)?;
    let plan = FramePlan::new(s, &lens).map_err(Refusal::data)?;
    let plan = plan.with_shutter(live.rendered_shutter(sensor));
    let view = plan.camera_view(s, i);
    let (w, h) = (view.rect.w as f64, view.rect.h as f64);
    let p = DVec2::new(w / 2.0 + x * w, h / 2.0 + y * h);
    plan.world_ray(&view, p).ok_or_else(|| {
        Refusal::Data(format!(
            "offset ({x:.3}, {y:.3}) of camera {i} sees nothing (outside the lens or the view)"
        ))
    })
}

/// Yaw and pitch of the pixel's ray: in the world (frame_rel 0) or in the view's own frame
/// (any non-zero frame_rel).
pub fn offset(live: &Live, s: &State, p: &CamOffset) -> Result<CamOffset, Refusal> {
    let i = p.cam_id as usize;
    let ray = pixel_ray(live, s, i, p.x, p.y)?;
    let (yaw, pitch) = if p.frame_rel != 0 {
        let vehicle = &s.vehicle;
        let world_from_view = s.cameras[i]
            .steering()
            .world_from_view(vehicle.attitude.euler(), &vehicle.position);
        relative_angles(world_from_view.transpose() * ray)
    } else {
        yaw_pitch(ray)
    };
    Ok(CamOffset { yaw, pitch, ..*p })
}

/// Turns the view so that its forward axis points along the pixel's ray, roll kept.
pub fn set_offset(live: &Live, s: &mut State, p: &CamOffset) -> Result<(), Refusal> {
    let i = p.cam_id as usize;
    let ray = pixel_ray(live, s, i, p.x, p.y)?;
    let vehicle = s.vehicle.attitude.euler();
    let c = &mut s.cameras[i];
    let a = aim(ray, c.euler(), c.locks(), vehicle);
    (c.yaw, c.pitch) = (a.yaw, a.pitch);
    c.steer_by_hand();
    Ok(())
}

/// Whether a CAM_TARGET message means its lat/lon/alt (x and y both exactly 0).
fn names_coordinates(p: &CamTarget) -> bool {
    p.x == 0.0 && p.y == 0.0
}

/// Where the pixel's ray meets the ground; with x = y = 0 the camera's current target.
pub fn target(live: &Live, s: &State, p: &CamTarget) -> Result<CamTarget, Refusal> {
    let i = p.cam_id as usize;
    let point = if names_coordinates(p) {
        s.cameras[i]
            .target
            .ok_or_else(|| Refusal::Data(format!("camera {i} has no target")))?
    } else {
        ground_of_pixel(live, s, i, p)?
    };
    Ok(CamTarget {
        t_latitude: point.lat,
        t_longitude: point.lon,
        t_altitude: point.alt,
        ..*p
    })
}

fn ground_of_pixel(live: &Live, s: &State, i: usize, p: &CamTarget) -> Result<GeoPoint, Refusal> {
    let ray = pixel_ray(live, s, i, p.x, p.y)?;
    ground_point(&s.vehicle.position, ray)
        .map(|(g, _)| g)
        .ok_or_else(|| Refusal::data("that pixel's ray does not meet the ground within 10 km"))
}

/// Aims the camera at the pixel's ground point, or at the given coordinates when x = y = 0,
/// and switches it to coordinate control so it stays on the target while the vehicle moves.
pub fn set_target(live: &Live, s: &mut State, p: &CamTarget) -> Result<(), Refusal> {
    let i = p.cam_id as usize;
    let point = if names_coordinates(p) {
        let g = GeoPoint {
            lat: p.t_latitude,
            lon: p.t_longitude,
            alt: p.t_altitude,
        };
        if !(-90.0..=90.0).contains(&g.lat) || !(-180.0..=180.0).contains(&g.lon) {
            return Err(Refusal::Data(format!(
                "{}, {} is not a latitude, longitude",
                g.lat, g.lon
            )));
        }
        g
    } else {
        ground_of_pixel(live, s, i, p)?
    };
    let c = &mut s.cameras[i];
    c.target = Some(point);
    c.control = control::COORDINATE;
    c.follow = None;
    Ok(())
}
