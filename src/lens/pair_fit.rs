//! Measuring how a lens pair sits: the rotation of its second lens from the back-to-back
//! pose, fitted to what both lenses see of the band around the seam. Each ray of the band is
//! seen by both; with the right rotation the two see the same thing, so the fit moves the
//! rotation until their pictures agree there (Gauss-Newton on the luma differences, from a
//! heavy blur down to the frame's own detail, so that a start a few degrees off still finds
//! its way). A gain and offset between the lenses are fitted alongside, so an exposure
//! difference does not pull the rotation. Features or a board are not needed: any scene with
//! texture across the seam will do.

use super::Lens;
use super::pair::{Pair, Side, back_to_back, correction};
use glam::{DMat3, DVec2, DVec3};
use image::GrayImage;
use rayon::prelude::*;
use std::f64::consts::FRAC_PI_2;

/// The blurs (standard deviation, frame pixels) the fit works through, coarse to fine.
const BLURS: [f32; 5] = [16.0, 8.0, 4.0, 2.0, 0.0];
/// Rays around the seam: this many azimuths, at each of [`ELEVATIONS`] angles off it.
const AZIMUTHS: usize = 4096;
const ELEVATIONS: usize = 16;
/// How far inside both lenses' fields the band keeps, radians.
const INSIDE: f64 = 0.026;

/// What the fit found.
#[derive(Clone, Debug)]
pub struct PairFit {
    /// The second lens's correction to the back-to-back pose: roll, pitch, yaw (radians).
    pub rotation: [f64; 3],
    /// Their formal standard errors (radians), from the residuals' spread.
    pub sigma: [f64; 3],
    /// Rms luma difference (code values) between the lenses over the band: at the nominal
    /// pose, and at the fitted one (after the gain and offset between them).
    pub before_rms: f64,
    pub after_rms: f64,
    /// Rays of the band both lenses saw.
    pub rays: usize,
    /// The gain and offset that carry the second lens's luma to the first's.
    pub gain: f64,
    pub offset: f64,
    /// How much (rms code values of luma) a 0.1° error in roll, pitch and yaw would change
    /// the lenses' agreement: what pins each angle down.
    pub sensitivity: [f64; 3],
}

/// The least change a 0.1° error must make (rms code values) for an angle to count as
/// measured.
pub const LEAST_SENSITIVITY: f64 = 1.0;

#[derive(Debug, thiserror::Error)]
pub enum PairFitError {
    #[error("{0} is not a lens pair")]
    NotAPair(String),
    #[error("the frame is {got:?} but the pair's lenses map into {want:?}")]
    Size { got: (u32, u32), want: (u32, u32) },
    #[error("the lenses overlap by {0:.1}deg: the fit needs a band both see of at least 2deg")]
    NoOverlap(f64),
    #[error("only {0} rays of the band have texture both lenses see: too little to fit")]
    TooFlat(usize),
    #[error(
        "the frame has too little detail across the seam to pin the {angle} down (a 0.1deg \
         error changes the picture by {change:.2} code values, {LEAST_SENSITIVITY} needed): use \
         a frame with detail all round the seam"
    )]
    Unpinned { angle: &'static str, change: f64 },
}

/// Fits the rotation of `lens`'s second lens (a pair, at the frame's size) from the frame's
/// luma, starting at the back-to-back pose. `progress` hears each blur's result.
pub fn fit_pair(
    lens: &Lens,
    luma: &GrayImage,
    mut progress: impl FnMut(&str),
) -> Result<PairFit, PairFitError> {
    let pair = lens
        .pair
        .as_ref()
        .ok_or_else(|| PairFitError::NotAPair(lens.name.clone()))?;
    if luma.dimensions() != (lens.width, lens.height) {
        return Err(PairFitError::Size {
            got: luma.dimensions(),
            want: (lens.width, lens.height),
        });
    }
    let rays = band(pair)?;
    let mut p = [0.0; 3];
    let sharp = Problem {
        pair,
        image: luma,
        rays: &rays,
    };
    let (before, _) = sharp.solve(p);
    for blur in BLURS {
        let blurred = (blur > 0.0).then(|| image::imageops::fast_blur(luma, blur));
        let problem = Problem {
            image: blurred.as_ref().unwrap_or(luma),
            ..sharp
        };
        p = problem.gauss_newton(p);
        progress(&format!(
            "blur {blur:>4.1} px: roll {:+.4}deg pitch {:+.4}deg yaw {:+.4}deg",
            p[0].to_degrees(),
            p[1].to_degrees(),
            p[2].to_degrees()
        ));
    }
    let (after, (gain, offset)) = sharp.solve(p);
    let seen = after.iter().filter(|r| r.is_some()).count();
    if seen < rays.len() / 4 {
        return Err(PairFitError::TooFlat(seen));
    }
    let (sensitivity, sigma) = sharp.spread(p);
    for (angle, change) in ["roll", "pitch", "yaw"].into_iter().zip(sensitivity) {
        if change < LEAST_SENSITIVITY {
            return Err(PairFitError::Unpinned { angle, change });
        }
    }
    Ok(PairFit {
        rotation: p,
        sensitivity,
        sigma,
        before_rms: rms(&before),
        after_rms: rms(&after),
        rays: seen,
        gain,
        offset,
    })
}

/// The rays (first lens's frame) of the band around the nominal seam that both lenses see.
fn band(pair: &Pair) -> Result<Vec<DVec3>, PairFitError> {
    let overlap = pair.first.half_fov + pair.second.half_fov - 2.0 * FRAC_PI_2;
    let half = (overlap / 2.0 - INSIDE).min(8f64.to_radians());
    if half < 1f64.to_radians() {
        return Err(PairFitError::NoOverlap(overlap.to_degrees()));
    }
    // The nominal seam: halfway between the two lenses' fields, off the first's axis.
    let seam = FRAC_PI_2 + (pair.first.half_fov - pair.second.half_fov) / 2.0;
    let mut rays = Vec::with_capacity(AZIMUTHS * ELEVATIONS);
    for i in 0..ELEVATIONS {
        let theta = seam - half + 2.0 * half * (i as f64 + 0.5) / ELEVATIONS as f64;
        for j in 0..AZIMUTHS {
            let a = std::f64::consts::TAU * j as f64 / AZIMUTHS as f64;
            rays.push(DVec3::new(
                theta.sin() * a.cos(),
                theta.sin() * a.sin(),
                theta.cos(),
            ));
        }
    }
    Ok(rays)
}

/// Each ray's luma difference; None where a lens does not see the ray.
type Residuals = Vec<Option<f64>>;

/// The fit's data: the pair, the (blurred) luma and the band's rays.
#[derive(Clone, Copy)]
struct Problem<'a> {
    pair: &'a Pair,
    image: &'a GrayImage,
    rays: &'a [DVec3],
}

impl Problem<'_> {
    /// Each ray's luma through the first lens and through the second turned by correction
    /// `p`; None where either does not see it.
    fn samples(&self, p: [f64; 3]) -> Vec<Option<(f64, f64)>> {
        let q = correction(p[0], p[1], p[2]) * back_to_back();
        self.rays
            .par_iter()
            .map(|&ray| {
                let a = self.pair.project_in(Side::First, ray)?;
                let b = self.pair.second.project(q * ray)?;
                Some((self.luma(a)?, self.luma(b)?))
            })
            .collect()
    }

    fn luma(&self, p: DVec2) -> Option<f64> {
        let (w, h) = self.image.dimensions();
        if p.x < 0.0 || p.y < 0.0 || p.x > w as f64 - 2.0 || p.y > h as f64 - 2.0 {
            return None;
        }
        Some(crate::image_ops::bilinear_luma(self.image, p))
    }

    /// The residuals at correction `p` after the best gain and offset from the second lens
    /// to the first, and that gain and offset.
    fn solve(&self, p: [f64; 3]) -> (Residuals, (f64, f64)) {
        let s = self.samples(p);
        let seen: Vec<(f64, f64)> = s.iter().flatten().copied().collect();
        let n = seen.len().max(1) as f64;
        let (ma, mb) = seen
            .iter()
            .fold((0.0, 0.0), |(x, y), (a, b)| (x + a / n, y + b / n));
        let (cov, var) = seen.iter().fold((0.0, 0.0), |(c, v), (a, b)| {
            (c + (a - ma) * (b - mb), v + (b - mb) * (b - mb))
        });
        let gain = if var > 0.0 { cov / var } else { 1.0 };
        let offset = ma - gain * mb;
        let r = s
            .iter()
            .map(|x| x.map(|(a, b)| a - gain * b - offset))
            .collect();
        (r, (gain, offset))
    }

    /// The residuals and their derivatives by each parameter (central differences), over the
    /// rays seen at `p` and at every step.
    fn jacobian(&self, p: [f64; 3]) -> (Vec<f64>, Vec<[f64; 3]>) {
        const H: f64 = 1e-4;
        let (base, _) = self.solve(p);
        // Each parameter's residuals a step below and a step above.
        let steps: Vec<[Residuals; 2]> = (0..3)
            .map(|k| {
                let (mut lo, mut hi) = (p, p);
                lo[k] -= H;
                hi[k] += H;
                [self.solve(lo).0, self.solve(hi).0]
            })
            .collect();
        let mut r = Vec::new();
        let mut j = Vec::new();
        for (i, b) in base.iter().enumerate() {
            let d = |k: usize| Some((steps[k][1][i]? - steps[k][0][i]?) / (2.0 * H));
            if let (Some(b), Some(d0), Some(d1), Some(d2)) = (b, d(0), d(1), d(2)) {
                r.push(*b);
                j.push([d0, d1, d2]);
            }
        }
        (r, j)
    }

    /// Gauss-Newton from `p`: up to 8 steps, until a step is under 1e-6 rad.
    fn gauss_newton(&self, mut p: [f64; 3]) -> [f64; 3] {
        for _ in 0..8 {
            let (r, j) = self.jacobian(p);
            let Some(step) = normal_step(&r, &j) else {
                break;
            };
            for k in 0..3 {
                p[k] -= step[k];
            }
            if step.iter().all(|s| s.abs() < 1e-6) {
                break;
            }
        }
        p
    }

    /// From one Jacobian at `p`: the rms change of the residuals a 0.1° change of each angle
    /// makes, and the angles' formal standard errors, σ² (JᵀJ)⁻¹.
    fn spread(&self, p: [f64; 3]) -> ([f64; 3], [f64; 3]) {
        let (r, j) = self.jacobian(p);
        let (jtj, _) = normal(&r, &j);
        let n = r.len().max(1) as f64;
        let sensitivity = [0, 1, 2].map(|k| (jtj.col(k)[k] / n).sqrt() * 0.1f64.to_radians());
        let var = r.iter().map(|x| x * x).sum::<f64>() / (n - 5.0).max(1.0);
        let sigma = match jtj.determinant().abs() > 0.0 {
            true => {
                let inv = jtj.inverse();
                [0, 1, 2].map(|k| (var * inv.col(k)[k]).sqrt())
            }
            false => [f64::INFINITY; 3],
        };
        (sensitivity, sigma)
    }
}

/// JᵀJ and Jᵀr.
fn normal(r: &[f64], j: &[[f64; 3]]) -> (DMat3, DVec3) {
    let mut jtj = DMat3::ZERO;
    let mut jtr = DVec3::ZERO;
    for (ri, ji) in r.iter().zip(j) {
        let v = DVec3::from_array(*ji);
        jtj += DMat3::from_cols(v * v.x, v * v.y, v * v.z);
        jtr += v * *ri;
    }
    (jtj, jtr)
}

/// The Gauss-Newton step (JᵀJ)⁻¹Jᵀr; None where the rays do not pin the rotation down.
fn normal_step(r: &[f64], j: &[[f64; 3]]) -> Option<[f64; 3]> {
    let (jtj, jtr) = normal(r, j);
    (jtj.determinant().abs() > 1e-12).then(|| (jtj.inverse() * jtr).to_array())
}

fn rms(r: &[Option<f64>]) -> f64 {
    let seen: Vec<f64> = r.iter().flatten().copied().collect();
    (seen.iter().map(|x| x * x).sum::<f64>() / seen.len().max(1) as f64).sqrt()
}
