//! Equisolid-angle fisheye: r = 2 sin(θ/2). WGSL twin: `equisolid_r`.

pub fn r_of_theta(theta: f64) -> f64 {
    2.0 * (theta / 2.0).sin()
}

pub fn theta_of_r(r: f64) -> Option<f64> {
    (0.0..=2.0 + 1e-9)
        .contains(&r)
        .then(|| 2.0 * (r / 2.0).min(1.0).asin())
}

pub const MAX_THETA: f64 = std::f64::consts::PI;
