//! Kannala-Brandt with four coefficients, as OpenCV's fisheye module and Kalibr's
//! "equidistant" distortion: r = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸), with θ = atan2(ρ, z) so the
//! model holds beyond 180°. WGSL twin: `kannala_brandt_r`.
//!
//! The polynomial can fold back (dr/dθ ≤ 0) at large θ; [`max_theta`] finds the first fold so
//! that the inverse is unique on [0, max_theta].

use super::solve::{first_fold, newton_monotone};

pub fn r_of_theta(k: &[f64; 4], theta: f64) -> f64 {
    let t2 = theta * theta;
    theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))))
}

fn dr_dtheta(k: &[f64; 4], theta: f64) -> f64 {
    let t2 = theta * theta;
    1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * 9.0 * k[3])))
}

/// The largest θ (≤ π) up to which r(θ) increases strictly.
pub fn max_theta(k: &[f64; 4]) -> f64 {
    first_fold(|t| dr_dtheta(k, t), std::f64::consts::PI)
}

/// Inverse by Newton's method, bracketed on [0, max_theta] so it never leaves the monotone branch.
pub fn theta_of_r(k: &[f64; 4], theta_max: f64, r: f64) -> Option<f64> {
    newton_monotone(
        |t| r_of_theta(k, t),
        |t| dr_dtheta(k, t),
        r,
        theta_max,
        Some(r),
    )
}
