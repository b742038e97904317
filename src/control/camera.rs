//! GET and SET of the per-camera parameter types (6..=13): angles, zoom, lock flags, control
//! and crop modes, fov, and the pixel-to-direction (CAM_OFFSET) and pixel-to-ground
//! (CAM_TARGET) queries, computed with the same frame plan the renderer draws. A SET is
//! translated into a view operation (`crate::state::view::Op`), which the gate applies.

use super::{Controller, Refusal};
use crate::geometry::GeoPoint;
use crate::geometry::ground::ground_point;
use crate::geometry::rotation::yaw_pitch;
use crate::geometry::view::relative_angles;
use crate::plan::FramePlan;
use crate::protocol::Param;
use crate::protocol::params::{
    CamControlMode, CamCropMode, CamEuler, CamFov, CamLockFlags, CamOffset, CamTarget, CamThermal,
    CamZoom,
};
use crate::state::view::{Op, Zoom};
use crate::state::{Camera, State};
use glam::{DVec2, DVec3};

pub fn euler(c: &Camera, cam_id: u8) -> CamEuler {
    CamEuler {
        cam_id,
        is_delta: 0,
        yaw: c.yaw(),
        pitch: c.pitch(),
        roll: c.roll(),
    }
}

pub fn zoom(c: &Camera, cam_id: u8) -> CamZoom {
    CamZoom {
        cam_id,
        zoom: c.zoom(),
    }
}

pub fn lock_flags(c: &Camera, cam_id: u8) -> CamLockFlags {
    CamLockFlags {
        cam_id,
        flags: c.locks().0,
    }
}

pub fn control_mode(c: &Camera, cam_id: u8) -> CamControlMode {
    CamControlMode {
        cam_id,
        mode: c.control().code(),
    }
}

pub fn crop_mode(c: &Camera, cam_id: u8) -> CamCropMode {
    CamCropMode {
        cam_id,
        mode: c.crop().code(),
    }
}

pub fn thermal(c: &Camera, cam_id: u8) -> CamThermal {
    CamThermal {
        cam_id,
        show: c.thermal().code(),
    }
}

pub fn fov(c: &Camera, cam_id: u8) -> CamFov {
    CamFov {
        cam_id,
        fov: c.fov(),
    }
}

/// The view operation a per-camera SET asks for: CAM_EULER's angles (added where is_delta is
/// non-zero), CAM_ZOOM's relative step, the lock flags, the control and crop modes, the fov,
/// CAM_OFFSET's pixel to look along and CAM_TARGET's place (its coordinates where x = y = 0,
/// else where the pixel's ray meets the ground). None for the other types.
pub fn operation(c: &Controller, s: &State, param: &Param) -> Result<Option<Op>, Refusal> {
    Ok(Some(match param {
        Param::CamEuler(p) => Op::Angles {
            yaw: p.yaw,
            pitch: p.pitch,
            roll: p.roll,
            delta: p.is_delta != 0,
        },
        Param::CamZoom(p) => Op::Zoom(Zoom::Step(p.zoom)),
        Param::CamLockFlags(p) => Op::Locks(p.flags as f64),
        Param::CamControlMode(p) => Op::Control(p.mode),
        Param::CamCropMode(p) => Op::Crop(p.mode),
        Param::CamThermal(p) => Op::Thermal(p.show),
        Param::CamFov(p) => Op::Zoom(Zoom::Fov(p.fov)),
        Param::CamOffset(p) => Op::LookAlong(pixel_ray(c, s, p.cam_id as usize, p.x, p.y)?),
        Param::CamTarget(p) if names_coordinates(p) => Op::Target(GeoPoint {
            lat: p.t_latitude,
            lon: p.t_longitude,
            alt: p.t_altitude,
        }),
        Param::CamTarget(p) => Op::Target(ground_of_pixel(c, s, p.cam_id as usize, p)?),
        _ => return Ok(None),
    }))
}

/// The world ray through the normalized offset (x, y) of camera `i`'s view, as drawn.
fn pixel_ray(c: &Controller, s: &State, i: usize, x: f64, y: f64) -> Result<DVec3, Refusal> {
    let settings = &s.settings;
    let sensor = settings.sensor_size();
    let lens = c
        .gate
        .settings()
        .lenses()
        .for_frame(settings.lens, sensor, settings.sensor.roi())
        .map_err(Refusal::data)?;
    let plan = FramePlan::new(s, &lens).map_err(Refusal::data)?;
    let plan = plan.with_shutter(c.report.rendered_shutter(sensor));
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
pub fn offset(c: &Controller, s: &State, p: &CamOffset) -> Result<CamOffset, Refusal> {
    let i = p.cam_id as usize;
    let ray = pixel_ray(c, s, i, p.x, p.y)?;
    let (yaw, pitch) = if p.frame_rel != 0 {
        let vehicle = &s.vehicle;
        let world_from_view = s.settings.cameras[i]
            .steering()
            .world_from_view(vehicle.attitude.euler(), &vehicle.position);
        relative_angles(world_from_view.transpose() * ray)
    } else {
        yaw_pitch(ray)
    };
    Ok(CamOffset { yaw, pitch, ..*p })
}

/// Whether a CAM_TARGET message means its lat/lon/alt (x and y both exactly 0).
fn names_coordinates(p: &CamTarget) -> bool {
    p.x == 0.0 && p.y == 0.0
}

/// Where the pixel's ray meets the ground; with x = y = 0 the camera's current target.
pub fn target(c: &Controller, s: &State, p: &CamTarget) -> Result<CamTarget, Refusal> {
    let i = p.cam_id as usize;
    let point = if names_coordinates(p) {
        s.settings.cameras[i]
            .target()
            .ok_or_else(|| Refusal::Data(format!("camera {i} has no target")))?
    } else {
        ground_of_pixel(c, s, i, p)?
    };
    Ok(CamTarget {
        t_latitude: point.lat,
        t_longitude: point.lon,
        t_altitude: point.alt,
        ..*p
    })
}

fn ground_of_pixel(
    c: &Controller,
    s: &State,
    i: usize,
    p: &CamTarget,
) -> Result<GeoPoint, Refusal> {
    let ray = pixel_ray(c, s, i, p.x, p.y)?;
    ground_point(&s.vehicle.position, ray)
        .map(|(g, _)| g)
        .ok_or_else(|| Refusal::data("that pixel's ray does not meet the ground within 10 km"))
}
