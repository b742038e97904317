//! Equidistant ("f-theta") fisheye: r = θ, defined up to θ = π (the ray straight back). WGSL
//! twin: `equidistant_r`.

use super::{ModelLimits, RadialModel, Sample, sample_pinhole};
use crate::lens::calfile::Fields;
use crate::lens::{LensError, PixelAffine};

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Equidistant;

impl RadialModel for Equidistant {
    const NAME: &'static str = "equidistant";

    fn read(fields: &Fields) -> Result<(Self, PixelAffine), LensError> {
        Ok((Equidistant, fields.pinhole()?))
    }

    fn limits(&self) -> ModelLimits {
        ModelLimits::up_to(self, std::f64::consts::PI)
    }

    fn r_of_theta(&self, theta: f64, _: &ModelLimits) -> Option<f64> {
        Some(theta)
    }

    fn theta_of_r(&self, r: f64, _: &ModelLimits) -> Option<f64> {
        (r >= 0.0).then_some(r)
    }

    fn sample() -> Sample<Self> {
        Sample {
            model: Equidistant,
            affine: sample_pinhole(300.0),
            fov: 190f64.to_radians(),
        }
    }
}
