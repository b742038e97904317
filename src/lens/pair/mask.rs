//! What the airframe hides from a lens of a pair: polygons drawn on the pair's frame (lens.cal's
//! `masks`, in the frame's pixels), each within one lens's image. The seam's blend
//! (`render::stitch`) gives the pixels a polygon covers the other lens's colour for the same
//! ray wherever that lens sees it, easing in over the pair's feather inside the polygon's edge,
//! so the airframe one lens sees is drawn from the other.

use glam::DVec2;

/// One polygon of what the airframe hides, in frame pixels (pixel centres at whole numbers).
#[derive(Clone, Debug, PartialEq)]
pub struct Mask {
    pub points: Vec<DVec2>,
}

impl Mask {
    /// Whether frame point `p` lies inside the polygon (even-odd rule).
    pub fn contains(&self, p: DVec2) -> bool {
        let mut inside = false;
        let n = self.points.len();
        for i in 0..n {
            let (a, b) = (self.points[i], self.points[(i + n - 1) % n]);
            if (a.y > p.y) != (b.y > p.y) && p.x < a.x + (p.y - a.y) * (b.x - a.x) / (b.y - a.y) {
                inside = !inside;
            }
        }
        inside
    }

    /// How far `p` lies from the polygon's nearest edge, pixels.
    pub fn distance(&self, p: DVec2) -> f64 {
        let n = self.points.len();
        (0..n)
            .map(|i| {
                let (a, b) = (self.points[i], self.points[(i + 1) % n]);
                let t = ((p - a).dot(b - a) / (b - a).length_squared().max(1e-12)).clamp(0.0, 1.0);
                p.distance(a + (b - a) * t)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// The share of the other lens's colour at `p`: 0 outside, rising smoothly to 1 at `edge`
    /// pixels inside the polygon's edge.
    pub fn share(&self, p: DVec2, edge: f64) -> f64 {
        if !self.contains(p) {
            return 0.0;
        }
        let t = (self.distance(p) / edge.max(1e-9)).min(1.0);
        t * t * (3.0 - 2.0 * t)
    }

    /// The polygon in a frame scaled by `scale` after cropping `origin` off (as
    /// `PixelAffine::rescaled` moves a lens's centre).
    pub fn rescaled(&self, scale: DVec2, origin: DVec2) -> Mask {
        let at = |p: DVec2| (p - origin + DVec2::splat(0.5)) * scale - DVec2::splat(0.5);
        Mask {
            points: self.points.iter().map(|&p| at(p)).collect(),
        }
    }
}

/// The share of the other lens's colour at frame point `p` under any of `masks`.
pub fn masked_share(masks: &[Mask], p: DVec2, edge: f64) -> f64 {
    masks.iter().map(|m| m.share(p, edge)).fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Mask {
        Mask {
            points: [(10.0, 10.0), (50.0, 10.0), (50.0, 50.0), (10.0, 50.0)]
                .map(|(x, y)| DVec2::new(x, y))
                .to_vec(),
        }
    }

    #[test]
    fn the_share_is_none_outside_whole_past_the_edge_and_eases_between() {
        let m = square();
        assert_eq!(m.share(DVec2::new(5.0, 30.0), 8.0), 0.0);
        assert_eq!(m.share(DVec2::new(60.0, 30.0), 8.0), 0.0);
        assert_eq!(m.share(DVec2::new(30.0, 30.0), 8.0), 1.0);
        let half = m.share(DVec2::new(14.0, 30.0), 8.0);
        assert!((half - 0.5).abs() < 1e-9, "{half}");
        assert!(m.share(DVec2::new(11.0, 30.0), 8.0) < half);
    }

    #[test]
    fn a_rescaled_polygon_covers_the_same_part_of_the_picture() {
        let m = square().rescaled(DVec2::splat(0.5), DVec2::ZERO);
        assert!(m.contains(DVec2::new(15.0, 15.0)));
        assert!(!m.contains(DVec2::new(26.0, 15.0)));
    }
}
