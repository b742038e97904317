//! Double Sphere (Usenko, Demmel and Cremers 2018): parameters ξ and α, closed form both ways.
//! Written here in its radial form (unit ray at angle θ), which is exact because the model is
//! rotationally symmetric in normalized coordinates. WGSL twin: `double_sphere_r`, reading
//! (ξ, α) from `k`.

use super::{Coefficients, ModelLimits, RadialModel, Sample, sample_pinhole};
use crate::lens::calfile::{Fields, TomlWriter};
use crate::lens::{LensError, PixelAffine};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DoubleSphere {
    pub xi: f64,
    pub alpha: f64,
}

impl RadialModel for DoubleSphere {
    const NAME: &'static str = "double_sphere";

    fn read(fields: &Fields) -> Result<(Self, PixelAffine), LensError> {
        let xi = fields.number("xi")?;
        let alpha = fields.number("alpha")?;
        if !(0.0..=1.0).contains(&alpha) {
            return Err(fields.invalid("alpha", format!("must be in [0, 1] (got {alpha})")));
        }
        Ok((DoubleSphere { xi, alpha }, fields.pinhole()?))
    }

    fn write(&self, affine: &PixelAffine, out: &mut TomlWriter) {
        out.pinhole(affine);
        out.number("xi", self.xi);
        out.number("alpha", self.alpha);
    }

    /// The model's own limit: rays with cos θ ≤ -w2 do not project (paper, eq. 43).
    fn limits(&self) -> ModelLimits {
        let (xi, alpha) = (self.xi, self.alpha);
        let w1 = if alpha <= 0.5 {
            alpha / (1.0 - alpha)
        } else {
            (1.0 - alpha) / alpha
        };
        let w2 = (w1 + xi) / (2.0 * w1 * xi + xi * xi + 1.0).sqrt();
        ModelLimits::up_to(self, (-w2).clamp(-1.0, 1.0).acos())
    }

    fn r_of_theta(&self, theta: f64, _: &ModelLimits) -> Option<f64> {
        let (xi, alpha) = (self.xi, self.alpha);
        let (s, c) = theta.sin_cos();
        let d2 = (s * s + (xi + c) * (xi + c)).sqrt();
        let denom = alpha * d2 + (1.0 - alpha) * (xi + c);
        (denom > 1e-12).then(|| s / denom)
    }

    fn theta_of_r(&self, r: f64, _: &ModelLimits) -> Option<f64> {
        let (xi, alpha) = (self.xi, self.alpha);
        let r2 = r * r;
        if alpha > 0.5 && r2 > 1.0 / (2.0 * alpha - 1.0) {
            return None;
        }
        let mz = (1.0 - alpha * alpha * r2)
            / (alpha * (1.0 - (2.0 * alpha - 1.0) * r2).sqrt() + 1.0 - alpha);
        let k = (mz * xi + (mz * mz + (1.0 - xi * xi) * r2).sqrt()) / (mz * mz + r2);
        let (x, z) = (k * r, k * mz - xi);
        Some(x.atan2(z))
    }

    fn coefficients(&self) -> Coefficients<'_> {
        Coefficients {
            k: [self.xi, self.alpha, 0.0, 0.0],
            ..Coefficients::default()
        }
    }

    fn sample() -> Sample<Self> {
        Sample {
            model: DoubleSphere {
                xi: -0.22,
                alpha: 0.58,
            },
            affine: sample_pinhole(180.0),
            fov: 190f64.to_radians(),
        }
    }
}
