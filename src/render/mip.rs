//! Minification filtering, shared in definition by both renderers: a mip chain of 2x2 box
//! averages and trilinear sampling at a level of detail taken from the pixel's quad
//! neighbours (as a fragment shader's derivatives are). The GPU builds the chain in
//! shaders/ingest.wgsl and shaders/mip.wgsl and samples it in shaders/render.wgsl; this is the
//! f64 twin the CPU reference renders with.

use crate::image_ops::bilinear;
use glam::{DVec2, DVec3};
use image::RgbImage;

/// The most mip levels kept: enough for 128x minification.
pub const MAX_LEVELS: u32 = 8;

/// How minified views are filtered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Filter {
    /// Trilinear from the mip chain at each pixel's footprint (the default).
    #[default]
    Mip,
    /// One bilinear sample of the full-size frame: sharper, aliases when minified.
    Bilinear,
}

impl Filter {
    /// The code the shader uses (`FILTER_*` in shaders/render.wgsl).
    pub fn shader_code(self) -> u32 {
        self as u32
    }
}

/// Mip levels for a frame: halving down to 1 pixel on the short side, at most [`MAX_LEVELS`].
pub fn levels_for(width: u32, height: u32) -> u32 {
    (width.min(height).max(1).ilog2() + 1).min(MAX_LEVELS)
}

/// The fisheye frame and its 2x2 box-averaged levels.
pub struct Pyramid {
    pub levels: Vec<RgbImage>,
}

impl Pyramid {
    pub fn new(base: &RgbImage) -> Pyramid {
        let n = levels_for(base.width(), base.height());
        let mut levels = vec![base.clone()];
        for _ in 1..n {
            let finer = levels.last().unwrap();
            let (w, h) = ((finer.width() / 2).max(1), (finer.height() / 2).max(1));
            levels.push(RgbImage::from_fn(w, h, |x, y| {
                let mut sum = [0u32; 3];
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let p = finer.get_pixel(2 * x + dx, 2 * y + dy);
                    for c in 0..3 {
                        sum[c] += p[c] as u32;
                    }
                }
                image::Rgb(sum.map(|s| ((s as f64 / 4.0).round()) as u8))
            }));
        }
        Pyramid { levels }
    }

    /// Trilinear sample at fisheye pixel `q` (level-0 pixel centres at integers), `lod`
    /// clamped to the chain; edges clamp, as the GPU's sampler does.
    pub fn sample(&self, q: DVec2, lod: f64) -> DVec3 {
        let lod = lod.clamp(0.0, (self.levels.len() - 1) as f64);
        let l0 = lod.floor() as usize;
        let f = lod - l0 as f64;
        let a = self.sample_level(l0, q);
        if f == 0.0 {
            return a;
        }
        a.lerp(self.sample_level(l0 + 1, q), f)
    }

    fn sample_level(&self, k: usize, q: DVec2) -> DVec3 {
        let (base, level) = (&self.levels[0], &self.levels[k]);
        let scale = DVec2::new(
            level.width() as f64 / base.width() as f64,
            level.height() as f64 / base.height() as f64,
        );
        bilinear(level, (q + 0.5) * scale - 0.5)
    }
}

/// The level of detail for a pixel whose fisheye position is `q` and whose quad neighbours
/// in x and y land at `nx` and `ny` (None where they see nothing).
pub fn lod(q: DVec2, nx: Option<DVec2>, ny: Option<DVec2>) -> f64 {
    let step = [nx, ny]
        .into_iter()
        .flatten()
        .map(|n| (n - q).length())
        .fold(0.0, f64::max);
    step.max(1.0).log2()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_level_is_the_box_average_of_the_one_below() {
        let img = RgbImage::from_fn(8, 6, |x, y| image::Rgb([(x * 30) as u8, (y * 40) as u8, 7]));
        let p = Pyramid::new(&img);
        assert_eq!(p.levels.len(), 3);
        assert_eq!(p.levels[1].dimensions(), (4, 3));
        // (0+30+0+30)/4 = 15, (0+0+40+40)/4 = 20
        assert_eq!(p.levels[1].get_pixel(0, 0).0, [15, 20, 7]);
        assert_eq!(p.levels[2].dimensions(), (2, 1));
    }

    #[test]
    fn sampling_at_level_zero_is_bilinear_and_between_levels_blends() {
        let img = RgbImage::from_fn(4, 4, |x, _| image::Rgb([if x < 2 { 0 } else { 200 }; 3]));
        let p = Pyramid::new(&img);
        let q = DVec2::new(1.5, 1.5);
        assert_eq!(p.sample(q, 0.0).x, 100.0);
        assert_eq!(p.sample(DVec2::new(0.0, 0.0), 0.0).x, 0.0);
        // Level 2 is one pixel: the mean, 100, everywhere.
        assert_eq!(p.sample(DVec2::new(0.0, 0.0), 2.0).x, 100.0);
        assert_eq!(p.sample(DVec2::new(0.0, 0.0), 9.0).x, 100.0, "lod clamps");
    }

    #[test]
    fn lod_is_log2_of_the_larger_neighbour_step_and_never_negative() {
        let q = DVec2::ZERO;
        assert_eq!(
            lod(q, Some(DVec2::new(4.0, 0.0)), Some(DVec2::new(0.0, 2.0))),
            2.0
        );
        assert_eq!(lod(q, Some(DVec2::new(0.5, 0.0)), None), 0.0);
        assert_eq!(lod(q, None, None), 0.0);
    }
}
