//! Pixel sampling and image metrics shared by the renderers, the scene synthesiser and the
//! tests: bilinear fetches in OpenCV pixel coordinates, PSNR, colour-blob centroids, and a
//! pixel's neighbours.

use crate::layout::Rect;
use glam::{DVec2, DVec3};
use image::{GrayImage, RgbImage};

pub fn pixel(img: &RgbImage, x: u32, y: u32) -> DVec3 {
    let p = img.get_pixel(x, y).0;
    DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
}

/// Bilinear sample at `p` (pixel centres at integers), edges clamped.
pub fn bilinear(img: &RgbImage, p: DVec2) -> DVec3 {
    let (w, h) = (img.width() as i64, img.height() as i64);
    bilinear_by(p, |x, y| {
        pixel(img, x.clamp(0, w - 1) as u32, y.clamp(0, h - 1) as u32)
    })
}

/// Bilinear sample of a one-channel image at `p`, edges clamped.
pub fn bilinear_luma(img: &GrayImage, p: DVec2) -> f64 {
    let (w, h) = (img.width() as i64, img.height() as i64);
    bilinear_by(p, |x, y| {
        let v = img.get_pixel(x.clamp(0, w - 1) as u32, y.clamp(0, h - 1) as u32)[0];
        DVec3::splat(v as f64)
    })
    .x
}

/// Bilinear sample at `p`, wrapping around in x (longitude) and clamped in y.
pub fn bilinear_wrap_x(img: &RgbImage, p: DVec2) -> DVec3 {
    let (w, h) = (img.width() as i64, img.height() as i64);
    bilinear_by(p, |x, y| {
        pixel(img, x.rem_euclid(w) as u32, y.clamp(0, h - 1) as u32)
    })
}

/// Bilinear interpolation of `at(x, y)` (which resolves out-of-range pixels) at `p`.
pub fn bilinear_by(p: DVec2, at: impl Fn(i64, i64) -> DVec3) -> DVec3 {
    let (x0, y0) = (p.x.floor(), p.y.floor());
    let (fx, fy) = (p.x - x0, p.y - y0);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let top = at(x0, y0).lerp(at(x0 + 1, y0), fx);
    let bottom = at(x0, y0 + 1).lerp(at(x0 + 1, y0 + 1), fx);
    top.lerp(bottom, fy)
}

pub fn to_rgb8(c: DVec3) -> [u8; 3] {
    let q = |v: f64| v.round().clamp(0.0, 255.0) as u8;
    [q(c.x), q(c.y), q(c.z)]
}

/// Sub-pixel offsets of an n × n stratified grid inside a unit pixel.
pub fn sample_offsets(n: u32) -> impl Iterator<Item = DVec2> {
    let k = 1.0 / n as f64;
    (0..n * n).map(move |i| DVec2::new(((i % n) as f64 + 0.5) * k, ((i / n) as f64 + 0.5) * k))
}

/// Peak signal-to-noise ratio in dB over a rectangle (8-bit peak 255); infinite when equal.
pub fn psnr(a: &RgbImage, b: &RgbImage, rect: Rect) -> f64 {
    let mut sum = 0.0;
    for y in rect.y..rect.bottom() {
        for x in rect.x..rect.right() {
            let d = pixel(a, x, y) - pixel(b, x, y);
            sum += d.length_squared();
        }
    }
    let mse = sum / (3.0 * rect.area() as f64);
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0 * 255.0 / mse).log10()
    }
}

/// Weighted centroid (pixel-centre coordinates) of the pixels near `colour` inside `rect`:
/// weight 1 at the colour, falling linearly to 0 at distance `tolerance`. Returns the centroid
/// and the total weight (about the blob's area in pixels), None if nothing matches.
pub fn centroid(img: &RgbImage, rect: Rect, colour: DVec3, tolerance: f64) -> Option<(DVec2, f64)> {
    let (mut sum, mut acc) = (0.0, DVec2::ZERO);
    for y in rect.y..rect.bottom() {
        for x in rect.x..rect.right() {
            let w = (1.0 - (pixel(img, x, y) - colour).length() / tolerance).max(0.0);
            sum += w;
            acc += DVec2::new(x as f64 + 0.5, y as f64 + 0.5) * w;
        }
    }
    (sum > 0.0).then(|| (acc / sum, sum))
}

/// The 8 pixels around pixel `i` of a w × h picture (pixels numbered along rows), those
/// inside it.
pub fn neighbours(i: usize, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (x, y) = ((i % w) as i64, (i / w) as i64);
    [
        (-1, -1),
        (0, -1),
        (1, -1),
        (-1, 0),
        (1, 0),
        (-1, 1),
        (0, 1),
        (1, 1),
    ]
    .into_iter()
    .map(move |(dx, dy)| (x + dx, y + dy))
    .filter(move |&(x, y)| x >= 0 && y >= 0 && x < w as i64 && y < h as i64)
    .map(move |(x, y)| y as usize * w + x as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_sampling_hits_pixel_centres_and_blends_between_them() {
        let mut img = RgbImage::new(2, 1);
        img.put_pixel(1, 0, image::Rgb([200, 100, 0]));
        assert_eq!(
            bilinear(&img, DVec2::new(1.0, 0.0)),
            DVec3::new(200.0, 100.0, 0.0)
        );
        assert_eq!(
            bilinear(&img, DVec2::new(0.5, 0.0)),
            DVec3::new(100.0, 50.0, 0.0)
        );
        assert_eq!(
            bilinear(&img, DVec2::new(-3.0, 5.0)),
            DVec3::ZERO,
            "edges clamp"
        );
    }

    #[test]
    fn psnr_and_centroid_measure_what_they_claim() {
        let a = RgbImage::from_pixel(10, 10, image::Rgb([100, 100, 100]));
        let mut b = a.clone();
        assert_eq!(psnr(&a, &b, Rect::new(0, 0, 10, 10)), f64::INFINITY);
        b.put_pixel(3, 4, image::Rgb([110, 100, 100]));
        // MSE = 100 / 300 → 10 log10(65025 · 3) = 52.9 dB
        assert!((psnr(&a, &b, Rect::new(0, 0, 10, 10)) - 52.90).abs() < 0.01);
        let (c, w) = centroid(
            &b,
            Rect::new(0, 0, 10, 10),
            DVec3::new(110.0, 100.0, 100.0),
            5.0,
        )
        .unwrap();
        assert_eq!((c, w), (DVec2::new(3.5, 4.5), 1.0));
    }
}
