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

/// A panorama of photographs: `photos` in cells of a grid of `columns` across the whole
/// longitude and rows of the same height (each photo scaled to fill its cell), taken in turn
/// and shifted by one per row; the rows start half a cell above the top, so that the horizon
/// runs through the middle of a row of photographs rather than along their edges.
pub fn mosaic(photos: &[RgbImage], width: u32, height: u32, columns: u32) -> RgbImage {
    assert!(!photos.is_empty() && columns > 0, "photographs to lay out");
    let cell = (width / columns, (height / 4).max(1));
    let scaled: Vec<RgbImage> = photos
        .iter()
        .map(|p| image::imageops::resize(p, cell.0, cell.1, image::imageops::FilterType::Triangle))
        .collect();
    let mut out = RgbImage::new(width, height);
    for (x, y, px) in out.enumerate_pixels_mut() {
        let shifted = y + cell.1 / 2;
        let (col, row) = ((x / cell.0).min(columns - 1), shifted / cell.1);
        let photo = &scaled[((row * columns + col + row) as usize) % scaled.len()];
        let (px_x, px_y) = ((x - col * cell.0).min(cell.0 - 1), shifted % cell.1);
        *px = *photo.get_pixel(px_x, px_y);
    }
    out
}
