//! Minification filtering, shared in definition by both renderers: a mip chain of 2x2 box
//! averages and trilinear sampling at a level of detail taken from the pixel's quad
//! neighbours (as a fragment shader's derivatives are). The GPU builds the chain in
//! shaders/ingest.wgsl and shaders/mip.wgsl and samples it in shaders/render.wgsl; this is the
//! f64 twin the CPU reference renders with.

use crate::frame::{PlaneLayout, yuv};
use crate::image_ops::{bilinear, bilinear_luma};
use crate::plan::MAX_LEVELS;
use glam::{DVec2, DVec3};
use image::{GrayImage, RgbImage};
use std::ops::Range;

/// Columns and rows of a frame (`Lens::imaged_box`).
pub type ImagedBox = (Range<u32>, Range<u32>);

/// Mip levels for a frame: halving down to 1 pixel on the short side, at most [`MAX_LEVELS`].
pub fn levels_for(width: u32, height: u32) -> u32 {
    (width.min(height).max(1).ilog2() + 1).min(MAX_LEVELS)
}

/// The fisheye's mip chain as both renderers hold it. Level 0 is the frame at full size: its
/// RGB, or for 4:2:0 input its luma alone (4:2:0 has no chroma at full size). Levels 1 and up
/// are 2x2 box averages: of RGB, or for 4:2:0 input of Y Cb Cr code values, level 1 taking
/// each block's own chroma sample. A sample is filtered in the chain's own colour space and
/// converted to RGB afterwards, as a GPU's YCbCr sampler does.
pub struct Pyramid {
    pub base: Base,
    /// Levels 1, 2, … (index 0 is level 1).
    pub coarse: Vec<RgbImage>,
}

/// A chain's level 0.
pub enum Base {
    Rgb(RgbImage),
    /// Luma code values; the chroma starts at level 1.
    Luma(GrayImage),
}

impl Pyramid {
    /// The chain of an RGB frame.
    pub fn new(base: &RgbImage) -> Pyramid {
        let n = levels_for(base.width(), base.height());
        let coarse = if n > 1 {
            chain(halve(base), n - 1)
        } else {
            Vec::new()
        };
        Pyramid {
            base: Base::Rgb(base.clone()),
            coarse,
        }
    }

    /// The chain of an RGB frame with every pixel outside `keep` (columns, rows) black, as
    /// the GPU holds it.
    pub fn kept(base: &RgbImage, keep: &ImagedBox) -> Pyramid {
        let (columns, rows) = keep;
        let mut kept = RgbImage::new(base.width(), base.height());
        for y in rows.clone() {
            for x in columns.clone() {
                kept.put_pixel(x, y, *base.get_pixel(x, y));
            }
        }
        Pyramid::new(&kept)
    }

    /// The chain of a frame's bytes with every pixel outside `keep` (columns, rows) black, as
    /// the GPU holds it. For 4:2:0, `keep` must start on even columns and rows.
    pub fn from_frame(data: &[u8], layout: &PlaneLayout, keep: &ImagedBox) -> Pyramid {
        let (columns, rows) = keep;
        let inside = |x: u32, y: u32| columns.contains(&x) && rows.contains(&y);
        if !layout.format.is_yuv() {
            let rgb = yuv::decode(data, layout).expect("a frame of its layout");
            return Pyramid::kept(&rgb, keep);
        }
        let luma = GrayImage::from_fn(layout.width, layout.height, |x, y| {
            image::Luma([if inside(x, y) {
                data[(y * layout.stride + x) as usize]
            } else {
                16
            }])
        });
        // Level 1: each 2x2 block's mean luma, rounded as a texture stores it, and its chroma.
        let level1 = RgbImage::from_fn(layout.width / 2, layout.height / 2, |bx, by| {
            let (x, y) = (2 * bx, 2 * by);
            if !inside(x, y) {
                return image::Rgb([16, 128, 128]);
            }
            let sum: u32 = [(0, 0), (1, 0), (0, 1), (1, 1)]
                .map(|(dx, dy)| luma.get_pixel(x + dx, y + dy)[0] as u32)
                .iter()
                .sum();
            let (u, v) = layout.chroma_at(bx, by);
            image::Rgb([(sum as f64 / 4.0).round() as u8, data[u], data[v]])
        });
        let n = levels_for(layout.width, layout.height);
        Pyramid {
            base: Base::Luma(luma),
            coarse: chain(level1, n - 1),
        }
    }

    /// Levels in all, level 0 included.
    pub fn levels(&self) -> usize {
        self.coarse.len() + 1
    }

    fn base_size(&self) -> DVec2 {
        let (w, h) = match &self.base {
            Base::Rgb(img) => img.dimensions(),
            Base::Luma(img) => img.dimensions(),
        };
        DVec2::new(w as f64, h as f64)
    }

    /// Whether this is a 4:2:0 chain (luma at level 0, chroma from level 1).
    pub fn is_420(&self) -> bool {
        matches!(self.base, Base::Luma(_))
    }

    /// Trilinear sample at fisheye pixel `q` (level-0 pixel centres at integers), `lod`
    /// clamped to the chain, as RGB (0..255); edges clamp, as the GPU's sampler does. Below
    /// level 1 it blends level 0 with level 1; 4:2:0 chroma is taken at `q` too, at level 1
    /// below `lod` 1 (see [`Pyramid::sample_420`] for chroma taken elsewhere).
    pub fn sample(&self, q: DVec2, lod: f64) -> DVec3 {
        match &self.base {
            Base::Rgb(img) => {
                let lod = lod.clamp(0.0, self.coarse.len() as f64);
                let t = lod.min(1.0);
                let fine = bilinear(img, q);
                if t == 0.0 {
                    return fine;
                }
                let coarse = self.sample_coarse(q, lod - t);
                if t == 1.0 {
                    coarse
                } else {
                    fine.lerp(coarse, t)
                }
            }
            Base::Luma(_) => self.sample_420(q, lod, q, (lod - 1.0).max(0.0)),
        }
    }

    /// A 4:2:0 chain's colour (RGB, 0..255): luma at `q` and `lod` as [`Pyramid::sample`]
    /// takes it, chroma at `chroma_q` and `chroma_lod` counted in the chroma's own chain
    /// (whose level 0 is the frame's level 1), clamped to it.
    pub fn sample_420(&self, q: DVec2, lod: f64, chroma_q: DVec2, chroma_lod: f64) -> DVec3 {
        let Base::Luma(luma) = &self.base else {
            panic!("sample_420 on an RGB chain");
        };
        let lod = lod.clamp(0.0, self.coarse.len() as f64);
        let t = lod.min(1.0);
        let y0 = bilinear_luma(luma, q);
        let y = if t == 0.0 {
            y0
        } else {
            y0 + (self.sample_coarse(q, lod - t).x - y0) * t
        };
        let last = (self.coarse.len() - 1) as f64;
        let c = self.sample_coarse(chroma_q, chroma_lod.clamp(0.0, last));
        yuv::yuv_to_rgb(DVec3::new(y, c.y, c.z))
    }

    /// Trilinear sample of levels 1 and up, `lod` counted from level 1.
    fn sample_coarse(&self, q: DVec2, lod: f64) -> DVec3 {
        let k = lod.floor() as usize;
        let f = lod - k as f64;
        let a = self.sample_level(k, q);
        if f == 0.0 {
            return a;
        }
        a.lerp(self.sample_level(k + 1, q), f)
    }

    fn sample_level(&self, k: usize, q: DVec2) -> DVec3 {
        let level = &self.coarse[k];
        let scale = DVec2::new(level.width() as f64, level.height() as f64) / self.base_size();
        bilinear(level, (q + 0.5) * scale - 0.5)
    }
}

/// `first` and the levels that halve it, `n` in all.
fn chain(first: RgbImage, n: u32) -> Vec<RgbImage> {
    let mut levels = vec![first];
    while (levels.len() as u32) < n {
        let next = halve(levels.last().unwrap());
        levels.push(next);
    }
    levels
}

/// The next level: each 2x2 block's mean, rounded (odd sizes drop their last row or column).
fn halve(finer: &RgbImage) -> RgbImage {
    let (w, h) = ((finer.width() / 2).max(1), (finer.height() / 2).max(1));
    RgbImage::from_fn(w, h, |x, y| {
        let mut sum = [0u32; 3];
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let p = finer.get_pixel(
                (2 * x + dx).min(finer.width() - 1),
                (2 * y + dy).min(finer.height() - 1),
            );
            for c in 0..3 {
                sum[c] += p[c] as u32;
            }
        }
        image::Rgb(sum.map(|s| ((s as f64 / 4.0).round()) as u8))
    })
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
    use crate::frame::PixelFormat;

    #[test]
    fn each_level_is_the_box_average_of_the_one_below() {
        let img = RgbImage::from_fn(8, 6, |x, y| image::Rgb([(x * 30) as u8, (y * 40) as u8, 7]));
        let p = Pyramid::new(&img);
        assert_eq!(p.levels(), 3);
        assert_eq!(p.coarse[0].dimensions(), (4, 3));
        // (0+30+0+30)/4 = 15, (0+0+40+40)/4 = 20
        assert_eq!(p.coarse[0].get_pixel(0, 0).0, [15, 20, 7]);
        assert_eq!(p.coarse[1].dimensions(), (2, 1));
    }

    #[test]
    fn sampling_at_level_zero_is_bilinear_and_between_levels_blends() {
        let img = RgbImage::from_fn(4, 4, |x, _| image::Rgb([if x < 2 { 0 } else { 200 }; 3]));
        let p = Pyramid::new(&img);
        let q = DVec2::new(1.5, 1.5);
        assert_eq!(p.sample(q, 0.0).x, 100.0);
        assert_eq!(p.sample(DVec2::new(0.0, 0.0), 0.0).x, 0.0);
        // Level 1 is 0 | 200 at texel centres 0.5 and 2.5: at x = 0 it is 0, at 1.5 it is 100.
        assert_eq!(p.sample(DVec2::new(0.0, 0.0), 0.5).x, 0.0);
        assert_eq!(p.sample(DVec2::new(1.0, 0.0), 0.5).x, 25.0);
        // Level 2 is one pixel: the mean, 100, everywhere.
        assert_eq!(p.sample(DVec2::new(0.0, 0.0), 2.0).x, 100.0);
        assert_eq!(p.sample(DVec2::new(0.0, 0.0), 9.0).x, 100.0, "lod clamps");
    }

    /// An 8x4 frame whose left half is grey and right half red, as bytes of `format`.
    fn grey_and_red(format: PixelFormat) -> (Vec<u8>, PlaneLayout) {
        let img = RgbImage::from_fn(8, 4, |x, _| {
            image::Rgb(if x < 4 { [128, 128, 128] } else { [255, 0, 0] })
        });
        let layout = PlaneLayout::tight(format, 8, 4).unwrap();
        (yuv::encode(&img, &layout), layout)
    }

    #[test]
    fn a_420_frame_filters_luma_from_full_size_and_chroma_from_level_one() {
        for format in [PixelFormat::I420, PixelFormat::Nv12] {
            let (data, layout) = grey_and_red(format);
            let p = Pyramid::from_frame(&data, &layout, &(0..8, 0..4));
            assert!(matches!(p.base, Base::Luma(_)));
            assert_eq!(p.levels(), 3);
            // Inside each half the colour comes back within a code.
            let red = p.sample(DVec2::new(7.0, 1.0), 0.0);
            assert!(
                (red - DVec3::new(255.0, 0.0, 0.0)).abs().max_element() <= 1.0,
                "{red}"
            );
            let grey = p.sample(DVec2::new(0.0, 1.0), 0.0);
            assert!(
                (grey - DVec3::splat(128.0)).abs().max_element() <= 1.0,
                "{grey}"
            );
            // At level 0 the luma edge is one pixel wide (x = 3 is grey's luma) while the
            // chroma, at half resolution, already blends: x = 3 is level 1's x = 1.25.
            let edge = p.sample(DVec2::new(3.0, 1.0), 0.0);
            assert!(edge.x > 128.0 && edge.x < 255.0, "{edge}");
            let luma = yuv::rgb_to_yuv(edge).x;
            let grey_luma = yuv::rgb_to_yuv(DVec3::splat(128.0)).x;
            assert!((luma - grey_luma).abs() < 1.5, "luma {luma} vs {grey_luma}");
        }
    }

    #[test]
    fn pixels_outside_the_kept_box_are_black_in_every_format() {
        for format in [PixelFormat::Rgba, PixelFormat::I420, PixelFormat::Nv12] {
            let (data, layout) = grey_and_red(format);
            let p = Pyramid::from_frame(&data, &layout, &(0..4, 0..4));
            let outside = p.sample(DVec2::new(7.0, 1.0), 0.0);
            assert!(outside.max_element() <= 1.0, "{format}: {outside}");
            let coarse = p.sample(DVec2::new(7.0, 1.0), 1.0);
            assert!(coarse.max_element() <= 1.0, "{format}: {coarse}");
        }
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
