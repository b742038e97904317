//! Root finding shared by the lens models that have no closed-form inverse.

/// The first x in (0, limit] where `deriv(x)` stops being positive, or `limit` if it never does.
/// Scans in small steps, then bisects the step where the sign changes.
pub fn first_fold(deriv: impl Fn(f64) -> f64, limit: f64) -> f64 {
    const STEPS: usize = 2048;
    let step = limit / STEPS as f64;
    let mut prev = 0.0;
    for i in 1..=STEPS {
        let x = step * i as f64;
        let d = deriv(x);
        if d.is_nan() || d <= 0.0 {
            let (mut lo, mut hi) = (prev, x);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if deriv(mid) > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            return lo;
        }
        prev = x;
    }
    limit
}

/// Solves f(x) = y for x in [0, x_max] where f increases strictly on that interval.
/// Newton steps from `guess`, falling back to bisection whenever a step leaves the bracket,
/// so it converges even where the derivative is near zero. None if y is outside f's range.
pub fn newton_monotone(
    f: impl Fn(f64) -> f64,
    df: impl Fn(f64) -> f64,
    y: f64,
    x_max: f64,
    guess: Option<f64>,
) -> Option<f64> {
    let (f0, f1) = (f(0.0), f(x_max));
    let tol = 1e-12 * (1.0 + y.abs());
    if !(y >= f0 - tol && y <= f1 + tol) {
        return None;
    }
    let (mut lo, mut hi) = (0.0, x_max);
    let mut x = guess
        .filter(|g| g.is_finite() && *g > lo && *g < hi)
        .unwrap_or(0.5 * (lo + hi));
    for _ in 0..100 {
        let fx = f(x) - y;
        if fx.abs() <= tol {
            return Some(x);
        }
        if fx > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        let d = df(x);
        let next = x - fx / d;
        x = if d > 0.0 && next > lo && next < hi {
            next
        } else {
            0.5 * (lo + hi)
        };
        if hi - lo < 1e-15 {
            break;
        }
    }
    Some(x.clamp(0.0, x_max))
}
