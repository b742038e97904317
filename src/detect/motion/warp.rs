//! The motion detector's warp: a scan view's background, kept from where the vehicle was, is
//! moved to where it is now through the ground plane before each comparison (the views are
//! fixed in the world, so only the vehicle's travel needs taking out).

use crate::geometry::Projection;
use glam::{DMat3, DVec2, DVec3};

/// The warp between backgrounds is computed on a grid this many pixels apart.
const GRID: usize = 8;

/// For each pixel of a view seen from `to` (world NED), where the view seen from `from`
/// showed the same thing: through the ground point it shows (the sky, through no point,
/// stays where it is). None where that is outside the view. Computed on a grid and
/// interpolated.
pub(super) fn sources(
    w: usize,
    h: usize,
    projection: Projection,
    world_from_view: DMat3,
    from: DVec3,
    to: DVec3,
) -> Vec<Option<DVec2>> {
    let still = from.distance(to) < 1e-3;
    let view_from_world = world_from_view.transpose();
    let source = |p: DVec2| -> Option<DVec2> {
        if still {
            return Some(p);
        }
        let ray = world_from_view * projection.ray(p);
        let seen = if ray.z > 1e-6 && to.z < 0.0 {
            let ground = to + ray * (-to.z / ray.z);
            (ground - from).normalize()
        } else {
            ray
        };
        projection.point(view_from_world * seen)
    };
    let (gw, gh) = (w.div_ceil(GRID) + 1, h.div_ceil(GRID) + 1);
    let nodes: Vec<Option<DVec2>> = (0..gh)
        .flat_map(|j| (0..gw).map(move |i| (i, j)))
        .map(|(i, j)| source(DVec2::new((i * GRID) as f64, (j * GRID) as f64) + 0.5))
        .collect();
    let mut out = vec![None; w * h];
    for y in 0..h {
        for x in 0..w {
            let (i, j) = (x / GRID, y / GRID);
            let (fx, fy) = (
                (x % GRID) as f64 / GRID as f64,
                (y % GRID) as f64 / GRID as f64,
            );
            let corners = [
                nodes[j * gw + i],
                nodes[j * gw + i + 1],
                nodes[(j + 1) * gw + i],
                nodes[(j + 1) * gw + i + 1],
            ];
            if let [Some(a), Some(b), Some(c), Some(d)] = corners {
                out[y * w + x] =
                    Some((a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy);
            }
        }
    }
    out
}

/// `picture` (w × h) sampled bilinearly at each of `at` (view points); None outside it.
pub(super) fn resample(
    picture: &[f32],
    w: usize,
    h: usize,
    at: &[Option<DVec2>],
) -> Vec<Option<f32>> {
    let sample = |q: DVec2| -> Option<f32> {
        let q = q - 0.5;
        let (x0, y0) = (q.x.floor(), q.y.floor());
        if x0 < 0.0 || y0 < 0.0 || x0 + 1.0 >= w as f64 || y0 + 1.0 >= h as f64 {
            return None;
        }
        let (fx, fy) = ((q.x - x0) as f32, (q.y - y0) as f32);
        let v = |x: f64, y: f64| picture[y as usize * w + x as usize];
        let top = v(x0, y0) * (1.0 - fx) + v(x0 + 1.0, y0) * fx;
        let bottom = v(x0, y0 + 1.0) * (1.0 - fx) + v(x0 + 1.0, y0 + 1.0) * fx;
        Some(top * (1.0 - fy) + bottom * fy)
    };
    at.iter().map(|q| q.and_then(sample)).collect()
}
