//! An equirectangular panorama as a world: any 2:1 image whose columns run over longitude
//! (north at the centre, east to the right) and rows over elevation (+90° at the top). The
//! eye's position does not matter: the panorama is at infinity.

use super::World;
use crate::image_ops::bilinear_wrap_x;
use glam::{DVec2, DVec3};
use image::RgbImage;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

pub struct PanoramaWorld {
    pub image: RgbImage,
}

impl PanoramaWorld {
    pub fn new(image: RgbImage) -> Self {
        PanoramaWorld { image }
    }

    /// The panorama point (pixel-centre coordinates) a world ray falls on.
    pub fn point(&self, ray: DVec3) -> DVec2 {
        let (w, h) = (self.image.width() as f64, self.image.height() as f64);
        let lon = ray.y.atan2(ray.x);
        let lat = (-ray.z).clamp(-1.0, 1.0).asin();
        DVec2::new((lon / TAU + 0.5) * w - 0.5, (0.5 - lat / PI) * h - 0.5)
    }

    /// The world ray through a panorama point, the inverse of [`PanoramaWorld::point`].
    pub fn ray(&self, p: DVec2) -> DVec3 {
        let (w, h) = (self.image.width() as f64, self.image.height() as f64);
        let lon = ((p.x + 0.5) / w - 0.5) * TAU;
        let lat = (0.5 - (p.y + 0.5) / h) * PI;
        crate::geometry::rotation::direction(lon, lat.clamp(-FRAC_PI_2, FRAC_PI_2))
    }
}

impl World for PanoramaWorld {
    fn colour(&self, _eye: DVec3, ray: DVec3, _t: f64) -> DVec3 {
        bilinear_wrap_x(&self.image, self.point(ray))
    }
}
