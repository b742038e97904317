//! Stereographic fisheye: r = 2 tan(θ/2). WGSL twin: `stereographic_r`.

pub fn r_of_theta(theta: f64) -> f64 {
    2.0 * (theta / 2.0).tan()
}

pub fn theta_of_r(r: f64) -> Option<f64> {
    (r >= 0.0).then(|| 2.0 * (r / 2.0).atan())
}

/// r grows without bound as θ → π; keep a margin so r stays finite.
pub const MAX_THETA: f64 = std::f64::consts::PI * 0.95;
