//! Boxes as the vehicle sees them: a detection's box in a crop becomes a direction in the
//! world (NED) with an angular width and height, so that boxes from different crops, frames
//! and attitudes compare directly: overlap is measured on the plane tangent to the sphere
//! between two boxes, never in a picture's pixels.

use crate::geometry::rotation::{direction, yaw_pitch};
use glam::{DVec2, DVec3};

/// A box on the sphere of directions: its centre (a unit vector in the world's NED frame) and
/// its angular width and height (radians) across the local horizontal and vertical there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AngularBox {
    pub centre: DVec3,
    pub width: f64,
    pub height: f64,
}

/// One thing a detector found: where, how sure it is (0..1) and what (the model's class).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Detection {
    pub bbox: AngularBox,
    pub confidence: f64,
    pub class: u16,
    /// How fast its centre moves across the sky (world NED, per second), where the detector
    /// measures it (the motion detector does, against its last scan): a new object is looked
    /// for where this takes it.
    pub velocity: Option<DVec3>,
}

impl AngularBox {
    /// The box centred at world `yaw` and `pitch`, `width` × `height` radians.
    pub fn new(yaw: f64, pitch: f64, width: f64, height: f64) -> AngularBox {
        AngularBox {
            centre: direction(yaw, pitch),
            width,
            height,
        }
    }

    /// The centre's world yaw and pitch.
    pub fn yaw_pitch(&self) -> (f64, f64) {
        yaw_pitch(self.centre)
    }

    /// The angular size the tiles frame: the larger side.
    pub fn size(&self) -> f64 {
        self.width.max(self.height)
    }

    /// The angle between the two centres.
    pub fn angle_to(&self, other: &AngularBox) -> f64 {
        self.centre.angle_between(other.centre)
    }

    /// Both boxes' centres on the plane tangent to the sphere midway between them (radians
    /// near the middle; horizontal axis level, vertical axis towards the zenith), and that
    /// plane's middle and axes. None for opposite directions.
    fn on_tangent_plane(&self, other: &AngularBox) -> Option<(DVec2, DVec2, [DVec3; 3])> {
        let mid = (self.centre + other.centre).try_normalize()?;
        // Level axis; at the zenith or nadir any pair of axes does.
        let (h, v) = match DVec3::Z.cross(mid).try_normalize() {
            Some(h) => (h, mid.cross(h)),
            None => mid.any_orthonormal_pair(),
        };
        // Gnomonic projection onto the tangent plane.
        let at = |d: DVec3| {
            let along = d.dot(mid);
            (along > 1e-9).then(|| DVec2::new(d.dot(h), d.dot(v)) / along)
        };
        Some((at(self.centre)?, at(other.centre)?, [mid, h, v]))
    }

    /// Intersection over union with `other`, both laid on the plane tangent to the sphere
    /// midway between their centres.
    pub fn overlap(&self, other: &AngularBox) -> f64 {
        let Some((a, b, _)) = self.on_tangent_plane(other) else {
            return 0.0;
        };
        let (ha, hb) = (self.half(), other.half());
        let low = (a - ha).max(b - hb);
        let high = (a + ha).min(b + hb);
        let inter = (high - low).max(DVec2::ZERO);
        let inter = inter.x * inter.y;
        let union = self.width * self.height + other.width * other.height - inter;
        if union > 0.0 { inter / union } else { 0.0 }
    }

    /// The gap between the two boxes (radians; 0 where they touch or overlap), the larger of
    /// the horizontal and vertical gaps.
    pub fn gap(&self, other: &AngularBox) -> f64 {
        let Some((a, b, _)) = self.on_tangent_plane(other) else {
            return std::f64::consts::PI;
        };
        let gap = (a - b).abs() - self.half() - other.half();
        gap.max_element().max(0.0)
    }

    /// The box enclosing both, on the plane tangent between them.
    pub fn union(&self, other: &AngularBox) -> AngularBox {
        let Some((a, b, [mid, h, v])) = self.on_tangent_plane(other) else {
            return *self;
        };
        let low = (a - self.half()).min(b - other.half());
        let high = (a + self.half()).max(b + other.half());
        let c = (low + high) / 2.0;
        AngularBox {
            centre: (mid + h * c.x + v * c.y).normalize(),
            width: high.x - low.x,
            height: high.y - low.y,
        }
    }

    fn half(&self) -> DVec2 {
        DVec2::new(self.width, self.height) / 2.0
    }
}

/// Non-maximum suppression, as a detector's raw boxes need: the boxes at `threshold`
/// confidence or more, highest first, each dropped when it overlaps one already kept by more
/// than `max_overlap`, and at most `limit` kept.
pub fn suppress(
    mut found: Vec<Detection>,
    threshold: f64,
    max_overlap: f64,
    limit: usize,
) -> Vec<Detection> {
    found.retain(|d| d.confidence >= threshold && d.confidence.is_finite());
    found.sort_by(|a, b| b.confidence.total_cmp(&a.confidence));
    let mut kept: Vec<Detection> = vec![];
    for d in found {
        if kept.len() == limit {
            break;
        }
        if kept.iter().all(|k| k.bbox.overlap(&d.bbox) <= max_overlap) {
            kept.push(d);
        }
    }
    kept
}
