//! Double Sphere (Usenko, Demmel and Cremers 2018): parameters ξ and α, closed form both ways.
//! Written here in its radial form (unit ray at angle θ), which is exact because the model is
//! rotationally symmetric in normalized coordinates. WGSL twin: `double_sphere_r`.

pub fn r_of_theta(xi: f64, alpha: f64, theta: f64) -> Option<f64> {
    let (s, c) = theta.sin_cos();
    let d2 = (s * s + (xi + c) * (xi + c)).sqrt();
    let denom = alpha * d2 + (1.0 - alpha) * (xi + c);
    (denom > 1e-12).then(|| s / denom)
}

/// The model's own limit: rays with cos θ ≤ -w2 do not project (paper, eq. 43).
pub fn max_theta(xi: f64, alpha: f64) -> f64 {
    let w1 = if alpha <= 0.5 {
        alpha / (1.0 - alpha)
    } else {
        (1.0 - alpha) / alpha
    };
    let w2 = (w1 + xi) / (2.0 * w1 * xi + xi * xi + 1.0).sqrt();
    (-w2).clamp(-1.0, 1.0).acos()
}

pub fn theta_of_r(xi: f64, alpha: f64, r: f64) -> Option<f64> {
    let r2 = r * r;
    if alpha > 0.5 && r2 > 1.0 / (2.0 * alpha - 1.0) {
        return None;
    }
    let mz = (1.0 - alpha * alpha * r2)
        / (alpha * (1.0 - (2.0 * alpha - 1.0) * r2).sqrt() + 1.0 - alpha);
    let k = (mz * xi + (mz * mz + (1.0 - xi * xi) * r2).sqrt()) / (mz * mz + r2);
    let (x, z) = (k * r, k * mz - xi);
    Some(x.atan2(z))
}
