//! The scan views: level rectilinear views fixed in the world, tiling the sphere, of which
//! each scan renders those the lens sees. Being fixed in the world, a view shows the same
//! scene whatever the vehicle's attitude, so consecutive scans compare pixel for pixel once
//! the vehicle's own motion over the ground is taken out (`motion`).

use super::AngularBox;
use crate::geometry::Projection;
use crate::geometry::rotation::direction;
use crate::lens::Lens;
use crate::plan::ViewMap;
use crate::plan::{FramePlan, PlannedView};
use glam::{DMat3, DVec2, DVec3};
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, TAU};

/// The size and field of the scan views.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewShape {
    pub width: u32,
    pub height: u32,
    /// Across the width; pixels are square.
    pub fov: f64,
}

const DEG: f64 = std::f64::consts::PI / 180.0;

/// The motion detector's views: 60° squares of 192 pixels. Neighbours overlap, so an object
/// cut by one view's edge is whole in the next.
pub const MOTION_VIEWS: ViewShape = ViewShape {
    width: 192,
    height: 192,
    fov: 60.0 * DEG,
};

/// A model's views, for a model whose input is `side` pixels square: 3:2, `side` pixels
/// tall and 80° across (58° down), squeezed into the model's square as a 3:2 photograph is
/// when resized plainly to it. Models trained that way (NanoDet, YOLO on COCO's 4:3 and 3:2
/// photographs) score things seen at their natural proportions lower: NanoDet-m's person in
/// darknet's person.jpg falls from 0.71 to 0.44 when the photograph is letterboxed instead.
pub fn model_views(side: u32) -> ViewShape {
    ViewShape {
        width: (side * 3 / 2) & !1,
        height: side,
        fov: 80.0 * DEG,
    }
}

/// One scan view: its index in the fixed set (the same view from scan to scan), and its aim.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScanView {
    pub index: usize,
    pub yaw: f64,
    pub pitch: f64,
    pub fov: f64,
}

/// The fixed set, `fov` across each: the nadir and zenith, and rings of 8 at 45° below, 10
/// at the horizon and 8 at 45° above.
pub fn all_views(fov: f64) -> Vec<ScanView> {
    let mut aims = vec![(0.0, -FRAC_PI_2)];
    for (pitch, count) in [(-FRAC_PI_4, 8), (0.0, 10), (FRAC_PI_4, 8)] {
        for k in 0..count {
            aims.push((k as f64 * TAU / count as f64, pitch));
        }
    }
    aims.push((0.0, FRAC_PI_2));
    aims.into_iter()
        .enumerate()
        .map(|(index, (yaw, pitch))| ScanView {
            index,
            yaw,
            pitch,
            fov,
        })
        .collect()
}

/// The scan views the lens sees any of (their centre or a corner, at this attitude), and
/// the mosaic that renders them, each of `shape`.
pub fn visible(
    lens: &Lens,
    lens_from_world: DMat3,
    shape: ViewShape,
) -> (Vec<ScanView>, FramePlan) {
    let all = all_views(shape.fov);
    let aims: Vec<_> = all.iter().map(|v| (v.yaw, v.pitch, v.fov)).collect();
    let size = (shape.width, shape.height);
    let probe = FramePlan::mosaic(lens, lens_from_world, &aims, size, 1);
    let s = DVec2::new(shape.width as f64, shape.height as f64);
    let points = [
        (0.5, 0.5),
        (0.02, 0.02),
        (0.98, 0.02),
        (0.02, 0.98),
        (0.98, 0.98),
    ];
    let seen: Vec<ScanView> = all
        .into_iter()
        .zip(&probe.views)
        .filter(|(_, view)| {
            points.iter().any(|&(x, y)| {
                let p = DVec2::new(x, y) * s;
                probe.fisheye_pixel(view, p).is_some()
            })
        })
        .map(|(v, _)| v)
        .collect();
    let aims: Vec<_> = seen.iter().map(|v| (v.yaw, v.pitch, v.fov)).collect();
    let columns = (seen.len() as f64).sqrt().ceil() as u32;
    let plan = FramePlan::mosaic(lens, lens_from_world, &aims, size, columns);
    (seen, plan)
}

/// Where a box in a scan view (pixels, `low` its top-left corner and `high` just past its
/// bottom-right) is in the world: its centre's direction and its angular size.
pub fn to_world(
    view: &ScanView,
    planned: &PlannedView,
    low: DVec2,
    high: DVec2,
) -> Option<AngularBox> {
    let ViewMap::Rays {
        projection,
        world_from_view,
    } = planned.map
    else {
        return None;
    };
    let focal = Projection::focal(planned.rect.w as f64, view.fov);
    let size = (high - low) / focal;
    Some(AngularBox {
        centre: world_from_view * projection.ray((low + high) / 2.0),
        width: size.x,
        height: size.y,
    })
}

/// Whether `view` (rendered as `planned`) shows a thing `size` radians across at `ray` at
/// least `margin` pixels clear of its edges.
pub fn clear_of_edges(
    view: &ScanView,
    planned: &PlannedView,
    ray: DVec3,
    size: f64,
    margin: f64,
) -> bool {
    let ViewMap::Rays {
        projection,
        world_from_view,
    } = planned.map
    else {
        return false;
    };
    let (w, h) = (planned.rect.w as f64, planned.rect.h as f64);
    let margin = size * Projection::focal(w, view.fov) / 2.0 + margin;
    projection
        .point(world_from_view.transpose() * ray)
        .is_some_and(|p| p.min_element() > margin && p.x < w - margin && p.y < h - margin)
}

/// The scan view that reports a thing `size` radians across at `ray`, views overlapping: of
/// the views showing it at least `margin` pixels clear of their edges (or, if none does, of
/// all), the one whose centre is nearest.
pub fn owner(
    views: &[ScanView],
    plan: &FramePlan,
    ray: DVec3,
    size: f64,
    margin: f64,
) -> Option<usize> {
    let nearest = |whole: bool| {
        views
            .iter()
            .zip(&plan.views)
            .filter(|(v, planned)| !whole || clear_of_edges(v, planned, ray, size, margin))
            .map(|(v, _)| (v.index, direction(v.yaw, v.pitch).angle_between(ray)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i)
    };
    nearest(true).or_else(|| nearest(false))
}

/// A crop around a tracked object for the track step: a square view aimed at where the
/// object should be, `CROP_MARGIN` times its size across (within [`CROP_FOV`]), so that it
/// is whole in it after moving a little, and large enough for a detector to see.
pub fn crop_view(id: u32, yaw: f64, pitch: f64, size: f64) -> ScanView {
    ScanView {
        index: CROPS + id as usize,
        yaw,
        pitch,
        fov: (size * CROP_MARGIN).clamp(CROP_FOV.0, CROP_FOV.1),
    }
}

/// A crop is this many times its object's size across.
const CROP_MARGIN: f64 = 3.0;
/// A crop's narrowest and widest field.
const CROP_FOV: (f64, f64) = (8.0 * DEG, 80.0 * DEG);
/// Crops' view indices start here, past the scan views'.
const CROPS: usize = 1 << 20;
