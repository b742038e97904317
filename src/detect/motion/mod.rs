//! The built-in detector, no model file: things that move. Each scan view keeps a background
//! (a slow average of what it showed); before each comparison the background is moved to
//! where the vehicle now is, point by point through the ground plane (the views are fixed in
//! the world, so the vehicle's rotation needs nothing). Pixels far from their background are
//! foreground; their connected blobs are the detections.

mod blob;
mod compare;
mod warp;

use super::angular::Detection;
use super::scan::ScanView;
use crate::geometry::Projection;
use crate::plan::FramePlan;
use crate::plan::ViewMap;
use blob::JOIN;
use glam::DVec3;
use std::collections::HashMap;
use warp::{resample, sources};

/// A pixel this many grey levels from its background is foreground.
const THRESHOLD: f32 = 18.0;
/// How fast the background follows the scene, per scan: background pixels, foreground ones.
const FOLLOW: f32 = 0.15;
const FOLLOW_FOREGROUND: f32 = 0.02;
/// Scans a view's background takes before it is compared with (what moved in the first
/// scan leaves a stain where it stood, which the stain rules below take back).
const WARM_UP: u32 = 2;
/// Where the background has edges, the threshold rises by this many times the edge's grey
/// levels per pixel: a background moved with the vehicle is a fraction of a pixel off.
const EDGE_SLACK: f32 = 2.0;
/// A blob's confidence: its mean difference over this (capped below 1).
const FULL_CONFIDENCE: f32 = 64.0;
/// Below this a pixel is taken for the black outside the lens's circle (16 in video-range
/// luma).
const DARK: f32 = 20.0;
/// How far from the rim of the circle (and from a view's edge) a pixel must be to count.
const EDGE: usize = 3;
/// The least width and height of a blob, pixels.
const MIN_SIDE: f64 = 2.0;
/// The class motion detections carry.
pub const MOVING: u16 = 0;

struct Background {
    luma: Vec<f32>,
    /// The picture the last scan showed.
    last: Vec<f32>,
    /// Where the vehicle was (world NED, ground at z = 0) when it was last brought up to date,
    /// and when (seconds).
    eye: DVec3,
    time: f64,
    scans: u32,
}

/// The moving-object detector over the scan views.
#[derive(Default)]
pub struct MotionDetector {
    backgrounds: HashMap<usize, Background>,
}

impl Background {
    fn new(luma: Vec<f32>, eye: DVec3, time: f64) -> Background {
        Background {
            last: luma.clone(),
            luma,
            eye,
            time,
            scans: 1,
        }
    }
}

impl MotionDetector {
    pub fn new() -> MotionDetector {
        MotionDetector::default()
    }

    /// Compares one scan with the backgrounds and brings them up to date. `plan` is the
    /// mosaic `views` were rendered with, `luma` its picture (`stride` bytes a row), `eye`
    /// the vehicle's position in a world frame whose ground is z = 0 (NED, metres) and `time`
    /// when the picture was taken (seconds). Each thing found carries its velocity, measured
    /// against where it stood in the last scan.
    pub fn detect(
        &mut self,
        views: &[ScanView],
        plan: &FramePlan,
        luma: &[u8],
        stride: usize,
        eye: DVec3,
        time: f64,
    ) -> Vec<Detection> {
        // Views no longer seen lose their background.
        self.backgrounds
            .retain(|i, _| views.iter().any(|v| v.index == *i));
        let mut found: Vec<Sighting> = vec![];
        // JOIN pixels, as an angle.
        let mut join = 0f64;
        for (view, planned) in views.iter().zip(&plan.views) {
            let ViewMap::Rays {
                projection,
                world_from_view,
            } = planned.map
            else {
                continue;
            };
            let r = planned.rect;
            join = join.max(JOIN as f64 / Projection::focal(r.w as f64, view.fov));
            let current = compare::view_luma(luma, stride, r);
            let Some(bg) = self.backgrounds.get_mut(&view.index) else {
                self.backgrounds
                    .insert(view.index, Background::new(current, eye, time));
                continue;
            };
            if bg.luma.len() != current.len() {
                *bg = Background::new(current, eye, time);
                continue;
            }
            let (w, h) = (r.w as usize, r.h as usize);
            let from = sources(w, h, projection, world_from_view, bg.eye, eye);
            let scan = compare::Scan {
                moved: resample(&bg.luma, w, h, &from),
                before: resample(&bg.last, w, h, &from),
                current,
                w,
                h,
            };
            let mut seen = scan.differences();
            let (things, taken) = scan.things(&mut seen);
            scan.follow(bg, &seen.mask, &taken);
            let since = time - bg.time;
            (bg.eye, bg.time) = (eye, time);
            bg.scans += 1;
            if bg.scans <= WARM_UP {
                bg.last = scan.current;
                continue;
            }
            let sightings = scan.sightings((view, planned), things, &seen.diff, since);
            found.extend(sightings);
            bg.last = scan.current;
        }
        one_per_thing(found, join)
    }
}

/// A thing as one scan view saw it.
pub(super) struct Sighting {
    view: usize,
    /// Whether the view shows it clear of its edges.
    clear: bool,
    detection: Detection,
}

/// Views overlap, so one thing is seen by several: sightings `join` radians apart or less
/// are one thing, reported as the view that saw most of it saw it (of the views showing it
/// clear of their edges, the largest box), its pieces in that view joined. Each view loses
/// some of a thing's pixels (where the rim of the lens's circle has just uncovered them, where
/// it crosses a line of the background as bright as itself, or where the view samples it
/// coarsest), and rarely gains any once stains are taken out.
fn one_per_thing(found: Vec<Sighting>, join: f64) -> Vec<Detection> {
    let mut groups: Vec<Vec<Sighting>> = vec![];
    for s in found {
        let mut group = vec![s];
        while let Some(k) = groups.iter().position(|g| {
            g.iter().any(|a| {
                group
                    .iter()
                    .any(|b| a.detection.bbox.gap(&b.detection.bbox) <= join)
            })
        }) {
            group.extend(groups.swap_remove(k));
        }
        groups.push(group);
    }
    groups
        .into_iter()
        .filter_map(|group| {
            let best = group
                .iter()
                .min_by(|a, b| {
                    let area = |s: &Sighting| s.detection.bbox.width * s.detection.bbox.height;
                    b.clear.cmp(&a.clear).then(area(b).total_cmp(&area(a)))
                })?
                .view;
            group
                .into_iter()
                .filter(|s| s.view == best)
                .map(|s| s.detection)
                .reduce(|a, b| Detection {
                    bbox: a.bbox.union(&b.bbox),
                    confidence: a.confidence.max(b.confidence),
                    class: MOVING,
                    velocity: a.velocity.or(b.velocity),
                })
        })
        .collect()
}
