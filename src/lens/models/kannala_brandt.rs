//! Kannala-Brandt with four coefficients, as OpenCV's fisheye module and Kalibr's
//! "equidistant" distortion: r = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸), with θ = atan2(ρ, z) so the
//! model holds beyond 180°. WGSL twin: `kannala_brandt_r`, reading k1..k4 from `k`.
//!
//! The polynomial can fold back (dr/dθ ≤ 0) at large θ; its limit is the first fold, so that
//! the inverse is unique on [0, θ_max].

use super::solve::{first_fold, newton_monotone};
use super::{Coefficients, ModelLimits, RadialModel, Sample, sample_pinhole};
use crate::lens::calfile::{Fields, TomlWriter};
use crate::lens::{LensError, PixelAffine};

/// OpenCV fisheye coefficients k1..k4.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KannalaBrandt {
    pub k: [f64; 4],
}

impl KannalaBrandt {
    fn r(&self, theta: f64) -> f64 {
        let (k, t2) = (&self.k, theta * theta);
        theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))))
    }

    fn dr_dtheta(&self, theta: f64) -> f64 {
        let (k, t2) = (&self.k, theta * theta);
        1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * 9.0 * k[3])))
    }
}

impl RadialModel for KannalaBrandt {
    const NAME: &'static str = "kannala_brandt";

    fn read(fields: &Fields) -> Result<(Self, PixelAffine), LensError> {
        let k = fields.coefficients("k", Self::NAME)?;
        Ok((KannalaBrandt { k }, fields.pinhole()?))
    }

    fn write(&self, affine: &PixelAffine, out: &mut TomlWriter) {
        out.pinhole(affine);
        out.list("k", &self.k);
    }

    /// Up to the largest θ (≤ π) where r(θ) still increases strictly.
    fn limits(&self) -> ModelLimits {
        ModelLimits::up_to(
            self,
            first_fold(|t| self.dr_dtheta(t), std::f64::consts::PI),
        )
    }

    fn r_of_theta(&self, theta: f64, _: &ModelLimits) -> Option<f64> {
        Some(self.r(theta))
    }

    /// By Newton's method, bracketed on [0, θ_max] so it never leaves the monotone branch.
    fn theta_of_r(&self, r: f64, limits: &ModelLimits) -> Option<f64> {
        newton_monotone(
            |t| self.r(t),
            |t| self.dr_dtheta(t),
            r,
            limits.theta_max,
            Some(r),
        )
    }

    fn coefficients(&self) -> Coefficients<'_> {
        Coefficients {
            k: self.k,
            ..Coefficients::default()
        }
    }

    fn sample() -> Sample<Self> {
        Sample {
            model: KannalaBrandt {
                k: [0.0423, -0.0126, 0.0031, -0.0004],
            },
            affine: sample_pinhole(290.0),
            fov: 195f64.to_radians(),
        }
    }
}
