//! How a view's pixels map to rays in the view's own frame (FRD) and back, for the crop modes
//! that rectify: rectilinear (1 and 3) and panorama (2). Pixel positions are continuous and
//! measured from the view's top-left corner, so pixel i's centre is at i + 0.5 and the
//! normalized offset (x, y) of CAM_OFFSET is the point (w/2 + x·w, h/2 + y·h).

use super::rotation::{Euler, direction, wrap_pi, yaw_pitch};
use crate::modes::Crop;
use glam::{DMat3, DVec2, DVec3};
use std::f64::consts::PI;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Pinhole: horizontal fov across the width, square pixels.
    Rectilinear { width: f64, height: f64, fov: f64 },
    /// Cylindrical panorama: azimuth linear over the width (fov up to 2π), elevation linear
    /// with the same angle per pixel, centred on the view's pitch. Seen from the world it is the
    /// level cylinder about the vertical, turned by the view's roll about its centre ray.
    Panorama {
        width: f64,
        height: f64,
        fov: f64,
        pitch: f64,
    },
}

impl Projection {
    /// Focal length in pixels of a rectilinear view.
    pub fn focal(width: f64, fov: f64) -> f64 {
        0.5 * width / (0.5 * fov).tan()
    }

    /// A panorama's view-frame direction for (azimuth a, elevation e) offsets from its centre:
    /// Ry(θ)ᵀ·Rz(a)·Ry(θ+e)·x̂. With R_world_view = Rz(ψ)Ry(θ)Rx(φ) this is, in the world, the
    /// level direction (ψ + a, θ + e) turned by φ about the centre ray (ψ, θ).
    fn panorama_dir(pitch: f64, a: f64, e: f64) -> DVec3 {
        DMat3::from_rotation_y(-pitch) * DMat3::from_rotation_z(a) * direction(0.0, pitch + e)
    }

    /// Unit ray (view FRD) through a point of the view.
    pub fn ray(&self, p: DVec2) -> DVec3 {
        match *self {
            Projection::Rectilinear { width, height, fov } => {
                let f = Self::focal(width, fov);
                DVec3::new(f, p.x - 0.5 * width, p.y - 0.5 * height).normalize()
            }
            Projection::Panorama {
                width,
                height,
                fov,
                pitch,
            } => {
                let k = fov / width;
                let a = (p.x - 0.5 * width) * k;
                let e = -(p.y - 0.5 * height) * k;
                Self::panorama_dir(pitch, a, e)
            }
        }
    }

    /// Point of the view a view-frame ray passes through; None if it does not (behind a
    /// pinhole, or outside the panorama's span). The point may lie outside the view.
    pub fn point(&self, ray: DVec3) -> Option<DVec2> {
        match *self {
            Projection::Rectilinear { width, height, fov } => {
                if ray.x <= 1e-12 {
                    return None;
                }
                let f = Self::focal(width, fov);
                Some(DVec2::new(
                    0.5 * width + f * ray.y / ray.x,
                    0.5 * height + f * ray.z / ray.x,
                ))
            }
            Projection::Panorama {
                width,
                height,
                fov,
                pitch,
            } => {
                // Undo the pitch offset, then read azimuth and elevation. A panorama tall
                // enough to reach past a pole draws the rays there a second time, at the
                // azimuth opposite and the elevation mirrored in the pole: the point inside
                // the view is the one wanted, the direct one when both or neither are.
                let level = DMat3::from_rotation_y(pitch) * ray;
                let (a, el) = yaw_pitch(level);
                let k = fov / width;
                let at = |a: f64, el: f64| {
                    DVec2::new(0.5 * width + a / k, 0.5 * height - (el - pitch) / k)
                };
                let spans_x = |p: &DVec2| (0.0..=width).contains(&p.x);
                let inside = |p: &DVec2| spans_x(p) && (0.0..=height).contains(&p.y);
                let direct = at(a, el);
                let opposite = wrap_pi(a + PI);
                let past_pole = [at(opposite, -PI - el), at(opposite, PI - el)];
                if !inside(&direct)
                    && let Some(p) = past_pole.into_iter().find(inside)
                {
                    return Some(p);
                }
                spans_x(&direct).then_some(direct)
            }
        }
    }

    /// The projection for a view of crop mode 1/3 or 2 with the composed angles `view`.
    pub fn for_view(
        crop_mode: Crop,
        width: f64,
        height: f64,
        fov: f64,
        view: Euler,
    ) -> Option<Projection> {
        match crop_mode {
            Crop::Rectilinear | Crop::RectifiedCrop => {
                Some(Projection::Rectilinear { width, height, fov })
            }
            Crop::Panorama => Some(Projection::Panorama {
                width,
                height,
                fov,
                pitch: view.pitch,
            }),
            _ => None,
        }
    }
}
