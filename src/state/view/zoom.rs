//! A view's fov as a camera's zoom: the zoom level a ground station shows (0 % the widest fov
//! the crop mode allows, 100 % the narrowest, even steps of zoom factor between), and the
//! focal length in millimetres that gives the same fov on a 35 mm frame (36 mm wide), the
//! sensor size CAMERA_INFORMATION reports, so a ground station's footprint and GSD figures
//! match the view.

use crate::geometry::view::{clamp_fov, fov_range};
use crate::modes::Crop;

/// The sensor width the focal lengths refer to (a 35 mm frame), mm.
pub const SENSOR_WIDTH_MM: f64 = 36.0;

/// 0 (widest) to 100 (narrowest): the fov's place on a log scale between the crop mode's
/// limits.
pub fn level(fov: f64, crop: Crop) -> f32 {
    let (lo, hi) = fov_range(crop);
    (100.0 * (hi / clamp_fov(fov, crop)).ln() / (hi / lo).ln()) as f32
}

/// The fov at a zoom level (0..=100, clamped).
pub fn fov_at_level(level: f64, crop: Crop) -> f64 {
    let (lo, hi) = fov_range(crop);
    hi * (lo / hi).powf(level.clamp(0.0, 100.0) / 100.0)
}

/// The focal length (mm, 35 mm frame) of a rectilinear view of `fov`; NaN where no focal
/// length gives it (π and wider).
pub fn focal_length_mm(fov: f64) -> f32 {
    if fov > 0.0 && fov < std::f64::consts::PI {
        (SENSOR_WIDTH_MM / 2.0 / (fov / 2.0).tan()) as f32
    } else {
        f32::NAN
    }
}

/// The fov that a focal length (mm, 35 mm frame) gives.
pub fn fov_of_focal_length(mm: f64) -> f64 {
    2.0 * (SENSOR_WIDTH_MM / 2.0 / mm).atan()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_span_the_crop_modes_fov_range_and_invert() {
        let (lo, hi) = fov_range(Crop::Rectilinear);
        assert_eq!(level(hi, Crop::Rectilinear), 0.0);
        assert!((level(lo, Crop::Rectilinear) - 100.0).abs() < 1e-4);
        for l in [0.0, 12.5, 50.0, 99.0] {
            let fov = fov_at_level(l, Crop::Rectilinear);
            assert!(
                (level(fov, Crop::Rectilinear) as f64 - l).abs() < 1e-3,
                "{l}"
            );
        }
        assert!(level(1.0, Crop::Rectilinear) > level(1.5, Crop::Rectilinear));
    }

    #[test]
    fn a_90_degree_view_is_an_18_mm_lens_on_a_35_mm_frame() {
        let fov = 90f64.to_radians();
        assert!((focal_length_mm(fov) - 18.0).abs() < 1e-4);
        assert!((fov_of_focal_length(18.0) - fov).abs() < 1e-9);
        assert!(focal_length_mm(std::f64::consts::PI).is_nan());
    }
}
