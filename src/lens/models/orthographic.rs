//! Orthographic fisheye: r = sin θ, valid only for the front hemisphere. WGSL twin:
//! `orthographic_r`.

use super::{ModelLimits, RadialModel, Sample, sample_pinhole};
use crate::lens::calfile::Fields;
use crate::lens::{LensError, PixelAffine};

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Orthographic;

impl RadialModel for Orthographic {
    const NAME: &'static str = "orthographic";

    fn read(fields: &Fields) -> Result<(Self, PixelAffine), LensError> {
        Ok((Orthographic, fields.pinhole()?))
    }

    fn limits(&self) -> ModelLimits {
        ModelLimits::up_to(self, std::f64::consts::FRAC_PI_2)
    }

    fn r_of_theta(&self, theta: f64, _: &ModelLimits) -> Option<f64> {
        Some(theta.sin())
    }

    fn theta_of_r(&self, r: f64, _: &ModelLimits) -> Option<f64> {
        (0.0..=1.0 + 1e-9).contains(&r).then(|| r.min(1.0).asin())
    }

    fn sample() -> Sample<Self> {
        Sample {
            model: Orthographic,
            affine: sample_pinhole(470.0),
            fov: 180f64.to_radians(),
        }
    }
}
