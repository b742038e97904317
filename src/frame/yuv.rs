//! BT.709 limited-range colour (Y 16..235, chroma 16..240), the twin of shaders/common.wgsl:
//! RGB images to and from frame bytes of any [`PixelFormat`], for the tests, the CLI's image
//! inputs and checks of the GPU's encoder-ready output. Chroma of a 2x2 block is the block's
//! mean colour; decoding repeats it over the block, as the GPU's upload does.

use super::{FrameError, PixelFormat, PlaneLayout};
use crate::image_ops::pixel as rgb;
use glam::DVec3;
use image::RgbImage;

/// BT.709's luma weights of red, blue and green (`KR`, `KB`, `KG` in shaders/common.wgsl).
pub const KR: f64 = 0.2126;
pub const KB: f64 = 0.0722;
pub const KG: f64 = 1.0 - KR - KB;

/// RGB (0..255) → Y, Cb, Cr code values.
pub fn rgb_to_yuv(c: DVec3) -> DVec3 {
    let c = c / 255.0;
    let y = KR * c.x + KG * c.y + KB * c.z;
    DVec3::new(
        16.0 + 219.0 * y,
        128.0 + 112.0 * (c.z - y) / (1.0 - KB),
        128.0 + 112.0 * (c.x - y) / (1.0 - KR),
    )
}

/// Y, Cb, Cr code values → RGB (0..255), clamped.
pub fn yuv_to_rgb(yuv: DVec3) -> DVec3 {
    let y = (yuv.x - 16.0) / 219.0;
    let cb = (yuv.y - 128.0) / 224.0;
    let cr = (yuv.z - 128.0) / 224.0;
    let r = y + 2.0 * (1.0 - KR) * cr;
    let b = y + 2.0 * (1.0 - KB) * cb;
    let g = (y - KR * r - KB * b) / KG;
    (DVec3::new(r, g, b) * 255.0).clamp(DVec3::ZERO, DVec3::splat(255.0))
}

fn byte(v: f64) -> u8 {
    v.round().clamp(0.0, 255.0) as u8
}

/// An RGB image as one frame of `layout` (which must match its size); padding bytes are 0.
pub fn encode(img: &RgbImage, layout: &PlaneLayout) -> Vec<u8> {
    assert_eq!((img.width(), img.height()), (layout.width, layout.height));
    let mut out = vec![0u8; layout.size as usize];
    let (w, h) = (layout.width, layout.height);
    if layout.format == PixelFormat::Rgba {
        for (x, y, p) in img.enumerate_pixels() {
            let i = (y * layout.stride + 4 * x) as usize;
            out[i..i + 4].copy_from_slice(&[p[0], p[1], p[2], 255]);
        }
        return out;
    }
    for y in 0..h {
        for x in 0..w {
            out[(y * layout.stride + x) as usize] = byte(rgb_to_yuv(rgb(img, x, y)).x);
        }
    }
    for by in 0..h / 2 {
        for bx in 0..w / 2 {
            let (x, y) = (2 * bx, 2 * by);
            let mean =
                (rgb(img, x, y) + rgb(img, x + 1, y) + rgb(img, x, y + 1)) + rgb(img, x + 1, y + 1);
            let c = rgb_to_yuv(mean / 4.0);
            let (u, v) = layout.chroma_at(bx, by);
            out[u] = byte(c.y);
            out[v] = byte(c.z);
        }
    }
    out
}

/// One frame of `layout` as an RGB image.
pub fn decode(data: &[u8], layout: &PlaneLayout) -> Result<RgbImage, FrameError> {
    layout.check(data)?;
    let at = |i: usize| data[i] as f64;
    Ok(RgbImage::from_fn(layout.width, layout.height, |x, y| {
        if layout.format == PixelFormat::Rgba {
            let i = (y * layout.stride + 4 * x) as usize;
            return image::Rgb([data[i], data[i + 1], data[i + 2]]);
        }
        let (u, v) = layout.chroma_at(x / 2, y / 2);
        let c = yuv_to_rgb(DVec3::new(
            at((y * layout.stride + x) as usize),
            at(u),
            at(v),
        ));
        image::Rgb([byte(c.x), byte(c.y), byte(c.z)])
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn black_white_and_primaries_take_their_bt709_limited_range_codes() {
        let yuv = |r, g, b| rgb_to_yuv(DVec3::new(r, g, b)).round();
        assert_eq!(yuv(0.0, 0.0, 0.0), DVec3::new(16.0, 128.0, 128.0));
        assert_eq!(yuv(255.0, 255.0, 255.0), DVec3::new(235.0, 128.0, 128.0));
        // ITU-R BT.709 red: Y 63, Cb 102, Cr 240.
        assert_eq!(yuv(255.0, 0.0, 0.0), DVec3::new(63.0, 102.0, 240.0));
        for c in [DVec3::new(255.0, 0.0, 0.0), DVec3::new(12.0, 200.0, 77.0)] {
            assert!((yuv_to_rgb(rgb_to_yuv(c)) - c).abs().max_element() < 1e-9);
        }
    }

    #[test]
    fn a_flat_colour_survives_every_format_within_one_code() {
        let img = RgbImage::from_pixel(6, 4, image::Rgb([30, 140, 220]));
        for format in [PixelFormat::Rgba, PixelFormat::I420, PixelFormat::Nv12] {
            for align in [1, 8] {
                let layout = PlaneLayout::aligned(format, 6, 4, align).unwrap();
                let back = decode(&encode(&img, &layout), &layout).unwrap();
                for p in back.pixels() {
                    for (a, b) in p.0.iter().zip([30u8, 140, 220]) {
                        assert!(a.abs_diff(b) <= 1, "{format} align {align}: {p:?}");
                    }
                }
            }
        }
    }
}
