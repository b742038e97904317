//! Stereographic fisheye: r = 2 tan(θ/2). WGSL twin: `stereographic_r`.

use super::{ModelLimits, RadialModel, Sample, sample_pinhole};
use crate::lens::calfile::Fields;
use crate::lens::{LensError, PixelAffine};

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stereographic;

/// r grows without bound as θ → π; keep a margin so r stays finite.
const MAX_THETA: f64 = std::f64::consts::PI * 0.95;

impl RadialModel for Stereographic {
    const NAME: &'static str = "stereographic";

    fn read(fields: &Fields) -> Result<(Self, PixelAffine), LensError> {
        Ok((Stereographic, fields.pinhole()?))
    }

    fn limits(&self) -> ModelLimits {
        ModelLimits::up_to(self, MAX_THETA)
    }

    fn r_of_theta(&self, theta: f64, _: &ModelLimits) -> Option<f64> {
        Some(2.0 * (theta / 2.0).tan())
    }

    fn theta_of_r(&self, r: f64, _: &ModelLimits) -> Option<f64> {
        (r >= 0.0).then(|| 2.0 * (r / 2.0).atan())
    }

    fn sample() -> Sample<Self> {
        Sample {
            model: Stereographic,
            affine: sample_pinhole(220.0),
            fov: 190f64.to_radians(),
        }
    }
}
