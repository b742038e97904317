//! Orthographic fisheye: r = sin θ, valid only for the front hemisphere. WGSL twin: `orthographic_r`.

pub fn r_of_theta(theta: f64) -> f64 {
    theta.sin()
}

pub fn theta_of_r(r: f64) -> Option<f64> {
    (0.0..=1.0 + 1e-9).contains(&r).then(|| r.min(1.0).asin())
}

pub const MAX_THETA: f64 = std::f64::consts::FRAC_PI_2;
