//! Scaramuzza's OCam model (OCamCalib): a direct polynomial z = pol(ρ) from the image plane to
//! the ray, an inverse polynomial ρ = invpol(θ') for speed, and an affine (c, d, e) with centre
//! (xc, yc) in OCamCalib's row/column order. The affine and centre live in the lens's pixel
//! affine (see `Lens`); this file owns the radial part. WGSL twin: `ocam_r`.
//!
//! OCam's camera frame has z pointing backwards, so a forward ray has pol(ρ) < 0 and the angle
//! from the optical axis is θ = atan2(ρ, -pol(ρ)).

use super::solve::{first_fold, newton_monotone};

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

/// θ as a function of the radius in the affine-corrected pixel plane.
pub fn theta_of_r(pol: &[f64], r: f64) -> f64 {
    r.atan2(-poly(pol, r))
}

fn dtheta_dr(pol: &[f64], r: f64) -> f64 {
    // d/dr atan2(r, -p) = (-p + r p') / (r² + p²)
    let p = poly(pol, r);
    (-p + r * dpoly(pol, r)) / (r * r + p * p)
}

/// The largest radius up to which θ(r) increases strictly (where pol stops folding back).
pub fn max_radius(pol: &[f64], search_to: f64) -> f64 {
    first_fold(|r| dtheta_dr(pol, r), search_to)
}

/// r for a given θ: the inverse polynomial gives the first guess, Newton on the direct
/// polynomial makes it exact (OCamCalib's invpol alone is only a fit, good to ~0.1 px).
pub fn r_of_theta(pol: &[f64], invpol: &[f64], r_max: f64, theta: f64) -> Option<f64> {
    // invpol takes OCam's angle from the image plane, θ - π/2.
    let guess = (!invpol.is_empty()).then(|| poly(invpol, theta - std::f64::consts::FRAC_PI_2));
    newton_monotone(
        |r| theta_of_r(pol, r),
        |r| dtheta_dr(pol, r),
        theta,
        r_max,
        guess,
    )
}
