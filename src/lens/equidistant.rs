//! Equidistant ("f-theta") fisheye: r = θ. The WGSL twin is `equidistant_r` in shaders/lens.wgsl.

pub fn r_of_theta(theta: f64) -> f64 {
    theta
}

pub fn theta_of_r(r: f64) -> Option<f64> {
    (r >= 0.0).then_some(r)
}

/// The model is defined up to θ = π (the ray straight back).
pub const MAX_THETA: f64 = std::f64::consts::PI;
