//! Equisolid-angle fisheye: r = 2 sin(θ/2), defined up to θ = π. WGSL twin: `equisolid_r`.

use super::{ModelLimits, RadialModel, Sample, sample_pinhole};
use crate::lens::calfile::Fields;
use crate::lens::{LensError, PixelAffine};

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Equisolid;

impl RadialModel for Equisolid {
    const NAME: &'static str = "equisolid";

    fn read(fields: &Fields) -> Result<(Self, PixelAffine), LensError> {
        Ok((Equisolid, fields.pinhole()?))
    }

    fn limits(&self) -> ModelLimits {
        ModelLimits::up_to(self, std::f64::consts::PI)
    }

    fn r_of_theta(&self, theta: f64, _: &ModelLimits) -> Option<f64> {
        Some(2.0 * (theta / 2.0).sin())
    }

    fn theta_of_r(&self, r: f64, _: &ModelLimits) -> Option<f64> {
        (0.0..=2.0 + 1e-9)
            .contains(&r)
            .then(|| 2.0 * (r / 2.0).min(1.0).asin())
    }

    fn sample() -> Sample<Self> {
        Sample {
            model: Equisolid,
            affine: sample_pinhole(300.0),
            fov: 190f64.to_radians(),
        }
    }
}
