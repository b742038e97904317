//! Exposure: the fisheye camera's exposure time and gain (CAM_SENSOR), beside the source at
//! the start of the data's path. The frame loop measures each new frame's brightness inside
//! the image circle ([`circle_luma`]); where DigiView runs the auto exposure itself
//! ([`auto`]), that measure picks the next exposure and gain. They reach a V4L2 camera as its
//! controls ([`v4l2`]) and the demo camera as its simulated sensor ([`SensorModel`]).

pub mod auto;
pub mod v4l2;

use crate::frame::{Frame, PixelFormat};
use glam::DVec2;
use serde::{Deserialize, Serialize};

/// CAM_SENSOR's gain for a gain of one (its unit is a thousandth).
pub const UNITY_GAIN: u32 = 1000;
/// The exposure at which the demo camera shows the world's own colours at unity gain.
pub const REFERENCE_EXPOSURE_US: u32 = 10_000;

/// `[exposure]` in the serve configuration.
#[derive(Clone, Debug, Default, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct ExposureConfig {
    /// With CAM_SENSOR's ae on: `camera` (the camera's own auto exposure, where it has one;
    /// target_brightness is then the camera's to ignore) or `software` (DigiView's, towards
    /// target_brightness, on any camera).
    pub auto: AutoExposureMode,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum AutoExposureMode {
    #[default]
    Camera,
    Software,
}

/// Exposure time and gain, in CAM_SENSOR's units.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Setting {
    pub exposure_us: u32,
    /// Thousandths: 1000 is a gain of one.
    pub gain: u32,
}

/// What a camera can be set to, in CAM_SENSOR's units.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    pub exposure_us: (u32, u32),
    pub gain: (u32, u32),
}

impl Setting {
    /// The light gathered, against 10 ms at a gain of one.
    pub fn brightness(&self) -> f64 {
        self.exposure_us as f64 / REFERENCE_EXPOSURE_US as f64 * self.gain as f64
            / UNITY_GAIN as f64
    }

    /// The setting within `limits` that gathers `brightness`: the exposure first (noise
    /// grows with gain), then gain once the exposure is at its longest; below the shortest
    /// exposure, the lowest gain.
    pub fn for_brightness(brightness: f64, limits: &Limits) -> Setting {
        let (e_lo, e_hi) = limits.exposure_us;
        let (g_lo, g_hi) = limits.gain;
        let wanted_us = brightness * REFERENCE_EXPOSURE_US as f64;
        // At the lowest gain, how long an exposure gives it.
        let at_lowest = wanted_us * UNITY_GAIN as f64 / g_lo as f64;
        let exposure_us = (at_lowest.round() as u32).clamp(e_lo, e_hi);
        let gain = (wanted_us / exposure_us as f64 * UNITY_GAIN as f64).round() as u32;
        Setting {
            exposure_us,
            gain: gain.clamp(g_lo, g_hi),
        }
    }
}

/// The demo camera's sensor: the picture's brightness is the world's times the light a
/// setting gathers, clipped at white, with noise that grows with gain (the read noise the gain
/// amplifies; none at a gain of one, so a unity frame is the world's own).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorModel {
    /// Multiplies the world's colours.
    pub scale: f64,
    /// The noise's standard deviation in luma code values.
    pub noise: f64,
}

/// Luma noise per gain of one above the first.
const NOISE_PER_GAIN: f64 = 1.5;

impl SensorModel {
    pub fn new(setting: Setting) -> SensorModel {
        let gain = setting.gain as f64 / UNITY_GAIN as f64;
        SensorModel {
            scale: setting.brightness(),
            noise: NOISE_PER_GAIN * (gain - 1.0).max(0.0),
        }
    }

    /// Adds this sensor's noise to a luma plane (`stride` bytes a row, `width` pixels used).
    /// The noise is a sum of four uniforms (near Gaussian) from a hash of the frame number and
    /// the pixel, so frames differ and the work parallelises.
    pub fn add_noise(&self, plane: &mut [u8], stride: usize, width: usize, frame: u64) {
        use rayon::prelude::*;
        if self.noise <= 0.0 {
            return;
        }
        // Four uniforms on [-0.5, 0.5) sum to a variance of 4/12.
        let k = self.noise / (4.0f64 / 12.0).sqrt();
        plane
            .par_chunks_mut(stride)
            .enumerate()
            .for_each(|(y, row)| {
                let mut h = splitmix(frame.wrapping_mul(0x9E37_79B9) ^ (y as u64) << 20);
                for px in row.iter_mut().take(width) {
                    h = splitmix(h);
                    let sum: f64 = (0..4)
                        .map(|i| ((h >> (16 * i)) & 0xffff) as f64 / 65536.0 - 0.5)
                        .sum();
                    *px = (*px as f64 + k * sum).round().clamp(0.0, 255.0) as u8;
                }
            });
    }
}

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Every how many pixels, each way, [`circle_luma`] samples: about 30 000 samples of a 4K
/// frame.
const SAMPLE_STEP: usize = 16;

/// The mean luma of the frame's pixels inside the image circle (`centre`, `radius` in
/// pixels), on the full 0..=255 scale (BT.601 weights; limited-range YUV is expanded), sampled
/// on a grid: what CAM_SENSOR's target_brightness is compared with. None when no sample falls
/// inside the circle.
pub fn circle_luma(frame: &Frame, centre: DVec2, radius: f64) -> Option<f64> {
    let l = &frame.layout;
    let r2 = radius * radius;
    let (mut sum, mut n) = (0.0, 0u64);
    let y_lo = (centre.y - radius).max(0.0) as usize;
    let y_hi = ((centre.y + radius).ceil() as usize).min(l.height as usize);
    for y in (y_lo..y_hi).step_by(SAMPLE_STEP) {
        let dy = y as f64 + 0.5 - centre.y;
        let half = (r2 - dy * dy).max(0.0).sqrt();
        let x_lo = (centre.x - half).max(0.0).ceil() as usize;
        let x_hi = ((centre.x + half) as usize).min(l.width as usize);
        let row = y * l.stride as usize;
        for x in (x_lo..x_hi).step_by(SAMPLE_STEP) {
            sum += match l.format {
                PixelFormat::Rgba => {
                    let p = &frame.data[row + 4 * x..row + 4 * x + 3];
                    0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64
                }
                PixelFormat::I420 | PixelFormat::Nv12 => {
                    ((frame.data[row + x] as f64 - 16.0) * 255.0 / 219.0).clamp(0.0, 255.0)
                }
            };
            n += 1;
        }
    }
    (n > 0).then(|| sum / n as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::PlaneLayout;

    const LIMITS: Limits = Limits {
        exposure_us: (10, 33_333),
        gain: (1000, 16_000),
    };

    #[test]
    fn brightness_goes_to_exposure_first_then_to_gain() {
        let s = Setting::for_brightness(0.5, &LIMITS);
        assert_eq!(
            s,
            Setting {
                exposure_us: 5000,
                gain: 1000
            }
        );
        let s = Setting::for_brightness(6.6666, &LIMITS);
        assert_eq!(s.exposure_us, 33_333);
        assert_eq!(s.gain, 2000);
        assert!((s.brightness() - 6.6666).abs() < 0.01);
        // Beyond the longest exposure at the highest gain, and below the shortest at unity.
        assert_eq!(
            Setting::for_brightness(1000.0, &LIMITS),
            Setting {
                exposure_us: 33_333,
                gain: 16_000
            }
        );
        assert_eq!(
            Setting::for_brightness(0.0001, &LIMITS),
            Setting {
                exposure_us: 10,
                gain: 1000
            }
        );
    }

    #[test]
    fn the_circles_luma_leaves_out_the_black_around_it_and_expands_limited_range() {
        // A 64x64 I420 frame: luma 126 (full-range 128) inside a circle of radius 20, black
        // (16) outside.
        let layout = PlaneLayout::tight(PixelFormat::I420, 64, 64).unwrap();
        let mut data = vec![128u8; layout.size as usize];
        let centre = DVec2::new(32.0, 32.0);
        for y in 0..64 {
            for x in 0..64 {
                let inside = DVec2::new(x as f64 + 0.5, y as f64 + 0.5).distance(centre) < 20.0;
                data[y * 64 + x] = if inside { 126 } else { 16 };
            }
        }
        let frame = Frame {
            data,
            layout,
            captured_us: 0,
        };
        let mean = circle_luma(&frame, centre, 19.0).unwrap();
        assert!((mean - 128.08).abs() < 0.01, "{mean}");
        let all = circle_luma(&frame, centre, 60.0).unwrap();
        assert!(
            all < 100.0,
            "the black counts once the circle takes it in: {all}"
        );
    }

    #[test]
    fn the_demo_sensor_scales_with_exposure_and_gain_and_is_noisy_only_with_gain() {
        let unity = SensorModel::new(Setting {
            exposure_us: 10_000,
            gain: 1000,
        });
        assert_eq!(
            unity,
            SensorModel {
                scale: 1.0,
                noise: 0.0
            }
        );
        let half = SensorModel::new(Setting {
            exposure_us: 5000,
            gain: 1000,
        });
        assert_eq!(half.scale, 0.5);
        let gained = SensorModel::new(Setting {
            exposure_us: 5000,
            gain: 4000,
        });
        assert_eq!(gained.scale, 2.0);
        let mut plane = vec![100u8; 256 * 64];
        gained.add_noise(&mut plane, 256, 256, 7);
        let n = plane.len() as f64;
        let mean = plane.iter().map(|&v| v as f64).sum::<f64>() / n;
        let sd = (plane
            .iter()
            .map(|&v| (v as f64 - mean).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        assert!((mean - 100.0).abs() < 0.1, "{mean}");
        assert!(
            (sd - gained.noise).abs() < 0.15 * gained.noise,
            "{sd} vs {}",
            gained.noise
        );
    }
}
