//! A rectilinear lens with radial distortion, as OpenCV's standard camera model (`plumb_bob`
//! without the tangential terms) and the calibrations of narrow cameras (a thermal core, a zoom
//! block) give it: r = t (1 + k1 t² + k2 t⁴ + k3 t⁶), with t = tan θ the undistorted radius. It
//! sees less than a hemisphere: its limit is the first fold of the polynomial or 89°, whichever
//! comes first. WGSL twin: `pinhole_r`, reading k1..k3 from `k`.

use super::solve::{first_fold, newton_monotone};
use super::{Coefficients, ModelLimits, RadialModel, Sample, sample_pinhole};
use crate::lens::calfile::{Fields, TomlWriter};
use crate::lens::{LensError, PixelAffine};

/// Where a rectilinear lens stops, however mild its distortion: tan θ grows without bound
/// towards 90°.
const WIDEST: f64 = 89.0 * std::f64::consts::PI / 180.0;

/// OpenCV's radial coefficients k1, k2, k3.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pinhole {
    pub k: [f64; 3],
}

impl Pinhole {
    fn r(&self, theta: f64) -> f64 {
        let (k, t) = (&self.k, theta.tan());
        let t2 = t * t;
        t * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * k[2])))
    }

    fn dr_dtheta(&self, theta: f64) -> f64 {
        let (k, t) = (&self.k, theta.tan());
        let t2 = t * t;
        let dr_dt = 1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * 7.0 * k[2]));
        dr_dt * (1.0 + t2)
    }
}

impl RadialModel for Pinhole {
    const NAME: &'static str = "pinhole";

    fn read(fields: &Fields) -> Result<(Self, PixelAffine), LensError> {
        let k = fields.coefficients("k", Self::NAME)?;
        Ok((Pinhole { k }, fields.pinhole()?))
    }

    fn write(&self, affine: &PixelAffine, out: &mut TomlWriter) {
        out.pinhole(affine);
        out.list("k", &self.k);
    }

    /// Up to the first fold of the polynomial, or 89°.
    fn limits(&self) -> ModelLimits {
        ModelLimits::up_to(self, first_fold(|t| self.dr_dtheta(t), WIDEST))
    }

    fn r_of_theta(&self, theta: f64, _: &ModelLimits) -> Option<f64> {
        Some(self.r(theta))
    }

    fn theta_of_r(&self, r: f64, limits: &ModelLimits) -> Option<f64> {
        newton_monotone(
            |t| self.r(t),
            |t| self.dr_dtheta(t),
            r,
            limits.theta_max,
            Some(r.atan()),
        )
    }

    fn coefficients(&self) -> Coefficients<'_> {
        Coefficients {
            k: [self.k[0], self.k[1], self.k[2], 0.0],
            ..Coefficients::default()
        }
    }

    /// A Boson-class core's lens seen through a 1280x960 frame: about 70° across, with the
    /// barrel distortion of a short focal length.
    fn sample() -> Sample<Self> {
        Sample {
            model: Pinhole {
                k: [-0.21, 0.045, -0.004],
            },
            affine: sample_pinhole(900.0),
            fov: 70f64.to_radians(),
        }
    }
}
