//! Scaramuzza's OCam model (OCamCalib): a direct polynomial z = pol(ρ) from the image plane to
//! the ray, an inverse polynomial ρ = invpol(θ') for speed, and an affine (c, d, e) with centre
//! (xc, yc) in OCamCalib's row/column order. The affine and centre live in the lens's pixel
//! affine (see `Lens`); this file owns the radial part. WGSL twin: `ocam_r`, reading `pol` and
//! `invpol`.
//!
//! OCam's camera frame has z pointing backwards, so a forward ray has pol(ρ) < 0 and the angle
//! from the optical axis is θ = atan2(ρ, -pol(ρ)).

use super::solve::{first_fold, newton_monotone};
use super::{Coefficients, ModelLimits, RadialModel, Sample};
use crate::lens::calfile::{Fields, TomlWriter};
use crate::lens::{LensError, PixelAffine};

/// OCamCalib polynomials, lowest order first, in pixel units of the calibration frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Ocam {
    pub pol: Vec<f64>,
    pub invpol: Vec<f64>,
}

/// How far out to look for the direct polynomial's fold, in pixels.
const SEARCH_RADIUS: f64 = 20_000.0;

fn poly(c: &[f64], x: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &a| acc * x + a)
}

fn dpoly(c: &[f64], x: f64) -> f64 {
    c.iter()
        .enumerate()
        .skip(1)
        .rev()
        .fold(0.0, |acc, (i, &a)| acc * x + i as f64 * a)
}

impl Ocam {
    /// θ as a function of the radius in the affine-corrected pixel plane.
    fn theta(&self, r: f64) -> f64 {
        r.atan2(-poly(&self.pol, r))
    }

    fn dtheta_dr(&self, r: f64) -> f64 {
        // d/dr atan2(r, -p) = (-p + r p') / (r² + p²)
        let p = poly(&self.pol, r);
        (-p + r * dpoly(&self.pol, r)) / (r * r + p * p)
    }
}

impl RadialModel for Ocam {
    const NAME: &'static str = "ocam";

    fn read(fields: &Fields) -> Result<(Self, PixelAffine), LensError> {
        let pol = fields.numbers("pol", "model `ocam` needs `pol`")?;
        if pol.len() < 2 || pol[0] >= 0.0 || pol.iter().any(|x| !x.is_finite()) {
            return Err(fields.invalid(
                "pol",
                "needs at least two finite coefficients, the first negative (OCamCalib's a0)"
                    .into(),
            ));
        }
        let invpol = fields.optional_numbers("invpol")?.unwrap_or_default();
        if invpol.iter().any(|x| !x.is_finite()) {
            return Err(fields.invalid("invpol", "coefficients must be finite".into()));
        }
        let (c, d, e) = (fields.number("c")?, fields.number("d")?, fields.number("e")?);
        if (c - d * e).abs() < 1e-9 {
            return Err(fields.invalid("c", "the affine [c d; e 1] is singular".into()));
        }
        let affine = PixelAffine::ocam(c, d, e, fields.number("xc")?, fields.number("yc")?);
        Ok((Ocam { pol, invpol }, affine))
    }

    fn write(&self, affine: &PixelAffine, out: &mut TomlWriter) {
        // The affine's columns are (1, d) and (e, c), its offset (yc, xc).
        let (m, o) = (affine.matrix, affine.offset);
        out.list("pol", &self.pol);
        out.list("invpol", &self.invpol);
        for (key, v) in [
            ("c", m.y_axis.y),
            ("d", m.x_axis.y),
            ("e", m.y_axis.x),
            ("xc", o.y),
            ("yc", o.x),
        ] {
            out.number(key, v);
        }
    }

    /// Found in r, where θ(r) stops increasing strictly (pol stops folding back); θ follows.
    fn limits(&self) -> ModelLimits {
        let r_max = first_fold(|r| self.dtheta_dr(r), SEARCH_RADIUS);
        ModelLimits {
            theta_max: self.theta(r_max),
            r_max,
        }
    }

    /// The inverse polynomial gives the first guess, Newton on the direct polynomial makes it
    /// exact (OCamCalib's invpol alone is only a fit, good to ~0.1 px).
    fn r_of_theta(&self, theta: f64, limits: &ModelLimits) -> Option<f64> {
        // invpol takes OCam's angle from the image plane, θ - π/2.
        let guess = (!self.invpol.is_empty())
            .then(|| poly(&self.invpol, theta - std::f64::consts::FRAC_PI_2));
        newton_monotone(
            |r| self.theta(r),
            |r| self.dtheta_dr(r),
            theta,
            limits.r_max,
            guess,
        )
    }

    fn theta_of_r(&self, r: f64, _: &ModelLimits) -> Option<f64> {
        Some(self.theta(r))
    }

    fn coefficients(&self) -> Coefficients<'_> {
        Coefficients {
            pol: &self.pol,
            invpol: &self.invpol,
            ..Coefficients::default()
        }
    }

    fn sample() -> Sample<Self> {
        Sample {
            model: Ocam {
                pol: vec![-190.0, 0.0, 1.1e-3, 2.0e-7, 1.0e-9],
                invpol: vec![280.0, 180.0, 30.0],
            },
            affine: PixelAffine::ocam(1.0004, 0.0003, -0.0002, 478.6, 640.9),
            fov: 195f64.to_radians(),
        }
    }
}
